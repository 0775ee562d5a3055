"""The generalized damped physical pendulum (Quiroga and Ospina-Henao 2017, eq 11-26).

    I φ'' = −m g l sin φ − γ I φ'|φ'|^(n−1) − f sgn(φ') + τ

State is ``(φ, φ')`` in rad and rad/s. ``γ`` has units s^(n−2); ``n = 0`` is dry (Coulomb)
friction of magnitude ``γ I``, ``n = 1`` viscous, ``n = 2`` quadratic drag (eq 15-16). ``f`` is
a Coulomb friction torque beside the power law (``friction``, N m; the URDF's
``<dynamics friction>``, MuJoCo's ``frictionloss``): at rest the joint sticks while
|τ − m g l sin φ| <= f (+ γ I where n = 0), :func:`coulomb_level`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from .errors import IntegratorError, ModelError
from .law import compile_damping, compile_power, damping_derivative

FloatArray = npt.NDArray[np.float64]


MAX_SPEED = 1e4
"""The largest |φ'| (rad/s) an initial state may have: the core's state bound.

Far above any physical joint (95 000 rpm), it keeps the kinetic energy, the guard's substep
counts and the angle swept per step finite and resolvable in float64."""

MAX_DAMPING_POWER = 1e250
"""Bound on the specific damping power γ |φ'|^(n+1) of an initial state (W per kg m²).

For large n the damping law itself overflows float64 long before the speed bound (5^1000);
refusing such states keeps the damping, its work and its slope finite."""

MAX_INPUT_ACCEL = 1e8
"""The largest |τ/I| (rad/s²) accepted as input: the speed it adds per step stays bounded."""

MAX_PHASE_PER_STEP = 100.0
"""The largest h ω0 accepted: a step may span at most this many radians of small-oscillation
phase (it is then cut into substeps that each resolve it, so the bound caps their number)."""

MAX_STEPS = 100_000_000
"""The default largest number of steps of one run (``simulate``, ``sweep``)."""

MAX_RUN_TRIALS = 1_000_000
"""The most trial substeps an adaptive method may spend in one ``simulate`` call.

