"""The careful path written to compile: friction, stiff transients, guarded split steps, redo.

:meth:`Engine.careful <pendulum_sim.core.engine.Engine.careful>` takes every step the fast path
refuses. For a guarded explicit method, :func:`careful_step` takes the same operations in the
same order, calling the very functions the engine calls, written to compile, so the compiled
sweep takes these steps without leaving compiled code (``decisions.kernel_source``):

- friction holding the pendulum (``coulomb.friction_step``): Coulomb sticking and break-away
  at rest (n = 0), the creep of a near-Coulomb law (0 < n < 1); beside a Coulomb friction
  c_f > 0 (``Problem.friction``) the rest rule inside the guard's substeps, as
  ``SplitSteps.friction`` leaves it;
- the stability guard's count of substeps (``guard.substep_count``, the function
  ``StabilityGuard.substeps`` itself runs: the real-axis count, the bisection on the method's
  stability polynomial, the cap, the angle count) and ``Engine.guarded``'s loop of substeps,
  re-judged after each one (:func:`guarded`);
- each substep the plain step split at a velocity reversal (``split.micro_step``, the function
  ``SplitSteps.micro`` runs, with ``split.split_step``, ``reversal.locate_on_branch`` and
  ``reversal.graded_landing``), with the same generated steps (``plain``, ``branch``:
  ``explicit.step_source_with_n``) and laws (``laws``: ``law.laws_source``);
- the L-stable fallback beyond the guard's cap or where a branch run cannot finish a split step
  (``implicit.fallback_run``: the SDIRK3 stages' Newton solves, the backward-Euler
  replacement, the angle-limited substeps, the functions ``implicit.fallback`` runs; the stage
  law is ``dirk.damping_formula``, every spelling of ``dirk.stage_law``);
- the stiff transient's error-controlled DOP853 substeps (``stiff.stiff_cover``, the function
  ``Engine.stiff`` runs: the step-size control and acceptance of ``error_control.py``, the cut
  at a reversal by ``reversal.locate_on_branch``, the guard taking the step where the substeps
  cannot cover it), with the pair's generated steps (``pair_plain``, ``pair_branch``:
  ``stiff.stiff_pair``, ``explicit.step_source_with_n``);
- the energy redo and projection (``energy_redo.redo``, the function ``Engine.redo_energy``
  runs).

It declines (returns ``done`` False; the sweep then hands the step to ``Engine.careful``, which
takes it from the same state) only where the fallback would refuse the whole step by its work
bound (``implicit.fallback_refused``: then ``Engine.check_ahead`` first refuses a step that must
end beyond the speed bound, before any work, as the Stepper does), where the fallback refuses the
rest of a step by that bound (so the user gets that IntegratorError from the one place that
raises it), where the fallback would take a friction beside the law (``engine.moving_fallback``
splits at a reversal through closures: it stays the one Python implementation) and where a
result is not finite:
Python raises OverflowError or ValueError (a power beyond float64, the sine of inf) where compiled
code gives inf or NaN, and which of the two happened decides the Python path (``Engine.careful``'s
``except`` or ``Engine._settle``), so those rare steps are taken by Python (inside a trial substep
of the stiff cover both reject the trial: the same decision; the stiff test's damping power, the
damping slope at the start of a stiff cover or the location of a reversal in it beyond float64
are declined). What the step did is added to the
pendulum's counters (:data:`COUNTERS`) only where it was taken. Parity tests
(``test_sweep_jit.py``) check that both give the same floats and counters.

The generated functions (``plain``, ``branch``, ``laws``, ``pair_plain``, ``pair_branch``, one
set per law text) are arguments, never names of this module: compiled by
``jit.first_class_twin`` they are first-class functions of one signature each, so
:func:`careful_step` and everything under it is compiled once, whatever the law texts, and
kept on disk for the next process (``jit_cache.py``).
"""
from __future__ import annotations

import math
from typing import Any

from .coulomb import friction_step, moving_input, stuck
from .decisions import energy_rose, specific_energy
from .dirk import damping_formula
from .energy_redo import redo
from .guard import FALLBACK, one_substep, substep_count
from .implicit import fallback_refused, fallback_run
from .law import power_formula
from .split import micro_step
from .stiff import NOT_FINITE, OVERFLOW, TO_GUARD, stiff_cover

