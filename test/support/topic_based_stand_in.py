"""A stand-in for ros2_control_node + TopicBasedSystem + forward_command_controller, in rclpy.

Message for message as their sources do it (PickNikRobotics/topic_based_ros2_control
``src/topic_based_system.cpp`` and ``include/topic_based_ros2_control/topic_based_system.hpp``;
ros-controls/ros2_control ``controller_manager/src/ros2_control_node.cpp``;
ros-controls/ros2_controllers ``forward_command_controller``):

- the hardware is read from the URDF's ``<ros2_control>`` block: ``joint_commands_topic``,
  ``joint_states_topic``, ``trigger_joint_command_threshold`` (default 1e-5), the joint's
  command interface, and ``initial_value`` of its state interfaces, which ``on_init`` copies into
  the commands of the same name (other commands and every state start at 0.0);
- the plugin's own node is ``topic_based_ros2_control_<name>``; its command publisher has
  ``rclcpp::QoS(1)`` (keep last 1, reliable, volatile), its state subscription
  ``rclcpp::SensorDataQoS()`` (best effort, keep last 5, volatile) and keeps the latest message;
- ``read()``: ``spin_some`` of the plugin's node, then the latest state's position, velocity and
  effort (when present) of the joint by name into the state interfaces;
- ``write()``: if ``Σ |state.position − command.position| <= threshold`` nothing is sent;
  otherwise a JointState with the joint's name, ``header.stamp = node.now()`` (the plugin's
  node: sim time when ``use_sim_time`` is given to the whole process) and the value of the
  joint's command interface in the field of that name;
- forward_command_controller: ``~/commands`` (std_msgs/Float64MultiArray, system default QoS);
  ``update()`` copies the latest message into the command interface, nothing before the first;
- the loop of ros2_control_node: ``current = now(); read; update; write``, then on sim time
  ``sleep_until(current + period)`` on the manager's clock (woken by /clock), else until the
  next wall-clock period.

Each update is logged (manager time, stamp of the state read, stamp and value sent).
"""
from __future__ import annotations

import time
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, qos_profile_sensor_data
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

INTERFACES = ('position', 'velocity', 'effort')
COMMAND_QOS = QoSProfile(depth=1)       # rclcpp::QoS(1): keep last 1, reliable, volatile
DEFAULT_THRESHOLD = 1e-5


@dataclass
class Hardware:
    """What TopicBasedSystem reads from the URDF."""

    name: str
    joint: str
    command_interface: str
    commands_topic: str
    states_topic: str
    threshold: float
    initial: dict[str, float]

    @classmethod
    def from_urdf(cls, urdf: str) -> Hardware:
        """Read the single-joint ``<ros2_control>`` block of ``urdf``."""
        block = ET.fromstring(urdf).find('ros2_control')
        assert block is not None
        params = {p.get('name'): p.text or '' for p in block.findall('hardware/param')}
        joint = block.find('joint')
        assert joint is not None
        (command,) = joint.findall('command_interface')
        initial = {}
        for state in joint.findall('state_interface'):
            for p in state.findall('param'):
                if p.get('name') == 'initial_value':
                    initial[str(state.get('name'))] = float(p.text or '')
        return cls(name=str(block.get('name')), joint=str(joint.get('name')),
                   command_interface=str(command.get('name')),
                   commands_topic=params.get('joint_commands_topic', '/robot_joint_commands'),
                   states_topic=params.get('joint_states_topic', '/robot_joint_states'),
                   threshold=float(params.get('trigger_joint_command_threshold',
                                              DEFAULT_THRESHOLD)),
                   initial=initial)


@dataclass
class Update:
    """One pass of the loop: manager time, stamp of the state read, what write() sent."""

    now_ns: int
    state_stamp_ns: int | None
    sent_stamp_ns: int | None
    sent_value: float | None


