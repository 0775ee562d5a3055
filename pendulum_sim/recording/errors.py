"""Exceptions of the recording area (MCAP writer, loader and replayer)."""
from __future__ import annotations

from pendulum_sim.core.errors import PendulumError


class RecorderError(PendulumError):
    """A recording cannot be created, written, read or replayed; the message names why."""
