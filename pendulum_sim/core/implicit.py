"""The implicit family: L-stable DIRK steps on a :class:`~pendulum_sim.core.problem.Problem`.

The implicit methods' own steps (``sdirk2``, ``sdirk3``) and the fallback every other family
hands a step to where explicit steps cannot take it (the guard's cap, an overflow, a cover that
cannot progress): :func:`fallback` covers a step in substeps that obey the angle limit.
"""
from __future__ import annotations

import math

from .dirk import dirk_step
from .errors import IntegratorError
from .guard import MAX_ANGLE
from .problem import Problem
from .tableaus import BACKWARD_EULER, SDIRK3, Tableau

FALLBACK_TABLEAU = SDIRK3
"""The fallback's method: the L-stable SDIRK of order 3."""

MAX_FALLBACK_SUBSTEPS = 100_000
"""The most substeps the fallback (:func:`fallback`) may take to cover one step: beyond it the
step is refused (an IntegratorError naming h) instead of taken in unbounded time. Each substep
sweeps at most MAX_ANGLE, so the bound is h (|φ'| + h (|τ/I| + ω0²) + ω0) <=
MAX_ANGLE · MAX_FALLBACK_SUBSTEPS."""


def dirk_safe(prob: Problem, tab: Tableau, p: float, v: float, h: float,
              ain: float) -> tuple[float, float, float]:
    """Take a DIRK step; replace it by backward Euler where it turned φ' round spuriously.

    Once φ' has passed 0 it can grow again by at most h (|τ/I| + ω0²) within the step, since
    damping only opposes the motion: a reversed velocity larger than that is the stages'
    doing, not the flow's. Backward Euler's single stage is monotone in φ'.
    """
    args = (p, v, h, ain, prob.w2, prob.gamma, prob.n, prob.damping)
    p1, v1, w, _ = dirk_step(tab, *args)
    if v1 * v < 0.0 and abs(v1) > prob.speed_gain(h, ain):
        pb, vb, wb, _ = dirk_step(BACKWARD_EULER, *args)
        return pb, vb, wb
    return p1, v1, w


def fallback(prob: Problem, p: float, v: float, h: float,
             ain: float) -> tuple[float, float, float]:
    """Take the step with the L-stable fallback, in substeps that obey the angle limit.

    A substep sweeps at most MAX_ANGLE (damping only slows, so |φ'| + h (|a_in| + ω0²)
    bounds the speed) and resolves ω0, re-judged after each one. A step that would need more
    than MAX_FALLBACK_SUBSTEPS substeps is refused (IntegratorError).
    """
    if not h * (abs(v) + prob.speed_gain(h, ain) + prob.omega0) <= (
            MAX_ANGLE * MAX_FALLBACK_SUBSTEPS):  # also inf and NaN
        raise IntegratorError(
            f'a step of {h:g} s from phi = {p:g} rad, dphi = {v:g} rad/s needs more than '
            f'MAX_FALLBACK_SUBSTEPS = {MAX_FALLBACK_SUBSTEPS} substeps of the fallback '
            f'(each sweeps at most {MAX_ANGLE:g} rad); use a smaller h')
    left, w = h, 0.0
    while left > 0.0:
        reach = left * (abs(v) + prob.speed_gain(left, ain) + prob.omega0)
        hh = left if reach <= MAX_ANGLE else left / math.ceil(reach / MAX_ANGLE)
        p, v, wi = dirk_safe(prob, FALLBACK_TABLEAU, p, v, hh, ain)
        w += wi
        left = 0.0 if hh == left else left - hh
    return p, v, w


__all__ = ['FALLBACK_TABLEAU', 'MAX_FALLBACK_SUBSTEPS', 'dirk_safe', 'fallback']
