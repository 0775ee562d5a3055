"""Plain explicit steps split at velocity reversals: the explicit family on a Problem.

Where the damping law is not smooth at φ' = 0 (``Problem.nonsmooth``) a plain step that
straddles a reversal has a local error of low order (the paper's Fig 9 remark on n = 2);
:func:`split_step` locates the reversal inside the step (``reversal.locate_on_branch``),
integrates each side on its own branch of the law in graded substeps (``reversal.graded_mesh``,
``reversal.graded_landing``), lets Coulomb friction stick at rest (``coulomb.rest_step``) and a
near-Coulomb law creep (``coulomb.creep_state``). It is written to compile: the careful step
(``careful.substep``) calls it, as Python for the Stepper and compiled in the compiled sweep.
"""
from __future__ import annotations

import math
from typing import Any

from .coulomb import creep_state, friction_work, moving_input, rest_step
from .decisions import reversal_suspect
from .reversal import (
    NEWTON_ITERATIONS,
    NEWTON_TOL,
    branch_run,
    graded_landing,
    graded_mesh,
    locate_on_branch,
)

SplitResult = tuple[bool, float, float, float, int, float, float, float, float]
"""``split_step``'s (done, φ₁, φ'₁, w, reversals, φm, φ'm, wm, rest)."""


def split_step(plain: Any, branch: Any, laws: Any, p: float, v: float, h: float, ain: float,
               w2: float, gamma: float, n: float, a0: float, reach: float,
               coulomb: bool, cf: float = 0.0) -> SplitResult:
    """Split a step of h that straddles φ' = 0 at the reversal (the paper's Fig 9 remark).

    A first guess comes from the cubic Hermite interpolant of φ' on the step, with the end
    slope from the damping branch of the start (its smooth continuation); Newton iterations
    on the partial step's own φ'(θh) put the reversal where the method says φ' = 0
    (``reversal.locate_on_branch``). Each side is then integrated on its own branch in graded
    substeps (``reversal.graded_mesh``), a last Newton step in time landing the first side on
    φ' = 0 exactly (``reversal.graded_landing``); from rest, Coulomb friction sticks or breaks
    away (``coulomb.rest_step``) and a near-Coulomb law may creep (``coulomb.creep_state``).

    ``plain``, ``branch`` are the generated steps and ``laws`` the laws with the exponent an
    argument (``explicit.step_source_with_n``, ``law.laws_source``), ``a0`` φ'' at the start.
    Returns (done, φ₁, φ'₁, w, reversals, φm, φ'm, wm, rest): where ``done`` is False the branch
    run from rest broke its bounds (a law too steep at rest for explicit steps) and the
    fallback must take ``rest`` from the reversal's (φm, φ'm), wm being the work up to it.
    With a friction ``cf`` = c_f beside the law (``coulomb`` then holds), the side up to the
    reversal is taken under ``coulomb.moving_input`` and its work counts the friction's.
    Written to compile: :func:`micro_step` calls it, as Python for the Stepper and compiled in
    the compiled sweep's careful step (``careful.py``), the same function.
    """
    sign = 1.0 if v > 0.0 else -1.0
    a = moving_input(ain, sign, cf)
    p1, v1, w1, _ = branch(p, v, h, a, w2, gamma, sign, n)
    if v1 * v > 0.0:
        # The branch step does not reach φ' = 0: no kink inside (graded if it is near).
        if reach > 0.0 and a0 != 0.0:
            # The reversal ahead at about x = |φ'|/|φ''| (a split is tried for x <= h, so the
            # reversal may lie beyond the step after all): the substeps cover the step's own
            # length h, graded towards its end where x < h.
            x = abs(v) / abs(a0)
            lens = graded_mesh(max(x - h, 0.0), max(x, h), h, n, reach)
            p1, v1, w1 = branch_run(branch, p, v, lens, True, a, w2, gamma, sign, n)
        if cf != 0.0:
            w1 += friction_work(cf, sign, p, p1)
        return True, p1, v1, w1, 0, p, v, 0.0, 0.0
    a1 = branch(p1, v1, 0.0, a, w2, gamma, sign, n)[3]  # φ'' on the branch at the end
    th, pm, vm, wm = locate_on_branch(branch, p, v, v1, a0, a1, h, a, w2, gamma, sign, n,
                                      NEWTON_TOL, NEWTON_ITERATIONS)
    th, pm, vm, wm = graded_landing(branch, laws, p, v, th, pm, vm, wm, h, a, w2, gamma,
                                    sign, n, reach)
    if cf != 0.0:
        wm += friction_work(cf, sign, p, pm)
    rest = (1.0 - th) * h
    if coulomb:
        p2, v2, w2_ = rest_step(branch, pm, vm, rest, ain, w2, gamma, n, cf)
        return True, p2, v2, wm + w2_, 1, pm, vm, wm, rest
    crept, p2, v2, w2_ = creep_state(laws, n, gamma, w2, pm, vm, rest, ain, 0.0)
    if crept:
        return True, p2, v2, wm + w2_, 1, pm, vm, wm, rest
    after = ain - w2 * math.sin(pm)
    if after == 0.0:
        p2, v2, w2_, _ = plain(pm, vm, rest, ain, w2, gamma, 1.0, n)
        return True, p2, v2, wm + w2_, 1, pm, vm, wm, rest
    side = 1.0 if after > 0.0 else -1.0
    p2, v2, w2_ = branch_run(branch, pm, vm, graded_mesh(0.0, rest, h, n, reach), False, ain,
                             w2, gamma, side, n)
    # From rest the pendulum moves with the force and no faster than the force alone would
    # take it (damping only opposes the motion; ``Problem.speed_gain``). A branch run that
    # breaks either bound met a law too steep at rest for explicit steps (n < 1 with a large
    # γ: the creep's rate is beyond any step): the fallback takes the rest of the step.
    if not (v2 * side >= 0.0 and abs(v2) <= rest * (abs(ain) + w2) * (1.0 + 1e-9)):
        return False, p2, v2, w2_, 1, pm, vm, wm, rest
    return True, p2, v2, wm + w2_, 1, pm, vm, wm, rest


