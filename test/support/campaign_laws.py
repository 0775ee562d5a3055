"""Controller laws for the campaign tests (imported by Dask workers by name)."""
from __future__ import annotations

import math

import numpy as np

from pendulum_sim.testing.examples import pd, pd_batch


def fragile(t: float, position: float, velocity: float) -> float:
    """Return the example PD torque, but raise on a fast swing and answer NaN far below."""
    if abs(velocity) > 3.2:
        raise RuntimeError(f'velocity {velocity:.3f} rad/s is out of range')
    if position < 0.40:
        return math.nan
    return pd(t, position, velocity)


def pd_batch_one(t: float, position: float, velocity: float) -> float:
    """Return the numpy example law for one state (the batched law, run one by one)."""
    return float(pd_batch(t, np.array([position]), np.array([velocity]))[0])


def pd_batch_one_to(t: float, position: float, velocity: float, *, target: float) -> float:
    """Return the numpy example law for one state towards ``target`` (run one by one)."""
    return float(pd_batch(t, np.array([position]), np.array([velocity]),
                          target=np.array([target]))[0])


def hold(t: float, position: float, velocity: float) -> float:
    """Return the example PD torque towards its fixed 0.5 rad (a law that takes no target)."""
    return pd(t, position, velocity)
