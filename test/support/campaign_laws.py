"""Controller laws for the campaign tests (imported by Dask workers by name)."""
from __future__ import annotations

import math

import numpy as np

from pendulum_sim.testing import vectorised
from pendulum_sim.testing.examples import energy_lqr, pd, pd_batch


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


@vectorised
def brittle_swing_up(t: float, position: np.ndarray, velocity: np.ndarray) -> np.ndarray:
    """Return the reference swing-up's torque, but NaN for a state moving faster than 8 rad/s
    and an exception (raised, so the scalar joint decides who) for one faster than 9 rad/s."""
    if np.any(np.abs(velocity) > 9.0):
        raise RuntimeError('velocity out of range')
    tau = np.asarray(energy_lqr(t, position, velocity), dtype=float)
    return np.where(np.abs(velocity) > 8.0, np.nan, tau)


def swing_up_one(t: float, position: float, velocity: float) -> float:
    """Return the reference swing-up's torque for one state (a law that is not vectorised)."""
    return float(energy_lqr(t, position, velocity))
