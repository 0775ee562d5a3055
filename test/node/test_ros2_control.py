"""The node under a controller manager: a faithful stand-in for TopicBasedSystem behind
forward_command_controller (``topic_based_stand_in.py``), over real DDS, the node in its own
process, the hardware read from the node's own robot_description.

Effort, velocity and position interfaces in real time; position in synchronous lockstep with the
manager on sim time, driven by /clock as ros2_control_node is: each update reads the state of
its period and its command answers that period, and the run equals the ROS-free joint stepped
with the same commands, bit for bit, twice.
"""
from __future__ import annotations

import re
import signal
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from mcap_ros2.reader import read_ros2_messages
from node_harness import NodeProcess, Probe
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64MultiArray, String
from std_srvs.srv import SetBool
from topic_based_stand_in import ControlManager, Hardware

from pendulum_sim.joint.joint import SimulatedJoint
from pendulum_sim.joint.parameters import SPECS, joint_config
from pendulum_sim.joint.scenes import find_scene, read_params_file

pytestmark = pytest.mark.ros

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
RATE = 100.0      # the controller manager's update_rate, Hz


def robot_description(node: NodeProcess) -> str:
    """Return the URDF the node publishes (transient local), as a controller manager gets it."""
    with Probe() as probe:
        got = probe.subscribe(String, f'{node.namespace}/robot_description', LATCHED)
        probe.spin_until(lambda: len(got) >= 1 or not node.alive(), 30.0, 'robot_description')
        assert node.alive(), node.output()
        return str(got.msgs[0].data)


def manager(node: NodeProcess, *, use_sim_time: bool) -> ControlManager:
    """Return a controller manager whose hardware is the node's robot_description."""
    hw = Hardware.from_urdf(robot_description(node))
    # The URDF names the node's own topics, not joint_state_broadcaster's /joint_states.
    assert (hw.states_topic, hw.commands_topic) == (f'{node.namespace}/joint_states',
                                                    f'{node.namespace}/joint_commands')
    assert hw.threshold == -1.0
    return ControlManager(hw, RATE, use_sim_time, controller=f'fwd_{uuid.uuid4().hex[:8]}')


def forward(cm: ControlManager, value: float, probe: Probe) -> None:
    """Publish ``value`` to the forward controller's ~/commands and wait until it has it."""
    pub = probe.node.create_publisher(Float64MultiArray, f'/{cm.controller}/commands', 10)
    probe.spin_until(lambda: pub.get_subscription_count() >= 1, 20.0, 'the controller')
    before = cm.received_commands
    pub.publish(Float64MultiArray(data=[value]))
    cm.spin_until(lambda: cm.received_commands > before, 20.0, 'the forward command')
    probe.node.destroy_publisher(pub)


class Tracker:
    """The state the plugin read at each update (its latest joint_states message)."""

    def __init__(self, cm: ControlManager) -> None:
        self.cm = cm
        self.seen: list[tuple[int, float, float, float]] = []

    def __call__(self) -> None:
        msg = self.cm.latest
        if msg is None:
            return
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        if not self.seen or self.seen[-1][0] != stamp:
            self.seen.append((stamp, msg.position[0], msg.velocity[0], msg.effort[0]))

    def settled(self, field: int, target: float, band: float, count: int) -> bool:
        """Return True when the last ``count`` states are within ``band`` of ``target``."""
        last = self.seen[-count:]
        return len(last) == count and all(abs(s[field] - target) <= band for s in last)


def run_until(cm: ControlManager, tracker: Tracker, done: Any, timeout: float = 60.0) -> None:
    def until() -> bool:
        tracker()
        return bool(done())
    cm.run(until, timeout)


# ---------------------------------------------------------------------- real time
@contextmanager
def real_time(params: dict[str, Any]) -> Iterator[tuple[ControlManager, Probe, Tracker]]:
    """Run the default scene with ``params`` under a manager on wall time; yield the manager,
    a probe and a tracker of the manager's states. The node must be alive at the end."""
    with NodeProcess('default', params) as node:
        with manager(node, use_sim_time=False) as cm, Probe() as probe:
            yield cm, probe, Tracker(cm)
            assert node.alive(), node.output()


def test_effort_interface() -> None:
    with real_time({'joint_commands_input': True}) as (cm, probe, tracker):
        # Before any controller command, the plugin sends the URDF's initial effort, 0.
        run_until(cm, tracker, lambda: len(tracker.seen) >= 20)
        assert cm.hardware.initial['effort'] == cm.commands['effort'] == 0.0
        assert {u.sent_value for u in cm.log} == {0.0}
        forward(cm, 0.7, probe)
        # The node reports the torque it applies: exactly the command (below max_effort).
        run_until(cm, tracker, lambda: tracker.settled(3, 0.7, 0.0, 20))


def test_velocity_interface_starts_and_tracks() -> None:
    """`-p command_interface:=velocity -p joint_commands_input:=true` on the default scene."""
    params = {'command_interface': 'velocity', 'joint_commands_input': True}
    with real_time(params) as (cm, probe, tracker):
        assert cm.hardware.command_interface == 'velocity'
        forward(cm, 1.0, probe)
        # 1 rad/s held within 1 % under gravity, for a whole second of states.
        run_until(cm, tracker, lambda: tracker.settled(2, 1.0, 0.01, 100))


