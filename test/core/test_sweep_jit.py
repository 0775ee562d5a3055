"""``sweep(..., jit=True)``: the sweep's runs and its careful split step compiled by numba.

Oracles: the ``Stepper`` (the run is the Stepper's generated fast step and the decision texts,
the compiled careful step mirrors ``Engine.careful`` and everything else goes to it, so both
take the same steps to the last bit, counters included), ``Engine.careful`` itself for the
compiled careful step, and the numpy sweep (the same decisions; the numbers equal to the bit
where the law is spelled with multiplications, to round-off where numpy's power differs from
the C library's pow).
"""
from __future__ import annotations

import itertools
import math
import re
from typing import Any

import numpy as np
import pytest
from sweep_population import mixed_population

from pendulum_sim.core import IntegratorError, PendulumParams, Stepper, codegen, jit
from pendulum_sim.core.careful import COUNTERS as CAREFUL_COUNTERS
from pendulum_sim.core.careful import (
    NOT_TRIED,
    TAKEN,
    LawSteps,
    Pendulum,
    Tried,
    careful_step,
)
from pendulum_sim.core.compiled_sweep import PARALLEL_MIN
from pendulum_sim.core.coulomb import creep_rate, friction_step, moving_input
from pendulum_sim.core.decisions import (
    STIFF_MAX_TRIALS,
    accuracy_speed,
    stiff_source,
    stiff_transient,
)
from pendulum_sim.core.engine import Engine, guard_for
from pendulum_sim.core.explicit import step_source
from pendulum_sim.core.guard import FALLBACK, GuardStats, one_substep, substep_count
from pendulum_sim.core.implicit import MAX_FALLBACK_SUBSTEPS
from pendulum_sim.core.jit import available, numba_twin
from pendulum_sim.core.kernel import compile_kernel, kernel_source, next_record, record_row
from pendulum_sim.core.law import (
    damping_derivative,
    damping_expression,
    power_formula,
    power_source,
)
from pendulum_sim.core.methods import METHODS
from pendulum_sim.core.model import _eigs, run_speed_limit
from pendulum_sim.core.problem import Problem
from pendulum_sim.core.stiff import TO_GUARD, stiff_cover, stiff_pair
from pendulum_sim.core.sweep import Sweep, sweep
from pendulum_sim.core.tableaus import TABLEAUS

pytestmark = pytest.mark.skipif(not available(), reason='numba is not installed (jit extra)')

W2 = 9.8
COUNTERS = ('substeps', 'fallbacks', 'reversals', 'sticks', 'energy_rejections', 'projections')

# (γ, n, h, φ0, φ'0, τ/I): smooth, fractional and Coulomb laws, stiff cells that take the
# guard's substeps and the fallback, a spinning start, with and without input.
GRID = list(itertools.product(
    [0.0, 1.0, 30.0, 1e4], [0.0, 0.3, 0.5, 1.0, 1.5, 2.0, 3.0, 3.7, 5.0], [1e-3, 2e-2],
    [0.3, 2.0, 3.1], [0.0, 8.0], [0.0, 1.7]))


@pytest.mark.parametrize('h', [1e-3, 2e-2])
def test_the_compiled_sweep_is_the_stepper_to_the_last_bit(h: float) -> None:
    cells = [c for c in GRID if c[2] == h]
    gam, nn, _, p0, v0, tau = (np.array(col) for col in zip(*cells, strict=True))
    steps = 40
    res = sweep(W2, gam, nn, p0, v0, steps * h, h, torque=tau, jit=True)
    acted = 0
    for i, (g, n, _, x0, dx0, ain) in enumerate(cells):
        st = Stepper(PendulumParams.from_omega0_sq(W2, g, n), x0, dx0, h)
        for _ in range(steps):
            st.step(ain)  # I = 1: the torque is τ/I
        got = tuple(int(getattr(res, k)[i]) for k in COUNTERS)
        assert got == tuple(getattr(st.stats, k) for k in COUNTERS), cells[i]
        assert (res.phi[i], res.dphi[i]) == (st.phi, st.dphi), cells[i]
        acted += any(got)
    assert acted >= len(cells) // 6  # the careful path took part


def test_the_compiled_and_numpy_sweeps_decide_alike() -> None:
    w2, gamma, n, p0, v0, tau = mixed_population()
    whole = (n == np.round(n)) & (n >= 1.0) | (n == 0.0)
    for method in ('rk4',):  # one method: each compiles a kernel per law text
        for torque in (0.0, tau):
            a = sweep(w2, gamma, n, p0, v0, 1.005, 0.01, method=method, torque=torque,
                      record_every=25)
            b = sweep(w2, gamma, n, p0, v0, 1.005, 0.01, method=method, torque=torque,
                      record_every=25, jit=True)
            for k in COUNTERS:
                assert np.array_equal(getattr(a, k), getattr(b, k)), (method, k)
            assert a.phi[whole].tobytes() == b.phi[whole].tobytes(), method
            assert a.dphi_record[:, whole].tobytes() == b.dphi_record[:, whole].tobytes()
            assert np.max(np.abs(a.phi - b.phi)) <= 1e-12
            assert np.max(np.abs(a.dphi - b.dphi)) <= 1e-12


def test_a_compiled_prepared_sweep_advances_as_a_chain_of_sweeps() -> None:
    rng = np.random.default_rng(4)
    size = 50
    ns = rng.choice([0.0, 1.0, 1.5, 2.0, 5.0], size)
    gs = rng.choice([0.2, 1.0, 300.0], size)
    p, v = rng.uniform(-3.0, 3.0, size), rng.uniform(-3.0, 3.0, size)
    prepared = Sweep(W2, gs, ns, p, v, 1e-2, jit=True)
    for _ in range(5):
        tau = rng.uniform(-5.0, 5.0, size)
        got = prepared.advance(0.1, tau)
        want = sweep(W2, gs, ns, p, v, 0.1, 1e-2, torque=tau, jit=True)
        assert got.phi.tobytes() == want.phi.tobytes()
        assert got.dphi.tobytes() == want.dphi.tobytes()
        p, v = want.phi, want.dphi


