"""The numpy sweep's careful steps: the one careful step, compiled over the refused pendulums.

For the laws graded at reversals (non-integer 0 < n < 3) about half the steps take the careful
path; the numpy sweep takes them by ``careful.careful_each`` (the one careful step compiled,
``jit.compile_careful_each``) and hands what it declines to ``Engine.careful``. Oracles: the
``Stepper`` (its counters exactly, its floats to round-off: the numpy plain step's power is not
the C library's pow), and the same sweep with every careful step taken as Python, to the bit.
"""
from __future__ import annotations

import numpy as np
import pytest

from pendulum_sim.core import PendulumParams, Stepper
from pendulum_sim.core import sweep as sweep_module
from pendulum_sim.core.jit import available
from pendulum_sim.core.sweep import sweep

pytestmark = pytest.mark.skipif(not available(), reason='numba is not installed (jit extra)')

COUNTERS = ('substeps', 'fallbacks', 'reversals', 'sticks', 'energy_rejections', 'projections')
FIELDS = ('phi', 'dphi', 'energy', *COUNTERS)


def _population(case: str, size: int, torque: float) -> tuple[np.ndarray, ...]:
    """Return (γ, n, φ0, φ'0, τ/I, f/I) for ``size`` pendulums of the exponent case ``case``."""
    rng = np.random.default_rng(29)
    n = {'n = 1.5': np.full(size, 1.5), 'distinct n': rng.uniform(0.2, 2.9, size)}[case]
    gamma = rng.uniform(0.1, 2.0, size)
    p0 = rng.uniform(-2.0, 2.0, size)
    v0 = rng.uniform(-3.0, 3.0, size)
    tau = np.where(rng.uniform(size=size) < 0.5, torque, 0.0)
    friction = np.where(rng.uniform(size=size) < 0.2, 0.05, 0.0)
    return gamma, n, p0, v0, tau, friction


@pytest.mark.parametrize('torque', [0.0, 1.5])
@pytest.mark.parametrize('case', ['n = 1.5', 'distinct n'])
def test_the_compiled_careful_steps_are_the_python_ones_to_the_bit(
        case: str, torque: float, monkeypatch: pytest.MonkeyPatch) -> None:
    # The same sweep twice: its careful steps compiled, then every one as Python
    # (Engine.careful: jit.compile_careful_each not serving); states, energies and counters
    # to the bit, and the compiled one took the careful steps the other handed back.
    gamma, n, p0, v0, tau, fr = _population(case, 200, torque)
    compiled = sweep(9.8, gamma, n, p0, v0, 0.3, 1e-3, torque=tau, friction=fr)
    monkeypatch.setattr(sweep_module, 'compile_careful_each', lambda fn: None)
    python = sweep(9.8, gamma, n, p0, v0, 0.3, 1e-3, torque=tau, friction=fr)
    for field in FIELDS:
        assert np.array_equal(getattr(compiled, field), getattr(python, field)), field
    assert python.batched == 0
    assert compiled.batched + compiled.handed_back == python.handed_back
    assert compiled.handed_back < python.handed_back // 20
    assert python.reversals.sum() > 50


def test_the_numpy_sweeps_careful_steps_take_the_steppers_steps() -> None:
    # Graded laws (1.5, distinct n, near-Coulomb 0.3 at a large γ that creeps), with and
    # without a friction beside the law: each pendulum ends with the Stepper's counters and
    # its state to round-off; the careful steps were taken compiled.
    rng = np.random.default_rng(7)
    size = 40
    n = np.where(np.arange(size) % 3 == 0, 1.5, rng.uniform(0.2, 2.9, size))
    gamma = rng.uniform(0.1, 2.0, size)
    n[::8], gamma[::8] = 0.3, 60.0
    p0, v0 = rng.uniform(-2.0, 2.0, size), rng.uniform(-3.0, 3.0, size)
    fr = np.where(np.arange(size) % 5 == 0, 0.05, 0.0)
    h, steps = 1e-3, 300
    res = sweep(9.8, gamma, n, p0, v0, steps * h, h, friction=fr)
    assert res.batched > steps * size // 4 and res.handed_back < res.batched // 20
    for i in range(size):
        st = Stepper(PendulumParams.from_omega0_sq(9.8, gamma[i], n[i], fr[i]), p0[i], v0[i], h)
        for _ in range(steps):
            st.step(0.0)
        want = tuple(getattr(st.stats, k) for k in COUNTERS)
        assert tuple(int(getattr(res, k)[i]) for k in COUNTERS) == want, i
        assert abs(res.phi[i] - st.phi) <= 1e-12 and abs(res.dphi[i] - st.dphi) <= 1e-12, i