COUNTERS = ('substeps', 'fallbacks', 'reversals', 'sticks', 'energy_rejections', 'projections')
"""The counters of ``guard.GuardStats`` the compiled sweep keeps per pendulum, in this order."""
SUBSTEPS, FALLBACKS, REVERSALS, STICKS, REJECTIONS, PROJECTIONS = range(len(COUNTERS))


def finite(p: float, v: float) -> bool:
    """Return True where φ and φ' are both finite."""
    return math.isfinite(p) and math.isfinite(v)


def careful_step(plain: Any, branch: Any, laws: Any, pair_plain: Any, pair_branch: Any,
                 p: float, v: float, h: float, ain: float, w2: float, gamma: float, n: float,
                 cf: float, v_acc: float, reach: float, check: bool, nonsmooth: bool,
                 coulomb: bool, guard: Any, counts: Any, known: bool, kp1: float, kv1: float,
                 kw: float, ka0: float, lo: float, hi: float) -> tuple[bool, float, float]:
    """Take ``Engine.careful``'s step of h from (φ, φ') for a guarded explicit method.

    The generated functions come first, all with the exponent an argument: the method's plain
    and branch steps (``plain``, ``branch``), the two laws (``laws``), the stiff transient's
    pair with error estimate (``pair_plain``, ``pair_branch``: ``stiff.stiff_pair``).
    ``cf`` is the friction c_f beside the law (``Problem.friction``; 0.0 for none: the step
    is then the one it was without it), ``reach`` is ``Problem.reach``, ``guard`` the guard's
    ``StabilityGuard.constants``,
    ``counts`` the pendulum's counters (:data:`COUNTERS`; what the step did is added there);
    with ``known``, (``kp1``, ``kv1``, ``kw``, ``ka0``) is the plain step of h the run took
    before it refused the step, ``plain(p, v, h, moving_input(ain, v, cf), w2, gamma, 1.0,
    n)``'s floats, which the careful step reads instead of taking that step again (its stiff
    test's φ''₀ where ``cf`` is 0, the first substep where the guard's count is 1); the run
    takes no plain step outside the guard's speed range (``known`` False there); (``lo``,
    ``hi``) is that range (``guard.safe_speed_range``), inside which, shrunk by its margin
    (``guard.one_substep``), the guard's count is 1 without computing it.
    Returns ``(done, φ₁, φ'₁)``; ``done`` False where ``Engine.careful`` must take the step
    (see the module docstring), the counters then untouched.
    """
    if fallback_refused(v, h, ain, w2, math.sqrt(w2)):
        # Too long to work through: Engine.check_ahead decides first (the module docstring).
        return False, p, v
    subs = fbs = turns = 0
    # Friction holds the pendulum (Engine.careful's first branch, SplitSteps.friction):
    # Coulomb sticking or break-away, the near-Coulomb creep (guarded: creep_state decides on
    # n and γ). Beside a friction (cf > 0) the guard's substeps take the rest and no creep.
    bare = cf == 0.0
    held, p1, v1, _ = friction_step(branch, laws, p, v, h, ain, w2, gamma, n,
                                    coulomb and bare, bare, cf)
    if not held:
        stiff = False
        if bare and abs(v) > v_acc:  # decisions.stiff_source, |φ'|^n by the power rule
            pw = power_formula(abs(v), n)
            if not pw < math.inf:  # Python's damping law raises OverflowError here
                return False, p, v
            # bare (c_f = 0): the known ka0 is plain(p, v, h, ain, ...)'s φ''₀
            a0 = ka0 if known else plain(p, v, h, ain, w2, gamma, 1.0, n)[3]
            stiff = abs(a0) > 0.5 * gamma * pw
        code = TO_GUARD
        if stiff:  # Engine.stiff: the error-controlled substeps
            code, p1, v1, _, subs, turns = stiff_cover(pair_plain, pair_branch, p, v, h, ain,
                                                       w2, gamma, n, nonsmooth, True)
            if code == OVERFLOW or code == NOT_FINITE:
                return False, p, v
        if code == TO_GUARD:  # Engine.guarded (after a stiff cover that failed: from the start)
            done, p1, v1, gsubs, fbs, gturns = guarded(plain, branch, laws, p, v, h, ain, w2,
                                                       gamma, n, cf, reach, nonsmooth,
                                                       coulomb, guard, known, kp1, kv1, kw,
                                                       ka0, one_substep(abs(v), lo, hi))
            if not done:
                return False, p, v
            subs += gsubs
            turns += gturns
    if not finite(p1, v1):
        return False, p, v
    rejected = projected = False
    if check and ain == 0.0:
        e0 = specific_energy(v, math.sin(0.5 * p), w2)
        e1 = specific_energy(v1, math.sin(0.5 * p1), w2)
        if energy_rose(e0, e1, w2):
            omega0 = math.sqrt(w2)
            if fallback_refused(v, h, 0.0, w2, omega0):
                return False, p, v
            rejected = True
            p1, v1, _, projected = redo(p, v, h, e0, w2, gamma, n, omega0, damping_formula)
            if not finite(p1, v1):
                return False, p, v
    counts[SUBSTEPS] += subs
    counts[FALLBACKS] += fbs
    counts[REVERSALS] += turns
    counts[STICKS] += 1 if stuck(coulomb, v, v1) else 0
    counts[REJECTIONS] += 1 if rejected else 0
    counts[PROJECTIONS] += 1 if projected else 0
    return True, p1, v1


