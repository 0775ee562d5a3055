"""Record runs to MCAP (ROS 2 profile, rosbag2-compatible), load them into numpy, replay them.

The names below are imported on first use, so that the recording's writer process, which runs
``pendulum_sim.recording.sink``, starts without rclpy or numpy.
"""
from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from pendulum_sim.recording.errors import RecorderError
    from pendulum_sim.recording.events import RESET_TOPIC, STOPPED_TOPIC
    from pendulum_sim.recording.loader import Recording, Segment, load
    from pendulum_sim.recording.writer import McapRecorder

__all__ = ['RESET_TOPIC', 'STOPPED_TOPIC', 'McapRecorder', 'RecorderError', 'Recording', 'Segment',
           'load']

_WHERE = {'McapRecorder': 'writer', 'RecorderError': 'errors', 'Recording': 'loader',
          'Segment': 'loader', 'load': 'loader', 'RESET_TOPIC': 'events',
          'STOPPED_TOPIC': 'events'}


def __getattr__(name: str) -> Any:
    if name not in _WHERE:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    return getattr(importlib.import_module(f'{__name__}.{_WHERE[name]}'), name)
