"""The QoS profiles of the node's topics and services, and why each is what it is."""
from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy


def profile(depth: int, reliable: bool = True, latched: bool = False,
            keep_all: bool = False) -> QoSProfile:
    """Return a profile: keep-last ``depth`` (or keep-all), reliable or best effort, volatile
    or latched."""
    return QoSProfile(depth=depth,
                      history=HistoryPolicy.KEEP_ALL if keep_all else HistoryPolicy.KEEP_LAST,
                      reliability=ReliabilityPolicy.RELIABLE if reliable
                      else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if latched
                      else DurabilityPolicy.VOLATILE)


# Reliable, volatile, depth 10: the default profile, which matches both reliable and best-effort
# subscriptions (robot_state_publisher, RViz, Foxglove, plain rclpy defaults).
JOINT_STATE_QOS = profile(10)
# Commands in real time and free lockstep: a best-effort subscription matches reliable and
# best-effort publishers alike (forward_command_controller publishes reliable; many
# teleoperation tools best effort).
COMMAND_QOS = profile(10, reliable=False)
# Synchronous mode: every command answers a state, so none may be lost.
SYNC_COMMAND_QOS = profile(100)
# ~/step_periods: every request counts, however many arrive at once (keep-last 100 lost the
# rest of a burst).
STEP_QOS = profile(1000, keep_all=True)
# Late joiners (RViz, Foxglove) must still get the URDF: transient local, as
# robot_state_publisher publishes robot_description (ros/robot_state_publisher, README.md).
LATCHED_QOS = profile(1, latched=True)
# Services keep many requests: a burst of 100 concurrent ~/reset calls is answered in full
# (the rmw default depth of 10 drops the rest).
SERVICE_QOS = profile(1000)
