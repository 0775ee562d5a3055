"""The independent high-accuracy reference every error in the reports is measured against.

How it is computed
------------------
scipy's ``solve_ivp`` (DOP853, order 8, at ``rtol = 1e-13, atol = 1e-15``; Radau IIA with the
analytic Jacobian for stiff cases) on the *plain* vector field of eq 20, restarted at every
velocity reversal: the reversal time is located by scipy's event finder on its dense output
(``φ' = 0``, terminal), the state is restarted there with ``φ' = 0`` exactly, and inside each
segment the damping ``s γ |φ'|^n`` has a fixed sign ``s``, so every segment is smooth and the
high order is kept across the kinks of non-smooth damping (n even or not an integer). Under
Coulomb friction (n = 0) a segment ending where ``|τ/I − ω0² sin φ| ≤ γ`` sticks for good.
None of the core's stepping code is used.

How accurate it is
------------------
Each reference is cross-checked against the core's own adaptive ``dopri5`` at ``rtol = 1e-13,
atol = 1e-15`` (a different method, different step control, different reversal treatment); the
largest 2-norm difference over the output grid is stored as ``disagreement`` and written into
every report. Without scipy, the core's ``dopri5`` at ``rtol = 1e-13`` is the reference and the
cross-check is the same method at ``rtol = 1e-11`` (a self-consistency bound, said so in the
report).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ..core.guard import terminal_speed
from ..core.law import compile_damping, damping_derivative
from ..core.model import PendulumParams
from ..core.simulate import simulate
from .plain import jacobian

FloatArray = npt.NDArray[np.float64]

REF_RTOL = 1e-13
REF_ATOL = 1e-15
STIFF_RTOL = 1e-11
STIFF_ATOL = 1e-13
MAX_SEGMENTS = 20000
MAX_EVALUATIONS = 150_000  # a few seconds of Python: beyond it, no reference
STIFF_WORK = 5e4  # above: Radau
CHECK_WORK = 3e6  # above: no cross-check (the explicit dopri5 would take too long)


@dataclass(frozen=True)
class Reference:
    """A reference trajectory on the output grid ``t`` and how it was obtained."""

    t: FloatArray
    phi: FloatArray
    dphi: FloatArray
    solver: str
    segments: int
    check_solver: str
    disagreement: float  # max 2-norm difference to the cross-check over the grid (nan: none)

    def error(self, phi: FloatArray, dphi: FloatArray) -> FloatArray:
        """Return the 2-norm error over (φ, φ') of a solution sampled on the same grid."""
        return np.asarray(np.hypot(phi - self.phi, dphi - self.dphi))


def scipy_available() -> bool:
    """Return True where scipy.integrate can be imported."""
    try:
        import scipy.integrate  # type: ignore[import-untyped]  # noqa: F401
    except ImportError:
        return False
    return True


def fast_rate(params: PendulumParams, dphi_scale: float) -> float:
    """Return |λ_fast| ≈ γ n |φ'|^(n−1) + ω0, a bound on the stiffness at speed ``dphi_scale``."""
    d = damping_derivative(params.gamma, params.n, max(dphi_scale, 1e-12))
    return d + math.sqrt(params.omega0_sq)


def stiffness_work(params: PendulumParams, dphi0: float, torque: float, t_end: float) -> float:
    """Return |λ_fast| t_end at a typical speed: about the steps an explicit method needs.

    The speed is the larger of |φ'(0)| and the speed gained falling from the top, capped by the
    terminal speed where damping balances gravity and torque: for n > 1 the velocity is pulled
    down to it within a short transient, and for n < 1, whose slope γ n |φ'|^(n−1) grows without
    bound at rest, the creeping motion at that speed is where the problem is stiffest.
    """
    speed = max(abs(dphi0), 2.0 * math.sqrt(params.omega0_sq))
    n, g = params.n, params.gamma
    if g > 0.0 and n > 0.0 and n != 1.0:
        force = params.omega0_sq + abs(torque) / params.inertia
        terminal = max(terminal_speed(g, n, force), 1e-12)
        # n > 1: the speed is pulled down to the terminal one; n < 1: the slope γ n |φ'|^(n−1)
        # is largest at the smallest speeds, which the creeping motion reaches.
        speed = min(speed, terminal)
    return fast_rate(params, speed) * t_end


def reference(params: PendulumParams, phi0: float, dphi0: float, t_eval: FloatArray,
              torque: float = 0.0, stiff: bool | None = None,
              cross_check: bool = True) -> Reference | None:
    """Return the reference on ``t_eval`` (starting at 0), or None where none can be had.

    ``stiff`` selects Radau instead of DOP853 (default: decided from γ, n and the initial
    speed). Returns None where the reversals accumulate (more than MAX_SEGMENTS).
    """
    t_eval = np.asarray(t_eval, dtype=float)
    if not scipy_available():
        return _core_reference(params, phi0, dphi0, t_eval, torque)
    work = stiffness_work(params, dphi0, torque, float(t_eval[-1]))
    if stiff is None:
        stiff = work > STIFF_WORK
    out = _scipy_segments(params, phi0, dphi0, t_eval, torque, stiff)
    if out is None:
        return None
    phi, dphi, segments, solver = out
    check, disagreement = 'none', math.nan
    if cross_check and work <= CHECK_WORK:
        check = f'core dopri5 rtol {REF_RTOL:g}'
        c_phi, c_dphi = _core_on_grid(params, phi0, dphi0, t_eval, torque, REF_RTOL, REF_ATOL)
        disagreement = float(np.max(np.hypot(c_phi - phi, c_dphi - dphi)))
    return Reference(t_eval, phi, dphi, solver, segments, check, disagreement)


def _core_on_grid(params: PendulumParams, phi0: float, dphi0: float, t_eval: FloatArray,
                  torque: float, rtol: float, atol: float) -> tuple[FloatArray, FloatArray]:
    dt = float(t_eval[1] - t_eval[0])
    run = simulate(params, phi0, dphi0, float(t_eval[-1]), dt, 'dopri5', torque=torque,
                   rtol=rtol, atol=atol)
    if len(run.t) != len(t_eval) or not np.allclose(run.t, t_eval, rtol=0.0, atol=1e-9 * dt):
        raise ValueError('the reference grid must be uniform and start at 0')
    return run.phi, run.dphi


def _core_reference(params: PendulumParams, phi0: float, dphi0: float, t_eval: FloatArray,
                    torque: float) -> Reference:
    phi, dphi = _core_on_grid(params, phi0, dphi0, t_eval, torque, REF_RTOL, REF_ATOL)
    c_phi, c_dphi = _core_on_grid(params, phi0, dphi0, t_eval, torque, 1e-11, 1e-13)
    dis = float(np.max(np.hypot(c_phi - phi, c_dphi - dphi)))
    return Reference(t_eval, phi, dphi, f'core dopri5 rtol {REF_RTOL:g} (scipy absent)', 0,
                     'core dopri5 rtol 1e-11 (self-consistency only)', dis)


def _scipy_segments(params: PendulumParams, phi0: float, dphi0: float, t_eval: FloatArray,
                    torque: float, stiff: bool
                    ) -> tuple[FloatArray, FloatArray, int, str] | None:
    from scipy.integrate import solve_ivp

    w2, g, n = params.omega0_sq, params.gamma, params.n
    ain = torque / params.inertia
    smooth = g == 0.0 or params.smooth_damping
    method = 'Radau' if stiff else 'DOP853'
    rtol, atol = (STIFF_RTOL, STIFF_ATOL) if stiff else (REF_RTOL, REF_ATOL)
    t_end = float(t_eval[-1])
    phi = np.full(len(t_eval), np.nan)
    dphi = np.full(len(t_eval), np.nan)
    t0, y = 0.0, np.array([phi0, dphi0], dtype=float)
    segments = 0
    jac = jacobian(params)
    budget = [MAX_EVALUATIONS]
    while True:
        segments += 1
        if segments > MAX_SEGMENTS:
            return None
        force = ain - w2 * math.sin(y[0])
        if y[1] == 0.0 and n == 0.0 and g > 0.0 and abs(force) <= g:
            mask = t_eval >= t0
            phi[mask], dphi[mask] = y[0], 0.0
            break
        s = math.copysign(1.0, y[1]) if y[1] != 0.0 else math.copysign(1.0, force)
        if smooth:
            fun = _smooth_field(w2, g, n, ain)
            events = None
        else:
            fun = _signed_field(w2, g, n, ain, s)

            def crossing(t: float, yy: FloatArray) -> float:
                return float(yy[1])
            crossing.terminal = True  # type: ignore[attr-defined]
            crossing.direction = -s  # type: ignore[attr-defined]
            events = crossing
        fun = _budgeted(fun, budget)
        idx = np.nonzero(t_eval >= t0)[0]
        kwargs: dict[str, object] = {'rtol': rtol, 'atol': atol, 't_eval': t_eval[idx]}
        if stiff:
            kwargs['jac'] = jac
        try:
            sol = solve_ivp(fun, (t0, t_end), y, method=method, events=events, **kwargs)
        except _OverBudget:
            return None
        if sol.status == -1:
            return None
        k = len(sol.t)
        if k:  # scipy returns an empty list, not an array, when no output time was reached
            phi[idx[:k]], dphi[idx[:k]] = sol.y[0], sol.y[1]
        if sol.status != 1 or not len(sol.t_events[0]):
            break
        t_new = float(sol.t_events[0][0])
        y = np.array([sol.y_events[0][0][0], 0.0])
        if t_new <= t0 and segments > 1:
            return None
        t0 = t_new
    return phi, dphi, segments - 1, f'scipy {method} rtol {rtol:g} atol {atol:g}, ' + (
        'one smooth segment' if smooth else 'restarted at each velocity reversal')


class _OverBudget(Exception):
    """The reference would take more than MAX_EVALUATIONS right-hand side evaluations."""


def _budgeted(fun: Any, budget: list[int]) -> Any:
    """Wrap ``fun`` so that it raises _OverBudget once the shared budget is spent."""
    def wrapped(t: float, y: FloatArray) -> list[float]:
        budget[0] -= 1
        if budget[0] < 0:
            raise _OverBudget
        return fun(t, y)  # type: ignore[no-any-return]
    return wrapped


def _smooth_field(w2: float, g: float, n: float, ain: float):  # type: ignore[no-untyped-def]
    law = compile_damping(n)  # the core's one damping law (eq 15)

    def fun(t: float, y: FloatArray) -> list[float]:
        v = float(y[1])
        return [v, ain - law(v, g, 1.0) - w2 * math.sin(y[0])]
    return fun


def _signed_field(w2: float, g: float, n: float, ain: float,  # type: ignore[no-untyped-def]
                  s: float):
    # The core's branch law s γ |φ'|^n: the smooth continuation of one direction of motion.
    law = compile_damping(n, branch=True)

    def fun(t: float, y: FloatArray) -> list[float]:
        v = float(y[1])
        return [v, ain - law(v, g, s) - w2 * math.sin(y[0])]
    return fun
