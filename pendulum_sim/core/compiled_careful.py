"""The careful path written to compile: guarded steps split at reversals, the fallback, the redo.

:meth:`Engine.careful <pendulum_sim.core.engine.Engine.careful>` takes every step the fast path
refuses. For a guarded explicit method and n >= 1 (no Coulomb or near-Coulomb friction, no
stiff transient), :func:`careful_step` takes the same operations in the same order, so the
compiled sweep takes these steps without leaving compiled code (``decisions.kernel_source``):

- the stability guard's count of substeps (``guard.substep_count``, the function
  ``StabilityGuard.substeps`` itself runs: the real-axis count, the bisection on the method's
  stability polynomial, the cap, the angle count) and ``Engine.guarded``'s loop of substeps,
  re-judged after each one (:func:`guarded`);
- each substep the plain step split at a velocity reversal (:func:`micro`, :func:`split`:
  ``SplitSteps.micro`` and ``SplitSteps.split``), with the same generated steps (``plain``,
  ``branch``: ``explicit.step_source`` with the exponent an argument), the same reversal
  location (``reversal.locate_on_branch``), graded substeps near a reversal
  (``reversal.graded_mesh``) and the same decision texts;
- the L-stable fallback beyond the guard's cap or where a branch run cannot finish a split step
  (``implicit.fallback_run``: the SDIRK3 stages' Newton solves, the backward-Euler
  replacement, the angle-limited substeps, the functions ``implicit.fallback`` runs; the stage
  law is ``dirk.damping_formula``, every spelling of ``dirk.stage_law``);
- the energy redo and projection (``energy_redo.redo``, the function ``Engine.redo_energy``
  runs).

It declines (returns ``done`` False; the sweep then hands the step to ``Engine.careful``, which
takes it from the same state) where the step needs what is not compiled here (a stiff transient,
Coulomb and near-Coulomb friction, n < 1), where the fallback refuses the step by its work
bound (so the user gets that IntegratorError from the one place that raises it), and where a
result is not finite: Python raises OverflowError or ValueError (a power beyond float64, the
sine of inf) where compiled code gives inf or NaN, and which of the two happened decides the
Python path (``Engine.careful``'s ``except`` or ``Engine._settle``), so those rare steps are
taken by Python. What the step did is added to the pendulum's counters (:data:`COUNTERS`) only
where it was taken. Parity tests (``test_sweep_jit.py``) check that both give the same floats
and counters.
"""
from __future__ import annotations

import math
from typing import Any

from .decisions import energy_rose, specific_energy
from .dirk import damping_formula
from .energy_redo import redo
from .guard import FALLBACK, substep_count
from .implicit import fallback_refused, fallback_run
from .problem import speed_gain
from .reversal import (
    GRADED_ITERATIONS,
    GRADED_TOL,
    NEWTON_ITERATIONS,
    NEWTON_TOL,
    graded_mesh,
    locate_on_branch,
)

COUNTERS = ('substeps', 'fallbacks', 'reversals', 'sticks', 'energy_rejections', 'projections')
"""The counters of ``guard.GuardStats`` the compiled sweep keeps per pendulum, in this order."""
SUBSTEPS, FALLBACKS, REVERSALS, STICKS, REJECTIONS, PROJECTIONS = range(len(COUNTERS))


def finite(p: float, v: float) -> bool:
    """Return True where φ and φ' are both finite."""
    return math.isfinite(p) and math.isfinite(v)


