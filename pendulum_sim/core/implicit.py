"""The implicit family: L-stable DIRK steps on a :class:`~pendulum_sim.core.problem.Problem`.

The implicit methods' own steps (``sdirk2``, ``sdirk3``) and the fallback every other family
hands a step to where explicit steps cannot take it (the guard's cap, an overflow, a cover that
cannot progress): :func:`fallback` covers a step in substeps that obey the angle limit.

The fallback is written to compile: :func:`fallback_refused` (its work bound) and
:func:`fallback_run` (its substeps, :func:`safe_step` each) take numbers and return numbers, so
the compiled sweep's careful step runs these very functions; :func:`fallback` is them for a
Problem, with the refusal raised.
"""
from __future__ import annotations

import functools
import math
from collections.abc import Callable

from .coulomb import friction_work, moving_input, rest_direction
from .dirk import Coefficients, StageLaw, coefficients, dirk_step, stage_law
from .errors import IntegratorError
from .guard import MAX_ANGLE, GuardStats
from .problem import Problem, speed_gain
from .reversal import CUT_ITERATIONS, CUT_TOL, branch_accel, locate_reversal
from .tableaus import BACKWARD_EULER, SDIRK3, Tableau

FALLBACK_TABLEAU = SDIRK3
"""The fallback's method: the L-stable SDIRK of order 3."""

MAX_FALLBACK_SUBSTEPS = 100_000
"""The most substeps the fallback (:func:`fallback`) may take to cover one step: beyond it the
step is refused (an IntegratorError naming h) instead of taken in unbounded time. Each substep
sweeps at most MAX_ANGLE, so the bound is h (|φ'| + h (|τ/I| + ω0²) + ω0) <=
MAX_ANGLE · MAX_FALLBACK_SUBSTEPS."""

FALLBACK_COEFFS = coefficients(FALLBACK_TABLEAU)
BACKWARD_EULER_COEFFS = coefficients(BACKWARD_EULER)


def safe_step(coeffs: Coefficients, p: float, v: float, h: float, ain: float, w2: float,
              gamma: float, n: float, law: StageLaw) -> tuple[float, float, float]:
    """Take a DIRK step; replace it by backward Euler where it turned φ' round spuriously.

    Once φ' has passed 0 it can grow again by at most h (|τ/I| + ω0²) within the step, since
    damping only opposes the motion: a reversed velocity larger than that is the stages'
    doing, not the flow's. Backward Euler's single stage is monotone in φ'.
    """
    p1, v1, w, _ = dirk_step(coeffs, p, v, h, ain, w2, gamma, n, law)
    if v1 * v < 0.0 and abs(v1) > speed_gain(h, ain, w2):
        pb, vb, wb, _ = dirk_step(BACKWARD_EULER_COEFFS, p, v, h, ain, w2, gamma, n, law)
        return pb, vb, wb
    return p1, v1, w


def dirk_safe(prob: Problem, tab: Tableau, p: float, v: float, h: float,
              ain: float) -> tuple[float, float, float]:
    """Take :func:`safe_step` of the DIRK tableau ``tab`` for the problem ``prob``."""
    return safe_step(coefficients(tab), p, v, h, ain, prob.w2, prob.gamma, prob.n,
                     stage_law(prob.n))


def fallback_refused(v: float, h: float, ain: float, w2: float, omega0: float) -> bool:
    """Return True where :func:`fallback` refuses the step (more than MAX_FALLBACK_SUBSTEPS)."""
    return not h * (abs(v) + speed_gain(h, ain, w2) + omega0) <= (
        MAX_ANGLE * MAX_FALLBACK_SUBSTEPS)  # also inf and NaN


def fallback_run(p: float, v: float, h: float, ain: float, w2: float, gamma: float, n: float,
                 omega0: float, law: StageLaw) -> tuple[float, float, float]:
    """Cover h with the fallback's substeps (the work bound checked by the caller)."""
    left, w = h, 0.0
    while left > 0.0:
        reach = left * (abs(v) + speed_gain(left, ain, w2) + omega0)
        hh = left if reach <= MAX_ANGLE else left / math.ceil(reach / MAX_ANGLE)
        p, v, wi = safe_step(FALLBACK_COEFFS, p, v, hh, ain, w2, gamma, n, law)
        w += wi
        left = 0.0 if hh == left else left - hh
    return p, v, w


