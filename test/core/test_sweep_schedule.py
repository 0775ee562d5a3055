"""A sweep driven by a torque schedule: a row of inputs per step, held over the step.

Oracles: a chain of one-step advances under each row (what a schedule stands for), a constant
input (a schedule of equal rows), the numpy sweep against the compiled one, and scipy's
``solve_ivp`` at tight tolerances, integrated interval by interval under the held input.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp  # type: ignore[import-untyped]

from pendulum_sim.core import ModelError
from pendulum_sim.core.jit import available
from pendulum_sim.core.sweep import Sweep, sweep

JITS = [False, True] if available() else [False]


def batch(seed: int, size: int = 24) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {'gamma': rng.choice([0.2, 1.0], size), 'n': rng.choice([0.0, 1.0, 1.5, 2.0], size),
            'friction': rng.choice([0.0, 0.3], size), 'phi0': rng.uniform(-2.0, 2.0, size),
            'dphi0': rng.uniform(-2.0, 2.0, size)}


@pytest.mark.parametrize('jit', JITS)
def test_a_schedule_is_a_chain_of_one_step_advances(jit: bool) -> None:
    b = batch(1)
    steps, h = 60, 0.01
    sched = np.random.default_rng(2).uniform(-3.0, 3.0, (steps, b['n'].size))
    got = sweep(9.8, b['gamma'], b['n'], b['phi0'], b['dphi0'], steps * h, h, torque=sched,
                jit=jit, friction=b['friction'], record_every=1)
    chain = Sweep(9.8, b['gamma'], b['n'], b['phi0'], b['dphi0'], h, jit=jit,
                  friction=b['friction'])
    assert got.phi_record is not None
    for k in range(steps):
        res = chain.advance(h, sched[k])
        np.testing.assert_allclose(got.phi_record[k + 1], res.phi, rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(got.dphi, res.dphi, rtol=0.0, atol=1e-12)


@pytest.mark.parametrize('jit', JITS)
def test_a_schedule_of_equal_rows_is_the_constant_input_to_the_bit(jit: bool) -> None:
    b = batch(3)
    steps, h = 50, 0.01
    tau = np.random.default_rng(4).uniform(-3.0, 3.0, b['n'].size)
    args = (9.8, b['gamma'], b['n'], b['phi0'], b['dphi0'], steps * h, h)
    rows = sweep(*args, torque=np.tile(tau, (steps, 1)), jit=jit, friction=b['friction'])
    const = sweep(*args, torque=tau, jit=jit, friction=b['friction'])
    assert rows.phi.tobytes() == const.phi.tobytes()
    assert rows.dphi.tobytes() == const.dphi.tobytes()


@pytest.mark.skipif(not available(), reason='numba is not installed (jit extra)')
def test_the_compiled_and_numpy_sweeps_take_a_schedule_alike() -> None:
    b = batch(5)
    steps, h = 40, 0.02
    sched = np.random.default_rng(6).uniform(-4.0, 4.0, (steps, b['n'].size))
    args = (9.8, b['gamma'], b['n'], b['phi0'], b['dphi0'], steps * h, h)
    a = sweep(*args, torque=sched, friction=b['friction'], record_every=1)
    c = sweep(*args, torque=sched, friction=b['friction'], record_every=1, jit=True)
    assert a.phi_record is not None and c.phi_record is not None
    np.testing.assert_allclose(a.phi_record, c.phi_record, rtol=0.0, atol=1e-12)
    assert np.array_equal(a.sticks, c.sticks) and np.array_equal(a.reversals, c.reversals)


def test_a_schedule_solves_the_held_input_as_scipy_does() -> None:
    w2, gamma, n = 9.8, 0.4, 1.0
    steps, h, every = 200, 0.01, 5   # the input changes every 5 steps (a 20 Hz command)
    held = np.random.default_rng(7).uniform(-6.0, 6.0, steps // every)
    sched = np.repeat(held, every)[:, None]
    got = sweep(w2, gamma, n, 1.0, 0.0, steps * h, h, torque=sched, record_every=every)
    assert got.phi_record is not None
    x = np.array([1.0, 0.0])
    for k, u in enumerate(held):
        sol = solve_ivp(lambda _t, s, u=u: [s[1], -w2 * math.sin(s[0]) - gamma * s[1] + u],
                        (0.0, every * h), x, rtol=1e-12, atol=1e-12, method='DOP853')
        x = sol.y[:, -1]
        # RK4 at h ω0 = 0.03: a global error of order (h ω0)^4 ~ 1e-6 of the swing.
        assert abs(got.phi_record[k + 1, 0] - x[0]) < 2e-7
        assert abs(got.dphi_record[k + 1, 0] - x[1]) < 2e-6   # type: ignore[index]


def test_a_schedule_of_the_wrong_shape_or_size_is_refused() -> None:
    prepared = Sweep(9.8, 0.5, 1.0, np.zeros(3), 0.0, 0.01)
    with pytest.raises(ModelError) as info:
        prepared.advance(0.05, np.zeros((4, 3)))
    assert str(info.value) == ('a torque schedule must have one row per step and one column '
                               'per pendulum, shape (steps, N) = (5, 3), got shape (4, 3)')
    sched = np.zeros((5, 3))
    sched[2, 1] = 1e9
    with pytest.raises(ModelError) as info:
        prepared.advance(0.05, sched)
    assert str(info.value).endswith(' at index 1, step 3')
    assert str(info.value).startswith('torque')
