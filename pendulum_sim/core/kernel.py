"""The compiled sweep's run, generated from a template that reads as the function it becomes.

``jit=True`` sweeps run each law text's pendulums through one function of many steps over arrays,
generated here and compiled by numba (``jit.compile_kernel``). Its text is
:data:`KERNEL_TEMPLATE`, a whole function with named holes (``codegen.fill``): the method's plain
step (``explicit.step_source``, inlined), the fast path's decisions (the texts of
``decisions.py``: the reversal test, the stiff-transient test, the energy test and its sound
pre-test), the moving friction input where the text serves a friction beside the law. The
refused steps are taken in the run by the one careful step (``careful.careful_step``).
``python -m pendulum_sim.core.codegen --write DIR`` writes the generated texts for review.
"""
from __future__ import annotations

import functools
import math
from typing import Any

from .careful import TAKEN, LawSteps, Pendulum, Tried, commit_tally
from .codegen import body_of, define, fill
from .coulomb import moving_input
from .decisions import (
    ENERGY_KEPT_SRC,
    ENERGY_SRC,
    ENERGY_TOL,
    REVERSAL_SRC,
    ROSE_SRC,
    STIFF_PAIR,
    kept_stage,
    stiff_source,
    stiff_transient,
)
from .explicit import step_source, step_source_with_n
from .law import SCALAR_ENV, damping_expression, laws_source, whole
from .model import smooth_law
from .tableaus import Tableau

KERNEL_ARGS = ('P', 'V', 'E', 'K', 'IDX', 'h', 'count', 'AIN', 'W2', 'GAMMA', 'CF', 'NN',
               'LO', 'HI', 'REACH', 'V_ACC', 'CHECK', 'NONSMOOTH', 'COULOMB', 'VMAX', 'base',
               'every', 'total', 'RP', 'RV', 'COUNTS', 'TALLY', 'CAREFUL', 'GUARD')
"""The arguments of a run (:data:`KERNEL_TEMPLATE`), arrays in capitals; the generated
functions of :data:`FUNCTION_ARGS` follow them."""

FUNCTION_ARGS = LawSteps._fields
"""The generated functions a run takes as its last arguments and passes to its careful step
(``careful.LawSteps``): the ones its module text defines (:func:`kernel_source`), compiled as
first-class functions of one signature each (``jit.compile_kernel``)."""

KERNEL_TEMPLATE = """\
def kernel(P, V, E, K, IDX, h, count, AIN, W2, GAMMA, CF, NN, LO, HI, REACH, V_ACC, CHECK,
           NONSMOOTH, COULOMB, VMAX, base, every, total, RP, RV, COUNTS, TALLY, CAREFUL, GUARD,
           plain, branch, laws, pair_plain, pair_branch):
    steps = LawSteps(plain, branch, laws, pair_plain, pair_branch)
    rows = RP.shape[0]
    # AIN is (1, N), one input per pendulum, or a schedule (steps, N): row base + k is the
    # input of step base + k + 1 of the stretch.
    rs = 1 if AIN.shape[0] > 1 else 0
    for j in prange(IDX.shape[0]):
        i = IDX[j]
        cf = $friction
        w2 = W2[i]
        gamma = GAMMA[i]
        lo = LO[i]
        hi = HI[i]
        reach = REACH[i]
        v_acc = V_ACC[i]
        check = CHECK[i]
        nonsmooth = NONSMOOTH[i]
        coulomb = COULOMB[i]
        vmax = VMAX[i]
        n = NN[i]
        use_careful = CAREFUL[i]
        p0 = P[i]
        v0 = V[i]
        e = E[i]
        k = K[i]
        stale = False
        nxt = next_record(base + k, every, total)
        while k < count:
            a_in = AIN[rs * (base + k), i]
            ain = a_in
            $moving_input
            av = abs(v0)
            known = lo <= av <= hi
            if known:
                $plain_step
                v = v0
                a0 = a_0
                ok = -INF < p1 < INF and -INF < v1 < INF
                $coulomb_test
                $reversal_test
                $stiff_test
                if ok and check:
                    $energy_test
            else:
                # Outside the guard's range the run refuses the step before taking it: the
                # careful step then takes its plain step itself where it needs one.
                ok = False
                p1 = 0.0
                v1 = 0.0
                w = 0.0
                a0 = 0.0
            if not ok:
                if not use_careful:
                    break
                code, p1, v1, w, _ = careful_step(
                    steps, Pendulum(w2, gamma, n, cf, v_acc, reach, check, nonsmooth,
                                    coulomb, True, GUARD, True),
                    p0, v0, h, a_in, NAN, Tried(known, p1, v1, w, a0, lo, hi), TALLY[i])
                commit_tally(COUNTS[i], TALLY[i], code == TAKEN)
                if code != TAKEN:
                    break
                if check:
                    $energy_renewed
            p0 = p1
            v0 = v1
            k += 1
            if base + k == nxt:
                r = record_row(nxt, every, total, rows)
                RP[r, i] = p0
                RV[r, i] = v0
                nxt = next_record(nxt, every, total)
            if not abs(v0) <= vmax:
                break
        $energy_at_end
        P[i] = p0
        V[i] = v0
        E[i] = e
        K[i] = k
"""
"""The run: ``kernel(P, V, E, K, IDX, h, count, ...)`` advances every pendulum ``i = IDX[j]`` (in
parallel over j where compiled with ``prange``), its state ``(P[i], V[i], E[i])`` held in
registers, from step ``K[i]`` to step ``count`` of size h, under the input ``AIN[0, i]`` (shape
(1, N)) or, where ``AIN`` is a schedule of shape (steps, N), ``AIN[base + k, i]`` in the step
after ``base + k`` (:func:`kernel_source` tells what fills each hole). A refused step is
taken, where ``CAREFUL[i]``, by the careful step, its counters gathered in the row ``TALLY[i]``
and added to ``COUNTS[i]`` (``careful.COUNTERS``) only where it took the step
(``careful.commit_tally``); the run stops at a step neither takes (``K[i]`` is then the step
``Engine.careful`` must take) or after a step that leaves |φ'| above
``VMAX[i]`` (the run's speed bound; the caller refuses to go on). The state after step
``base + k`` is written to the row :func:`record_row` gives of ``RP`` and ``RV`` (the next such
step kept by :func:`next_record`)."""

