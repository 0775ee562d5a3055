"""Events the recording keeps besides the published topics."""
from __future__ import annotations

from typing import Final

RESET_TOPIC: Final = '/pendulum_sim/reset'
"""Topic of the reset events (``std_msgs/msg/String``, data = why), written in write order by
:meth:`McapRecorder.write_reset`; :func:`~pendulum_sim.recording.load` splits the run there."""
RESET_TYPE: Final = 'std_msgs/msg/String'
