"""``sweep(..., jit=True)``: the sweep's fast path compiled by numba from the generated source.

Oracles: the ``Stepper`` (the kernel is the Stepper's generated fast step and the decision
texts, run in one loop, so both take the same steps to the last bit) and the numpy sweep (the
same decisions; the numbers equal to the bit where the law is spelled with multiplications,
to round-off where numpy's power differs from the C library's pow).
"""
from __future__ import annotations

import itertools

import numpy as np
import pytest

from pendulum_sim.core import IntegratorError, PendulumParams, Stepper
from pendulum_sim.core.decisions import kernel_source
from pendulum_sim.core.explicit import step_source
from pendulum_sim.core.jit import available
from pendulum_sim.core.law import damping_expression
from pendulum_sim.core.sweep import Sweep, sweep
from pendulum_sim.core.tableaus import TABLEAUS

pytestmark = pytest.mark.skipif(not available(), reason='numba is not installed (jit extra)')

W2 = 9.8
COUNTERS = ('substeps', 'fallbacks', 'reversals', 'sticks')

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
    rng = np.random.default_rng(18)
    size = 400
    n = rng.choice(np.array([0.0, 0.01, 0.3, 0.5, 1.0, 1.5, 2.0, 3.0, 3.7, 5.0]), size)
    gamma = rng.choice(np.array([0.0, 0.1, 1.0, 30.0, 1000.0]), size)
    w2 = rng.choice(np.array([0.0, 9.8, 40.0]), size)
    p0 = rng.uniform(-3.0, 3.0, size)
    v0 = rng.uniform(-4.0, 4.0, size)
    v0[::5] = 0.0
    tau = np.where(rng.uniform(size=size) < 0.3, rng.uniform(-20.0, 20.0, size), 0.0)
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
