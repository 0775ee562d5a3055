"""The stability guard: keep every step inside the method's region of absolute stability.

Before a step the guard linearises the pendulum at the current state. The Jacobian
``[[0, 1], [−ω0² cos φ, −d]]`` with ``d = γ n |φ'|^(n−1)`` has the closed-form eigenvalues
``λ = (−d ± sqrt(d² − 4 ω0² cos φ)) / 2`` (eq 18-19). Where ``h λ`` for an eigenvalue with
negative real part lies outside the region ``|R(z)| ≤ 1`` of the method, the step is split into
the fewest equal substeps that bring every ``h λ / m`` back inside; where that would take more
than ``max_substeps``, the step falls back to the L-stable implicit method. An eigenvalue with
non-negative real part (the pendulum above the horizontal) is physics, not numerical
instability, and is left alone.

A cheap sufficient test runs first: every eigenvalue has ``|λ| ≤ d + ω0``, so a step with
``h (d + ω0) ≤ r`` is safe when the half-disk ``{|z| ≤ r, Re z ≤ 0}`` lies inside the region.
"""
from __future__ import annotations

import functools
import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from .law import damping_derivative
from .model import _eigs
from .tableaus import Tableau

FALLBACK = 0
"""Returned by :meth:`StabilityGuard.substeps` when the implicit method must take the step."""

MAX_ANGLE = 0.5
"""The largest angle (rad) one step may sweep: a pendulum spinning over the top at 100 rad/s
forces gravity at 100 rad/s, a frequency the Jacobian at one point does not show."""


def terminal_formula(gamma: float, n: float, force: float) -> float:
    """Return (force/γ)^(1/n) without exception handling (compiled, an overflow is inf)."""
    if gamma <= 0.0 or n == 0.0:
        return math.inf
    return float((force / gamma) ** (1.0 / n))


def terminal_speed(gamma: float, n: float, force: float) -> float:
    """Return the speed at which damping balances an acceleration ``force``: (force/γ)^(1/n)."""
    try:
        return terminal_formula(gamma, n, force)
    except OverflowError:
        return math.inf


def max_speed(gamma: float, n: float, dphi: float, h: float, force: float) -> float:
    """Return a bound on |φ'| over a step of h of the exact flow.

    Damping only ever slows the pendulum, so |φ'| can grow by at most h · force, and never past
    the terminal speed once it is above it.
    """
    return abs(dphi) + min(h * force, terminal_speed(gamma, n, force))


def stiffness_speed(gamma: float, n: float, dphi: float, h: float, force: float) -> float:
    """Return the speed at which to evaluate d = γ n |φ'|^(n−1) for the stiffest point of a step.

    For n > 1 the damping is stiffest at the highest speed; for n < 1 at the lowest, where it is
    not Lipschitz: there the speed the step can reach, or the terminal speed of a creeping
    pendulum, sets the scale (reversals themselves are split off by the stepper).
    """
    if n >= 1.0:
        return max_speed(gamma, n, dphi, h, force)
    return max(abs(dphi), min(0.5 * h * force, terminal_speed(gamma, n, force)))


@dataclass
class GuardStats:
    """Count what the integrator did beyond plain fixed steps."""

    steps: int = 0
    substeps: int = 0  # extra steps taken because of the guard (m − 1 per split step)
    fallbacks: int = 0  # steps handed to the implicit method
    reversals: int = 0  # steps split at a velocity reversal (non-smooth damping)
    sticks: int = 0  # times the pendulum came to rest under static (Coulomb) friction
    energy_rejections: int = 0  # explicit steps redone because energy rose without input
    projections: int = 0  # steps projected onto the energy balance after the redo rose too

    def as_dict(self) -> dict[str, int]:
        """Return the counters as a plain dict."""
        return asdict(self)

    def add(self, other: GuardStats) -> None:
        """Add another set of counters to this one."""
        for k, v in other.as_dict().items():
            setattr(self, k, getattr(self, k) + v)

    def __getitem__(self, k: int) -> int:
        """Return the careful step's counter ``k`` (:data:`CAREFUL_COUNTERS`' position)."""
        value: int = getattr(self, CAREFUL_COUNTERS[k])
        return value

    def __setitem__(self, k: int, value: int) -> None:
        """Set the careful step's counter ``k``: the careful step counts into these as Python."""
        setattr(self, CAREFUL_COUNTERS[k], value)