An adaptive method's work is set by its inputs together: t_end ω0 radians of oscillation at
some 1-130 trial substeps a radian (more the tighter rtol and the lower the method's order),
plus what a stiff damping slope costs an explicit pair. Fast gravity makes that unbounded in
practice (g = 1e11: ω0 = 3.2e5 s⁻¹, 3.5e6 trials a second of ``dopri5`` at rtol = 1e-8), so
a run that spends this many is stopped there with the reason (:func:`run_work_refusal`), and
one that :func:`oscillation_trials` puts beyond it is refused before any work."""

INERTIA_RTOL = 1e-12
"""Round-off allowed in the parallel-axis test I >= m l²."""


NOT_REAL = (bool, np.bool_, str, bytes, complex, np.complexfloating)
"""Types refused as a real number although ``float()`` may take them: ``True`` is not a number
of anything and a complex value would make the state complex (arrays of one or more entries
are refused as well: an array is not one number)."""


def shown(value: object) -> str:
    """Return ``repr(value)`` for a message, at most 60 characters (a long array or integer)."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) > 2 ** 1024:
        return f'an integer of {value.bit_length()} bits'  # repr may refuse > 4300 digits
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + '...'


def check_finite(name: str, value: float) -> float:
    """Return ``value`` as a float, or raise ModelError naming it if not a finite real.

    Booleans, strings, complex numbers and arrays are refused (:data:`NOT_REAL`); an integer
    beyond float64 is refused as not finite.
    """
    if isinstance(value, NOT_REAL) or np.ndim(value) > 0:
        raise ModelError(f'{name} must be a real number, got {shown(value)}')
    try:
        x = float(value)
    except OverflowError:
        raise ModelError(f'{name} must be finite, got {shown(value)} (beyond float64)') from None
    except (TypeError, ValueError):
        raise ModelError(f'{name} must be a real number, got {shown(value)}') from None
    if not math.isfinite(x):
        raise ModelError(f'{name} must be finite, got {x}')
    return x


def _check_positive(name: str, value: float, unit: str) -> float:
    x = check_finite(name, value)
    if x <= 0.0:
        raise ModelError(f'{name} must be > 0 {unit}, got {x}')
    return x


def _check_nonneg(name: str, value: float, unit: str) -> float:
    x = check_finite(name, value)
    if x < 0.0:
        raise ModelError(f'{name} must be >= 0{unit}, got {x}')
    return x


@dataclass(frozen=True)
class PendulumParams:
    """Validated physical parameters of the pendulum.

    Parameters
    ----------
    m : float
        Mass in kg (> 0).
    l : float
        Distance from the pivot to the centre of mass in m (> 0).
    inertia : float
        Moment of inertia about the pivot in kg m² (> 0).
    g : float
        Gravitational acceleration in m/s² (>= 0).
    gamma : float
        Damping coefficient γ in s^(n−2) (>= 0).
    n : float
        Damping exponent (>= 0, real): 0 Coulomb, 1 viscous, 2 quadratic drag.
    friction : float
        Coulomb friction torque f in N m (>= 0) beside the power law: −f sgn(φ'), and at rest
        the joint sticks while the other torques stay within the Coulomb level
        (:func:`coulomb_level`). 0 (the default) leaves the power law alone, to the bit.

    The defaults are the paper's set-up: m = 0.2 kg, l = 1 m, I = 0.2 kg m², g = 9.8 m/s²,
    so ω0² = 9.8 s⁻², with γ = 1 and n = 1.
    """

    m: float = 0.2
    l: float = 1.0  # noqa: E741 - the paper's symbol
    inertia: float = 0.2
    g: float = 9.8
    gamma: float = 1.0
    n: float = 1.0
    friction: float = 0.0

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, 'm', _check_positive('m', self.m, 'kg'))
        set_(self, 'l', _check_positive('l', self.l, 'm'))
        set_(self, 'inertia', _check_positive('inertia', self.inertia, 'kg m^2'))
        set_(self, 'g', _check_nonneg('g', self.g, ' m/s^2'))
        set_(self, 'gamma', _check_nonneg('gamma', self.gamma, ' s^(n-2)'))
        set_(self, 'n', _check_nonneg('n', self.n, ''))
        set_(self, 'friction', _check_nonneg('friction', self.friction, ' N m'))
        # Parallel-axis theorem: I = I_cm + m l² >= m l² for every rigid body.
        limit = self.m * self.l * self.l
        if self.inertia < limit * (1.0 - INERTIA_RTOL):
            raise ModelError(f'inertia must be >= m*l**2 = {limit:.6g} kg m^2 for a rigid body '
                             f'(parallel-axis theorem), got {self.inertia:.6g}')

    @classmethod
    def from_omega0_sq(cls, omega0_sq: float, gamma: float, n: float,
                       friction: float = 0.0) -> PendulumParams:
        """Build parameters with m = I = 1 kg (m²) and l = 1 m, g = ω0², for dimensionless use.

        ω0² is checked under its own name (``omega0_sq``), before it becomes g; ``friction`` is
        then f/I in rad/s².
        """
        w2 = _check_nonneg('omega0_sq', omega0_sq, ' s^-2')
        return cls(m=1.0, l=1.0, inertia=1.0, g=w2, gamma=gamma, n=n, friction=friction)

    @property
    def omega0_sq(self) -> float:
        """Return ω0² = m g l / I (eq 11), in s⁻²."""
        return self.m * self.g * self.l / self.inertia

    @property
    def friction_accel(self) -> float:
        """Return the Coulomb friction per unit inertia f/I in rad/s²."""
        return self.friction / self.inertia

    @property
    def mgl(self) -> float:
        """Return the gravity torque scale m g l in N m."""
        return self.m * self.g * self.l

    def with_changes(self, **changes: Any) -> PendulumParams:
        """Return a validated copy with some fields changed."""
        return replace(self, **changes)

    def damping(self, dphi: float) -> float:
        """Return the damping acceleration γ φ'|φ'|^(n−1) (eq 15) at velocity ``dphi``.

        For n = 0 this is γ sgn(φ'), zero at rest; sticking is handled by the integrators.
        The law is the core's one definition (``law.damping_expression``), compiled for n.
        """
        return float(compile_damping(self.n)(dphi, self.gamma, 1.0))

    def acceleration(self, phi: float, dphi: float, torque: float = 0.0) -> float:
        """Return φ'' = −γ φ'|φ'|^(n−1) − (f/I) sgn φ' − ω0² sin φ + τ/I (eq 16 with input).

        Off rest; at rest (φ' = 0) the friction term is 0 here (sticking is the integrators').
        """
        acc = -self.damping(dphi) - self.omega0_sq * math.sin(phi) + torque / self.inertia
        if self.friction > 0.0 and dphi != 0.0:
            acc -= math.copysign(self.friction_accel, dphi)
        return acc

    @property
    def smooth_damping(self) -> bool:
        """Return True where φ'|φ'|^(n−1) is infinitely differentiable (n = 1, 3, 5, ...)."""
        return smooth_law(self.n)

    def jacobian_eigenvalues(self, phi: float, dphi: float) -> tuple[complex, complex]:
        """Return the eigenvalues of the Jacobian [[0, 1], [−ω0² cos φ, −d]] (eq 18-19).

        ``d = γ n |φ'|^(n−1)``; for n < 1 at rest d is unbounded and ``inf`` is used.
        """
        d = damping_derivative(self.gamma, self.n, dphi)
        c = self.omega0_sq * math.cos(phi)
        return _eigs(d, c)


