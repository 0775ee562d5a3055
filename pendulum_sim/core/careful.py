"""The careful step, written once: every step the fast path refuses, in Python and compiled.

A step of h from (φ, φ') under the input a_in = τ/I that the fast path refuses is taken here, by
plain Python functions that numba compiles (as ``guard.substep_count`` is): the Stepper's engine
(``Engine.careful``) calls them as Python, the compiled sweep's run (``kernel.kernel_source``)
calls :func:`careful_step` compiled, and the numpy sweep takes its refused steps by
:func:`careful_each` compiled (or hands them to the engine). One function per rule, each in its
own module and called from here:

- friction holding the pendulum, Coulomb sticking and break-away at rest and the near-Coulomb
  creep (``coulomb.friction_step``; the moving friction as an input, ``coulomb.moving_input``);
- the stiff-transient test (``decisions.stiff_transient``, its power |φ'|^n by the law's rule,
  ``law.power_formula``) and the error-controlled substeps (``stiff.stiff_cover``);
- the stability guard's count of substeps (``guard.substep_count``), re-judged after each one
  (:func:`guarded`);
- each substep the plain step split at a velocity reversal (``split.micro_step``: the reversal
  test ``decisions.reversal_suspect``, ``split.split_step``, the graded landing
  ``reversal.graded_landing``);
- the L-stable fallback beyond the guard's cap or where a split's run from rest cannot finish
  (:func:`fallback_step`);
- the energy redo and projection (``energy_redo.redo``) and the finiteness of the result
  (:func:`careful_settle`).

:func:`careful_step` takes the path of the step (friction, the stiff cover or the guard's
substeps), then settles its result (:func:`careful_settle`: the energy test, the result's
finiteness, the Coulomb stick). Python and compiled code differ in two ways, and both are data
here, not a second copy of a rule:

- where Python raises (OverflowError for a power beyond float64, ValueError for the sine of inf)
  compiled code gives inf or NaN. Run as Python (``Pendulum.strict`` False) the exception
  leaves :func:`careful_step` and the engine takes the step by the fallback (``Engine.careful``);
  compiled (``strict`` True) the step is declined (:data:`DECLINED`, :data:`NOT_FINITE`)
  wherever Python may have raised or taken another path, and the sweep hands it to the engine;
- the fallback (:func:`fallback_step`) and the energy redo's refusal (:func:`redo_refused`) are
  Python functions (the fallback's refusal is an IntegratorError with its message, a friction
  beside the law is split at a reversal through closures) whose compiled forms
  (:data:`COMPILED_FORMS`, read by ``jit.numba_twin``) decline instead.

The arguments come in three groups, each a named tuple (:class:`LawSteps`, :class:`Pendulum`,
:class:`Tried`: named where they are built and in numba's signature); the functions unpack each
by position, so the engine passes the same fields as plain tuples, which CPython unpacks several
times faster than a named tuple (``Engine.careful`` takes several steps a millisecond).

What a step did is added to ``counts`` (:data:`COUNTERS`, the counters of ``guard.GuardStats``)
as it goes, so that a step Python leaves by an exception has counted what it did: the engine's
``GuardStats`` itself (indexed by position), compiled a row of scratch counters committed only
for a step taken (:func:`commit_tally`).
"""
from __future__ import annotations

import math
from typing import Any, NamedTuple

from .coulomb import friction_step, moving_input, stuck
from .decisions import energy_rose, specific_energy, stiff_transient
from .dirk import damping_formula
from .energy_redo import redo
from .errors import IntegratorError
from .guard import CAREFUL_COUNTERS, FALLBACK, one_substep, substep_count
from .implicit import fallback_refused, fallback_run, moving_fallback, refusal
from .law import power_formula
from .problem import Problem
from .split import NOT_FINITE as SPLIT_NOT_FINITE
from .split import micro_step
from .stiff import NOT_FINITE as STIFF_NOT_FINITE
from .stiff import OVERFLOW, TO_GUARD, stiff_cover

COUNTERS = CAREFUL_COUNTERS
"""The counters of ``guard.GuardStats`` the careful step adds to, in this order."""
SUBSTEPS, FALLBACKS, REVERSALS, STICKS, REJECTIONS, PROJECTIONS = range(len(COUNTERS))

TAKEN, DECLINED, OVERFLOWED, NOT_FINITE = range(4)
"""The codes of the careful step: the step is taken; declined (compiled: the Python path must
take it); the damping slope at the start of a stiff cover overflowed (the fallback takes the
step, as where Python raised); the result is not finite (the fallback takes the step)."""