CAREFUL_COUNTERS = ('substeps', 'fallbacks', 'reversals', 'sticks', 'energy_rejections',
                    'projections')
"""The counters the careful step adds to, by position (``careful.COUNTERS``): a
:class:`GuardStats` in Python, a row of an array compiled."""


@functools.cache
def half_disk_radius(tableau: Tableau, samples: int = 721) -> float:
    """Return the largest r with ``{|z| ≤ r, Re z ≤ 0}`` inside ``|R(z)| ≤ 1`` (0 if none).

    Sampled on a polar grid of the half-disk and bisected on r; explicit methods only.
    """
    coeffs = tableau.stability_poly[::-1]
    theta = np.linspace(np.pi / 2, 3 * np.pi / 2, samples)
    lo, hi = 0.0, 8.0
    for _ in range(40):
        r = 0.5 * (lo + hi)
        zs = np.outer(np.linspace(r / 64, r, 64), np.exp(1j * theta))
        if np.max(np.abs(np.polyval(coeffs, zs))) <= 1.0:
            lo = r
        else:
            hi = r
    return lo


@functools.cache
def real_axis_bound(tableau: Tableau) -> float:
    """Return the length of the stability interval on the negative real axis (inf if A-stable)."""
    x = 0.0
    dx = 0.01
    while x < 1e3:
        if abs(tableau.stability_function(complex(-(x + dx), 0.0))) > 1.0:
            lo, hi = x, x + dx
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                if abs(tableau.stability_function(complex(-mid, 0.0))) > 1.0:
                    hi = mid
                else:
                    lo = mid
            return lo
        x += dx
    return math.inf


class StabilityGuard:
    """Decide, per step, how many substeps keep an explicit method stable.

    Parameters
    ----------
    tableau : Tableau
        The explicit method to guard.
    safety : float
        Fraction of the region's extent to use (keeps a margin for the variation of λ within
        the step, which grows with the velocity for n ≥ 2).
    max_substeps : int
        Above this, the step falls back to the implicit method.
    """

    def __init__(self, tableau: Tableau, safety: float = 0.8, max_substeps: int = 64) -> None:
        self.tableau = tableau
        self.safety = safety
        self.max_substeps = max_substeps
        self.disk = half_disk_radius(tableau) * safety
        self.real = real_axis_bound(tableau) * safety
        self.max_angle = MAX_ANGLE
        # What substep_count reads: (disk, real, max_angle, safety, max_substeps, c_s, …, c_0),
        # the bounds, the cap and R(z)'s coefficients, highest power first.
        self.constants: tuple[float, ...] = (
            self.disk, self.real, self.max_angle, safety, float(max_substeps),
            *tableau.stability_poly[::-1].tolist())

    def fast_ok(self, h: float, d: float, omega0: float, speed: float) -> bool:
        """Return True when the cheap bound already proves the step stable and resolved."""
        return h * (d + omega0) <= self.disk and h * speed <= self.max_angle

    def substeps(self, h: float, omega0_sq: float, gamma: float, n: float, phi: float,
                 dphi: float, force: float, force_now: float | None = None) -> int:
        """Return m ≥ 1 substeps for a stable step, or FALLBACK for the implicit method.

        ``force`` bounds the non-damping acceleration over the step (|τ/I| + ω0²); it bounds
        how far the velocity, and with it the damping's stiffness, can move within the step.
        ``force_now`` is that acceleration at the start (|τ/I − ω0² sin φ|): for n < 1 it sets
        the creeping speed, where the bound would overstate it near the bottom.
        (:func:`substep_count` with this guard's constants.)
        """
        return substep_count(h, omega0_sq, gamma, n, phi, dphi, force,
                             force if force_now is None else force_now, self.constants)



def stability_ok(z: complex, consts: tuple[float, ...]) -> bool:
    """Return |R(z)| <= 1 for the explicit method whose guard ``constants`` are ``consts``.

    R is evaluated by Horner's rule from its highest coefficient, as ``numpy.polyval`` does.
    """
    r = 0j
    for k in range(5, len(consts)):
        r = r * z + consts[k]
    return abs(r) <= 1.0


