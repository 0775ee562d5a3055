"""Dry (Coulomb) friction at rest: stick where the force balance allows, else break away."""
from __future__ import annotations

import math

from .explicit import StepFn
from .problem import Problem


def from_rest(prob: Problem, branch: StepFn, p: float, h: float, ain: float,
              v: float = 0.0) -> tuple[float, float, float]:
    """Take a step of h from rest (or within round-off of it) under Coulomb friction.

    The pendulum sticks while |a_in − ω0² sin φ| <= γ; otherwise it breaks away on the branch
    of the law in the direction of the force (``branch``: the method's branch step), and stops
    again if that step reversed.
    """
    force = ain - prob.w2 * math.sin(p)
    if abs(force) <= prob.gamma:
        return p, 0.0, 0.0
    sign = 1.0 if force > 0.0 else -1.0
    p1, v1, w, _ = branch(p, v, h, ain, prob.w2, prob.gamma, sign)
    if v1 * sign < 0.0:
        return p, 0.0, 0.0  # the break-away reversed within the step: it stops again
    return p1, v1, w


__all__ = ['from_rest']