class LawSteps(NamedTuple):
    """The generated functions of one law text, the exponent an argument of each.

    ``plain`` and ``branch``: the method's step on the plain law and on the branch s of one
    direction of motion, ``(φ, φ', h, a_in, ω0², γ, s, n)`` → (φ₁, φ'₁, w, φ''₀)
    (``explicit.step_source_with_n``); ``laws``: ``(v, γ, s, n)`` → (plain law, branch law)
    (``law.laws_source``); ``pair_plain`` and ``pair_branch``: the stiff transient's pair with
    its error estimate (``stiff.stiff_pair``). Compiled, each is a first-class function of its
    one signature (``jit.first_class_twin``), so the careful step compiles once for every text.
    """

    plain: Any
    branch: Any
    laws: Any
    pair_plain: Any
    pair_branch: Any


class Pendulum(NamedTuple):
    """What one pendulum fixes for the careful step (the engine's ``Problem`` and settings).

    ``w2``, ``gamma``, ``n``: ω0² (s⁻²), γ (s^(n−2)), n (eq 11, 15); ``cf``: the Coulomb friction
    beside the law, c_f = f/I (rad/s², ``Problem.friction``); ``v_acc``: the speed above which a
    damping-dominated transient is error-controlled (``Problem.v_acc``, inf without the guard);
    ``reach``: the grading window S (``Problem.reach``); ``check``: the energy test applies
    (damped, no friction beside the law, the guard's explicit steps; with a_in = 0 only);
    ``nonsmooth``, ``coulomb``: ``Problem.nonsmooth``, ``Problem.coulomb``; ``guarded``: the
    stability guard counts the substeps (False: plain steps as asked, one micro step);
    ``guard``: its ``StabilityGuard.constants``; ``strict``: compiled, decline where Python
    may raise (module docstring).
    """

    w2: float
    gamma: float
    n: float
    cf: float
    v_acc: float
    reach: float
    check: bool
    nonsmooth: bool
    coulomb: bool
    guarded: bool
    guard: Any
    strict: bool


class Tried(NamedTuple):
    """The plain step of h a compiled run took before it refused the step, and the guard's range.

    With ``taken``, (``p1``, ``v1``, ``w``, ``a0``) is ``plain(φ, φ', h, moving_input(a_in,
    φ', c_f), ...)``'s floats, read instead of taking that step again (its φ''₀ for the
    stiff test, the first substep where the guard's count is 1); (``lo``, ``hi``) is the
    guard's safe speed range (``guard.safe_speed_range``), inside which, shrunk by its margin
    (``guard.one_substep``), the guard's count is 1 without computing it. :data:`NOT_TRIED`
    for a step nothing was tried for (the engine's).
    """

    taken: bool
    p1: float
    v1: float
    w: float
    a0: float
    lo: float
    hi: float


StepsArg = LawSteps | tuple[Any, ...]
"""A :class:`LawSteps`, or its fields as a plain tuple (the engine's)."""
PendulumArg = Pendulum | tuple[Any, ...]
"""A :class:`Pendulum`, or its fields as a plain tuple (the engine's)."""
TriedArg = Tried | tuple[Any, ...]
"""A :class:`Tried`, or its fields as a plain tuple (:data:`NOT_TRIED`)."""

NOT_TRIED = tuple(Tried(False, 0.0, 0.0, 0.0, 0.0, math.inf, -math.inf))
"""No plain step tried, no safe range known: the careful step decides everything itself."""

Result = tuple[int, float, float, float]
"""(code, φ₁, φ'₁, w) of the careful step's functions; w is the damping work per unit inertia."""
Settled = tuple[int, float, float, float, float]
"""(code, φ₁, φ'₁, w, E₁/I) of the settled careful step (E₁/I NaN where not known)."""


class FallbackDiverged(Exception):
    """The fallback taking the rest of a split step overflowed from (``p``, ``v``) (Python)."""

    def __init__(self, p: float, v: float) -> None:
        super().__init__(p, v)
        self.p, self.v = p, v


def fallback_step(p: float, v: float, h: float, ain: float, w2: float, gamma: float, n: float,
                  cf: float, rest: bool) -> tuple[bool, float, float, float]:
    """Take a step of h by the L-stable fallback (``implicit.moving_fallback``).

    Returns (True, φ₁, φ'₁, w).

    Python: the fallback refuses a step beyond its work bound (IntegratorError); beside a
    friction c_f = ``cf`` it splits the step at a reversal; where it overflows, the step that
    called it overflows (``rest`` False: the guard's cap) or, taking the ``rest`` of a split
    step, diverged (:class:`FallbackDiverged`). Compiled: :func:`fallback_formula`.
    """
    prob = Problem(w2, gamma, n, cf)
    if not rest:
        p1, v1, w = moving_fallback(prob, p, v, h, ain)
        return True, p1, v1, w
    try:
        p1, v1, w = moving_fallback(prob, p, v, h, ain)
    except IntegratorError:  # the refusal by the work bound
        raise
    except (OverflowError, ValueError):
        raise FallbackDiverged(p, v) from None
    return True, p1, v1, w


