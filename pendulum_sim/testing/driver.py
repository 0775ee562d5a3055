"""Step a paused synchronous ``pendulum_node`` N control periods; exit when the last state is out.

Run by :mod:`pendulum_sim.testing.ros` in a process of its own (rclpy stays out of the caller)::

    python -m pendulum_sim.testing.driver NAMESPACE PERIODS LAST_STAMP_NS

It publishes ``PERIODS`` on ``NAMESPACE/pendulum_node/step_periods`` once the node subscribes,
then waits for the ``joint_states`` message stamped ``LAST_STAMP_NS``: the node publishes it
only after taking the answer to the state before it, so every answer of the run is recorded.
Exit 0 then; 2 for bad arguments. The caller ends it when the run takes too long.
"""
from __future__ import annotations

import os
import sys


def main(argv: list[str] | None = None) -> int:
    """Step the node and wait for the last state; return the exit code."""
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) != 3:
        print('usage: python -m pendulum_sim.testing.driver NAMESPACE PERIODS LAST_STAMP_NS',
              file=sys.stderr)
        return 2
    namespace, periods, last = args[0], int(args[1]), int(args[2])
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    from std_msgs.msg import UInt32

    from pendulum_sim.dds import shut_down, use_loopback_profile

    use_loopback_profile(os.environ)
    reliable = QoSProfile(depth=100, history=HistoryPolicy.KEEP_LAST,
                          reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)
    rclpy.init(args=[])
    node = rclpy.create_node('closed_loop_driver', namespace=namespace)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    seen: list[int] = []

    def on_state(msg: JointState) -> None:
        seen.append(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)

    node.create_subscription(JointState, 'joint_states', on_state, reliable)
    step = node.create_publisher(UInt32, 'pendulum_node/step_periods', reliable)
    try:
        while step.get_subscription_count() < 1:
            executor.spin_once(timeout_sec=0.01)
        step.publish(UInt32(data=periods))
        while not seen or seen[-1] < last:
            executor.spin_once(timeout_sec=0.05)
    finally:
        executor.shutdown()
        shut_down(node, 0)
    return 0


if __name__ == '__main__':
    sys.exit(main())