def test_the_kernel_is_the_generated_step_and_the_decision_texts() -> None:
    tab = TABLEAUS['rk4']
    text = kernel_source(tab, 1.5)
    for line in step_source(tab, damping_expression(1.5, scalar=True)).splitlines()[1:-1]:
        assert '    ' + line in text
    # One text for every exponent the law spells alike: the exponent is an argument.
    assert kernel_source(tab, 1.5) == kernel_source(tab, 3.7) != kernel_source(tab, 2.0)


def test_jit_must_be_a_bool() -> None:
    with pytest.raises(IntegratorError) as info:
        sweep(W2, 1.0, 1.0, 0.1, 0.0, 0.1, 1e-2, jit=1)  # type: ignore[arg-type]
    assert str(info.value) == 'jit must be True or False, got 1'


def _careful_steps(method: str, n: float) -> LawSteps:
    """Return the generated functions a sweep's run passes to its careful step, as Python."""
    env = compile_kernel(TABLEAUS[method], n, careful_step).__globals__
    return LawSteps(*(env[name] for name in LawSteps._fields))


def _compiled(method: str, n: float) -> tuple[Any, LawSteps]:
    """Return the compiled careful_step and the generated functions a compiled run passes it.

    The very objects of the sweep's kernel for this law (``jit.compile_kernel``: compiled
    once per text), so the test checks what the sweep runs and compiles nothing again.
    """
    grp = Sweep(W2, 1.0, n, 0.5, 0.0, 1e-3, method=method, jit=True)._groups[0]
    env = grp.kernel[1].py_func.__globals__
    return env['careful_step'], LawSteps(*(env[name] for name in LawSteps._fields))


def _pendulum(eng: Engine, method: str) -> Pendulum:
    """Return what a compiled run gives its careful step for the engine's pendulum (strict)."""
    consts = np.array(guard_for(TABLEAUS[method]).constants)
    return Pendulum(eng.w2, eng.gamma, eng.n, eng.cf, eng.v_acc, eng.reach, eng.energy_check,
                    eng.nonsmooth, eng.coulomb, True, consts, True)


def _same(a: tuple[Any, ...], b: tuple[Any, ...]) -> bool:
    """Return True where the tuples hold the same values, NaN the same as NaN."""
    return len(a) == len(b) and all(x == y or (x != x and y != y)
                                    for x, y in zip(a, b, strict=True))


def _stats(st: GuardStats) -> tuple[int, ...]:
    return tuple(getattr(st, k) for k in CAREFUL_COUNTERS)


def _random_state(rng: np.random.Generator) -> tuple[float, ...]:
    """Return (γ, ω0², h, a_in, φ, φ'): slow and fast states, at rest, weak to stiff γ."""
    gamma = float(rng.choice([0.001, 0.1, 1.0, 30.0, 1e3, 1e4]))
    w2 = float(rng.choice([0.0, 9.8, 40.0]))
    h = float(rng.choice([1e-3, 2e-2, 5e-2]))
    ain = float(rng.choice([0.0, 0.0, 1.7, -3.0]))
    p = float(rng.uniform(-3.0, 3.0))
    v = float(rng.uniform(-0.05, 0.05) if rng.uniform() < 0.6 else rng.uniform(-8.0, 8.0))
    return gamma, w2, h, ain, p, 0.0 if rng.uniform() < 0.15 else v


def _stiff_state(rng: np.random.Generator, n: float) -> tuple[float, ...]:
    """Return a state in a damping-dominated transient: |φ'| 1.5-30 times the accuracy speed."""
    gamma = float(rng.choice([0.5, 2.0, 10.0, 50.0]))
    w2 = float(rng.choice([0.0, 9.8, 40.0]))
    h = float(rng.choice([1e-3, 2e-2, 5e-2]))
    ain = float(rng.choice([0.0, 0.0, 1.7, -3.0]))
    p = float(rng.uniform(-3.0, 3.0))
    speed = min(accuracy_speed(gamma, n, math.sqrt(w2)) * float(rng.uniform(1.5, 30.0)),
                0.5 * run_speed_limit(gamma, n, w2))
    return gamma, w2, h, ain, p, speed if rng.uniform() < 0.5 else -speed


@pytest.mark.parametrize(('method', 'n'), [
    ('rk4', 0.0), ('rk4', 0.01), ('rk4', 0.3), ('rk4', 0.5), ('rk4', 1.0), ('rk4', 1.5),
    ('rk4', 2.0), ('rk4', 2.5), ('rk4', 4.0), ('rk4', 5.0), ('euler', 2.0)])
