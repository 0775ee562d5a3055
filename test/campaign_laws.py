"""Controller laws for the campaign tests (imported by Dask workers by name)."""
from __future__ import annotations

import math

from pendulum_sim.testing.examples import pd


def fragile(t: float, position: float, velocity: float) -> float:
    """Return the example PD torque, but raise on a fast swing and answer NaN far below."""
    if abs(velocity) > 3.2:
        raise RuntimeError(f'velocity {velocity:.3f} rad/s is out of range')
    if position < 0.40:
        return math.nan
    return pd(t, position, velocity)