@dataclass
class ControlManager:
    """The controller manager's process: manager node, controller, plugin node."""

    hardware: Hardware
    update_rate: float
    use_sim_time: bool
    controller: str = 'forward_command_controller'
    log: list[Update] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.context = Context()
        rclpy.init(context=self.context)
        overrides = [Parameter('use_sim_time', value=self.use_sim_time)]
        self.cm = Node('controller_manager', context=self.context,
                       parameter_overrides=overrides)
        self.ctl = Node(self.controller, context=self.context, parameter_overrides=overrides)
        self.plugin = Node(f'topic_based_ros2_control_{self.hardware.name}',
                           context=self.context, parameter_overrides=overrides)
        self.forward: list[float] | None = None
        self.received_commands = 0
        self.ctl.create_subscription(Float64MultiArray, '~/commands', self._on_forward, 10)
        hw = self.hardware
        self.commands = {name: hw.initial.get(name, 0.0) for name in INTERFACES}
        self.states = dict.fromkeys(INTERFACES, 0.0)
        self.latest: JointState | None = None
        self.pub = self.plugin.create_publisher(JointState, hw.commands_topic, COMMAND_QOS)
        self.plugin.create_subscription(JointState, hw.states_topic, self._on_state,
                                        qos_profile_sensor_data)
        self.cm_exec = SingleThreadedExecutor(context=self.context)
        self.cm_exec.add_node(self.cm)
        self.cm_exec.add_node(self.ctl)
        self.plugin_exec = SingleThreadedExecutor(context=self.context)
        self.plugin_exec.add_node(self.plugin)

    def _on_forward(self, msg: Float64MultiArray) -> None:
        self.forward = list(msg.data)
        self.received_commands += 1

    def _on_state(self, msg: JointState) -> None:
        self.latest = msg

    # ------------------------------------------------------------ the hardware interface
    def read(self) -> int | None:
        """spin_some the plugin's node, copy the latest state in; return its stamp (ns)."""
        for _ in range(50):
            self.plugin_exec.spin_once(timeout_sec=0.0)
        msg = self.latest
        if msg is None:
            return None
        for i, name in enumerate(msg.name):
            if name != self.hardware.joint:
                continue
            self.states['position'] = msg.position[i]
            if len(msg.velocity):
                self.states['velocity'] = msg.velocity[i]
            if len(msg.effort):
                self.states['effort'] = msg.effort[i]
        return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)

    def update(self) -> None:
        """forward_command_controller: the latest ~/commands into the command interface."""
        if self.forward is None:
            return
        assert len(self.forward) == 1, 'one joint, one value'
        self.commands[self.hardware.command_interface] = self.forward[0]

    def write(self) -> tuple[int | None, float | None]:
        """Publish the command unless the position difference is within the threshold."""
        diff = abs(self.states['position'] - self.commands['position'])
        if diff <= self.hardware.threshold:
            return None, None
        msg = JointState()
        msg.name = [self.hardware.joint]
        msg.header.stamp = self.plugin.get_clock().now().to_msg()
        value = self.commands[self.hardware.command_interface]
        setattr(msg, self.hardware.command_interface, [value])
        self.pub.publish(msg)
        return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec, value

    # ------------------------------------------------------------ ros2_control_node's loop
    def now_ns(self) -> int:
        return self.cm.get_clock().now().nanoseconds

    def spin_until(self, condition: Callable[[], bool], timeout: float, what: str) -> None:
        """Serve the manager's and the controller's callbacks until ``condition`` holds."""
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                raise AssertionError(f'timed out waiting for {what}')
            self.cm_exec.spin_once(timeout_sec=0.01)

    def run(self, until: Callable[[], bool], timeout: float) -> None:
        """Run the loop until ``until()`` holds after an update (or fail after ``timeout``)."""
        period_ns = round(1e9 / self.update_rate)
        deadline = time.monotonic() + timeout
        next_wall = time.monotonic_ns()
        while True:
            current = self.now_ns()
            stamp = self.read()
            self.update()
            sent, value = self.write()
            self.log.append(Update(current, stamp, sent, value))
            if until():
                return
            if self.use_sim_time:
                wake = current + period_ns
                while self.now_ns() < wake:
                    if time.monotonic() > deadline:
                        raise AssertionError(f'timed out at manager time {current} ns')
                    self.cm_exec.spin_once(timeout_sec=0.01)
            else:
                next_wall += period_ns
                while time.monotonic_ns() < next_wall:
                    self.cm_exec.spin_once(timeout_sec=max(
                        0.0, (next_wall - time.monotonic_ns()) / 1e9))
                if time.monotonic() > deadline:
                    raise AssertionError('timed out')

    def close(self) -> None:
        for ex in (self.cm_exec, self.plugin_exec):
            ex.shutdown()
        for node in (self.cm, self.ctl, self.plugin):
            node.destroy_node()
        rclpy.shutdown(context=self.context)

    def __enter__(self) -> ControlManager:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