def test_the_compiled_careful_step_is_the_engines_careful_path(method: str, n: float) -> None:
    # The compiled careful step takes every one of these steps (it declines only the
    # fallback's refusal and results that are not finite; test below), each Engine.careful's
    # step to the bit, every counter equal (the guard's substeps, the fallback, reversals,
    # Coulomb sticks, the energy redo and projection). For n > 1 the states include stiff
    # transients (|φ'| well above decisions.accuracy_speed), which the careful step covers with
    # error-controlled DOP853 substeps (stiff.stiff_cover, compiled here). The same function
    # run as Python and compiled must agree. Friction at rest (Coulomb, the near-Coulomb
    # creep) is among them.
    steps = _careful_steps(method, n)
    compiled, compiled_steps = _compiled(method, n)
    rng = np.random.default_rng(int(10 * n))
    held = stiff = stiff_turns = inside = 0
    seen = np.zeros(len(CAREFUL_COUNTERS), dtype=np.int64)
    for k in range(300 + (200 if n > 1.0 else 0)):
        gamma, w2, h, ain, p, v = _random_state(rng) if k < 300 else _stiff_state(rng, n)
        eng = Engine(w2, gamma, n, METHODS[method])
        st = GuardStats()
        want = eng.careful(p, v, h, ain, st)
        pend = _pendulum(eng, method)
        # The plain step of h the compiled run took before it refused the step.
        known = steps.plain(p, v, h, moving_input(ain, v, eng.cf), w2, gamma, 1.0, n)
        # The guard's safe range: inside it (by its margin) the count is 1 without computing it.
        lo, hi = eng.fast_range(h, ain)
        inside += bool(one_substep(abs(v), lo, hi))
        tried = Tried(True, *known, lo, hi)
        counts = np.zeros(len(CAREFUL_COUNTERS), dtype=np.int64)
        got = compiled(compiled_steps, pend, p, v, h, ain, math.nan, tried, counts)
        again = np.zeros_like(counts)
        assert _same(careful_step(steps, pend, p, v, h, ain, math.nan, tried, again), got)
        # Outside the guard's range the run takes no plain step: the careful step takes it;
        # with an empty range the guard's count is computed.
        alone = np.zeros_like(counts)
        assert _same(compiled(compiled_steps, pend, p, v, h, ain, math.nan, Tried(*NOT_TRIED),
                              alone), got)
        assert np.array_equal(alone, counts)
        assert np.array_equal(again, counts)
        assert got[:4] == (TAKEN, *want), (gamma, w2, h, ain, p, v)  # taken compiled, w too
        assert tuple(counts.tolist()) == _stats(st), (gamma, w2, h, ain, p, v)
        seen += counts
        held += friction_step(steps.branch, steps.laws, p, v, h, ain, w2, gamma, n, eng.coulomb,
                              True)[0]
        if abs(v) > eng.v_acc and stiff_transient(
                abs(v), ain - eng.damping(v) - w2 * math.sin(p), gamma, power_formula(abs(v), n),
                eng.v_acc):
            stiff += 1
            stiff_turns += counts[CAREFUL_COUNTERS.index('reversals')] > 0
        else:
            assert k < 300  # every state of _stiff_state is a stiff transient
    assert inside >= 10  # states where the count 1 was taken without computing it
    sub, fb, rev, sticks, rej, proj = seen.tolist()
    # The guard's substeps taken compiled (Coulomb friction has no slope: never substeps; at
    # n = 0.01 the slope is within the disk or beyond the cap: one step or the fallback).
    assert sub > 0 if n not in (0.0, 0.01) else sub == 0
    if n in (0.01, 1.0, 5.0) or method == 'euler':
        assert fb > 0  # and the fallback
    if n != int(n) or n % 2 == 0:
        assert rev > 10  # reversals split compiled
    assert held > 20 if n < 1.0 else held == 0  # Coulomb at rest, the creep
    assert sticks > 0 if n == 0.0 else sticks == 0
    if method == 'euler':
        assert rej > 0 and proj > 0  # energy redos and projections taken compiled
    # Stiff transients taken compiled (none for n <= 1), cut at reversals for non-smooth laws.
    assert stiff > 200 if n > 1.0 else stiff == 0
    if n > 1.0 and (n != int(n) or n % 2 == 0):
        assert stiff_turns > 5


def _tried(steps: LawSteps, eng: Engine, p: float, v: float, h: float, ain: float) -> Tried:
    """Return the plain step of h a compiled run takes before it refuses the step (compiled)."""
    known = steps.plain(p, v, h, moving_input(ain, v, eng.cf), eng.w2, eng.gamma, 1.0, eng.n)
    return Tried(True, *known, *eng.fast_range(h, ain))


def _decline(eng: Engine, method: str, p: float, v: float, h: float) -> None:
    """Assert that the compiled careful step declines the step (the run then drops its tally)."""
    compiled, steps = _compiled(method, eng.n)
    counts = np.zeros(len(CAREFUL_COUNTERS), dtype=np.int64)
    got = compiled(steps, _pendulum(eng, method), p, v, h, 0.0, math.nan,
                   _tried(steps, eng, p, v, h, 0.0), counts)
    assert got[0] != TAKEN and got[1:4] == (p, v, 0.0)


def test_overflow_and_the_fallbacks_refusal_are_left_to_python() -> None:
    # The plain step's power overflows float64: Python raises OverflowError and Engine.careful
    # hands the step to the fallback (its except), where compiled code gives inf; which of
    # the two happened decides Python's path, so the compiled step declines the step and
    # Engine.careful takes it. Where the fallback refuses a step by its work bound, the
    # compiled step declines as well and Engine.careful raises the refusal itself.
    eng = Engine(9.8, 1e-300, 2.5, METHODS['rk4'])
    p, v, h = 0.5, 1e150, 1e-151
    assert abs(v) <= eng.v_acc  # not a stiff transient: the guard takes it
    st = GuardStats()
    eng.careful(p, v, h, 0.0, st)
    assert st.fallbacks > 0  # the except path (and _settle's replacement) took it
    _decline(eng, 'rk4', p, v, h)
    eng = Engine(9.8, 1e6, 1.0, METHODS['rk4'])
    p, v, h = 0.5, 1e7, 0.01
    msg = (f'a step of 0.01 s from phi = 0.5 rad, dphi = 1e+07 rad/s needs more than '
           f'MAX_FALLBACK_SUBSTEPS = {MAX_FALLBACK_SUBSTEPS} substeps of the fallback (each '
           f'sweeps at most 0.5 rad); use a smaller h')
    with pytest.raises(IntegratorError, match=re.escape(msg)):
        eng.careful(p, v, h, 0.0, GuardStats())
    _decline(eng, 'rk4', p, v, h)


