"""A population of pendulums that mixes every law a sweep decides on (seeded, reproducible)."""
from __future__ import annotations

import numpy as np


def mixed_population(size: int = 400, seed: int = 18) -> tuple[np.ndarray, ...]:
    """Return (ω0², γ, n, φ0, φ'0, τ/I) of ``size`` pendulums drawn with ``seed``.

    Exponents from Coulomb (0) and near-Coulomb (0.01) through fractional to 5, damping up to
    the stiff γ = 1000, ω0² = 0 among them, one in five starting at rest, and a torque on about
    30 % of them. test/golden/core.npz holds sweeps of the default draw: changing it changes
    those arrays.
    """
    rng = np.random.default_rng(seed)
    n = rng.choice(np.array([0.0, 0.01, 0.3, 0.5, 1.0, 1.5, 2.0, 3.0, 3.7, 5.0]), size)
    gamma = rng.choice(np.array([0.0, 0.1, 1.0, 30.0, 1000.0]), size)
    w2 = rng.choice(np.array([0.0, 9.8, 40.0]), size)
    phi0 = rng.uniform(-3.0, 3.0, size)
    dphi0 = rng.uniform(-4.0, 4.0, size)
    dphi0[::5] = 0.0
    tau = np.where(rng.uniform(size=size) < 0.3, rng.uniform(-20.0, 20.0, size), 0.0)
    return w2, gamma, n, phi0, dphi0, tau
