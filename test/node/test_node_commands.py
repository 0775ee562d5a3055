"""ros2_control conventions from another process: effort, velocity and position commands on
``effort_command``, ``joint_commands`` (topic_based_ros2_control) and ``commands``
(forward_command_controller), bad commands, and QoS matching both ways.

The expected servo response is computed here from the documented servo law with the core's
``Stepper`` (position: τ = kp (x − φ) − kd φ', velocity: τ = kv (v − φ'), saturated at
max_effort), not with the node's own joint class.
"""
from __future__ import annotations

import math
import signal
from pathlib import Path
from typing import Any

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from mcap_ros2.reader import read_ros2_messages
from node_harness import NodeProcess, Probe, diagnostics_of, stamp_ns
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray

from pendulum_sim.core import PendulumParams, Stepper

pytestmark = [pytest.mark.ros, pytest.mark.slow]

BEST_EFFORT = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                         reliability=ReliabilityPolicy.BEST_EFFORT,
                         durability=DurabilityPolicy.VOLATILE)
RELIABLE = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)
JOINT = 'pendulum_joint'
MAX_EFFORT = 5.0


def joint_command(**fields: list[float]) -> JointState:
    msg = JointState(name=[JOINT])
    for key, value in fields.items():
        setattr(msg, key, value)
    return msg


def servo_run(params: PendulumParams, law: Any, h: float, steps: int) -> list[tuple[float, float]]:
    """Return (φ, φ') after each step of the core's closed loop from rest at the bottom."""
    st = Stepper(params, 0.0, 0.0, h)
    out = []
    for _ in range(steps):
        st.step(min(max(law(st.phi, st.dphi), -MAX_EFFORT), MAX_EFFORT))
        out.append((st.phi, st.dphi))
    return out