def test_the_guards_count_is_one_function_python_and_compiled() -> None:
    # guard.substep_count (which StabilityGuard.substeps runs) compiled gives the Python count
    # on states that take each of its branches: one substep, the real-axis count, the
    # bisection on the stability polynomial (complex eigenvalues), the angle count, the cap.
    twin = numba_twin(substep_count)
    rng = np.random.default_rng(7)
    branches = set()
    for name in ('rk4', 'euler', 'midpoint'):
        g = guard_for(TABLEAUS[name])
        consts = np.array(g.constants)
        for _ in range(400):
            gamma = float(rng.choice([0.01, 1.0, 30.0, 1e3, 1e5]))
            n = float(rng.choice([1.0, 1.5, 2.0, 3.0, 0.5]))
            w2 = float(rng.choice([0.0, 9.8, 400.0, 1e4]))
            h = float(rng.choice([1e-3, 1e-2, 5e-2]))
            p, v = float(rng.uniform(-3.0, 3.0)), float(rng.uniform(-30.0, 30.0))
            force, now = w2 + 1.0, abs(1.0 - w2 * math.sin(p))
            want = g.substeps(h, w2, gamma, n, p, v, force, now)
            assert twin(h, w2, gamma, n, p, v, force, now, consts) == want
            lam = _eigs(damping_derivative(gamma, n, abs(v) + h * force), w2 * math.cos(p))
            branches.add('fallback' if want == FALLBACK else 'one' if want == 1 else
                         'complex' if lam[0].imag else 'real')
    assert branches == {'fallback', 'one', 'complex', 'real'}


# Cells whose steps the careful path takes: near-Coulomb creep and Coulomb sticking, a stiff
# γ with substeps and the fallback, reversals for non-integer and even n, the energy check.
CAREFUL = [(100.0, 0.001, 1e-3, 0.3, 0.0, 0.0), (100.0, 0.01, 1e-3, 0.3, 0.0, 0.0),
           (5.0, 0.0, 1e-2, 0.2, 0.3, 0.0), (5.0, 0.0, 1e-2, 2.0, 1.0, 1.5),
           (1e4, 1.0, 2e-2, 1.0, 3.0, 0.0), (1e3, 5.0, 2e-2, 0.5, 6.0, 0.0),
           (2.0, 3.7, 2e-2, 2.5, 0.0, 0.0), (0.5, 1.5, 1e-2, 1.0, 0.0, 0.0),
           (0.5, 2.0, 1e-2, 2.0, 0.0, 0.0), (0.5, 4.0, 1e-2, 2.0, 0.0, -2.0),
           (30.0, 0.3, 2e-2, 3.1, 8.0, 0.0), (0.0, 2.0, 2e-2, 3.1, 8.0, 0.0)]


def test_careful_cases_take_the_steppers_steps_on_both_sweeps() -> None:
    gam, nn, hs, p0, v0, tau = (np.array(col) for col in zip(*CAREFUL, strict=True))
    steps = 60
    seen = np.zeros(len(COUNTERS), dtype=np.int64)
    for h in sorted(set(hs.tolist())):
        sel = hs == h
        a = sweep(W2, gam[sel], nn[sel], p0[sel], v0[sel], steps * h, h, torque=tau[sel])
        b = sweep(W2, gam[sel], nn[sel], p0[sel], v0[sel], steps * h, h, torque=tau[sel],
                  jit=True)
        for i, (g, n, _, x0, dx0, ain) in enumerate(c for c in CAREFUL if c[2] == h):
            st = Stepper(PendulumParams.from_omega0_sq(W2, g, n), x0, dx0, h)
            for _ in range(steps):
                st.step(ain)
            want = tuple(getattr(st.stats, k) for k in COUNTERS)
            seen += want
            for res in (a, b):
                assert tuple(int(getattr(res, k)[i]) for k in COUNTERS) == want, (g, n)
                assert (res.phi[i], res.dphi[i]) == (st.phi, st.dphi), (g, n)
    assert seen[:4].all()  # substeps, fallbacks, reversals and sticks all took part


# (method, γ, n, h, φ0, φ'0): cells whose refused steps need the guard's substeps, the fallback,
# reversal splits and the energy redo with its projection, and no stiff transient.
COMPILED_CAREFUL = [('rk4', 1e4, 1.0, 2e-2, 1.0, 3.0), ('rk4', 1e3, 2.0, 2e-2, 2.0, 0.0),
                    ('euler', 0.001, 2.0, 0.05, 0.5, 5.0), ('euler', 0.001, 2.0, 0.05, 3.1, 0.0)]


def test_the_compiled_sweep_takes_the_careful_steps_without_handing_back() -> None:
    # On these cells every refused step is taken compiled (handed_back 0, where the numpy
    # sweep hands each to Engine.careful) with the Stepper's floats and counters.
    seen = np.zeros(len(COUNTERS), dtype=np.int64)
    steps = 40
    for method in ('rk4', 'euler'):
        cells = [c[1:] for c in COMPILED_CAREFUL if c[0] == method]
        for h in sorted({c[2] for c in cells}):
            on = [c for c in cells if c[2] == h]
            gam, nn, _, p0, v0 = (np.array(col) for col in zip(*on, strict=True))
            a = sweep(W2, gam, nn, p0, v0, steps * h, h, method=method)
            b = sweep(W2, gam, nn, p0, v0, steps * h, h, method=method, jit=True)
            assert b.handed_back == 0 < a.handed_back
            for i, (g, n, _, x0, dx0) in enumerate(on):
                st = Stepper(PendulumParams.from_omega0_sq(W2, g, n), x0, dx0, h, method=method)
                for _ in range(steps):
                    st.step(0.0)
                want = tuple(getattr(st.stats, k) for k in COUNTERS)
                seen += want
                for res in (a, b):
                    assert tuple(int(getattr(res, k)[i]) for k in COUNTERS) == want, (g, n)
                    assert (res.phi[i], res.dphi[i]) == (st.phi, st.dphi), (g, n)
    assert seen[[0, 1, 2, 4, 5]].all()  # all but Coulomb's sticks took part


