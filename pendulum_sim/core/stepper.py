"""The stateful fixed-step integrator: what the real-time node and ``simulate`` both drive.

One :class:`Stepper` owns a pendulum's state and advances it by a fixed step ``h``. Around the
method's plain step (compiled from its tableau, ``explicit.py``) it adds what a trustworthy joint
needs:

- the stability guard (``guard.py``): substeps, or the implicit method, where ``h λ`` would leave
  the stability region;
- velocity reversals: with non-smooth damping (n even or not an integer) a step that straddles
  φ' = 0 is split at the reversal, located by Hermite interpolation of φ', which restores the
  method's order (the paper's Fig 9 remark on n = 2);
- static friction (n = 0): at rest the pendulum sticks while ``|τ/I − ω0² sin φ| ≤ γ``;
- an energy check: without input torque and with γ > 0 an explicit step whose energy rose is redone
  by the implicit method;
- the energy balance: damping and input work accumulated by the same quadrature as the state.
"""
from __future__ import annotations

import functools
import math

from .errors import IntegratorError, ModelError
from .explicit import ErrStepFn, StepFn, compile_damping, compile_error_step, compile_step
from .guard import FALLBACK, GuardStats, StabilityGuard, max_speed
from .implicit import dirk_step
from .methods import FALLBACK_METHOD, Method, get_method
from .model import PendulumParams, validate_state
from .tableaus import BACKWARD_EULER, RK4, Tableau

# An explicit step may raise the energy by round-off and by the conservative part of its
# truncation error near turning points, where the damping removes almost nothing; anything
# above this relative size is treated as a defect and the step is redone implicitly.
ENERGY_TOL = 1e-12


@functools.lru_cache(maxsize=256)
def _compiled(tableau: Tableau, w2: float, gamma: float, n: float) -> StepFn:
    return compile_step(tableau, w2, gamma, n)


@functools.lru_cache(maxsize=256)
def _compiled_branch(tableau: Tableau, w2: float, gamma: float, n: float,
                     sign: float) -> StepFn:
    """Compile a step whose damping is one smooth branch, sign · γ |φ'|^n, on both sides of 0.

    Used on either side of a velocity reversal, so that no stage of a partial step sees the
    kink (for n = 0 it is the constant friction of one direction of motion).
    """
    if n == 0.0:
        force = gamma * sign
        return compile_step(tableau, w2, gamma, 0.0, damping=lambda v: force)
    return compile_step(tableau, w2, gamma, n, damping=lambda v: sign * gamma * abs(v) ** n)


@functools.lru_cache(maxsize=64)
def _compiled_error(tableau: Tableau, w2: float, gamma: float, n: float) -> ErrStepFn:
    return compile_error_step(tableau, w2, gamma, n)


@functools.lru_cache(maxsize=64)
def _guard(tableau: Tableau) -> StabilityGuard:
    return StabilityGuard(tableau)


def hermite_root(v0: float, v1: float, dv0: float, dv1: float) -> float:
    """Return θ in (0, 1) where the cubic Hermite interpolant of φ' vanishes.

    ``v0``, ``v1`` are φ' at both ends (opposite signs), ``dv0``, ``dv1`` the derivatives
    h φ''. Newton's method, safeguarded by bisection on the bracket.
    """
    lo, hi = 0.0, 1.0
    flo = v0
    th = v0 / (v0 - v1)
    for _ in range(60):
        t2 = th * th
        t3 = t2 * th
        f = ((2 * t3 - 3 * t2 + 1) * v0 + (t3 - 2 * t2 + th) * dv0
             + (-2 * t3 + 3 * t2) * v1 + (t3 - t2) * dv1)
        if f == 0.0:
            return th
        if (f < 0.0) == (flo < 0.0):
            lo = th
        else:
            hi = th
        df = ((6 * t2 - 6 * th) * v0 + (3 * t2 - 4 * th + 1) * dv0
              + (-6 * t2 + 6 * th) * v1 + (3 * t2 - 2 * th) * dv1)
        nt = th - f / df if df != 0.0 else 0.5 * (lo + hi)
        if not lo < nt < hi:
            nt = 0.5 * (lo + hi)
        if abs(nt - th) <= 1e-15:
            return nt
        th = nt
    return th