def assert_follows_the_servo_law(states: list[JointState], params: PendulumParams,
                                 law: Any) -> int:
    """Assert the states after the command equal the core's closed loop; return its index."""
    first = next(i for i, m in enumerate(states) if m.effort[0] != 0.0)
    # lockstep scene: one state per step of 1 ms, so the torque began in the step that ended
    # at the first state with effort, from rest at the bottom.
    t0 = stamp_ns(states[first]) - 1_000_000
    after = states[first:]
    ks = [(stamp_ns(m) - t0) // 1_000_000 for m in after]
    ref = servo_run(params, law, 1e-3, ks[-1])
    worst = max(max(abs(m.position[0] - ref[k - 1][0]), abs(m.velocity[0] - ref[k - 1][1]))
                for m, k in zip(after, ks, strict=True))
    assert worst < 1e-9
    return first


def run_servo(tmp: Path, interface: str, target: float,
              extra: dict[str, Any]) -> list[JointState]:
    """Step ``interface`` to ``target`` from rest in free lockstep; return every state.

    Free lockstep publishes faster than a subscriber keeps up with, so the states are read
    back from the recording (every one of them) with the independent reader.
    """
    path = tmp / f'{interface}.mcap'
    params = {'command_interface': interface, 'effort_input': False,
              'joint_commands_input': True, 'phi0': 0.0, 'gamma': 0.1,
              'max_effort': MAX_EFFORT, 'command_timeout': 0.0, 'recording.path': str(path),
              **extra}
    with NodeProcess('lockstep', params) as node, Probe() as probe:
        states = probe.subscribe(JointState, f'{node.namespace}/joint_states')
        pub = probe.node.create_publisher(JointState, f'{node.namespace}/joint_commands',
                                          RELIABLE)
        probe.spin_until(lambda: len(states) >= 1 and pub.get_subscription_count() >= 1, 30.0,
                         'joint_states and the joint_commands subscription')
        pub.publish(joint_command(**{interface: [target]}))
        probe.spin_until(lambda: any(m.effort[0] != 0.0 for m in states.msgs), 20.0,
                         'the command applied')
        start = next(stamp_ns(m) for m in states.msgs if m.effort[0] != 0.0)
        probe.spin_until(lambda: stamp_ns(states.msgs[-1]) - start > 8e9, 60.0,
                         '8 s of simulated time after the command')
        assert node.stop(signal.SIGINT) == 0
    return [m.ros_msg for m in read_ros2_messages(str(path))
            if m.channel.topic.endswith('/joint_states')]


def cascaded_servo(x: float, body: PendulumParams, kpos: float, kv: float, ki: float,
                   h: float = 1e-3) -> Any:
    """Return the documented drive law as a function of (φ, φ'), called once a step.

    Speed demand ``kpos (x − φ)``, velocity PI with gravity feed-forward, torque saturated at
    MAX_EFFORT and the integral frozen while saturation is pushed further (written out here,
    independently of the node's code).
    """
    z = [0.0]

    def law(p: float, v: float) -> float:
        e = kpos * (x - p) - v
        u = body.mgl * math.sin(p) + kv * e + ki * z[0]
        tau = min(max(u, -MAX_EFFORT), MAX_EFFORT)
        if u == tau or e * (u - tau) < 0.0:
            z[0] += h * e
        return u
    return law


def test_position_step_is_reached_under_gravity(tmp_path: Path) -> None:
    kpos, kv, ki, x = 8.0, 4.0, 20.0, 1.5
    body = PendulumParams(m=0.2, l=1.0, inertia=0.2, g=9.8, gamma=0.1, n=1.0)
    states = run_servo(tmp_path, 'position', x, {'servo.position_p': kpos,
                                                 'servo.velocity_p': kv,
                                                 'servo.velocity_i': ki})
    first = next(i for i, m in enumerate(states) if m.effort[0] != 0.0)
    # kv kpos x = 48 N m asks for more than max_effort: saturation is visible in effort.
    assert states[first].effort[0] == MAX_EFFORT
    last = states[-1]
    # The drive reaches the commanded angle itself (gravity fed forward, the integral holds
    # the rest), not a balance of a spring against gravity.
    assert abs(last.position[0] - x) < 1e-6
    assert abs(last.velocity[0]) < 1e-6
    assert abs(last.effort[0] - body.mgl * math.sin(x)) < 1e-4
    # The whole response is the servo law's, computed independently with the core.
    assert_follows_the_servo_law(states, body, cascaded_servo(x, body, kpos, kv, ki))


def test_velocity_step_and_velocity_limit(tmp_path: Path) -> None:
    kv = 2.0
    states = run_servo(tmp_path, 'velocity', 200.0, {'servo.velocity_p': kv, 'g': 0.0,
                                                     'servo.velocity_i': 0.0, 'gamma': 0.0,
                                                     'max_velocity': 3.0})
    # 200 rad/s is limited to max_velocity; without gravity or damping φ' → 3 exactly.
    assert abs(states[-1].velocity[0] - 3.0) < 1e-9
    assert max(m.velocity[0] for m in states) <= 3.0 + 1e-9
    first = next(i for i, m in enumerate(states) if m.effort[0] != 0.0)
    assert states[first].effort[0] == MAX_EFFORT   # kv * 3 = 6 N m saturated
    body = PendulumParams(m=0.2, l=1.0, inertia=0.2, g=0.0, gamma=0.0, n=1.0)
    assert_follows_the_servo_law(states, body, lambda p, v: kv * (3.0 - v))


def test_array_commands_bad_commands_and_qos_both_ways() -> None:
    params = {'array_command_input': True, 'joint_commands_input': True,
              'command_timeout': 0.0, 'max_effort': MAX_EFFORT}
    with NodeProcess('default', params) as node, Probe() as probe:
        ns = node.namespace
        states = probe.subscribe(JointState, f'{ns}/joint_states')
        diags = probe.subscribe(DiagnosticArray, '/diagnostics')
        array = probe.node.create_publisher(Float64MultiArray, f'{ns}/commands', RELIABLE)
        joint = probe.node.create_publisher(JointState, f'{ns}/joint_commands', BEST_EFFORT)
        effort_be = probe.node.create_publisher(Float64, f'{ns}/effort_command', BEST_EFFORT)
        effort_rel = probe.node.create_publisher(Float64, f'{ns}/effort_command', RELIABLE)
        pubs = (array, joint, effort_be, effort_rel)
        probe.spin_until(lambda: all(p.get_subscription_count() >= 1 for p in pubs), 30.0,
                         'every command publisher matched')

        def send_until_applied(pub: Any, msg: Any, value: float) -> None:
            # A best-effort subscription may miss what arrives before it knows the writer, as
            # a controller publishing every period would not notice: send until applied.
            for _ in range(100):
                pub.publish(msg)
                try:
                    probe.spin_until(lambda: bool(states.msgs) and
                                     states.msgs[-1].effort[0] == value, 0.2)
                    return
                except AssertionError:
                    continue
            raise AssertionError(f'effort {value} never applied')

        # forward_command_controller's convention, then a best-effort and a reliable
        # publisher on effort_command, then topic_based_ros2_control's JointState.
        send_until_applied(array, Float64MultiArray(data=[1.25]), 1.25)
        send_until_applied(effort_be, Float64(data=-0.5), -0.5)
        send_until_applied(effort_rel, Float64(data=0.75), 0.75)
        send_until_applied(joint, joint_command(effort=[2.0]), 2.0)
        # Bad commands: dropped, counted per reason, never applied.
        array.publish(Float64MultiArray(data=[1.0, 2.0]))
        joint.publish(JointState(name=['other_joint'], effort=[3.0]))
        joint.publish(joint_command(position=[0.1]))
        joint.publish(joint_command(effort=[math.nan]))
        array.publish(Float64MultiArray(data=[math.inf]))
        n = len(diags)

        def dropped() -> dict[str, str]:
            found = diagnostics_of(diags.msgs[n:], node.fqn)
            return found[-1] if found else {}

        probe.spin_until(lambda: dropped().get('commands_rejected_nonfinite') == '2', 20.0,
                         'the bad commands counted')
        report = dropped()
        # One key per topic and reason, whatever the message held (the details are logged).
        assert report[f'commands_dropped[{ns}/commands: expected 1 value (one joint)]'] == '1'
        assert report[f"commands_dropped[{ns}/joint_commands: no joint named "
                      f"'{JOINT}']"] == '1'
        assert report[f"commands_dropped[{ns}/joint_commands: no effort for joint "
                      f"'{JOINT}']"] == '1'
        assert states.msgs[-1].effort[0] == 2.0
        assert node.stop(signal.SIGINT) == 0
        out = node.output()
    assert out.count(f'dropped a command on {ns}/commands: expected 1 value (one joint), '
                     'got 2 (1 so far)') == 1
    assert (f"dropped a command on {ns}/joint_commands: no joint named '{JOINT}', names "
            "['other_joint'] (1 so far)") in out
    assert 'Traceback' not in out


def test_synchronous_mode_says_when_a_best_effort_publisher_cannot_connect() -> None:
    with NodeProcess('controller_test') as node, Probe() as probe:
        probe.node.create_publisher(Float64, f'{node.namespace}/effort_command', BEST_EFFORT)
        topic = f'{node.namespace}/effort_command'
        probe.spin_until(lambda: f'a publisher on {topic} cannot connect' in node.output(),
                         30.0, 'the incompatible-QoS warning')
        assert node.stop(signal.SIGINT) == 0
        assert (f'a publisher on {topic} cannot connect: its QoS is incompatible '
                '(RELIABILITY); publish reliable (synchronous mode loses no command) '
                '(1 so far)') in node.output()


def test_servo_gains_beyond_the_sampled_loops_limit_are_refused_live_and_at_start() -> None:
    """position_p 1e6 (in its range) used to be taken and run the joint away to ~1e3 rad."""
    import re

    from servo_matrix import eigen_limit

    from pendulum_sim.joint.servo import ServoGains
    params = {'command_interface': 'position', 'joint_commands_input': True,
              'status_line': False}
    inertia = 0.2   # the default body's inertia in config/default.yaml ...
    with NodeProcess('default', params) as node, Probe() as probe:
        inertia = float(probe.get_parameters(node.fqn, ['inertia'])['inertia'])   # ... as run
        limit = eigen_limit(ServoGains(), inertia, 1e-3)
        reason = (f'servo.position_p 1e+06 1/s makes the position servo unstable at h = 0.001 s '
                  f'(its loop is sampled every step, inertia {inertia:g} kg m^2): it must be '
                  f'below {limit:.6g} 1/s with the other gains as set')
        [result] = probe.set_parameters(node.fqn, {'servo.position_p': 1e6})
        assert (result.successful, result.reason) == (False, reason)
        assert probe.get_parameters(node.fqn, ['servo.position_p']) == {'servo.position_p': 8.0}
        [result] = probe.set_parameters(node.fqn, {'servo.position_p': 0.9 * limit})
        assert result.successful, result.reason
        assert node.stop(signal.SIGINT, timeout=2.0) == 0
    with NodeProcess('default', {**params, 'servo.position_p': 1e6}) as node:
        assert node.wait(30.0) == 2
        assert re.search(re.escape(reason), node.output()), node.output()