# (γ, n, φ0, φ'0, τ/I) at h = 2e-2: each starts in a damping-dominated transient (|φ'| far
# above decisions.accuracy_speed), smooth (n = 5) and non-smooth (n = 2, 2.5) laws.
STIFF_CELLS = [(10.0, 2.0, 1.0, 30.0, 0.0), (50.0, 2.0, 2.0, -20.0, 1.7),
               (2.0, 2.5, 0.5, 40.0, 0.0), (50.0, 2.5, -1.0, 15.0, -3.0),
               (2.0, 5.0, 0.5, 8.0, 0.0), (0.5, 5.0, 3.0, -10.0, 0.0)]


def test_the_compiled_sweep_takes_stiff_transients_without_handing_back() -> None:
    # The stiff transient's error-controlled substeps run compiled (stiff.stiff_cover): the numpy
    # sweep hands each stiff step to Engine.careful, the compiled sweep none. The compiled
    # sweep ends on the Stepper's floats and counters; the numpy one on its counters, its
    # floats to round-off for non-integer n (numpy's power is not the C library's pow).
    h, steps = 2e-2, 40
    gam, nn, p0, v0, tau = (np.array(col) for col in zip(*STIFF_CELLS, strict=True))
    for g, n, _, dx0, _ in STIFF_CELLS:
        assert abs(dx0) > 1.5 * Problem(W2, g, n).v_acc
    a = sweep(W2, gam, nn, p0, v0, steps * h, h, torque=tau)
    b = sweep(W2, gam, nn, p0, v0, steps * h, h, torque=tau, jit=True)
    assert b.handed_back == 0 < a.handed_back
    turns = 0
    for i, (g, n, x0, dx0, ain) in enumerate(STIFF_CELLS):
        st = Stepper(PendulumParams.from_omega0_sq(W2, g, n), x0, dx0, h)
        for _ in range(steps):
            st.step(ain)
        want = tuple(getattr(st.stats, k) for k in COUNTERS)
        assert want[0] > 0  # the transient's substeps
        turns += want[2]
        for res in (a, b):
            assert tuple(int(getattr(res, k)[i]) for k in COUNTERS) == want, (g, n)
        assert (b.phi[i], b.dphi[i]) == (st.phi, st.dphi), (g, n)
        assert math.isclose(a.phi[i], st.phi, rel_tol=1e-12, abs_tol=1e-15), (g, n)
        assert math.isclose(a.dphi[i], st.dphi, rel_tol=1e-12, abs_tol=1e-15), (g, n)
    assert turns > 0  # reversals cut on the way


# (γ, ω0², h, a_in, φ, φ') for n = 1.5: a stiff transient whose error-controlled substeps
# chatter at rest and spend STIFF_MAX_TRIALS trials without covering the step.
UNCOVERED = [(1e5, 1e4, 0.2, 1.7, -0.18886198245603225, 34.53516442633296),
             (1e5, 1e4, 0.2, 0.0, -2.808724818925504, 0.006014820267336139),
             (1e5, 1e4, 0.2, -3.0, 0.4608082759477723, 0.05588963700501084)]


def test_a_stiff_step_the_substeps_cannot_cover_goes_to_the_guard_compiled() -> None:
    # stiff_cover returns TO_GUARD; the careful step then has the guard take the step from its
    # start, the cover's trials still counted. The compiled careful step does the same, to the
    # bit and counter.
    n = 1.5
    compiled, steps = _compiled('rk4', n)
    for gamma, w2, h, ain, p, v in UNCOVERED:
        eng = Engine(w2, gamma, n, METHODS['rk4'])
        code, *_, subs, _ = stiff_cover(*stiff_pair(n), p, v, h, ain, w2, gamma, n,
                                        eng.nonsmooth, False)
        assert code == TO_GUARD and subs == STIFF_MAX_TRIALS  # every trial after the first
        st = GuardStats()
        want = eng.careful(p, v, h, ain, st)
        counts = np.zeros(len(CAREFUL_COUNTERS), dtype=np.int64)
        got = compiled(steps, _pendulum(eng, 'rk4'), p, v, h, ain, math.nan,
                       _tried(steps, eng, p, v, h, ain), counts)
        assert got[:4] == (TAKEN, *want)
        assert tuple(counts.tolist()) == _stats(st)
        assert st.substeps >= STIFF_MAX_TRIALS and st.reversals > 0


def test_a_run_beyond_the_speed_bound_is_refused_alike() -> None:
    # An input drives the second pendulum beyond the run's speed bound: both sweeps stop
    # with the model's message at the same step, naming the pendulum.
    msg = None
    for compiled in (False, True):
        with pytest.raises(IntegratorError) as info:
            sweep(W2, [0.0, 0.0, 1.0], [1.0, 1.0, 2.0], 0.0, [0.0, 9999.0, 0.0], 0.01, 1e-3,
                  torque=[0.0, 1e6, 0.0], jit=compiled)
        assert str(info.value).endswith(' (index 1)')
        assert 'at t = 0.001 s' in str(info.value)
        assert msg is None or str(info.value) == msg
        msg = str(info.value)


def test_distinct_exponents_share_their_generated_code() -> None:
    # Issue 20: 2000 distinct non-integer n compile one text per law spelling (the exponent is
    # a name the code reads), for numpy and compiled alike: the set-up's work does not grow
    # with the number of exponents.
    rng = np.random.default_rng(20)
    n = rng.uniform(3.0, 5.0, 2000)
    n = n[n != np.round(n)]
    before = codegen._code.cache_info().misses
    kernels = len(jit._KERNELS)
    prepared = Sweep(W2, 0.5, n, 1.0, 0.0, 1e-3, jit=True)
    assert len(prepared._groups) == 1  # one group, the exponent a column of it (issue 30)
    assert codegen._code.cache_info().misses - before <= 3
    assert len(jit._KERNELS) - kernels <= 1
    assert len({id(grp.kernel[0]) for grp in prepared._groups}) == 1


