"""The environments' ``rgb_array`` frames: :func:`pendulum_sim.frames.frame`."""
from __future__ import annotations

from pendulum_sim.frames import BACKGROUND, BOB, PIVOT, ROD, SIZE, TARGET, TORQUE, frame

__all__ = ['BACKGROUND', 'BOB', 'PIVOT', 'ROD', 'SIZE', 'TARGET', 'TORQUE', 'frame']