def careful_step(plain: Any, branch: Any, p: float, v: float, h: float, ain: float, w2: float,
                 gamma: float, n: float, v_acc: float, reach: float, check: bool,
                 nonsmooth: bool, guard: Any, counts: Any) -> tuple[bool, float, float]:
    """Take ``Engine.careful``'s step of h from (φ, φ') for a guarded law with n >= 1.

    ``reach`` is ``Problem.reach``, ``guard`` the guard's ``StabilityGuard.constants``,
    ``counts`` the pendulum's counters (:data:`COUNTERS`; what the step did is added there).
    Returns ``(done, φ₁, φ'₁)``; ``done`` False where ``Engine.careful`` must take the step
    (see the module docstring), the counters then untouched.
    """
    _, _, _, a0 = plain(p, v, h, ain, w2, gamma, 1.0, n)
    if abs(v) > v_acc:  # decisions.STIFF_SRC: a stiff transient is declined
        pw = abs(v) ** n
        if not pw < math.inf or abs(a0) > 0.5 * gamma * pw:
            return False, p, v
    done, p1, v1, subs, fbs, turns = guarded(plain, branch, p, v, h, ain, w2, gamma, n, reach,
                                             nonsmooth, guard)
    if not (done and finite(p1, v1)):
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
    counts[REJECTIONS] += 1 if rejected else 0
    counts[PROJECTIONS] += 1 if projected else 0
    return True, p1, v1


def guarded(plain: Any, branch: Any, p: float, v: float, h: float, ain: float, w2: float,
            gamma: float, n: float, reach: float, nonsmooth: bool,
            guard: Any) -> tuple[bool, float, float, int, int, int]:
    """Return ``Engine.guarded``'s step: (done, φ₁, φ'₁, substeps, fallbacks, reversals).

    The fewest stable substeps (``guard.substep_count``), re-judged after each one, each a
    :func:`micro` step; beyond the guard's cap the fallback takes what is left. ``done`` False
    where a substep is not finite or the fallback refuses.
    """
    force = abs(ain) + w2
    left = h
    taken = fbs = turns = 0
    while left > 0.0:
        m = substep_count(left, w2, gamma, n, p, v, force, abs(ain - w2 * math.sin(p)), guard)
        if m == FALLBACK:
            omega0 = math.sqrt(w2)
            if fallback_refused(v, left, ain, w2, omega0):
                return False, p, v, 0, 0, 0
            p, v, _ = fallback_run(p, v, left, ain, w2, gamma, n, omega0, damping_formula)
            return True, p, v, max(taken - 1, 0), fbs + 1, turns
        hh = left / m
        done, p, v, k, f = micro(plain, branch, p, v, hh, ain, w2, gamma, n, reach, nonsmooth)
        if not (done and finite(p, v)):
            return False, p, v, 0, 0, 0
        turns += k
        fbs += f
        taken += 1
        left = 0.0 if m == 1 else left - hh
    return True, p, v, taken - 1, fbs, turns


def micro(plain: Any, branch: Any, p: float, v: float, h: float, ain: float, w2: float,
          gamma: float, n: float, reach: float,
          nonsmooth: bool) -> tuple[bool, float, float, int, int]:
    """Return ``SplitSteps.micro``'s step for n >= 1: (done, φ₁, φ'₁, reversals, fallbacks).

    ``done`` False where the plain step is not finite (Python may have raised inside it).
    """
    p1, v1, _, a0 = plain(p, v, h, ain, w2, gamma, 1.0, n)
    if not (finite(p1, v1) and math.isfinite(a0)):
        return False, p, v, 0, 0
    # decisions.REVERSAL_SRC, then the split or the graded branch run.
    if nonsmooth and ((v1 * v < 0.0) or ((a0 * v < 0.0) and (abs(v) <= h * abs(a0)))
                      or (abs(v) < reach * abs(a0))):
        if v1 * v < 0.0 or (a0 * v < 0.0 and abs(v) <= h * abs(a0)):
            return split(plain, branch, p, v, h, ain, w2, gamma, n, a0, reach)
        if reach > 0.0 and a0 != 0.0:
            side = 1.0 if (v > 0.0 or (v == 0.0 and a0 > 0.0)) else -1.0
            x = abs(v) / abs(a0)
            if a0 * v < 0.0:
                lens = graded_mesh(max(x - h, 0.0), x, h, n, reach)
                back = True
            else:
                lens = graded_mesh(x, x + h, h, n, reach)
                back = False
            pg, vg = branch_run(branch, p, v, lens, back, ain, w2, gamma, side, n)
            if vg * v >= 0.0:
                return True, pg, vg, 0, 0
            # The branch reached φ' = 0 within the step after all: split there.
            return split(plain, branch, p, v, h, ain, w2, gamma, n, a0, reach)
    return True, p1, v1, 0, 0