def test_the_stiff_test_spells_the_power_by_the_laws_rule() -> None:
    # The stiff-transient threshold ½ γ |φ'|^n is the law's power (law.power_source): whole n
    # as multiplications, in the Stepper's fast step, the kernel and the careful path alike.
    tab = TABLEAUS['rk4']
    for n in (2.0, 3.0, 3.7):
        power = power_source(n, 'n')
        assert power in stiff_source(n)
        assert power in kernel_source(tab, n).split('def kernel')[1]
    assert '**' not in stiff_source(3.0)
    # A speed where the product |v|·|v|·|v| is below the C library's pow in the last bit, and a
    # net deceleration one float above half the product's γ|v|³: stiff by the law's rule.
    rng = np.random.default_rng(3)
    v = next(x for x in rng.uniform(1.0, 2.0, 100_000).tolist() if x * x * x < x ** 3.0)
    gamma = 1.0
    a0 = -float(np.nextafter(0.5 * gamma * (v * v * v), np.inf))
    assert stiff_transient(v, a0, gamma, v * v * v, 0.5)
    assert stiff_transient(np.array([v]), np.array([a0]), gamma, np.array([v * v * v]),
                           np.array([0.5]))[0]
    assert not stiff_transient(v, np.nextafter(a0, 0.0), gamma, v * v * v, 0.5)
    assert not stiff_transient(0.5, a0, gamma, v * v * v, 0.5)  # not above the speed


def test_the_run_keeps_the_next_recorded_step() -> None:
    # next_record gives the first step after `done` that record_row records: the compiled run
    # writes the rows record_row gives without a division per step.
    for every, total in itertools.product(range(5), range(1, 13)):
        rows = 1 + total // every + (1 if total % every else 0) if every else 0
        for done in range(total + 1):
            later = [d for d in range(done + 1, total + 1)
                     if record_row(d, every, total, rows) >= 0]
            assert next_record(done, every, total) == (later[0] if later else -1)


def _assert_each_takes_the_steppers_steps(res: Any, gamma: Any, n: Any, p0: Any, v0: Any,
                                          h: float, steps: int, every: int) -> None:
    """Assert that each pendulum of a sweep recorded ``every`` steps took the Stepper's steps."""
    assert res.dphi_record is not None and res.phi_record is not None
    for i in range(n.size):
        st = Stepper(PendulumParams.from_omega0_sq(W2, float(gamma[i]), float(n[i])),
                     float(p0[i]), float(v0[i]), h)
        for k in range(1, steps + 1):
            st.step()
            if k % every == 0 or k == steps:
                row = k // every if k % every == 0 else -1
                assert (res.phi_record[row, i], res.dphi_record[row, i]) == (st.phi, st.dphi)
        assert tuple(int(getattr(res, c)[i]) for c in COUNTERS) == tuple(
            getattr(st.stats, c) for c in COUNTERS), i


def test_exponents_sharing_a_kernel_run_together_each_its_own_steps() -> None:
    # Distinct non-integer n (and n < 1, which the compiled careful step hands back) share one
    # kernel and run in one call, side by side: every pendulum still takes the Stepper's steps,
    # its recording rows included.
    rng = np.random.default_rng(21)
    n = np.concatenate([rng.uniform(1.05, 4.95, 12), rng.uniform(0.2, 0.95, 4)])
    gamma = rng.choice([0.5, 5.0, 40.0], n.size)
    p0, v0 = rng.uniform(-3.0, 3.0, n.size), rng.uniform(-2.0, 2.0, n.size)
    h, steps = 1e-2, 30
    res = sweep(W2, gamma, n, p0, v0, steps * h, h, record_every=7, jit=True)
    _assert_each_takes_the_steppers_steps(res, gamma, n, p0, v0, h, steps, 7)
    assert res.reversals.sum() > 0  # the compiled careful step took part


def test_the_parallel_run_takes_each_pendulums_stepper_steps() -> None:
    # At least PARALLEL_MIN pendulums of one law text: the run's first call is the parallel
    # kernel (prange over the pendulums), with careful steps among them (the guard's substeps,
    # reversal splits, the stiff transients of every seventh, started ten times faster): each
    # pendulum ends on the Stepper's floats and counters, its recording rows included.
    rng = np.random.default_rng(512)
    size = PARALLEL_MIN + 88
    n = rng.choice([1.5, 2.5, 3.7], size)
    gamma = rng.choice([0.2, 5.0, 50.0], size)
    p0, v0 = rng.uniform(-3.0, 3.0, size), rng.uniform(-3.0, 3.0, size)
    v0[::7] *= 10.0  # stiff transients
    h, steps = 2e-2, 12
    res = sweep(W2, gamma, n, p0, v0, steps * h, h, record_every=5, jit=True)
    parallel, _ = jit.compile_kernel(compile_kernel(TABLEAUS['rk4'], 2.5, careful_step))
    assert parallel.signatures  # the parallel kernel ran (compiled on its first call)
    assert res.handed_back == 0
    _assert_each_takes_the_steppers_steps(res, gamma, n, p0, v0, h, steps, 5)
    assert min(res.substeps.sum(), res.reversals.sum()) > 0  # careful steps took part


def test_a_kernel_text_leaves_out_the_tests_its_exponent_cannot_fail() -> None:
    # Texts of one special exponent drop what its Problem never sets (Coulomb only at n = 0,
    # no kink for odd whole n, no stiff transient for n <= 1); the shared text keeps them all.
    tab = TABLEAUS['rk4']
    body = {n: kernel_source(tab, n).split('def kernel')[1] for n in (0.0, 1.0, 2.0, 3.0, 3.7)}
    assert 'coulomb and' in body[0.0] and 'coulomb and' not in body[2.0]
    assert 'nonsmooth and (' not in body[3.0] and 'nonsmooth and (' in body[2.0]
    assert 'if ok and av > v_acc' not in body[1.0] and 'if ok and av > v_acc' in body[2.0]
    assert all(k in body[3.7] for k in ('coulomb and', 'nonsmooth and (', 'if ok and av > v_acc'))
    for n in (1.0, 3.0, 5.0):
        assert not Problem(W2, 1.0, n).nonsmooth and not Problem(W2, 1.0, n).coulomb
    assert math.isinf(Problem(W2, 1.0, 1.0).v_acc) and math.isinf(Problem(W2, 1.0, 0.5).v_acc)