def smooth_law(n: float) -> bool:
    """Return True where φ'|φ'|^(n−1) is infinitely differentiable: n = 1, 3, 5, ... (eq 15).

    Every other law has a kink at φ' = 0 (n even, non-integer, or 0): the core's one test.
    """
    return n >= 1.0 and n == int(n) and int(n) % 2 == 1


def _eigs(d: float, c: float) -> tuple[complex, complex]:
    if math.isinf(d):
        return complex(-math.inf, 0.0), complex(0.0, 0.0)
    disc = d * d - 4.0 * c
    if disc >= 0.0:
        s = math.sqrt(disc)
        # Stable form: avoid cancellation in the slow root.
        fast = -(d + s) / 2.0
        slow = c / fast if fast != 0.0 else (-d + s) / 2.0
        return complex(fast, 0.0), complex(slow, 0.0)
    s = math.sqrt(-disc)
    return complex(-d / 2.0, s / 2.0), complex(-d / 2.0, -s / 2.0)


def wrap_pi(x: Any) -> Any:
    """Return ``x`` wrapped into ``[−π, π)``: the angle equal to ``x`` modulo 2π (rad).

    Upright is ``φ = π + 2πk``, so ``wrap_pi(φ − π)`` is the angle from upright the short way
    round (a swing-up's goal box and the balance law read it).
    """
    return np.remainder(np.add(x, math.pi), 2.0 * math.pi) - math.pi


def energy(params: PendulumParams, phi: Any, dphi: Any) -> Any:
    """Return the mechanical energy E = ½ I φ'² + m g l (1 − cos φ) in J (eq 23)."""
    return kinetic_energy(params, dphi) + potential_energy(params, phi)


def kinetic_energy(params: PendulumParams, dphi: Any) -> Any:
    """Return the kinetic energy ½ I φ'² in J."""
    return 0.5 * params.inertia * np.square(dphi)


def potential_energy(params: PendulumParams, phi: Any) -> Any:
    """Return the potential energy m g l (1 − cos φ) in J, written as 2 m g l sin²(φ/2).

    The half-angle form keeps full relative precision near the bottom, where 1 − cos φ cancels.
    """
    return 2.0 * params.mgl * np.square(np.sin(np.multiply(phi, 0.5)))


def dissipated_power(params: PendulumParams, dphi: Any) -> Any:
    """Return the power lost to damping, γ I |φ'|^(n+1) + f |φ'| in W (eq 26; >= 0).

    φ' times the damping torque I D(φ'), generated from the law (``law.power_expression``),
    plus the Coulomb friction's f |φ'| where ``friction`` > 0.
    """
    power = compile_power(params.n)(dphi, params.gamma * params.inertia)
    if params.friction > 0.0:
        power = power + params.friction * np.abs(dphi)
    return power


def coulomb_level(gamma: float, n: float, friction: float) -> float:
    """Return the Coulomb level c per unit inertia (rad/s²): the joint sticks while |F| <= c.

    ``friction`` is f/I; the power law adds its own dry friction γ where n = 0 (eq 15). The
    core's one rule for the level: the rest test (``coulomb.rest_step``), ``Problem.coulomb``.
    """
    return friction + gamma if n == 0.0 else friction