class Stepper:
    """Advance one pendulum by a fixed step ``h``, guarded, with its energy balance.

    Parameters
    ----------
    params : PendulumParams
        The physical parameters; replace them live with :meth:`set_params`.
    phi0, dphi0 : float
        Initial angle (rad) and angular velocity (rad/s).
    h : float
        The fixed step in s (> 0).
    method : str
        A name of ``METHODS``: ``'rk4'`` (default, the paper's), ``'euler'``, ``'midpoint'``,
        ``'sdirk2'``, ``'sdirk3'`` or ``'dopri5'`` (error-controlled inside each step of h).
    guard : bool
        Keep explicit steps inside their stability region (substeps or implicit fallback).
    energy_check : bool
        Redo an explicit step implicitly when energy rose without input (γ > 0).
    rtol, atol : float
        Tolerances of the adaptive method.
    """

    def __init__(self, params: PendulumParams, phi0: float, dphi0: float, h: float,
                 method: str = 'rk4', *, guard: bool = True, energy_check: bool = True,
                 rtol: float = 1e-8, atol: float = 1e-10) -> None:
        if not isinstance(h, (int, float)) or not math.isfinite(h) or h <= 0.0:
            raise IntegratorError(f'h must be a finite step > 0 s, got {h!r}')
        for name, tol in (('rtol', rtol), ('atol', atol)):
            if not math.isfinite(tol) or tol <= 0.0:
                raise IntegratorError(f'{name} must be a finite tolerance > 0, got {tol!r}')
        self._method: Method = get_method(method)
        self._h = float(h)
        self._guard_on = guard
        self._energy_check = energy_check
        self._rtol, self._atol = float(rtol), float(atol)
        self._initial = validate_state(phi0, dphi0)
        self._h_try = 0.0  # the adaptive method's next trial step
        self.stats = GuardStats()
        self._configure(params)
        self.reset()

    # ------------------------------------------------------------------ configuration
    def _configure(self, params: PendulumParams) -> None:
        self._params = params
        tab = self._method.tableau
        w2, g, n = params.omega0_sq, params.gamma, params.n
        self._w2, self._gamma, self._n = w2, g, n
        self._omega0 = math.sqrt(w2)
        self._inv_inertia = 1.0 / params.inertia
        self._coulomb = n == 0.0 and g > 0.0
        self._nonsmooth = g > 0.0 and not params.smooth_damping
        self._damping = compile_damping(g, n)
        kind = self._method.kind
        self._explicit = kind == 'explicit'
        # The plain explicit step: the method's own, or RK4 where the method is implicit (used
        # only for a Coulomb break-away and never for the implicit method's own steps).
        self._plain_tableau = tab if tab.explicit else RK4
        self._step_fn: StepFn = _compiled(self._plain_tableau, w2, g, n)
        guard_needed = self._guard_on and self._explicit
        self._guard = _guard(tab) if guard_needed else None
        # For n = 1 the damping slope is constant, so the stability bound is decided once here.
        self._always_safe = (n == 1.0 and self._guard is not None
                             and self._h * (g + self._omega0) <= self._guard.disk)
        self._slope_scale = g * n
        self._e_cache = (math.nan, math.nan, 0.0)  # (φ, φ', E/I) of the last energy check
        self._margin_ain = math.nan  # the (τ/I, h) the speed margin was computed for
        self._margin_h = math.nan
        self._fast_speed = -1.0
        if self._guard is not None:
            self._set_margin(0.0, self._h)

    def _set_margin(self, ain: float, h: float) -> None:
        """Cache how much the speed can grow in a step of h under τ/I = ``ain``."""
        self._margin_ain, self._margin_h = ain, h
        force = abs(ain) + self._w2
        self._margin = max_speed(self._gamma, self._n, 0.0, h, force)
        # |φ'| below this keeps a step of h within the angle limit, whatever the torque: the
        # inlined fast path checks it without recomputing the margin.
        assert self._guard is not None
        self._fast_speed = self._guard.max_angle - self._h * (self._w2 + abs(ain))

    def set_params(self, params: PendulumParams) -> None:
        """Replace the physical parameters from the next step on; the state is kept.

        ``n`` and ``γ`` may change while running (the node's live parameters): the state
        (φ, φ') is continuous, only the vector field changes.
        """
        if not isinstance(params, PendulumParams):
            raise ModelError(f'params must be PendulumParams, got {type(params).__name__}')
        self._configure(params)

    def reset(self, phi0: float | None = None, dphi0: float | None = None) -> None:
        """Return to t = 0 and the initial state (or a new one), clearing work and counters."""
        if phi0 is not None or dphi0 is not None:
            self._initial = validate_state(self._initial[0] if phi0 is None else phi0,
                                           self._initial[1] if dphi0 is None else dphi0)
        self._p, self._v = self._initial
        self._steps = 0
        self._work_damping = 0.0  # per unit inertia, J / (kg m²)
        self._work_input = 0.0  # J
        self._e0 = self.energy()
        self._h_try = 0.0
        self.stats = GuardStats()

    # ------------------------------------------------------------------ state
    @property
    def params(self) -> PendulumParams:
        """Return the current physical parameters."""
        return self._params

    @property
    def method(self) -> str:
        """Return the method's name."""
        return self._method.name

    @property
    def h(self) -> float:
        """Return the fixed step in s."""
        return self._h

    @property
    def steps(self) -> int:
        """Return the number of steps of h taken since the last reset."""
        return self._steps

    @property
    def t(self) -> float:
        """Return the simulated time, ``steps · h`` (no accumulated round-off)."""
        return self._steps * self._h

    @property
    def phi(self) -> float:
        """Return the angle φ in rad."""
        return self._p

    @property
    def dphi(self) -> float:
        """Return the angular velocity φ' in rad/s."""
        return self._v

    def energy(self) -> float:
        """Return the mechanical energy E = ½ I φ'² + m g l (1 − cos φ) in J (eq 23)."""
        p = self._params
        s = math.sin(0.5 * self._p)
        return 0.5 * p.inertia * self._v * self._v + 2.0 * p.mgl * s * s

    @property
    def dissipated_work(self) -> float:
        """Return ∫ γ I |φ'|^(n+1) dt since the reset, in J (eq 26)."""
        return self._work_damping * self._params.inertia

    @property
    def input_work(self) -> float:
        """Return ∫ τ φ' dt since the reset, in J."""
        return self._work_input

    @property
    def residual(self) -> float:
        """Return the energy-balance residual E(t) − E(0) + ∫ dissipated − ∫ input, in J."""
        return self.energy() - self._e0 + self.dissipated_work - self._work_input

    # ------------------------------------------------------------------ stepping
    def advance(self, k: int, torque: float = 0.0) -> None:
        """Take ``k`` steps of h with constant torque."""
        for _ in range(k):
            self.step(torque)

    def step(self, torque: float = 0.0) -> None:
        """Advance one step h under the constant input torque ``torque`` (N m)."""
        self._advance(self._h, torque, 1)

    def step_by(self, h: float, torque: float = 0.0) -> None:
        """Advance by a one-off step ``h`` (for landing on an end time); ``t`` is not moved."""
        if not math.isfinite(h) or h <= 0.0:
            raise IntegratorError(f'h must be a finite step > 0 s, got {h!r}')
        self._advance(h, torque, 0)

    def _advance(self, h: float, torque: float, count: int) -> None:
        if not math.isfinite(torque):
            raise ModelError(f'torque must be finite, got {torque}')
        ain = torque * self._inv_inertia
        p, v = self._p, self._v
        stats = self.stats
        if self._coulomb and v == 0.0:
            p1, v1, w = self._from_rest(p, h, ain)
        elif self._explicit:
            try:
                if self._guard is None:
                    p1, v1, w = self._micro(p, v, h, ain)
                elif (self._always_safe and h == self._h and ain == self._margin_ain
                      and abs(v) * h < self._fast_speed):
                    # The common case, inlined: n = 1 inside the region, angle resolved.
                    p1, v1, w, _ = self._step_fn(p, v, h, ain)
                else:
                    if ain != self._margin_ain or h != self._margin_h:
                        self._set_margin(ain, h)
                    speed = abs(v) + self._margin
                    if h * speed <= self._guard.max_angle and (
                            self._always_safe or h * (self._slope(speed) + self._omega0)
                            <= self._guard.disk):
                        p1, v1, w = self._micro(p, v, h, ain)
                    else:
                        p1, v1, w = self._guarded(p, v, h, ain)
            except OverflowError:
                # Reachable only unguarded (the step blew up): the implicit method takes it.
                stats.fallbacks += 1
                p1, v1, w = self._implicit(p, v, h, ain)
            if self._energy_check and ain == 0.0 and self._gamma > 0.0:
                # Inlined accept test (the common case); _redo_energy handles a rise.
                w2 = self._w2
                cp, cv, e0 = self._e_cache
                if cp != p or cv != v:
                    s0 = math.sin(0.5 * p)
                    e0 = 0.5 * v * v + 2.0 * w2 * s0 * s0
                s1 = math.sin(0.5 * p1)
                e1 = 0.5 * v1 * v1 + 2.0 * w2 * s1 * s1
                if e1 <= e0 + ENERGY_TOL * (e0 + w2):
                    self._e_cache = (p1, v1, e1)
                else:
                    p1, v1, w = self._redo_energy(p, v, h, e0)
        elif self._method.kind == 'implicit':
            p1, v1, w = self._dirk_plain(p, v, h, ain)
        else:
            p1, v1, w = self._adaptive(p, v, h, ain)
        if not (math.isfinite(p1) and math.isfinite(v1)):
            # Last line of defence; the guard should make this unreachable for valid inputs.
            stats.fallbacks += 1
            p1, v1, w = self._implicit(p, v, h, ain)
        self._work_damping += w
        self._work_input += torque * (p1 - p)
        if v1 == 0.0 and v != 0.0 and self._coulomb:
            stats.sticks += 1
        self._p, self._v = p1, v1
        stats.steps += 1
        self._steps += count

    def _slope(self, speed: float) -> float:
        """Return the damping slope d at ``speed`` (inf where the cheap bound cannot decide)."""
        n = self._n
        if n == 2.0:
            return self._slope_scale * speed
        if n == 0.0:
            return 0.0
        if n < 1.0:
            return math.inf
        try:
            return float(self._slope_scale * speed ** (n - 1.0))
        except OverflowError:
            return math.inf

    def _guarded(self, p: float, v: float, h: float, ain: float) -> tuple[float, float, float]:
        """Cover h with the fewest stable substeps, re-judged after each one.

        The stiffness of n ≠ 1 damping moves with the velocity, so after each substep the
        guard looks again at what is left of the step.
        """
        assert self._guard is not None
        force = abs(ain) + self._w2
        left, w, taken = h, 0.0, 0
        while left > 0.0:
            m = self._guard.substeps(left, self._w2, self._gamma, self._n, p, v, force,
                                     abs(ain - self._w2 * math.sin(p)))
            if m == FALLBACK:
                self.stats.fallbacks += 1
                p, v, wi = self._implicit(p, v, left, ain)
                return p, v, w + wi
            hh = left / m
            p, v, wi = self._micro(p, v, hh, ain)
            w += wi
            taken += 1
            left = 0.0 if m == 1 else left - hh
        self.stats.substeps += taken - 1
        return p, v, w

    def _redo_energy(self, p: float, v: float, h: float,
                     e0: float) -> tuple[float, float, float]:
        """Redo a step whose energy rose without input; project if the implicit one rose too.

        The projection (Hairer, Lubich and Wanner, Geometric Numerical Integration, IV.4) keeps
        φ₁ and rescales |φ'₁| onto the energy E₀ − W the step itself says was dissipated, which
        is the energy balance the exact flow obeys.
        """
        tol = ENERGY_TOL * (e0 + self._w2)
        self.stats.energy_rejections += 1
        p1, v1, w = self._implicit(p, v, h, 0.0)
        e1 = 0.5 * v1 * v1 + 2.0 * self._w2 * math.sin(0.5 * p1) ** 2
        if e1 <= e0 + tol:
            return p1, v1, w
        self.stats.projections += 1
        u1 = 2.0 * self._w2 * math.sin(0.5 * p1) ** 2
        target = max(e0 - max(w, 0.0), u1)
        v1 = math.copysign(math.sqrt(2.0 * (target - u1)), v1)
        if u1 > e0:
            p1 = p  # even the angle would climb above the energy available: stay put
            v1 = 0.0
        return p1, v1, e0 - (0.5 * v1 * v1 + 2.0 * self._w2 * math.sin(0.5 * p1) ** 2)

    def _implicit(self, p: float, v: float, h: float, ain: float) -> tuple[float, float, float]:
        """Take the step with the L-stable fallback (see :meth:`_dirk_safe`).

        Across a violent power-law transient (n = 10 at 10 rad/s) the SDIRK stages, with their
        negative weight, can turn the velocity round where the flow cannot; backward Euler's
        single stage is monotone in φ', so it takes such a step instead.
        """
        return self._dirk_safe(FALLBACK_METHOD.tableau, p, v, h, ain)

    def _dirk_safe(self, tab: Tableau, p: float, v: float, h: float,
                   ain: float) -> tuple[float, float, float]:
        """Take a DIRK step; replace it by backward Euler where it turned φ' round spuriously.

        Once φ' has passed 0 it can grow again by at most h (|τ/I| + ω0²) within the step, since
        damping only opposes the motion: a reversed velocity larger than that is the stages'
        doing, not the flow's.
        """
        args = (p, v, h, ain, self._w2, self._gamma, self._n, self._damping)
        p1, v1, w, _ = dirk_step(tab, *args)
        if v1 * v < 0.0 and abs(v1) > h * (abs(ain) + self._w2):
            pb, vb, wb, _ = dirk_step(BACKWARD_EULER, *args)
            return pb, vb, wb
        return p1, v1, w

    def _micro(self, p: float, v: float, h: float, ain: float) -> tuple[float, float, float]:
        """Take one plain step, split at a velocity reversal where the damping is not smooth."""
        if self._coulomb and v == 0.0:
            return self._from_rest(p, h, ain)
        p1, v1, w, a0 = self._step_fn(p, v, h, ain)
        # A reversal shows as a sign change over the step, or, where a stage already crossed
        # and spoiled the result, as a deceleration that could stop the pendulum within h.
        if self._nonsmooth and (v1 * v < 0.0 or (a0 * v < 0.0 and abs(v) <= h * abs(a0))):
            return self._split(p, v, h, ain, a0)
        return p1, v1, w

    def _split(self, p: float, v: float, h: float, ain: float,
               a0: float) -> tuple[float, float, float]:
        """Split a step that straddles φ' = 0 at the reversal, located to round-off.

        A first guess comes from the cubic Hermite interpolant of φ' on the step, with the
        end slope taken from the damping branch of the start (its smooth continuation); Newton
        iterations on the partial step's own φ'(θh) then put the reversal where the method
        itself says φ' = 0, so neither part straddles the kink.
        """
        sign = 1.0 if v > 0.0 else -1.0
        n, gamma, w2 = self._n, self._gamma, self._w2
        before = _compiled_branch(self._plain_tableau, w2, gamma, n, sign)

        def accel_branch(pp: float, vv: float) -> float:
            return float(ain - sign * gamma * abs(vv) ** n - w2 * math.sin(pp))

        p1, v1, w1, _ = before(p, v, h, ain)
        if v1 * v > 0.0:
            return p1, v1, w1  # the branch step does not reach φ' = 0: no kink inside
        th = hermite_root(v, v1, h * a0, h * accel_branch(p1, v1))
        pm, vm, wm, _ = before(p, v, th * h, ain)
        for _ in range(4):
            if abs(vm) <= 1e-14 * abs(v):
                break
            acc = accel_branch(pm, vm)
            if acc == 0.0:
                break
            nth = th - vm / (acc * h)
            if not 0.0 < nth < 1.0:
                break
            th = nth
            pm, vm, wm, _ = before(p, v, th * h, ain)
        self.stats.reversals += 1
        rest = (1.0 - th) * h
        if self._coulomb:
            p2, v2, w2_ = self._from_rest(pm, rest, ain, vm)
        else:
            after = ain - w2 * math.sin(pm)
            step = _compiled_branch(self._plain_tableau, w2, gamma, n,
                                    1.0 if after > 0.0 else -1.0) if after != 0.0 else (
                self._step_fn)
            p2, v2, w2_, _ = step(pm, vm, rest, ain)
        return p2, v2, wm + w2_

    def _from_rest(self, p: float, h: float, ain: float,
                   v: float = 0.0) -> tuple[float, float, float]:
        """Coulomb friction at (or within round-off of) rest: stick, or break away."""
        force = ain - self._w2 * math.sin(p)
        if abs(force) <= self._gamma:
            return p, 0.0, 0.0
        sign = 1.0 if force > 0.0 else -1.0
        step = _compiled_branch(self._plain_tableau, self._w2, self._gamma, 0.0, sign)
        p1, v1, w, _ = step(p, v, h, ain)
        if v1 * sign < 0.0:
            # The break-away reversed within the step: it stops again.
            return p, 0.0, 0.0
        return p1, v1, w

    def _adaptive(self, p: float, v: float, h: float, ain: float) -> tuple[float, float, float]:
        """Cover one step h with error-controlled substeps of the embedded pair."""
        tab = self._method.tableau
        estep = _compiled_error(tab, self._w2, self._gamma, self._n)
        rtol, atol = self._rtol, self._atol
        q = 1.0 / (tab.error_order + 1)
        done, w_total = 0.0, 0.0
        hh = self._h_try if self._h_try > 0.0 else h * 0.1
        while done < h:
            if self._coulomb and v == 0.0:
                p, v, w = self._from_rest(p, h - done, ain)
                w_total += w
                break
            last = hh >= h - done
            step_h = h - done if last else hh
            try:
                p1, v1, w, _, ep, ev = estep(p, v, step_h, ain)
                sp = atol + rtol * max(abs(p), abs(p1))
                sv = atol + rtol * max(abs(v), abs(v1))
                err = math.sqrt(0.5 * ((ep / sp) ** 2 + (ev / sv) ** 2))
            except OverflowError:
                err = math.inf  # a trial step that overflows is rejected like any other
            if err <= 1.0 and math.isfinite(err):
                if self._coulomb and (v1 < 0.0 < v or v < 0.0 < v1) and abs(
                        ain - self._w2 * math.sin(p1)) <= self._gamma:
                    v1 = 0.0
                done = h if last else done + step_h
                p, v = p1, v1
                w_total += w
                factor = 5.0 if err == 0.0 else min(5.0, 0.9 * err ** -q)
                hh = step_h * factor if not last else max(hh, step_h * factor)
            else:
                self.stats.substeps += 1
                factor = 0.2 if not math.isfinite(err) else max(0.2, 0.9 * err ** -q)
                hh = step_h * factor
                if hh < 1e-14 * max(1.0, h):
                    raise IntegratorError(f'adaptive step fell below {hh:.3g} s at t = '
                                          f'{self.t + done:.6g} s')
        self._h_try = hh
        return p, v, w_total

    # ------------------------------------------------------------------ diagnostics
    def local_error_estimate(self, torque: float = 0.0) -> float:
        """Return a step-doubling estimate of the local error of the next step (state kept).

        One step h against two steps h/2 of the same plain method, scaled by 1 / (2^p − 1):
        the 2-norm over (φ, φ') of the error the next step will make, in rad and rad/s.
        """
        saved = (self.stats, self._h_try)
        self.stats = GuardStats()
        try:
            ain = torque * self._inv_inertia
            p, v, h = self._p, self._v, self._h
            step = self._dirk_plain if self._method.kind == 'implicit' else self._micro
            pa, va, _ = step(p, v, h, ain)
            pb, vb, _ = step(p, v, 0.5 * h, ain)
            pb, vb, _ = step(pb, vb, 0.5 * h, ain)
        finally:
            self.stats, self._h_try = saved
        return math.hypot(pa - pb, va - vb) / (2.0 ** self._method.order - 1.0)

    def _dirk_plain(self, p: float, v: float, h: float, ain: float) -> tuple[float, float, float]:
        return self._dirk_safe(self._method.tableau, p, v, h, ain)