# (γ, n, φ0, φ'0, τ/I) at h = 1 ms: Coulomb friction sticking after a reversal, breaking away
# under input, held at rest against an input; near-Coulomb laws creeping from rest (the issue's
# n = 0.001 and 0.01 at γ = 100), swinging, reversing and creeping, with input.
FRICTION = [(5.0, 0.0, 0.2, 0.3, 0.0), (5.0, 0.0, 2.0, 1.0, 1.5), (12.0, 0.0, 1.0, 0.0, -3.0),
            (100.0, 0.001, 0.3, 0.0, 0.0), (100.0, 0.01, 0.3, 0.0, 0.0),
            (100.0, 0.3, 0.3, 0.0, 0.0), (4.0, 0.1, 1.5, 0.0, 0.0), (5.0, 0.5, 1.0, 3.0, 1.0)]


def test_friction_steps_run_compiled_as_the_stepper_takes_them() -> None:
    # Coulomb sticking and break-away, the near-Coulomb creep and the n < 1 splits are taken
    # inside the compiled run (nothing handed back to Engine.careful), to the Stepper's bit,
    # counters included; the numpy sweep decides alike (its power differs from C's pow in the
    # last bit for non-integer n). A stiff γ's guard substeps are taken compiled too.
    h, steps = 1e-3, 1000
    gam, nn, p0, v0, tau = (np.array(col) for col in zip(*FRICTION, strict=True))
    a = sweep(W2, gam, nn, p0, v0, steps * h, h, torque=tau)
    b = sweep(W2, gam, nn, p0, v0, steps * h, h, torque=tau, jit=True)
    assert b.handed_back == 0
    for i, (g, n, x0, dx0, ain) in enumerate(FRICTION):
        st = Stepper(PendulumParams.from_omega0_sq(W2, g, n), x0, dx0, h)
        for _ in range(steps):
            st.step(ain)
        want = tuple(getattr(st.stats, k) for k in COUNTERS)
        assert want[:2] == (0, 0)  # no guard substeps, no fallback
        for res in (a, b):
            assert tuple(int(getattr(res, k)[i]) for k in COUNTERS) == want, (g, n)
        assert (b.phi[i], b.dphi[i]) == (st.phi, st.dphi), (g, n)
        assert abs(a.phi[i] - st.phi) <= 1e-12 and abs(a.dphi[i] - st.dphi) <= 1e-12
        if 0.0 < n < 1.0 and g == 100.0:  # on the creep: φ' is the closed-form creep speed
            assert b.dphi[i] == creep_rate(ain - W2 * math.sin(b.phi[i]), g, n)
    assert b.sticks.sum() > 0 and b.reversals.sum() >= 3
    assert (b.phi[2], b.dphi[2]) == (1.0, 0.0)  # held at rest: |τ/I − ω0² sin φ| <= γ
    stiff = sweep(W2, 1e4, 1.0, 1.0, 3.0, 0.01, h, jit=True)
    assert stiff.substeps[0] > 0 and stiff.handed_back == 0  # the guard substeps compiled too


# (γ, n, f/I, φ0, φ'0, τ/I) at h = 20 ms: a Coulomb friction beside the law of every kind of
# text (n = 0, the smooth whole n = 1 and 3, whose texts otherwise leave out the Coulomb and
# reversal tests, the shared text of 1.5), sticking and breaking away, with and without input,
# and stiff γ (the guard's substeps; at γ = 1e4 the fallback, which beside a friction is the
# Python path's, handed back).
BESIDE = list(itertools.product([0.0, 0.5, 30.0, 1e4], [0.0, 1.0, 1.5, 3.0], [0.4, 3.0],
                                [0.3, 2.5], [0.0, 4.0], [0.0, 1.7]))


def test_a_friction_beside_the_law_runs_compiled_as_the_stepper_takes_it() -> None:
    gam, nn, fr, p0, v0, tau = (np.array(col) for col in zip(*BESIDE, strict=True))
    h, steps = 2e-2, 60
    a = sweep(W2, gam, nn, p0, v0, steps * h, h, torque=tau, friction=fr)
    b = sweep(W2, gam, nn, p0, v0, steps * h, h, torque=tau, friction=fr, jit=True)
    for i, (g, n, f, x0, dx0, ain) in enumerate(BESIDE):
        st = Stepper(PendulumParams.from_omega0_sq(W2, g, n, f), x0, dx0, h)
        for _ in range(steps):
            st.step(ain)
        want = tuple(getattr(st.stats, k) for k in COUNTERS)
        for res in (a, b):
            assert tuple(int(getattr(res, k)[i]) for k in COUNTERS) == want, BESIDE[i]
        assert (b.phi[i], b.dphi[i]) == (st.phi, st.dphi), BESIDE[i]
        assert abs(a.phi[i] - st.phi) <= 1e-12 and abs(a.dphi[i] - st.dphi) <= 1e-12
    whole = nn != 1.5
    assert a.phi[whole].tobytes() == b.phi[whole].tobytes()
    assert a.dphi[whole].tobytes() == b.dphi[whole].tobytes()
    # Sticks, reversals and the guard's substeps were taken compiled; only the fallback's
    # steps beside the friction (stiff γ = 1e4) went to Engine.careful.
    assert min(b.sticks.sum(), b.reversals.sum(), b.substeps.sum()) > 20
    assert b.handed_back == b.fallbacks.sum() > 0
    assert not b.fallbacks[gam < 1e4].any()
    tame = gam < 1e4
    c = sweep(W2, gam[tame], nn[tame], p0[tame], v0[tame], steps * h, h, torque=tau[tame],
              friction=fr[tame], jit=True)
    assert c.handed_back == 0
    assert c.phi.tobytes() == b.phi[tame].tobytes()


