"""Synthetic records for the identification tests and benchmark: known truth, sensor faults.

The truth is simulated by the core's sweep at a fine step (1 ms, 16-64 times finer than the
fit's), sampled at jittered stamps, with Gaussian sensor noise and an encoder's quantisation
added, and a zero offset. A record starts released from rest (``start='rest'``) or passing the
centre at full speed (``start='centre'``): φ = 0 with the speed 2 ω0 sin(A/2) that swings out to
the same release angle A (energy ½φ'² = ω0² (1 − cos A), neglecting the damping).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from pendulum_sim.core.sweep import sweep

FloatArray = npt.NDArray[np.float64]

LAWS = {'viscous': (1.0, (0.05, 0.3)), 'quadratic': (2.0, (0.05, 0.3)),
        'coulomb': (0.0, (0.1, 0.3))}
"""Each law's exponent and the range its γ is drawn from."""


@dataclass(frozen=True)
class Truth:
    """The parameters a synthetic record was made with."""

    model: str
    omega0: float
    gamma: float
    n: float
    phi_offset: float


def records(count: int, seed: int, *, duration: float = 6.0, rate: float = 25.0,
            noise: float = 2e-3, resolution: float = 1e-3,
            laws: tuple[str, ...] = tuple(LAWS), start: str = 'rest'
            ) -> list[tuple[Truth, FloatArray, FloatArray]]:
    """Return ``count`` records (truth, t, position), the laws taken in turn."""
    if start not in ('rest', 'centre'):
        raise ValueError(f"start must be 'rest' or 'centre', got {start!r}")
    rng = np.random.default_rng(seed)
    truths = []
    for i in range(count):
        name = laws[i % len(laws)]
        n, (lo, hi) = LAWS[name]
        truths.append(Truth(name, float(rng.uniform(2.5, 4.0)), float(rng.uniform(lo, hi)), n,
                            float(rng.uniform(-0.1, 0.1))))
    h = 1e-3
    amp = rng.uniform(0.6, 1.2, count)
    omega0 = np.array([t.omega0 for t in truths])
    phi0, dphi0 = (amp, 0.0) if start == 'rest' else (0.0, 2.0 * omega0 * np.sin(amp / 2.0))
    run = sweep(omega0 ** 2, np.array([t.gamma for t in truths]),
                np.array([t.n for t in truths]), phi0, dphi0, duration, h, record_every=1)
    assert run.t_record is not None and run.phi_record is not None
    every = round(1.0 / (rate * h))
    out = []
    for i, truth in enumerate(truths):
        idx = np.arange(0, run.t_record.size, every)
        idx = np.unique(np.clip(idx + rng.integers(-3, 4, idx.size), 0, run.t_record.size - 1))
        y = run.phi_record[idx, i] + truth.phi_offset + rng.normal(0.0, noise, idx.size)
        y = np.round(y / resolution) * resolution
        out.append((truth, run.t_record[idx].copy(), y))
    return out