def guarded(plain: Any, branch: Any, laws: Any, p: float, v: float, h: float, ain: float,
            w2: float, gamma: float, n: float, cf: float, reach: float, nonsmooth: bool,
            coulomb: bool, guard: Any, known: bool, kp1: float, kv1: float, kw: float,
            ka0: float, one: bool) -> tuple[bool, float, float, int, int, int]:
    """Return ``Engine.guarded``'s step: (done, φ₁, φ'₁, substeps, fallbacks, reversals).

    The fewest stable substeps (``guard.substep_count``), re-judged after each one, each a
    ``split.micro_step`` (a split it cannot finish handed to the fallback, as
    ``SplitSteps.micro`` does); beyond the guard's cap the fallback takes what is left.
    ``done`` False where a substep is not finite or the fallback refuses, and where the
    fallback would take friction beside the law (c_f = ``cf`` > 0: ``engine.moving_fallback``,
    the Python path's one implementation, takes that step). Where the count is 1 the substep
    is the whole step, whose plain step (``kp1``, ``kv1``, ``kw``, ``ka0``) is given where
    ``known``; with ``one`` (``guard.one_substep`` of the step's speed) the count is 1 without
    computing it.
    """
    force = abs(ain) + cf + w2
    omega0 = math.sqrt(w2)
    left = h
    taken = fbs = turns = 0
    while left > 0.0:
        if one and taken == 0:
            m = 1
        else:
            m = substep_count(left, w2, gamma, n, p, v, force,
                              abs(moving_input(ain, v, cf) - w2 * math.sin(p)), guard)
        if m == FALLBACK:
            if cf != 0.0 or fallback_refused(v, left, ain, w2, omega0):
                return False, p, v, 0, 0, 0
            p, v, _ = fallback_run(p, v, left, ain, w2, gamma, n, omega0, damping_formula)
            return True, p, v, max(taken - 1, 0), fbs + 1, turns
        hh = left / m
        whole = known and m == 1 and taken == 0  # the step of h the run took plain
        done, p1, v1, _, k, pm, vm, _, rest = micro_step(plain, branch, laws, p, v, hh, ain, w2,
                                                         gamma, n, reach, nonsmooth, coulomb,
                                                         True, cf, whole, kp1, kv1, kw, ka0)
        if not done:
            # split.NOT_FINITE; the fallback beside a friction is the Python path's
            if k < 0 or cf != 0.0 or fallback_refused(vm, rest, ain, w2, omega0):
                return False, p, v, 0, 0, 0
            # The fallback takes the rest of the split step (SplitSteps.micro).
            p1, v1, _ = fallback_run(pm, vm, rest, ain, w2, gamma, n, omega0, damping_formula)
            fbs += 1
        if not finite(p1, v1):
            return False, p, v, 0, 0, 0
        p, v = p1, v1
        turns += k
        taken += 1
        left = 0.0 if m == 1 else left - hh
    return True, p, v, taken - 1, fbs, turns


__all__ = ['COUNTERS', 'careful_step', 'finite', 'guarded']
