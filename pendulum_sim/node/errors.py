"""Exceptions of the ROS node."""
from __future__ import annotations

from pendulum_sim.core import PendulumError


class NodeError(PendulumError):
    """The node cannot start or run as configured."""


class SceneError(NodeError):
    """A scene name or file cannot be resolved."""


class ParameterError(NodeError, ValueError):
    """A node parameter has a value the node cannot use."""


class JointError(NodeError, ValueError):
    """The simulated joint cannot take a configuration or state (the reason says why)."""


class LiveError(NodeError):
    """The live Foxglove server cannot start (the reason says why)."""
