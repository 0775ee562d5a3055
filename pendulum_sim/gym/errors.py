"""Exceptions of the Gymnasium environments."""
from __future__ import annotations

from pendulum_sim.core.errors import PendulumError


class GymError(PendulumError, ValueError):
    """An environment cannot be made or stepped as asked (bad keyword, action or call order)."""
