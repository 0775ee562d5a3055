"""Exceptions of the simulated joint: its configuration, scenes, parameters and live view."""
from __future__ import annotations

from pendulum_sim.core import PendulumError


class JointError(PendulumError, ValueError):
    """The simulated joint cannot take a configuration or state (the reason says why)."""


class ParameterError(PendulumError, ValueError):
    """A joint parameter has a value the joint cannot use."""


class SceneError(PendulumError):
    """A scene name or file cannot be resolved."""


class LiveError(PendulumError):
    """The live Foxglove server cannot start (the reason says why)."""