def _search(h: float, lam1: complex, lam2: complex, two: bool,
            consts: tuple[float, ...]) -> int:
    """Return the fewest substeps m whose h/m puts h λ (λ = lam1 and, with ``two``, lam2) inside.

    The safety margin is applied through the disk bound: the smallest m that is stable for
    h / safety is used; beyond max_substeps the result is max_substeps + 1.
    """
    hs = h / consts[3]
    cap = int(consts[4])
    m = 1
    while not (stability_ok(hs / m * lam1, consts)
               and (not two or stability_ok(hs / m * lam2, consts))):
        m *= 2
        if m > cap:
            return cap + 1
    lo = m // 2
    while m - lo > 1:
        mid = (lo + m) // 2
        hm = hs / mid
        if stability_ok(hm * lam1, consts) and (not two or stability_ok(hm * lam2, consts)):
            m = mid
        else:
            lo = mid
    return m


def substep_count(h: float, omega0_sq: float, gamma: float, n: float, phi: float, dphi: float,
                  force: float, force_now: float, consts: tuple[float, ...]) -> int:
    """Return :meth:`StabilityGuard.substeps`: m ≥ 1 substeps, or FALLBACK.

    Written to compile (numbers in, an int out, no exception raised for an overflow: the
    compiled form reads ``terminal_formula`` and ``law.slope_formula``, which give inf), so
    that the careful step (``careful.guarded``), in Python and compiled, runs this one decision.
    ``consts`` is :attr:`StabilityGuard.constants`.
    """
    disk, real, max_angle, cap = consts[0], consts[1], consts[2], int(consts[4])
    creep = force if n >= 1.0 else force_now
    d = damping_derivative(gamma, n, stiffness_speed(gamma, n, dphi, h, creep))
    if not math.isfinite(d):
        return FALLBACK
    m_angle = max(1, math.ceil(h * max_speed(gamma, n, dphi, h, force) / max_angle))
    c = omega0_sq * math.cos(phi)
    lam1, lam2 = _eigs(d, c)
    # The eigenvalues with Re λ < 0, the first of them in lam1 (lam2 with ``two``).
    two = lam1.real < 0.0 and lam2.real < 0.0
    some = lam1.real < 0.0 or lam2.real < 0.0
    if not lam1.real < 0.0:
        lam1 = lam2
    big = max(abs(lam1), abs(lam2)) if two else abs(lam1)
    if not some:
        m = 1
    elif big * h <= disk:
        m = 1
    elif lam1.imag == 0.0 and (not two or lam2.imag == 0.0) and math.isfinite(real):
        x = big * h / real  # inf where d² overflowed in the eigenvalues: beyond the cap
        m = max(1, math.ceil(x)) if x <= cap else cap + 1
    else:
        m = _search(h, lam1, lam2, two, consts)
    if m > cap:
        return FALLBACK
    # The angle limit alone never calls for the fallback: explicit substeps resolve it.
    return max(m, m_angle)


RANGE_MARGIN = 1e-9
"""Relative margin inside the guard's safe speed range (:func:`safe_speed_range`): inside the
range the guard's stability and angle bounds hold at the largest speed of the step, so its count
(:func:`substep_count`) is one substep; the margin keeps the rounding of the two computations of
those bounds (the range's and ``substep_count``'s) far from deciding it."""


def one_substep(speed: Any, lo: Any, hi: Any) -> Any:
    """Return where a step at |φ'| = ``speed`` is surely one substep of the guard.

    Inside the safe speed range ``(lo, hi)`` shrunk by :data:`RANGE_MARGIN`; floats or numpy
    arrays. The numpy sweep's batched careful path and the compiled careful step take the
    guard's count as 1 there without computing it (``test_sweep_jit.py`` holds the compiled
    step to ``Engine.careful``, which computes it).
    """
    return (lo * (1.0 + RANGE_MARGIN) <= speed) & (speed <= hi * (1.0 - RANGE_MARGIN))


def safe_speed_range(guard: StabilityGuard, omega0_sq: float, gamma: float, n: float, h: float,
                     ain_bound: float) -> tuple[float, float]:
    """Return (lo, hi): one plain step of h is safe for every state with lo <= |φ'| <= hi.

    The range of one pendulum: :func:`safe_speed_ranges`, the guard's one fast-path decision,
    for an array of one (``Engine.fast_range`` keeps it per step length and torque octave).
    """
    lo, hi = safe_speed_ranges(guard, [omega0_sq], [gamma], [n], h, [ain_bound])
    return float(lo[0]), float(hi[0])