TEST_TEMPLATE = """\
if ok and $test:
    ok = False
"""
"""A fast-path decision that refuses the step (:data:`KERNEL_TEMPLATE`'s tests)."""

ENERGY_EXACT_TEMPLATE = """\
e0 = e
v = v1
s = sin(0.5 * p1)
e1 = $energy
if $rose:
    ok = False
else:
    e = e1
"""
"""The energy test of a step, E/I carried in ``e`` from step to step."""

ENERGY_LAZY_TEMPLATE = """\
$kept
if kept:
    stale = True
else:
    $energy_made
    $energy_exact
"""
"""The energy test behind its sound pre-test (``decisions.ENERGY_KEPT_SRC``): a step the
pre-test accepts leaves E/I stale, and it is made from (φ₀, φ'₀) by the same formula where
it is read (the same float as carried)."""

ENERGY_MADE_TEMPLATE = """\
if stale:
    v = v0
    s = sin(0.5 * p0)
    e = $energy
    stale = False
"""
"""E/I made from the state where a stale value is read."""

ENERGY_RENEWED_TEMPLATE = """\
v = v1
s = sin(0.5 * p1)
e = $energy
"""
"""E/I of the careful step's result, for a method without the pre-test's stage."""


def record_row(done: int, every: int, total: int, rows: int) -> int:
    """Return the row of the recording that holds the state after step ``done``, or −1.

    Row 0 is the start; a state is recorded every ``every`` steps and after the last step
    ``total`` (in the last of ``rows`` rows); ``every`` = 0 records nothing.
    """
    if every <= 0:
        return -1
    if done % every == 0:
        return done // every
    if done == total:
        return rows - 1
    return -1


