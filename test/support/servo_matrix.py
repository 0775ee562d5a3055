"""The position servo's loop written out as a matrix: its spectral radius and stability limit.

An oracle independent of ``pendulum_sim.joint.servo``'s Jury test: one step of the linearised
loop on (φ, φ', z), from the law (τ held over the step, ``I φ'' = τ`` stepped exactly).
"""
from __future__ import annotations

from pendulum_sim.joint.servo import ServoGains


def step_matrix(gains: ServoGains, inertia: float, h: float) -> object:
    """Return the matrix of one step of the linearised position loop on (φ, φ', z), written
    out from the law (τ held over the step, ``I φ'' = τ`` stepped exactly)."""
    import numpy as np

    kp, ki, pp = gains.velocity_p, gains.velocity_i, gains.position_p
    c = h * h / (2.0 * inertia)
    return np.array([[1.0 - c * kp * pp, h - c * kp, c * ki],
                     [-h * kp * pp / inertia, 1.0 - h * kp / inertia, h * ki / inertia],
                     [-h * pp, -h, 1.0]])


def spectral_radius(gains: ServoGains, inertia: float, h: float) -> float:
    import numpy as np
    return float(max(abs(np.linalg.eigvals(step_matrix(gains, inertia, h)))))  # type: ignore


def eigen_limit(gains: ServoGains, inertia: float, h: float) -> float:
    """Return the largest position_p with spectral radius < 1, by bisection on eigenvalues."""
    from dataclasses import replace

    lo, hi = 1.0, 1e9
    assert spectral_radius(replace(gains, position_p=lo), inertia, h) < 1.0
    assert spectral_radius(replace(gains, position_p=hi), inertia, h) > 1.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if spectral_radius(replace(gains, position_p=mid), inertia, h) < 1.0:
            lo = mid
        else:
            hi = mid
    return lo
