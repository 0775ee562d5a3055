"""The core's public API reproduces its golden outputs to the last bit.

``test/golden/core.npz`` holds what ``simulate`` (every method), ``Stepper`` and ``sweep``
returned on a grid of exponents n (0, 0.01, 0.5, 1, 2, 3.7), damping coefficients (up to the
stiff γ = 1000), torques and states; ``test/golden/make_golden.py`` wrote it. A change of the
core's structure must leave every one of these floats and counters unchanged.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

GOLDEN_DIR = Path(__file__).resolve().parents[1] / 'golden'
sys.path.insert(0, str(GOLDEN_DIR))

import make_golden  # noqa: E402


@pytest.fixture(scope='module')
def recorded() -> dict[str, np.ndarray]:
    with np.load(make_golden.GOLDEN) as data:
        return {k: data[k] for k in data.files}


@pytest.mark.parametrize('cases', [make_golden.simulate_cases, make_golden.stepper_cases,
                                   make_golden.sweep_cases],
                         ids=['simulate', 'stepper', 'sweep'])
def test_outputs_are_bit_identical(recorded: dict[str, np.ndarray], cases: object) -> None:
    assert callable(cases)
    seen = 0
    differ: list[str] = []
    for key, arrays in cases():
        for field, arr in arrays.items():
            name = f'{key}/{field}'
            want = recorded[name]
            got = np.asarray(arr)
            seen += 1
            if got.dtype != want.dtype or got.shape != want.shape or (
                    np.ascontiguousarray(got).tobytes() != np.ascontiguousarray(want).tobytes()):
                differ.append(name)
    assert seen > 0
    assert differ == []


def test_golden_covers_every_method_and_exponent(recorded: dict[str, np.ndarray]) -> None:
    from pendulum_sim.core import METHODS

    for method in METHODS:
        for n in (0.0, 0.5, 1.0, 2.0, 3.7):
            for gamma in make_golden.GAMMAS:
                assert f'sim/{method}/n={n}/g={gamma}/tau=0.4/phi' in recorded
    assert any(k.startswith('sweep/rk4/torque=1/') for k in recorded)