def fallback_formula(p: float, v: float, h: float, ain: float, w2: float, gamma: float,
                     n: float, cf: float, rest: bool) -> tuple[bool, float, float, float]:
    """Return :func:`fallback_step` compiled: (False, …) where Python refuses or splits.

    Beside a friction (c_f = ``cf`` > 0) the fallback splits at a reversal through closures,
    and beyond its work bound it raises its refusal: both are the Python path's, so the
    compiled step declines there; elsewhere ``implicit.fallback_run`` with the stage law every
    spelling of ``dirk.stage_law`` (``dirk.damping_formula``).
    """
    omega0 = math.sqrt(w2)
    if cf != 0.0 or fallback_refused(v, h, ain, w2, omega0):
        return False, p, v, 0.0
    p1, v1, w = fallback_run(p, v, h, ain, w2, gamma, n, omega0, damping_formula)
    return True, p1, v1, w


def redo_refused(p: float, v: float, h: float, w2: float) -> bool:
    """Refuse the energy redo of a step of h beyond the fallback's work bound (Python: raise).

    Returns False where the fallback takes it; compiled (:func:`redo_refusal_formula`) True
    where Python raises ``implicit.refusal``'s IntegratorError.
    """
    if fallback_refused(v, h, 0.0, w2, math.sqrt(w2)):
        raise refusal(p, v, h)
    return False


def redo_refusal_formula(p: float, v: float, h: float, w2: float) -> bool:
    """Return :func:`redo_refused` compiled: True where Python raises the refusal."""
    return fallback_refused(v, h, 0.0, w2, math.sqrt(w2))


COMPILED_FORMS = {fallback_step: fallback_formula, redo_refused: redo_refusal_formula}
"""The Python functions of the careful step and the forms numba compiles for them."""


def finite(p: float, v: float) -> bool:
    """Return True where φ and φ' are both finite."""
    return math.isfinite(p) and math.isfinite(v)


def guarded(steps: StepsArg, pend: PendulumArg, p: float, v: float, h: float, ain: float,
            tried: TriedArg, counts: Any) -> Result:
    """Cover h with the fewest stable substeps (``guard.substep_count``), re-judged after each.

    The stiffness of n ≠ 1 damping moves with the velocity, so after each substep the guard
    looks again at what is left of the step; beyond its cap the fallback takes what is left
    (:func:`fallback_step`). Each substep is :func:`substep`. Without the guard
    (``Pendulum.guarded`` False) the count is 1; where the step's speed is inside the guard's safe
    range (``tried``, ``guard.one_substep``) the first count is 1 without computing it.
    """
    w2, gamma, n, cf, _, _, _, _, _, with_guard, consts, _ = pend
    force = abs(ain) + cf + w2
    known, _, _, _, _, lo, hi = tried
    one = one_substep(abs(v), lo, hi)
    left, w, taken = h, 0.0, 0
    while left > 0.0:
        if not with_guard or (one and taken == 0):
            m = 1
        else:
            m = substep_count(left, w2, gamma, n, p, v, force,
                              abs(moving_input(ain, v, cf) - w2 * math.sin(p)), consts)
        if m == FALLBACK:
            counts[FALLBACKS] += 1
            done, p, v, wi = fallback_step(p, v, left, ain, w2, gamma, n, cf, False)
            if not done:
                return DECLINED, p, v, 0.0
            counts[SUBSTEPS] += max(taken - 1, 0)
            return TAKEN, p, v, w + wi
        hh = left / m
        whole = known and m == 1 and taken == 0  # the step of h the run took plain
        code, p, v, wi = substep(steps, pend, p, v, hh, ain, whole, tried, counts)
        if code != TAKEN:
            return code, p, v, 0.0
        w += wi
        taken += 1
        left = 0.0 if m == 1 else left - hh
    counts[SUBSTEPS] += taken - 1
    return TAKEN, p, v, w


