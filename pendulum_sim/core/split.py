"""Plain explicit steps split at velocity reversals: the explicit family on a Problem.

Where the damping law is not smooth at φ' = 0 (``Problem.nonsmooth``) a plain step that
straddles a reversal has a local error of low order (the paper's Fig 9 remark on n = 2);
:class:`SplitSteps` locates the reversal inside the step (``reversal.locate_reversal``),
integrates each side on its own branch of the law in graded substeps (``reversal.graded_mesh``)
and lets Coulomb friction stick at rest (``coulomb.from_rest``).
"""
from __future__ import annotations

import math
from collections.abc import Callable

from .coulomb import creep, from_rest
from .decisions import reversal_suspect
from .explicit import StepFn, compile_step
from .guard import GuardStats
from .law import compile_damping
from .problem import Problem
from .reversal import (
    GRADED_ITERATIONS,
    GRADED_TOL,
    NEWTON_ITERATIONS,
    NEWTON_TOL,
    branch_accel,
    graded_mesh,
    locate_reversal,
)
from .tableaus import Tableau

Fallback = Callable[[float, float, float, float], tuple[float, float, float]]


class SplitSteps:
    """The plain steps of an explicit ``tableau`` for one problem, split at reversals.

    Parameters
    ----------
    prob : Problem
        The pendulum.
    tableau : Tableau
        An explicit method.
    last_resort : callable
        ``(φ, φ', h, a_in) → (φ₁, φ'₁, w)``: the step where the branch run cannot take it.
    """

    def __init__(self, prob: Problem, tableau: Tableau, last_resort: Fallback) -> None:
        self.problem = prob
        self.w2, self.gamma, self.n = prob.w2, prob.gamma, prob.n
        self.coulomb, self.nonsmooth, self.reach = prob.coulomb, prob.nonsmooth, prob.reach
        self.step_fn: StepFn = compile_step(tableau, prob.n)
        self.branch_fn: StepFn = compile_step(tableau, prob.n, branch=True)
        self.last_resort = last_resort

    def from_rest(self, p: float, h: float, ain: float,
                  v: float = 0.0) -> tuple[float, float, float]:
        """Coulomb friction at (or within round-off of) rest: stick, or break away."""
        return from_rest(self.problem, self.branch_fn, p, h, ain, v)

    def speed_gain(self, h: float, ain: float) -> float:
        """Return the most |φ'| can grow in h (:meth:`Problem.speed_gain`)."""
        return self.problem.speed_gain(h, ain)

    def micro(self, p: float, v: float, h: float, ain: float,
              stats: GuardStats) -> tuple[float, float, float]:
        """Take one plain step, split at a velocity reversal where the damping is not smooth."""
        if self.coulomb and v == 0.0:
            return self.from_rest(p, h, ain)
        p1, v1, w, a0 = self.step_fn(p, v, h, ain, self.w2, self.gamma, 1.0)
        if self.nonsmooth and reversal_suspect(v, v1, a0, h, self.reach):
            if v1 * v < 0.0 or (a0 * v < 0.0 and abs(v) <= h * abs(a0)):
                return self.split(p, v, h, ain, a0, stats)
            if self.reach > 0.0 and a0 != 0.0:
                # Within the window of a reversal without crossing one: graded substeps, by
                # the distance |φ'|/|φ''| to the reversal ahead (decelerating) or behind.
                side = 1.0 if (v > 0.0 or (v == 0.0 and a0 > 0.0)) else -1.0
                x = abs(v) / abs(a0)
                if a0 * v < 0.0:
                    lens = graded_mesh(max(x - h, 0.0), x, h, self.n, self.reach)[::-1]
                else:
                    lens = graded_mesh(x, x + h, h, self.n, self.reach)
                pg, vg, wg = self._branch_run(p, v, lens, ain, side)
                if vg * v >= 0.0:
                    return pg, vg, wg
                # The branch reached φ' = 0 within the step after all: split there.
                return self.split(p, v, h, ain, a0, stats)
        return p1, v1, w

    def _branch_run(self, p: float, v: float, lengths: list[float], ain: float,
                    sign: float) -> tuple[float, float, float]:
        w = 0.0
        for hh in lengths:
            p, v, wi, _ = self.branch_fn(p, v, hh, ain, self.w2, self.gamma, sign)
            w += wi
        return p, v, w

    def split(self, p: float, v: float, h: float, ain: float, a0: float,
              stats: GuardStats) -> tuple[float, float, float]:
        """Split a step that straddles φ' = 0 at the reversal (the paper's Fig 9 remark).

        A first guess comes from the cubic Hermite interpolant of φ' on the step, with the end
        slope from the damping branch of the start (its smooth continuation); Newton iterations
        on the partial step's own φ'(θh) put the reversal where the method says φ' = 0. Each
        side is then integrated on its own branch in graded substeps (:func:`graded_mesh`),
        and a last Newton step in time lands the first side on φ' = 0 exactly.
        """
        sign = 1.0 if v > 0.0 else -1.0
        n, g, w2 = self.n, self.gamma, self.w2
        before = self.branch_fn

        def accel(pp: float, vv: float) -> float:
            return branch_accel(pp, vv, ain, sign, g, n, w2)

        def at(hh: float) -> tuple[float, float, float]:
            pa, va, wa, _ = before(p, v, hh, ain, w2, g, sign)
            return pa, va, wa

        p1, v1, w1, _ = before(p, v, h, ain, w2, g, sign)
        if v1 * v > 0.0:
            # The branch step does not reach φ' = 0: no kink inside (graded if it is near).
            if self.reach > 0.0 and a0 != 0.0:
                x = abs(v) / abs(a0)
                lens = graded_mesh(max(x - h, 0.0), x, h, n, self.reach)[::-1]
                return self._branch_run(p, v, lens, ain, sign)
            return p1, v1, w1
        th, pm, vm, wm = locate_reversal(at, accel, v, v1, a0, accel(p1, v1), h, NEWTON_TOL,
                                         NEWTON_ITERATIONS)
        lens = graded_mesh(0.0, th * h, h, n, self.reach)[::-1]
        if len(lens) > 1:
            for _ in range(GRADED_ITERATIONS):
                # Newton on the graded run's own φ'(θh) = 0 (its θ differs from the single
                # step's by the single step's O(h^(n+1)) error).
                pm, vm, wm = self._branch_run(p, v, lens, ain, sign)
                acc = accel(pm, vm)
                if acc == 0.0 or abs(vm) <= GRADED_TOL * abs(v):
                    break
                nth = th - vm / (acc * h)
                if not 0.0 < nth < 1.0:
                    break
                th = nth
                lens = graded_mesh(0.0, th * h, h, n, self.reach)[::-1]
            if acc != 0.0:
                dt = min(max(-vm / acc, -th * h), (1.0 - th) * h)
                pm += dt * (vm + 0.5 * dt * acc)
                wm += dt * vm * compile_damping(n, True)(vm, g, sign)
                vm = 0.0
                th += dt / h
        stats.reversals += 1
        rest = (1.0 - th) * h
        if self.coulomb:
            p2, v2, w2_ = self.from_rest(pm, rest, ain, vm)
            return p2, v2, wm + w2_
        crept = creep(self.problem, pm, vm, rest, ain)
        if crept is not None:
            return crept[0], crept[1], wm + crept[2]
        after = ain - w2 * math.sin(pm)
        if after == 0.0:
            p2, v2, w2_, _ = self.step_fn(pm, vm, rest, ain, w2, g, 1.0)
            return p2, v2, wm + w2_
        side = 1.0 if after > 0.0 else -1.0
        p2, v2, w2_ = self._branch_run(pm, vm, graded_mesh(0.0, rest, h, n, self.reach), ain, side)
        # From rest the pendulum moves with the force and no faster than the force alone would
        # take it (damping only opposes the motion). A branch run that breaks either bound met
        # a law too steep at rest for explicit steps (n < 1 with a large γ: the creep's rate is
        # beyond any step): the fallback takes the rest of the step.
        if not (v2 * side >= 0.0 and abs(v2) <= self.speed_gain(rest, ain) * (1.0 + 1e-9)):
            stats.fallbacks += 1
            p2, v2, w2_ = self.last_resort(pm, vm, rest, ain)
        return p2, v2, wm + w2_


__all__ = ['SplitSteps']