def input_power(dphi: Any, torque: Any) -> Any:
    """Return the power put in by the external torque, τ φ' in W."""
    return np.multiply(torque, dphi)


def speed_limit(gamma: float, n: float) -> float:
    """Return the largest |φ'| accepted in a state for damping ``γ``, ``n`` (rad/s).

    The smaller of :data:`MAX_SPEED` and the speed where γ |φ'|^(n+1) reaches
    :data:`MAX_DAMPING_POWER` (computed in logarithms, so it never overflows itself).
    """
    if gamma <= 0.0:
        return MAX_SPEED
    log_v = (math.log(MAX_DAMPING_POWER) - math.log(gamma)) / (n + 1.0)
    return MAX_SPEED if log_v >= math.log(MAX_SPEED) else math.exp(log_v)


def states_accepted(phi0: Any, dphi0: Any, params: PendulumParams | None = None) -> Any:
    """Return where :func:`validate_state` accepts the states (φ0, φ'0): its rule, element-wise.

    A finite angle and a velocity within ±:func:`speed_limit` of the damping (±``MAX_SPEED``
    without ``params``; the speed limit is never above it); NaN and infinities are refused.
    Floats give a numpy bool, arrays an array of them (many episodes' start states at once).
    """
    bound = MAX_SPEED if params is None else speed_limit(params.gamma, params.n)
    with np.errstate(invalid='ignore'):
        return np.isfinite(phi0) & (np.abs(dphi0) <= bound)


def validate_state(phi0: float, dphi0: float,
                   params: PendulumParams | None = None) -> tuple[float, float]:
    """Check an initial state and return it as floats: the core's one state validation.

    The angle must be finite, the velocity finite and within ``±MAX_SPEED`` (and, given
    ``params``, within :func:`speed_limit` of its damping), so that energy, damping and
    every quantity derived from them stay finite in float64.
    """
    phi = check_finite('phi0', phi0)
    dphi = check_finite('dphi0', dphi0)
    if states_accepted(phi, dphi, params):
        return phi, dphi
    if abs(dphi) > MAX_SPEED:
        raise ModelError(f'dphi0 must be within +-{MAX_SPEED:g} rad/s (the state bound that '
                         f'keeps energy and damping finite), got {dphi:g}')
    if params is not None:
        lim = speed_limit(params.gamma, params.n)
        if abs(dphi) > lim:
            raise ModelError(
                f'dphi0 must be within +-{lim:.6g} rad/s for gamma = {params.gamma:g} and '
                f'n = {params.n:g} (keeps gamma*|dphi|**(n+1) below {MAX_DAMPING_POWER:g}), '
                f'got {dphi:g}')
    return phi, dphi


def check_torque(torque: float, params: PendulumParams) -> float:
    """Return the input torque as a float: finite and |τ/I| <= :data:`MAX_INPUT_ACCEL`."""
    tau = check_finite('torque', torque)
    if abs(tau) > MAX_INPUT_ACCEL * params.inertia:
        raise ModelError(f'torque must be within +-{MAX_INPUT_ACCEL * params.inertia:g} N m '
                         f'(|torque/I| <= {MAX_INPUT_ACCEL:g} rad/s^2), got {tau:g}')
    return tau


def check_step(h: float, params: PendulumParams | None = None) -> float:
    """Return the step ``h`` as a float: finite, > 0 and, given ``params``, h ω0 <= 100."""
    try:
        x = check_finite('h', h)
    except ModelError:
        x = math.nan
    if not x > 0.0:
        raise IntegratorError(f'h must be a finite step > 0 s, got {shown(h)}')
    if params is not None and params.omega0_sq > 0.0:
        limit = MAX_PHASE_PER_STEP / math.sqrt(params.omega0_sq)
        if x > limit:
            raise IntegratorError(f'h must be <= {MAX_PHASE_PER_STEP:g}/omega0 = {limit:.6g} s '
                                  f'for these parameters, got {x:g}')
    return x


MAX_TOLERANCE = {'rtol': 1e-3, 'atol': 1e-3}
"""The loosest ``rtol`` and ``atol`` an adaptive method accepts.

The error control rests on the pair's error estimate, which is asymptotic: it bounds the error
only while the error is small. At rtol or atol around 1 and above it no longer does (``dopri5``
at rtol = 10 ran to an infinite energy, at γ = 1e4 with rtol = atol = 1 to 1e138 J; ``rodas4``
at rtol = atol = 1e-2 gained 3.6 % energy in 2 s without damping), so such tolerances are
refused rather than answered with garbage. At 1e-3 the unforced energy rises by at most 7e-4
of its start over 10 s for every adaptive method (``test_core_hardening.py``)."""