def substep(steps: StepsArg, pend: PendulumArg, p: float, v: float, h: float, ain: float,
            whole: bool, tried: TriedArg, counts: Any) -> Result:
    """Take one plain step of h split at a velocity reversal (``split.micro_step``).

    The reversals it split at are counted; where the split's branch run from rest cannot
    finish it, the fallback takes the rest from the reversal (:func:`fallback_step`). With
    ``whole`` the plain step of h is ``tried``'s.
    """
    w2, gamma, n, cf, _, reach, _, nonsmooth, coulomb, _, _, strict = pend
    plain, branch, laws, _, _ = steps
    _, kp1, kv1, kw, ka0, _, _ = tried
    done, p1, v1, w, turns, pm, vm, wm, rest = micro_step(
        plain, branch, laws, p, v, h, ain, w2, gamma, n, reach, nonsmooth, coulomb, strict, cf,
        whole, kp1, kv1, kw, ka0)
    if turns == SPLIT_NOT_FINITE:
        return DECLINED, p, v, 0.0
    counts[REVERSALS] += turns
    if not done:
        counts[FALLBACKS] += 1
        done, p1, v1, w = fallback_step(pm, vm, rest, ain, w2, gamma, n, cf, True)
        if not done:
            return DECLINED, p, v, 0.0
        w += wm
    if strict and not finite(p1, v1):
        return DECLINED, p, v, 0.0
    return TAKEN, p1, v1, w


def careful_settle(pend: PendulumArg, p: float, v: float, h: float, ain: float, p1: float,
                   v1: float, w: float, e0: float, counts: Any) -> Settled:
    """Settle the careful step's result: the energy test and redo, finiteness, a Coulomb stick.

    Where ``Pendulum.check`` and a_in = 0, a step whose energy rose (``decisions.energy_rose``; E/I
    at the start ``e0``, or made here where it is NaN) is redone by the fallback and projected
    (``energy_redo.redo``). Returns (code, φ₁, φ'₁, w, E₁/I): :data:`NOT_FINITE` where the
    result is not finite (the engine's fallback takes the step), E₁/I NaN where not known.
    """
    w2, gamma, n, _, _, _, check, _, coulomb, _, _, strict = pend
    e1 = math.nan
    if strict and not finite(p1, v1):
        return NOT_FINITE, p, v, 0.0, e1
    if check and ain == 0.0:
        if not e0 == e0:
            e0 = specific_energy(v, math.sin(0.5 * p), w2)
        e1 = specific_energy(v1, math.sin(0.5 * p1), w2)
        if energy_rose(e0, e1, w2):
            counts[REJECTIONS] += 1
            if redo_refused(p, v, h, w2):
                return DECLINED, p, v, 0.0, math.nan
            p1, v1, w, projected = redo(p, v, h, e0, w2, gamma, n, math.sqrt(w2),
                                        damping_formula)
            counts[PROJECTIONS] += 1 if projected else 0
            e1 = math.nan
    if not (math.isfinite(p1) and math.isfinite(v1) and math.isfinite(w)):
        return NOT_FINITE, p, v, 0.0, math.nan
    if stuck(coulomb, v, v1):
        counts[STICKS] += 1
    return TAKEN, p1, v1, w, e1


