"""Example laws for closed loops and campaigns: the example controller's PD law as a callable.

``pd`` is what ``pendulum_pd_controller`` answers with its default gains
(:func:`pendulum_sim.controller.pd_law.pd_torque`), towards its keyword ``target`` (default
0.5 rad, the controller's default), so a campaign can name it as
``pendulum_sim.testing.examples:pd`` and vary the target; ``pd_batch`` is the same law on
arrays (a target per episode), declared :func:`~pendulum_sim.testing.vectorised`.
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pendulum_sim.controller.pd_law import PDGains, pd_torque

from .vector import vectorised

GAINS = PDGains()


@functools.lru_cache(maxsize=64)
def gains_for(target: float) -> PDGains:
    """Return the default gains with the reference ``target`` (rad; built once per target)."""
    return dataclasses.replace(GAINS, target=target)


def pd(t: float, position: float, velocity: float, *, target: float = GAINS.target) -> float:
    """Return the example controller's torque for one state, towards ``target`` (rad)."""
    return pd_torque(gains_for(target), position, velocity)


@vectorised
def pd_batch(t: NDArray[np.float64], position: NDArray[np.float64],
             velocity: NDArray[np.float64], *,
             target: ArrayLike = GAINS.target) -> NDArray[np.float64]:
    """Return :func:`pd` for many states at once (same operations, element by element)."""
    g = GAINS
    error = np.remainder(np.asarray(target, dtype=float) - position + np.pi, 2 * np.pi) - np.pi
    tau = g.mgl * np.sin(position) + g.kp * error - g.kd * velocity
    return np.clip(tau, -g.max_effort, g.max_effort)