def fallback(prob: Problem, p: float, v: float, h: float,
             ain: float) -> tuple[float, float, float]:
    """Take the step with the L-stable fallback, in substeps that obey the angle limit.

    A substep sweeps at most MAX_ANGLE (damping only slows, so |φ'| + h (|a_in| + ω0²)
    bounds the speed) and resolves ω0, re-judged after each one. A step that would need more
    than MAX_FALLBACK_SUBSTEPS substeps is refused (IntegratorError).
    """
    if fallback_refused(v, h, ain, prob.w2, prob.omega0):
        raise refusal(p, v, h)
    return fallback_run(p, v, h, ain, prob.w2, prob.gamma, prob.n, prob.omega0,
                        stage_law(prob.n))


def refusal(p: float, v: float, h: float) -> IntegratorError:
    """Return the fallback's refusal of a step of h from (φ, φ') (:func:`fallback_refused`)."""
    return IntegratorError(
        f'a step of {h:g} s from phi = {p:g} rad, dphi = {v:g} rad/s needs more than '
        f'MAX_FALLBACK_SUBSTEPS = {MAX_FALLBACK_SUBSTEPS} substeps of the fallback '
        f'(each sweeps at most {MAX_ANGLE:g} rad); use a smaller h')


StepFn = Callable[[float, float, float, float], tuple[float, float, float]]
"""An implicit step ``(φ, φ', h, a_in) → (φ₁, φ'₁, w)`` that knows only the power law."""


def slide(prob: Problem, step: StepFn, p: float, v: float, h: float, ain: float,
          stats: GuardStats | None = None) -> tuple[float, float, float]:
    """Take an implicit ``step`` of h with the friction beside the law; return (φ₁, φ'₁, w).

    The implicit family's own DIRK steps (``Engine.implicit_advance``) and the L-stable
    fallback (:func:`moving_fallback`) take the friction the way the explicit family's steps
    do. At rest the rest rule decides (``coulomb.rest_direction``): the joint sticks, or breaks
    away in the direction of the force. Moving in the direction s, the friction is the input
    ``coulomb.moving_input`` (constant over a step that does not reverse) and its work
    ``coulomb.friction_work`` is counted. A step that reverses is split at the reversal
    (counted in ``stats`` where given), located on the step's own φ'(θh) = 0
    (``reversal.locate_reversal``, the embedded cover's cut), and the rest of it is taken from
    rest by the same rule; a break-away that reverses within its step stops again
    (``coulomb.rest_step``'s rule). Without friction, ``step`` itself.
    """
    cf = prob.friction
    if cf == 0.0:
        return step(p, v, h, ain)
    w2, g, n = prob.w2, prob.gamma, prob.n
    if v == 0.0:
        sign = rest_direction(p, ain, w2, g, n, cf)
        if sign == 0.0:
            return p, 0.0, 0.0
    else:
        sign = 1.0 if v > 0.0 else -1.0
    a = moving_input(ain, sign, cf)
    p1, v1, w = step(p, v, h, a)
    if v1 * sign >= 0.0:
        return p1, v1, w + friction_work(cf, sign, p, p1)
    if v == 0.0:
        return p, 0.0, 0.0  # the break-away reversed within the step: it stops again

    def accel(pp: float, vv: float) -> float:
        return branch_accel(pp, vv, a, sign, g, n, w2)

    th, pm, _, wm = locate_reversal(lambda hh: step(p, v, hh, a), accel, v, v1, accel(p, v),
                                    accel(p1, v1), h, CUT_TOL, CUT_ITERATIONS)
    wm += friction_work(cf, sign, p, pm)
    if stats is not None:
        stats.reversals += 1
    p2, v2, w2_ = slide(prob, step, pm, 0.0, (1.0 - th) * h, ain, stats)
    return p2, v2, wm + w2_


def moving_fallback(prob: Problem, p: float, v: float, h: float,
                    ain: float) -> tuple[float, float, float]:
    """Return the L-stable fallback's step (:func:`fallback`) with the friction beside it.

    :func:`slide` over the fallback: the friction of the direction of motion an input, the
    step split at a reversal, the rest rule at rest. Without friction, ``fallback`` itself.
    """
    return slide(prob, functools.partial(fallback, prob), p, v, h, ain)


__all__ = ['BACKWARD_EULER_COEFFS', 'FALLBACK_COEFFS', 'FALLBACK_TABLEAU',
           'MAX_FALLBACK_SUBSTEPS', 'StepFn', 'dirk_safe', 'fallback', 'fallback_refused',
           'fallback_run', 'moving_fallback', 'refusal', 'safe_step', 'slide']