def careful_step(steps: StepsArg, pend: PendulumArg, p: float, v: float, h: float, ain: float,
                 e0: float, tried: TriedArg, counts: Any) -> Settled:
    """Take the careful step of h from (φ, φ'): its path, then :func:`careful_settle`.

    In this order: where friction holds the pendulum, ``coulomb.friction_step`` (beside a
    friction c_f > 0 the guard's substeps take the rest, and a near-Coulomb law creeps under
    the moving friction, ``coulomb.creep_state``); a step in a
    damping-dominated transient (``decisions.stiff_transient``) by ``stiff.stiff_cover`` (the
    guard takes it from its start where the cover cannot); every other step by
    :func:`guarded` (without the guard, one micro step). ``e0`` is E/I at the start where known
    (NaN: made where the energy test needs it). Returns (code, φ₁, φ'₁, w, E₁/I) as
    :func:`careful_settle`: any code but :data:`TAKEN` hands the step to the fallback
    (:data:`OVERFLOWED`, :data:`NOT_FINITE`: ``Engine.careful``, which also has the fallback
    take it where Python raised, then settles its result) or, compiled, to ``Engine.careful``.
    """
    w2, gamma, n, cf, v_acc, _, _, nonsmooth, coulomb, with_guard, _, strict = pend
    if strict and fallback_refused(v, h, ain, w2, math.sqrt(w2)):
        # Too long to work through: Engine.check_ahead decides first (the sweep's caller).
        return DECLINED, p, v, 0.0, math.nan
    bare = cf == 0.0
    _, branch, laws, pair_plain, pair_branch = steps
    held, p1, v1, w = friction_step(branch, laws, p, v, h, ain, w2, gamma, n,
                                    coulomb and bare, with_guard, cf)
    if held:
        return careful_settle(pend, p, v, h, ain, p1, v1, w, e0, counts)
    speed = abs(v)
    if bare and speed > v_acc:
        power = power_formula(speed, n)  # as Python: `**` beyond float64 raises OverflowError
        if strict and not power < math.inf:
            return DECLINED, p, v, 0.0, math.nan
        taken, _, _, _, a0, _, _ = tried
        if not taken:
            a0 = ain - laws(v, gamma, 1.0, n)[0] - w2 * math.sin(p)
        if stiff_transient(speed, a0, gamma, power, v_acc):
            code, p1, v1, w, subs, turns = stiff_cover(pair_plain, pair_branch, p, v, h, ain,
                                                       w2, gamma, n, nonsmooth, strict)
            counts[SUBSTEPS] += subs
            counts[REVERSALS] += turns
            if code == OVERFLOW:
                return OVERFLOWED, p, v, 0.0, math.nan
            if code == STIFF_NOT_FINITE:
                return DECLINED, p, v, 0.0, math.nan
            if code != TO_GUARD:
                return careful_settle(pend, p, v, h, ain, p1, v1, w, e0, counts)
    code, p1, v1, w = guarded(steps, pend, p, v, h, ain, tried, counts)
    if code != TAKEN:
        return code, p, v, 0.0, math.nan
    return careful_settle(pend, p, v, h, ain, p1, v1, w, e0, counts)


def careful_each(steps: StepsArg, h: float, idx: Any, p: Any, v: Any, ain: Any, w2: Any,
                 gamma: Any, n: Any, cf: Any, v_acc: Any, reach: Any, check: Any, nonsmooth: Any,
                 coulomb: Any, lo: Any, hi: Any, guard: Any, p1: Any, v1: Any, taken: Any,
                 counts: Any, tally: Any) -> None:
    """Take the careful step of h of each pendulum ``i = idx[j]`` of a group, compiled.

    The numpy sweep's refused steps (``sweep._careful``): the arrays are the group's columns
    (its state ``p``, ``v``, the input, the pendulums' constants as :class:`Pendulum` names
    them, the guard's safe range ``lo``, ``hi``), each step the guarded, strict careful step
    (:func:`careful_step`, nothing tried: the numpy plain step's floats are not the C
    library's). Where it takes the step, (φ₁, φ'₁) go to ``p1[i]``, ``v1[i]``, ``taken[j]`` is
    set and what it did is added to the row ``counts[i]``; elsewhere nothing changes (the
    sweep hands the step to ``Engine.careful``). ``tally`` is a row of scratch counters, zero
    (:func:`commit_tally`).
    """
    for j in range(idx.shape[0]):
        i = idx[j]
        code, pi, vi, _, _ = careful_step(
            steps, Pendulum(w2[i], gamma[i], n[i], cf[i], v_acc[i], reach[i], check[i],
                            nonsmooth[i], coulomb[i], True, guard, True),
            p[i], v[i], h, ain[i], math.nan,
            Tried(False, 0.0, 0.0, 0.0, 0.0, lo[i], hi[i]), tally)
        commit_tally(counts[i], tally, code == TAKEN)
        if code == TAKEN:
            p1[i] = pi
            v1[i] = vi
            taken[j] = True


def commit_tally(counts: Any, tally: Any, taken: bool) -> None:
    """Add a compiled careful step's scratch counters to the pendulum's where ``taken``.

    The scratch row ``tally`` is cleared either way: a step declined counts nothing (the
    engine takes it and counts it). Element by element, so that nothing is allocated.
    """
    for c in range(tally.shape[0]):
        t = tally[c]
        if t != 0:
            if taken:
                counts[c] += t
            tally[c] = 0


__all__ = [
    'COMPILED_FORMS',
    'COUNTERS',
    'DECLINED',
    'NOT_FINITE',
    'NOT_TRIED',
    'OVERFLOWED',
    'TAKEN',
    'FallbackDiverged',
    'LawSteps',
    'Pendulum',
    'PendulumArg',
    'Result',
    'Settled',
    'StepsArg',
    'Tried',
    'TriedArg',
    'careful_each',
    'careful_settle',
    'careful_step',
    'commit_tally',
    'fallback_formula',
    'fallback_step',
    'finite',
    'guarded',
    'redo_refusal_formula',
    'redo_refused',
    'substep',
]