NOT_FINITE = -1
""":func:`micro_step`'s reversal count where it declined a plain step that is not finite."""


def micro_step(plain: Any, branch: Any, laws: Any, p: float, v: float, h: float, ain: float,
               w2: float, gamma: float, n: float, reach: float, nonsmooth: bool, coulomb: bool,
               strict: bool, cf: float = 0.0, known: bool = False, kp1: float = 0.0,
               kv1: float = 0.0, kw: float = 0.0, ka0: float = 0.0) -> SplitResult:
    """Take one plain step of h, split at a velocity reversal where the damping is not smooth.

    Under Coulomb friction at rest, ``coulomb.rest_step``; otherwise the plain step, and where
    a reversal is suspected (``decisions.reversal_suspect``) :func:`split_step` or, within the
    window of a reversal it does not cross, graded substeps on the branch
    (``reversal.graded_mesh``) by the distance |φ'|/|φ''| to the reversal ahead (decelerating)
    or behind. Returns :func:`split_step`'s tuple. With ``strict`` a plain step that is not
    finite (where Python may have raised inside it) is declined: ``done`` False and
    ``reversals`` NOT_FINITE. With a friction ``cf`` = c_f beside the law, a step in motion is
    taken under ``coulomb.moving_input`` and its work counts the friction's. Written to compile:
    ``careful.substep`` calls it, as Python for the Stepper and compiled in the compiled
    sweep's careful step. With ``known`` the plain step's result is given,
    (``kp1``, ``kv1``, ``kw``, ``ka0``) = ``plain(p, v, h, moving_input(ain, v, cf), ...)``,
    the very floats the compiled sweep's run took before it refused the step, and is not
    taken again.
    """
    if coulomb and v == 0.0:
        p1, v1, w = rest_step(branch, p, 0.0, h, ain, w2, gamma, n, cf)
        return True, p1, v1, w, 0, p, v, 0.0, 0.0
    a = moving_input(ain, v, cf)
    if known:
        p1, v1, w, a0 = kp1, kv1, kw, ka0
    else:
        p1, v1, w, a0 = plain(p, v, h, a, w2, gamma, 1.0, n)
    if strict and not (math.isfinite(p1) and math.isfinite(v1) and math.isfinite(a0)):
        return False, p, v, 0.0, NOT_FINITE, p, v, 0.0, 0.0
    if nonsmooth and reversal_suspect(v, v1, a0, h, reach):
        if v1 * v < 0.0 or (a0 * v < 0.0 and abs(v) <= h * abs(a0)):
            return split_step(plain, branch, laws, p, v, h, ain, w2, gamma, n, a0, reach,
                              coulomb, cf)
        if reach > 0.0 and a0 != 0.0:
            side = 1.0 if (v > 0.0 or (v == 0.0 and a0 > 0.0)) else -1.0
            x = abs(v) / abs(a0)
            if a0 * v < 0.0:
                lens = graded_mesh(max(x - h, 0.0), x, h, n, reach)
                back = True
            else:
                lens = graded_mesh(x, x + h, h, n, reach)
                back = False
            pg, vg, wg = branch_run(branch, p, v, lens, back, a, w2, gamma, side, n)
            if vg * v >= 0.0:
                if cf != 0.0:
                    wg += friction_work(cf, side, p, pg)
                return True, pg, vg, wg, 0, p, v, 0.0, 0.0
            # The branch reached φ' = 0 within the step after all: split there.
            return split_step(plain, branch, laws, p, v, h, ain, w2, gamma, n, a0, reach,
                              coulomb, cf)
    if cf != 0.0:
        w += friction_work(cf, v, p, p1)
    return True, p1, v1, w, 0, p, v, 0.0, 0.0


__all__ = ['NOT_FINITE', 'SplitResult', 'micro_step', 'split_step']