def check_tolerance(name: str, value: float) -> float:
    """Return a tolerance as a float: finite, > 0, <= :data:`MAX_TOLERANCE` (IntegratorError)."""
    try:
        x = check_finite(name, value)
    except ModelError:
        x = math.nan
    if not x > 0.0:
        raise IntegratorError(f'{name} must be a finite tolerance > 0, got {shown(value)}')
    limit = MAX_TOLERANCE[name]
    if x > limit:
        raise IntegratorError(f'{name} must be <= {limit:g} (the error control cannot honour a '
                              f'looser tolerance), got {x:g}')
    return x


def check_flag(name: str, value: object) -> bool:
    """Return a switch (``guard``, ``energy_check``) as a bool: True or False only."""
    if not isinstance(value, (bool, np.bool_)):
        raise IntegratorError(f'{name} must be True or False, got {shown(value)}')
    return bool(value)


RUN_SPEED_SLACK = 1e-6
"""Relative slack of :func:`run_speed_limit` for the integrators' own energy error (``dopri5``
at rtol 1e-8 carried a state at the bound 1.3e-8 of it past the exact limit within 3 ms)."""


def run_speed_limit(gamma: float, n: float, omega0_sq: float) -> float:
    """Return the largest |φ'| (rad/s) a run may reach: the state bound raised by gravity.

    ``sqrt(L² + 4 ω0²)`` with L = :func:`speed_limit`: the most a state within the state bound
    reaches without input, since gravity can turn at most 2 ω0² of E/I into ½ φ'² (eq 23),
    times 1 + :data:`RUN_SPEED_SLACK`. Only an input torque drives a run beyond it.
    """
    lim = speed_limit(gamma, n)
    return math.sqrt(lim * lim + 4.0 * omega0_sq) * (1.0 + RUN_SPEED_SLACK)


def check_speed(dphi: float, gamma: float, n: float, omega0_sq: float,
                t: float | None = None) -> None:
    """Refuse to go on from a state faster than :func:`run_speed_limit`.

    Called after every step along a guarded run (``Stepper``, ``simulate``, ``sweep``; the
    adaptive substeps reject a trial beyond the limit instead): an input torque that drives
    |φ'| beyond it ends the run there with an IntegratorError (at time ``t`` where known), so
    that no step starts far outside the state bound of :func:`validate_state` (the work of a
    step grows with the speed it starts at).
    """
    lim = run_speed_limit(gamma, n, omega0_sq)
    if not abs(dphi) <= lim:
        at = '' if t is None else f' at t = {t:g} s'
        raise IntegratorError(
            f'dphi reached {dphi:.9g} rad/s{at}, beyond +-{lim:.9g} rad/s (the state bound '
            f'{speed_limit(gamma, n):.6g} rad/s raised by the most gravity adds, '
            f'sqrt(bound**2 + 4*omega0**2)): the run stops there')



def check_speed_ahead(dphi: float, ain: float, h: float, gamma: float, n: float,
                      omega0_sq: float, t: float) -> None:
    """Refuse, before it is taken, a step from t that certainly ends beyond the speed bound.

    While |φ'| <= L (:func:`run_speed_limit`), the input acceleration ``ain`` = τ/I outweighs
    gravity (at most ω0²) and damping (at most γ L^n) by c = |τ/I| − ω0² − γ L^n; where c > 0
    the speed along τ grows at least at c and cannot fall back through L, so a start
    ``sign(τ) φ'`` with ``sign(τ) φ' + c h > L`` ends the step of the exact flow beyond L
    (:func:`check_speed` would refuse it after the work). The caller asks only where that
    work is beyond the one-step work bound (``implicit.fallback_refused``).
    """
    lim = run_speed_limit(gamma, n, omega0_sq)
    try:
        damping = gamma * lim ** n if gamma > 0.0 else 0.0
    except OverflowError:
        return
    c = abs(ain) - omega0_sq - damping
    least = (dphi if ain > 0.0 else -dphi) + c * h
    if c > 0.0 and least > lim:
        raise IntegratorError(
            f'dphi would pass +-{lim:.9g} rad/s within the step of h = {h:g} s from t = {t:g} '
            f's: torque/I = {ain:g} rad/s^2 outweighs gravity and damping below that bound by '
            f'{c:.6g} rad/s^2, so from dphi = {dphi:g} rad/s it reaches at least {least:.6g} '
            f'rad/s: the run stops there, before the step')


