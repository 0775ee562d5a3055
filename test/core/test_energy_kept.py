"""The energy test's sound pre-test: wherever it accepts a step, the energy test does too.

``decisions.energy_kept`` proves without a sine of its own (it takes the sine of a point the step
already visited) that E/I did not rise beyond ENERGY_TOL; the compiled sweep tries it first and
evaluates ``energy_rose`` only where it cannot prove that. Its soundness is checked here on
plain RK4 steps over wide ranges, around turning points, at large |φ| and on states built to lie
just around the energy test's threshold; and it is shown to refuse.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from pendulum_sim.core import kernel
from pendulum_sim.core.careful import careful_step
from pendulum_sim.core.decisions import (
    ENERGY_TOL,
    energy_kept,
    energy_rose,
    kept_stage,
    specific_energy,
)
from pendulum_sim.core.explicit import compile_step
from pendulum_sim.core.guard import StabilityGuard
from pendulum_sim.core.tableaus import TABLEAUS

RK4 = TABLEAUS['rk4']
PROPERTY = settings(max_examples=3000, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.filter_too_much])


def energies(p0: float, v0: float, p1: float, v1: float, w2: float) -> list[tuple[float, float]]:
    """Return (e0, e1) as the sweep has them: the C library's sine, and e0 by numpy's."""
    e1 = specific_energy(v1, math.sin(0.5 * p1), w2)
    e0_c = specific_energy(v0, math.sin(0.5 * p0), w2)
    e0_np = float(specific_energy(v0, float(np.sin(np.array([0.5 * p0]))[0]), w2))
    return [(e0_c, e1), (e0_np, e1)]


def rk4_step(p0: float, v0: float, h: float, w2: float, gamma: float,
             n: float) -> tuple[float, float, float]:
    """Return (φ₁, φ'₁, q): a plain RK4 step and its third stage's φ, as the kernel has them."""
    p1, v1, _, a0 = compile_step(RK4, n)(p0, v0, h, 0.0, w2, gamma, 1.0)
    h0 = 0.5 * h
    return p1, v1, p0 + h0 * (v0 + h0 * a0)


def assert_sound(p0: float, v0: float, p1: float, v1: float, q: float, w2: float) -> bool:
    kept = energy_kept(p0, v0, p1, v1, q, w2)
    if kept:
        for e0, e1 in energies(p0, v0, p1, v1, w2):
            assert not energy_rose(e0, e1, w2), (p0, v0, p1, v1, q, w2)
    return kept


angles = st.one_of(st.floats(-7.0, 7.0), st.floats(-1e5, 1e5))
speeds = st.one_of(st.floats(-40.0, 40.0), st.floats(-1e-4, 1e-4))  # near turning points
steps = st.floats(-5.0, -1.0).map(lambda x: 10.0 ** x)


@PROPERTY
@given(p0=angles, v0=speeds, h=steps, w2=st.floats(0.0, 1e4), gamma=st.floats(0.0, 100.0),
       n=st.sampled_from([0.0, 0.3, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0]))
def test_an_accepted_rk4_step_passes_the_energy_test(p0: float, v0: float, h: float, w2: float,
                                                     gamma: float, n: float) -> None:
    p1, v1, q = rk4_step(p0, v0, h, w2, gamma, n)
    assume(math.isfinite(p1) and math.isfinite(v1))
    assert_sound(p0, v0, p1, v1, q, w2)


@PROPERTY
@given(p0=angles, v0=speeds, half=st.floats(-0.5, 0.5), off=st.floats(-1e-3, 1e-3),
       w2=st.floats(0.0, 1e4), f=st.floats(-3.0, 3.0), flip=st.booleans())
def test_states_around_the_threshold_are_never_accepted_wrongly(
        p0: float, v0: float, half: float, off: float, w2: float, f: float,
        flip: bool) -> None:
    # φ₁ = φ₀ + 2δ, q near the midpoint, φ'₁ chosen so that E/I changes by f ENERGY_TOL
    # (E₀ + ω0²): the energy test's threshold is f = 1 (up to the rounding of this set-up).
    p1 = p0 + 2.0 * half
    q = p0 + half + off * abs(half)
    e0 = 0.5 * v0 * v0 + w2 * (1.0 - math.cos(p0))
    kinetic = v0 * v0 + 2.0 * (f * ENERGY_TOL * (e0 + w2) - w2 * (math.cos(p0) - math.cos(p1)))
    assume(kinetic >= 0.0)
    v1 = math.copysign(math.sqrt(kinetic), -v0 if flip else v0)
    assert_sound(p0, v0, p1, v1, q, w2)


def test_the_pre_test_refuses_where_the_energy_test_fires() -> None:
    # An undamped step (its energy error far below ENERGY_TOL) with φ'₁ raised so that E/I
    # rises by f ENERGY_TOL (E₀ + ω0²): the energy test fires for f = 2 and 1.5, not for 0.7;
    # the pre-test refuses all three (it accepts only up to 0.4 of the threshold).
    w2, p0, v0 = 9.8, 1.0, 2.0
    p1, v1, q = rk4_step(p0, v0, 1e-3, w2, 0.0, 1.0)
    e0 = specific_energy(v0, math.sin(0.5 * p0), w2)
    for f, rose in ((2.0, True), (1.5, True), (0.7, False)):
        v1_up = math.sqrt(v1 * v1 + 2.0 * f * ENERGY_TOL * (e0 + w2))
        assert energy_rose(e0, specific_energy(v1_up, math.sin(0.5 * p1), w2), w2) == rose
        assert not energy_kept(p0, v0, p1, v1_up, q, w2)
    # Without gravity's sign the identity does not bound the change: the pre-test stays out.
    assert energy_kept(p0, v0, p1, v1 * (1.0 - 1e-9), q, w2)
    assert not energy_kept(p0, v0, p1, v1 * (1.0 - 1e-9), q, -w2)


def test_the_pre_test_decides_the_ordinary_damped_step() -> None:
    # The benchmark's pendulums (n = 1..5, γ 0.05..1, h = 1 ms): away from turning points the
    # damping removes far more than the bound, so nearly every step is decided without a sine.
    rng = np.random.default_rng(7)
    kept = total = 0
    for _ in range(4000):
        n = float(rng.choice([1.0, 2.0, 3.0, 4.0, 5.0]))
        p0, v0 = rng.uniform(-2.5, 2.5), rng.uniform(-3.0, 3.0)
        p1, v1, q = rk4_step(p0, v0, 1e-3, 9.8, rng.uniform(0.05, 1.0), n)
        kept += assert_sound(p0, v0, p1, v1, q, 9.8)
        total += 1
    assert kept >= 0.99 * total
    # It is the midpoint-nearest stage of each method with one (Euler has none).
    assert (kept_stage(RK4), kept_stage(TABLEAUS['midpoint']), kept_stage(TABLEAUS['euler'])) \
        == (2, 1, None)


def run_kernel(pre_test: bool, n: float, h: float, steps: int) -> list[bytes]:
    """Run the sweep's kernel as Python on a fixed batch; return its arrays' bytes."""
    tab = RK4
    stage = kernel.kept_stage
    kernel.kernel_source.cache_clear()
    try:
        if not pre_test:
            kernel.kept_stage = lambda tableau: None
        run = kernel.compile_kernel(tab, n, careful_step)
    finally:
        kernel.kept_stage = stage
        kernel.kernel_source.cache_clear()
    rng = np.random.default_rng(11)
    size = 240
    w2 = rng.choice(np.array([0.0, 9.8, 40.0]), size)
    gamma = rng.choice(np.array([0.0, 0.05, 1.0]), size)
    p = rng.uniform(-3.0, 3.0, size)
    v = rng.uniform(-4.0, 4.0, size)
    v[::4] = 0.0  # at rest at a turning point
    e = specific_energy(v, np.sin(0.5 * p), w2)
    k = np.zeros(size, dtype=np.int64)
    counts = np.zeros((size, 6), dtype=np.int64)
    check = np.ones(size, dtype=np.bool_)  # the energy test even where γ = 0: it fires there
    check[::7] = False
    careful = np.ones(size, dtype=np.bool_)
    careful[::5] = False  # these stop at a refused step, E/I written back where they stop
    full, zero = np.full(size, math.inf), np.zeros(size)
    guard = np.array(StabilityGuard(tab).constants)
    functions = [run.__globals__[name] for name in kernel.FUNCTION_ARGS]
    run(p, v, e, k, np.arange(size), h, steps, zero.reshape(1, -1).copy(), w2, gamma,
        zero.copy(), np.full(size, n),
           zero.copy(), full.copy(), zero.copy(), full.copy(), check, np.zeros(size, np.bool_),
           np.zeros(size, np.bool_), full.copy(), 0, 0, steps, np.empty((0, size)),
           np.empty((0, size)), counts, np.zeros_like(counts), careful, guard, *functions)
    return [a.tobytes() for a in (p, v, e, k, counts)]


@pytest.mark.parametrize(('n', 'h'), [(1.0, 2e-2), (3.0, 5e-2)])
def test_the_kernel_with_the_pre_test_takes_the_same_steps_and_energies(n: float,
                                                                         h: float) -> None:
    # The run with the pre-test (E/I carried lazily) against the run that tests every step
    # exactly: the same states, E/I (to the bit, where the runs stop), steps and counters.
    with_pre = run_kernel(True, n, h, 60)
    assert with_pre == run_kernel(False, n, h, 60)
    counts = np.frombuffer(with_pre[-1], dtype=np.int64).reshape(-1, 6)
    stopped = np.frombuffer(with_pre[3], dtype=np.int64) < 60
    assert counts[:, 4].sum() > 0 and stopped.any()  # energy rejections taken, runs stopped
