"""Example laws for closed loops and campaigns: the example controller's PD law as a callable.

``pd`` is what ``pendulum_pd_controller`` answers with its default parameters
(:func:`pendulum_sim.controller.pd_law.pd_torque`), so a campaign can name it as
``pendulum_sim.testing.examples:pd``; ``pd_batch`` is the same law on arrays, declared
:func:`~pendulum_sim.testing.vectorised`.
"""
from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pendulum_sim.controller.pd_law import PDGains, pd_torque

from .vector import vectorised

GAINS = PDGains()


def pd(t: float, position: float, velocity: float) -> float:
    """Return the example controller's torque for one state (default gains, target 0.5 rad)."""
    return pd_torque(GAINS, position, velocity)


@vectorised
def pd_batch(t: NDArray[np.float64], position: NDArray[np.float64],
             velocity: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return :func:`pd` for many states at once (same operations, element by element)."""
    g = GAINS
    error = np.remainder(g.target - position + np.pi, 2 * np.pi) - np.pi
    tau = g.mgl * np.sin(position) + g.kp * error - g.kd * velocity
    return np.clip(tau, -g.max_effort, g.max_effort)
