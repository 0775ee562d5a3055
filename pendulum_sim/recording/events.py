"""Events the recording keeps besides the published topics."""
from __future__ import annotations

from typing import Final

RESET_TOPIC: Final = '/pendulum_sim/reset'
"""Topic of the reset events (``std_msgs/msg/String``, data = why), written in write order by
:meth:`McapRecorder.write_reset`; :func:`~pendulum_sim.recording.load` splits the run there."""
RESET_TYPE: Final = 'std_msgs/msg/String'
STOPPED_TOPIC: Final = '/pendulum_sim/recording_stopped'
"""Topic of the event that ends a recording cut short (``std_msgs/msg/String``, data = why; its
log time is the stamp of the first message left out, the message it stopped at), written by
:class:`~pendulum_sim.recording.writer.McapRecorder` when its writer process falls too far
behind, or by the writer process itself when its input ends without ``CLOSE`` (log time: the
last stamp it received); :func:`~pendulum_sim.recording.load` then reports the file
incomplete."""
STOPPED_TYPE: Final = 'std_msgs/msg/String'