def next_record(done: int, every: int, total: int) -> int:
    """Return the first step after ``done`` whose state :func:`record_row` records, or −1.

    The compiled run keeps it beside its step counter, so that a step that records nothing
    costs one comparison (no division).
    """
    if every <= 0 or done >= total:
        return -1
    return min((done // every + 1) * every, total)


def _energy_holes(tableau: Tableau) -> dict[str, str]:
    """Return the energy holes of :data:`KERNEL_TEMPLATE` for the method ``tableau``.

    Where the method has a stage for the pre-test (``decisions.kept_stage``), the test behind
    the pre-test, E/I carried lazily; otherwise the test itself, E/I carried at every step.
    """
    exact = fill(ENERGY_EXACT_TEMPLATE, energy=ENERGY_SRC, rose=ROSE_SRC)
    stage = kept_stage(tableau)
    if stage is None:
        return {'energy_test': exact,
                'energy_renewed': fill(ENERGY_RENEWED_TEMPLATE, energy=ENERGY_SRC),
                'energy_at_end': ''}
    made = fill(ENERGY_MADE_TEMPLATE, energy=ENERGY_SRC)
    lazy = fill(ENERGY_LAZY_TEMPLATE, kept=ENERGY_KEPT_SRC.format(q=f'p_{stage}'),
                energy_made=made, energy_exact=exact)
    return {'energy_test': lazy, 'energy_renewed': 'stale = True', 'energy_at_end': made}


@functools.lru_cache(maxsize=256)
def kernel_source(tableau: Tableau, n: float, friction: bool = False) -> str:
    """Return the module text of the sweep's run for one law text: its functions and the run.

    The generated functions the run passes to its careful step (:data:`FUNCTION_ARGS`: the
    method's plain and branch steps with the exponent an argument, the two laws, the stiff
    pair's steps) and :data:`KERNEL_TEMPLATE` filled: the plain step of ``explicit.step_source``
    inlined; the tests a pendulum of this text can fail (a text that serves one special
    exponent leaves out those its pendulums cannot fail: Coulomb only at n = 0, no kink for odd
    whole n, no stiff transient for n <= 1), each the decision text of ``decisions.py``; the
    energy test (:func:`_energy_holes`). The exponent is read per pendulum (``NN[i]``), so one
    text serves every exponent its law spells alike, in one call. With ``friction`` the text
    serves pendulums with a Coulomb friction c_f = ``CF[i]`` beside the law: a moving step
    takes it as the input ``coulomb.moving_input`` of its direction, and the Coulomb rest and
    the reversal tests are kept whatever the exponent (friction makes every law stick and kink
    at φ' = 0); without it c_f is 0.0 and never read.
    """
    special = n in (0.0, 0.5) or whole(n)
    coulomb = friction or not special or n == 0.0
    kinked = friction or not (special and smooth_law(n))
    stiff = not special or n > 1.0
    run = fill(
        KERNEL_TEMPLATE,
        friction='CF[i]' if friction else '0.0',
        moving_input='ain = moving_input(a_in, v0, cf)' if friction else '',
        plain_step=body_of(step_source(tableau, damping_expression(n, scalar=True))),
        coulomb_test=fill(TEST_TEMPLATE, test='coulomb and v == 0.0') if coulomb else '',
        reversal_test=(fill(TEST_TEMPLATE, test=f'nonsmooth and ({REVERSAL_SRC})') if kinked
                       else ''),
        stiff_test=(fill(TEST_TEMPLATE, test=f'av > v_acc and {stiff_source(n)}') if stiff
                    else ''),
        **_energy_holes(tableau))
    functions = [step_source_with_n(tableau, n, False, 'plain'),
                 step_source_with_n(tableau, n, True, 'branch'),
                 laws_source(n),
                 step_source_with_n(STIFF_PAIR, n, False, 'pair_plain', True),
                 step_source_with_n(STIFF_PAIR, n, True, 'pair_branch', True)]
    return ''.join(functions) + run


def compile_kernel(tableau: Tableau, n: float, careful_step: Any, friction: bool = False) -> Any:
    """Return the Python function of :func:`kernel_source` (``jit.compile_kernel`` compiles it).

    ``careful_step`` is ``careful.careful_step``; ``friction`` as for :func:`kernel_source`.
    Run as Python, ``prange`` is ``range``: the same steps, one pendulum after another.
    """
    env: dict[str, object] = dict(
        SCALAR_ENV, INF=math.inf, NAN=math.nan, ENERGY_TOL=ENERGY_TOL, prange=range,
        record_row=record_row, next_record=next_record, careful_step=careful_step,
        stiff_transient=stiff_transient, moving_input=moving_input, LawSteps=LawSteps,
        Pendulum=Pendulum, Tried=Tried, TAKEN=TAKEN, commit_tally=commit_tally)
    return define(kernel_source(tableau, n, friction), 'kernel', env,
                  f'<kernel {tableau.name}>')


__all__ = ['ENERGY_EXACT_TEMPLATE', 'ENERGY_LAZY_TEMPLATE', 'ENERGY_MADE_TEMPLATE',
           'ENERGY_RENEWED_TEMPLATE', 'FUNCTION_ARGS', 'KERNEL_ARGS', 'KERNEL_TEMPLATE',
           'TEST_TEMPLATE', 'compile_kernel', 'kernel_source', 'next_record', 'record_row']