def test_a_friction_text_keeps_the_coulomb_and_reversal_tests() -> None:
    tab = TABLEAUS['rk4']
    for n in (1.0, 2.0, 3.0):
        plain = kernel_source(tab, n).split('def kernel')[1]
        beside = kernel_source(tab, n, True).split('def kernel')[1]
        assert 'coulomb and v == 0.0' not in plain and 'coulomb and v == 0.0' in beside
        assert 'nonsmooth and (' in beside
        assert 'moving_input(a_in, v0, cf)' in beside and 'moving_input' not in plain
        assert 'CF[i]' in beside and 'CF[i]' not in plain  # without friction it is never read
    assert Problem(W2, 1.0, 3.0, 0.5).coulomb and Problem(W2, 1.0, 3.0, 0.5).nonsmooth


def _call_twice(f: Any, x: float) -> float:
    """Return f(x, 1) + f(x, 2): a caller of a function argument, for first_class_twin."""
    return float(f(x, 1.0) + f(x, 2.0))


def test_the_careful_step_compiles_once_for_every_law_text() -> None:
    # careful_step takes each law text's generated functions (plain, branch, laws) as
    # arguments; compiled by jit.first_class_twin they are first-class functions of one
    # signature, so the careful step (and the tree under it) has one compiled form however
    # many law texts the process runs, and further texts add none. Each sweep takes careful
    # steps (the guard's substeps, a reversal split), compiled, to the Stepper's bit.
    twin = jit.first_class_twin(careful_step)
    h = 1e-3
    for n in (1.0, 2.0, 0.3, 3.7):
        res = sweep(W2, 1e4, n, 1.0, 3.0, 0.01, h, jit=True)
        assert res.substeps[0] + res.reversals[0] > 0
        st = Stepper(PendulumParams.from_omega0_sq(W2, 1e4, n), 1.0, 3.0, h)
        for _ in range(10):
            st.step(0.0)
        assert (res.phi[0], res.dphi[0]) == (st.phi, st.dphi), n
        assert len(twin.signatures) == 1, twin.signatures
    fn_type = type(numba_types().FunctionType(numba_types().float64()))
    steps = twin.signatures[0][0]  # careful.LawSteps, a named tuple of first-class functions
    assert steps.instance_class is LawSteps
    assert [type(a) for a in steps.types] == [fn_type] * len(LawSteps._fields)


def numba_types() -> Any:
    """Return ``numba.core.types`` (numba is imported only where the tests run)."""
    from numba.core import types

    return types


def test_a_function_argument_is_first_class_of_its_one_signature() -> None:
    # Two compiled functions of one signature share one compiled caller; a function without a
    # signature yet is compiled for float64 arguments; one with two signatures is refused.
    import numba

    caller = jit.first_class_twin(_call_twice)
    add = numba.njit('float64(float64, float64)')(lambda x, y: x + y)
    mul = numba.njit('float64(float64, float64)')(lambda x, y: x * y)
    lazy = numba.njit(lambda x, y: x - y)
    assert (caller(add, 3.0), caller(mul, 3.0), caller(lazy, 3.0)) == (9.0, 9.0, 3.0)
    assert len(caller.signatures) == 1
    both = numba.njit(['float64(float64, float64)', 'int64(int64, int64)'])(lambda x, y: x + y)
    msg = ('a function passed to a compiled careful path must have one signature; <lambda> '
           'has 2')
    with pytest.raises(IntegratorError, match=re.escape(msg)):
        caller(both, 3.0)


def test_warm_up_compiles_the_runs_a_sweep_then_finds() -> None:
    # After warm_up, sweeps of the laws it was given (the serial and the parallel run, an
    # exponent of a spelling it compiled: 2.5 is spelled as 1.5) compile nothing: numba reports
    # every compile (a load from the disk cache, jit_cache.py, is none), and here none.
    from numba.core import event

    from pendulum_sim.core.warm_up import warm_up

    seconds = warm_up((2.0, 1.5))
    assert seconds > 0.0
    with event.install_recorder('numba:compile') as rec:
        for n in (2.0, 1.5, 2.5):
            for size in (1, PARALLEL_MIN):
                sweep(W2, np.full(size, 0.5), n, 1.0, 0.5, 5e-3, 1e-3, jit=True)
    assert rec.buffer == []


def test_the_compiled_sweep_keeps_order_four_for_real_n_through_reversals() -> None:
    # The paper's start (x0 = 2 rad, φ'0 = 0, ω0² = 9.8, γ = 1) over 6 s, five reversals for
    # every n here, non-integer n in one compiled sweep (n = 1.5 and distinct n, graded at
    # reversals, and 3.5, split only): against the independent reference (scipy's DOP853
    # restarted at every reversal, ``reports.reference``) each pendulum's error falls as h^4.
    pytest.importorskip('scipy')
    from pendulum_sim.reports.reference import reference

    ns = np.array([0.5, 1.5, 1.23, 2.5, 2.71, 3.5])
    t_end, hs = 6.0, (0.02, 0.01, 0.005)
    refs = [reference(PendulumParams(gamma=1.0, n=float(n)), 2.0, 0.0, np.array([0.0, t_end]))
            for n in ns]
    errs = []
    for h in hs:
        res = sweep(W2, 1.0, ns, 2.0, 0.0, t_end, h, jit=True)
        assert res.handed_back == 0  # every careful step taken compiled
        assert list(res.reversals) == [5] * ns.size
        errs.append([math.hypot(res.phi[i] - r.phi[-1], res.dphi[i] - r.dphi[-1])
                     for i, r in enumerate(refs)])
    err = np.array(errs)
    assert np.all(err[-1] > 100.0 * np.array([r.disagreement for r in refs]))  # above the ref
    orders = np.polyfit(np.log(hs), np.log(err), 1)[0]
    assert np.all(orders >= 3.8), dict(zip(ns.tolist(), orders.tolist(), strict=True))