def _powers(base: npt.NDArray[np.float64], exponent: Any,
            on_error: Any) -> npt.NDArray[np.float64]:
    """Return ``base ** exponent`` element-wise as Python's float power computes it.

    numpy's ``power`` may differ from the C library's ``pow`` in the last bit, so the floats go
    through Python's own operator; where it raises (overflow, 0 to a negative power) the value
    is ``on_error``, as the scalar code's ``except`` gives it. ``exponent`` and ``on_error``
    are floats or arrays like ``base``.
    """
    values = base.tolist()
    exps = np.broadcast_to(exponent, base.shape).tolist()
    errs = np.broadcast_to(on_error, base.shape).tolist()
    try:
        return np.array([b ** e for b, e in zip(values, exps, strict=True)], dtype=np.float64)
    except (OverflowError, ZeroDivisionError):
        out = []
        for b, e, err in zip(values, exps, errs, strict=True):
            try:
                out.append(b ** e)
            except (OverflowError, ZeroDivisionError):
                out.append(err)
        return np.array(out, dtype=np.float64)


def safe_speed_ranges(guard: StabilityGuard, omega0_sq: npt.ArrayLike, gamma: npt.ArrayLike,
                      n: npt.ArrayLike, h: float, ain_bound: npt.ArrayLike
                      ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Return (lo, hi) for arrays of (ω0², γ, n, a_in bound): one plain step of h is safe there.

    Safe means the cheap sufficient test of the module docstring holds at the speed the step can
    reach: ``h (d(speed) + ω0) <= r`` and ``h · speed <= MAX_ANGLE``, with ``speed = |φ'| +
    margin`` and the margin the speed an input acceleration up to the a_in bound plus gravity
    can add in h (:func:`max_speed`). For n > 1 the slope d = γ n s^(n−1) grows with the speed,
    so the range has an upper end; for n < 1 it falls, so it has a lower end (the slowest speed
    in the step is |φ'| − h · force); for n = 0 and n = 1 it is constant. This is the guard's
    one fast-path decision, written once over arrays: the sweep takes it for its pendulums,
    ``Stepper`` for one (:func:`safe_speed_range`). Sums, products, quotients and square roots
    are correctly rounded in numpy as in Python; powers go through Python's float power
    (:func:`_powers`). An empty range is (inf, −inf). ``n`` is one exponent or one per pendulum.
    """
    w2, gam, nn, bound = (np.asarray(x, dtype=np.float64)
                          for x in (omega0_sq, gamma, n, ain_bound))
    w2, gam, nn, bound = np.broadcast_arrays(w2, gam, nn, bound)
    size = w2.shape
    with np.errstate(divide='ignore', invalid='ignore', over='ignore'):
        force = bound + w2
        omega0 = np.sqrt(w2)
        # max_speed(gamma, n, 0.0, h, force): 0 + min(h force, terminal_speed(gamma, n, force)).
        term = np.full(size, math.inf)
        pos = (gam > 0.0) & (nn != 0.0)
        if pos.any():
            term[pos] = _powers(force[pos] / gam[pos], 1.0 / nn[pos], math.inf)
        margin = 0.0 + np.minimum(h * force, term)
        hi = guard.max_angle / h - margin
        room = guard.disk / h - omega0
        lo = np.zeros(size)
        empty = (room < 0.0) | (hi < 0.0)
        one, other = nn == 1.0, (nn != 0.0) & (nn != 1.0)
        empty |= one & (gam != 0.0) & ~(gam <= room)
        empty |= other & (gam != 0.0) & (room == 0.0)
        act = ~empty & (gam != 0.0) & other
        if act.any():
            na = nn[act]
            up = na > 1.0
            s = _powers(room[act] / (gam[act] * na), 1.0 / (na - 1.0),
                        np.where(up, math.inf, 0.0))
            at = np.flatnonzero(act)
            top = np.minimum(hi[act], s - margin[act])
            low = s + h * force[act]
            hi[at[up]] = top[up]
            lo[at[~up]] = low[~up]
            empty[at[up & ~(top >= 0.0)]] = True
            empty[at[~up & ~(low <= hi[act])]] = True
    lo[empty] = math.inf
    hi[empty] = -math.inf
    return lo, hi