def branch_run(branch: Any, p: float, v: float, lens: list[float], back: bool, ain: float,
               w2: float, gamma: float, sign: float, n: float) -> tuple[float, float]:
    """Return ``SplitSteps._branch_run``'s (φ, φ') over ``lens`` (in reverse where ``back``)."""
    m = len(lens)
    for k in range(m):
        p, v, _, _ = branch(p, v, lens[m - 1 - k] if back else lens[k], ain, w2, gamma, sign, n)
    return p, v


def split(plain: Any, branch: Any, p: float, v: float, h: float, ain: float, w2: float,
          gamma: float, n: float, a0: float,
          reach: float) -> tuple[bool, float, float, int, int]:
    """Return ``SplitSteps.split``'s (done, φ₁, φ'₁, reversals, fallbacks) for n >= 1.

    ``done`` False where the fallback that takes the rest of the step refuses it.
    """
    sign = 1.0 if v > 0.0 else -1.0
    p1, v1, _, _ = branch(p, v, h, ain, w2, gamma, sign, n)
    if v1 * v > 0.0:  # no kink inside (graded if it is near)
        if reach > 0.0 and a0 != 0.0:
            x = abs(v) / abs(a0)
            lens = graded_mesh(max(x - h, 0.0), x, h, n, reach)
            p1, v1 = branch_run(branch, p, v, lens, True, ain, w2, gamma, sign, n)
        return True, p1, v1, 0, 0
    # The reversal location (reversal.LOCATE_SRC): the Hermite root (end slope: φ'' on the
    # branch at the step's end, reversal.branch_accel), then Newton on the partial step's φ'(θh).
    a1 = branch(p1, v1, 0.0, ain, w2, gamma, sign, n)[3]
    th, pm, vm, _ = locate_on_branch(branch, p, v, v1, a0, a1, h, ain, w2, gamma, sign, n,
                                     NEWTON_TOL, NEWTON_ITERATIONS)
    lens = graded_mesh(0.0, th * h, h, n, reach)
    if len(lens) > 1:
        acc = 0.0
        for _ in range(GRADED_ITERATIONS):
            pm, vm = branch_run(branch, p, v, lens, True, ain, w2, gamma, sign, n)
            acc = branch(pm, vm, 0.0, ain, w2, gamma, sign, n)[3]
            if acc == 0.0 or abs(vm) <= GRADED_TOL * abs(v):
                break
            nth = th - vm / (acc * h)
            if not 0.0 < nth < 1.0:
                break
            th = nth
            lens = graded_mesh(0.0, th * h, h, n, reach)
        if acc != 0.0:
            dt = min(max(-vm / acc, -th * h), (1.0 - th) * h)
            pm += dt * (vm + 0.5 * dt * acc)
            vm = 0.0
            th += dt / h
    rest = (1.0 - th) * h
    after = ain - w2 * math.sin(pm)
    if after == 0.0:
        p2, v2, _, _ = plain(pm, vm, rest, ain, w2, gamma, 1.0, n)
        return True, p2, v2, 1, 0
    side = 1.0 if after > 0.0 else -1.0
    p2, v2 = branch_run(branch, pm, vm, graded_mesh(0.0, rest, h, n, reach), False, ain, w2,
                        gamma, side, n)
    if not (v2 * side >= 0.0 and abs(v2) <= speed_gain(rest, ain, w2) * (1.0 + 1e-9)):
        # The fallback takes the rest of the step (Engine.last_resort).
        omega0 = math.sqrt(w2)
        if fallback_refused(vm, rest, ain, w2, omega0):
            return False, p, v, 0, 0
        p2, v2, _ = fallback_run(pm, vm, rest, ain, w2, gamma, n, omega0, damping_formula)
        return True, p2, v2, 1, 1
    return True, p2, v2, 1, 0


__all__ = ['COUNTERS', 'branch_run', 'careful_step', 'finite', 'guarded', 'micro',
           'split']