def check_count(name: str, value: object, minimum: int = 1) -> int:
    """Return an integer count >= ``minimum`` (bools and floats refused, IntegratorError)."""
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise IntegratorError(f'{name} must be an integer >= {minimum}, got {value!r}')
    return value


OSCILLATION_TRIALS = {'dopri5': 0.12, 'dop853': 0.09, 'rodas4': 0.13, 'extrap6': 0.11,
                      'extrap8': 0.09}
"""Trial substeps a radian of oscillation, times rtol^(1/(q+1)) (q the order of the error
estimate): half the least each adaptive method took on undamped swings of 1e-3 and 2 rad at
rtol 1e-3 to 1e-10, so :func:`oscillation_trials` stays below the work it estimates."""


def oscillation_trials(method: str, error_order: int, t_end: float, rtol: float, atol: float,
                       params: PendulumParams, phi0: float, dphi0: float) -> float:
    """Return a lower estimate of the trials an adaptive run without input must spend (0: none).

    The run swings through t_end ω0 radians at some c rtol^(−1/(q+1)) trials a radian
    (:data:`OSCILLATION_TRIALS`) while rtol, not atol, sets its error scale: where the speed
    scale sqrt(2 E/I) (eq 23) stays at least atol/rtol to t_end, as the damping guarantees
    (E/E0 >= exp(−2 γ V^(n−1) t) for n >= 1, since dE/dt = −γ I |φ'|^(n+1) with |φ'| <= V;
    E0/I − γ V^(n+1) t for n < 1). Otherwise, and for an unknown method, 0 (no estimate).
    """
    c = OSCILLATION_TRIALS.get(method, 0.0)
    w2, g, n = params.omega0_sq, params.gamma, params.n
    e0 = 0.5 * dphi0 * dphi0 + 2.0 * w2 * math.sin(0.5 * phi0) ** 2
    if c == 0.0 or w2 == 0.0 or e0 == 0.0:
        return 0.0
    v = math.sqrt(2.0 * e0)
    if n >= 1.0:
        try:
            rate = v ** (n - 1.0)
        except OverflowError:   # a large n at v > 1 (n = 1e300): the bound is 0
            rate = math.inf
        left = e0 * math.exp(-2.0 * g * rate * t_end)
    else:
        left = e0 - g * v ** (n + 1.0) * t_end
    if not (left > 0.0 and rtol * math.sqrt(2.0 * left) >= atol):
        return 0.0
    return float(c * t_end * math.sqrt(w2) * max(rtol, 1e-13) ** (-1.0 / (error_order + 1)))


def run_work_refusal(method: str, t_end: float, rtol: float, omega0_sq: float,
                     budget: int) -> IntegratorError:
    """Return the error that stops an adaptive run beyond ``budget`` trial substeps.

    The message names the arguments that set the work (t_end, rtol, and gravity through ω0)
    and the limit, :data:`MAX_RUN_TRIALS`.
    """
    omega0 = math.sqrt(omega0_sq)
    return IntegratorError(
        f'{method} needs more than MAX_RUN_TRIALS = {budget} trial substeps for t_end = '
        f'{t_end:g} s at rtol = {rtol:g} (omega0 = {omega0:.6g} rad/s: {t_end * omega0:.3g} '
        f'rad of oscillation), beyond the work budget of one call: shorten t_end, loosen rtol '
        f'or simulate the run in parts')


def check_run_length(t_end: float, h: float, max_steps: int) -> float:
    """Return ``t_end`` as a float: finite, > 0 and at most ``max_steps`` steps of ``h``."""
    t = check_finite('t_end', t_end)
    if t <= 0.0:
        raise IntegratorError(f't_end must be > 0 s, got {t}')
    steps = t / h
    if steps > max_steps:
        raise IntegratorError(f't_end / h = {steps:.6g} steps exceeds max_steps = {max_steps} '
                              f'(pass a larger max_steps to run it)')
    return t
