"""Exceptions of the example controller."""
from __future__ import annotations

from pendulum_sim.core import PendulumError


class ControllerError(PendulumError, ValueError):
    """A controller gain, limit or threshold has a value the controller cannot use."""