def test_position_interface_holds_the_initial_state_then_tracks() -> None:
    params = {'command_interface': 'position', 'joint_commands_input': True}
    with real_time(params) as (cm, probe, tracker):
        # initial_value of the position state interface is φ0: the plugin commands 0.3
        # before any controller does, and the joint stays there (it does not fall to 0).
        assert cm.hardware.initial['position'] == 0.3
        run_until(cm, tracker, lambda: len(tracker.seen) >= 100)
        assert all(abs(s[1] - 0.3) <= 1e-3 for s in tracker.seen), tracker.seen[-1]
        forward(cm, 1.0, probe)
        run_until(cm, tracker, lambda: tracker.settled(1, 1.0, 1e-3, 100))


# ---------------------------------------------------------------------- synchronous
SYNC = {'lockstep': True, 'synchronous': True, 'publish_rate': RATE, 'real_time_factor': 0.0,
        'start_time': 1.0, 'command_interface': 'position', 'joint_commands_input': True,
        'sync_timeout': 10.0, 'status_line': False, 'start_paused': True}
T0 = 1_000_000_000              # start_time: the node's first state and /clock
SWITCH_NS = 1_500_000_000       # after the update at t = 1.5 s the command changes
END_NS = 2_000_000_000
COMMANDS = (1.0, -0.5)


def synchronous_run(tmp: Path, name: str) -> tuple[list[tuple[int, float, float, float]],
                                                    ControlManager, str]:
    """Run the loop from t = 1 s to 2 s; return the node's recorded states, the manager, log."""
    path = tmp / f'{name}.mcap'
    with NodeProcess('default', {**SYNC, 'recording.path': str(path)}) as node:
        with manager(node, use_sim_time=True) as cm, Probe() as probe:
            forward(cm, COMMANDS[0], probe)

            def until() -> bool:
                if len(cm.log) == 1:
                    # The documented start: the node waits paused until the manager runs
                    # (its first pass, at manager time 0, is done), then goes on.
                    reply = probe.call(SetBool, f'{node.fqn}/pause', SetBool.Request(data=False))
                    assert reply.success, reply.message
                sent = cm.log[-1].sent_stamp_ns
                if sent == SWITCH_NS:
                    forward(cm, COMMANDS[1], probe)
                return sent is not None and sent >= END_NS
            cm.run(until, 120.0)
        assert node.stop(signal.SIGINT) == 0
        log = node.output()
    states = [(m.ros_msg.header.stamp.sec * 1_000_000_000 + m.ros_msg.header.stamp.nanosec,
               m.ros_msg.position[0], m.ros_msg.velocity[0], m.ros_msg.effort[0])
              for m in read_ros2_messages(str(path)) if m.channel.topic.endswith('/joint_states')]
    return states, cm, log


def offline(count: int) -> list[tuple[int, float, float, float]]:
    """Return the ROS-free joint's states under the same commands, one per control period."""
    values: dict[str, Any] = {s.name: s.default for s in SPECS}
    values.update(read_params_file(find_scene('default')))
    values.update(SYNC)
    joint = SimulatedJoint(joint_config(values, T0))
    k = joint.config.period_steps
    out = []
    for _ in range(count):
        sample = joint.sample()
        assert sample is not None
        out.append(tuple(sample))
        joint.command(COMMANDS[0] if joint.stamp_ns() <= SWITCH_NS else COMMANDS[1])
        joint.advance(k)
    return out  # type: ignore[return-value]


def test_synchronous_on_sim_time_reads_its_period_and_reproduces(tmp_path: Path) -> None:
    runs = [synchronous_run(tmp_path, name) for name in ('a', 'b')]
    for states, cm, log in runs:
        period = round(1e9 / RATE)
        # ros2_control_node's first pass runs at manager time 0, before any /clock, while the
        # node is paused: it reads no state, and its command, stamped 0, answers none.
        early = cm.log[0]
        assert (early.now_ns, early.state_stamp_ns, early.sent_stamp_ns) == (0, None, 0)
        updates = cm.log[1:]
        # Then one pass per period from the node's first state (t = start_time): each woken
        # by its period's /clock, read the state of that period, sent a command stamped with
        # it. (The plugin's best-effort subscription may miss the very first state; the node
        # publishes it again with its /clock until answered.)
        assert [u.sent_stamp_ns for u in updates] == list(range(T0, END_NS + 1, period))
        assert all(u.now_ns == u.sent_stamp_ns for u in updates)
        assert updates[0].state_stamp_ns in (None, T0)
        assert all(u.state_stamp_ns == u.sent_stamp_ns for u in updates[1:])
        # The node took every answer: no timeout, nothing late, no duplicate.
        found = re.search(r'sync answered / timeouts / late / duplicates\W+(\d+) / (\d+) / '
                          r'(\d+) / (\d+)', log)
        assert found is not None, log
        answered, timeouts, late, duplicates = map(int, found.groups())
        assert (timeouts, late, duplicates) == (0, 0, 0), found.group(0)
        assert answered >= len(updates)
        # What the node published is the ROS-free joint under the same commands, exactly.
        assert states[:len(updates)] == offline(len(updates))
    assert runs[0][0] == runs[1][0]
    # The commands made a difference: the joint went towards 1.0, then back towards -0.5.
    positions = [s[1] for s in runs[0][0]]
    assert max(positions) > 0.9 and positions[-1] < max(positions) - 0.3
