"""Synchronous lockstep across processes: the controller test is reproduced bit for bit.

The node (scene ``controller_test``) and ``pendulum_pd_controller`` run in their own processes
over real DDS; a probe steps the paused node N control periods. Each run is recorded; the
recordings are read back with the independent reader ``mcap-ros2-support``.
"""
from __future__ import annotations

import math
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from controller_probe import Controller
from diagnostic_msgs.msg import DiagnosticArray
from mcap_ros2.reader import read_ros2_messages
from node_harness import NodeProcess, Probe, stamp_ns
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import UInt32
from std_srvs.srv import SetBool, Trigger

from pendulum_sim.core import PendulumParams, simulate

pytestmark = [pytest.mark.ros, pytest.mark.slow]

RELIABLE = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)
PERIODS = 400
PERIOD_NS = 10_000_000       # controller_test: publish_rate 100 Hz
GAINS = {'kp': 4.0, 'kd': 1.0, 'target': 0.0}


def read(path: Path) -> dict[str, list[Any]]:
    """Return the recorded messages per topic, in write order, as (log time, message)."""
    out: dict[str, list[Any]] = {}
    for m in read_ros2_messages(str(path)):
        out.setdefault(m.channel.topic.rsplit('/', 1)[-1], []).append((m.log_time_ns,
                                                                       m.ros_msg))
    return out


def run_loop(tmp: Path, name: str, hog: bool) -> dict[str, list[Any]]:
    """Run node + controller for PERIODS control periods; return the recording."""
    path = tmp / f'{name}.mcap'
    hogs: list[subprocess.Popen[bytes]] = []
    if hog:   # one busy process per core beside the loop
        hogs = [subprocess.Popen([sys.executable, '-c', 'while True: pass'])
                for _ in range(2)]
    try:
        node = NodeProcess('controller_test', {'start_paused': True,
                                               'recording.path': str(path)})
        with node, Controller(GAINS, ['--count', str(PERIODS + 1)],
                              namespace=node.namespace) as ctrl, Probe() as probe:
            step = probe.node.create_publisher(UInt32, f'{node.fqn}/step_periods', RELIABLE)
            probe.spin_until(lambda: step.get_subscription_count() >= 1, 30.0, '~/step_periods')
            step.publish(UInt32(data=PERIODS))
            # The controller answers states 0..N and exits by itself.
            assert ctrl.wait(60.0) == 0, ctrl.output()
            assert node.stop(signal.SIGINT) == 0, node.output()
            assert 'synchronous: a controller is connected; stepping' in node.output()
    finally:
        for p in hogs:
            p.kill()
            p.wait()
    return read(path)


def test_synchronous_runs_are_bit_identical_and_every_state_is_answered_once(
        tmp_path: Path) -> None:
    quiet = run_loop(tmp_path, 'quiet', hog=False)
    loaded = run_loop(tmp_path, 'loaded', hog=True)
    for rec in (quiet, loaded):
        states = [m for _, m in rec['joint_states']]
        commands = rec['effort_command']
        # Paused, then stepped N periods: states 0..N, one period apart, nothing more.
        stamps = [stamp_ns(m) for m in states]
        assert stamps == [k * PERIOD_NS for k in range(PERIODS + 1)]
        # Every state is answered by exactly one command, recorded at the state's stamp; the
        # last state's answer arrived while paused (held for the next step).
        assert [t for t, _ in commands] == stamps
        # The answer to state k is the torque applied during period k (saturated at 5 N m).
        effort = np.array([m.effort[0] for m in states])
        answers = np.array([m.data for _, m in commands])
        np.testing.assert_array_equal(effort[1:], np.clip(answers[:-1], -5.0, 5.0))
    # Bit for bit: every sample of position, velocity, effort and every command.
    def samples(rec: dict[str, list[Any]]) -> tuple[list[Any], list[Any]]:
        return ([(t, stamp_ns(m), tuple(m.position), tuple(m.velocity), tuple(m.effort))
                 for t, m in rec['joint_states']],
                [(t, m.data) for t, m in rec['effort_command']])

    assert samples(quiet) == samples(loaded)
    # The loop settled: at the target, at rest.
    last = quiet['joint_states'][-1][1]
    assert abs(last.position[0]) < 1e-3 and abs(last.velocity[0]) < 1e-3


def test_paused_publishes_nothing_until_stepped_then_exactly_n_periods() -> None:
    params = {'start_paused': True, 'publish_rate': 200.0, 'diagnostics': True}
    with NodeProcess('lockstep', params) as node, Probe() as probe:
        states = probe.subscribe(JointState, f'{node.namespace}/joint_states')
        clock = probe.subscribe(Clock, '/clock')
        diags = probe.subscribe(DiagnosticArray, '/diagnostics')
        step = probe.node.create_publisher(UInt32, f'{node.fqn}/step_periods', RELIABLE)
        probe.spin_until(lambda: step.get_subscription_count() >= 1, 30.0, '~/step_periods')
        # Two diagnostics reports (a second of the node's wall clock apart) and still nothing.
        probe.spin_until(lambda: sum(1 for a in diags.msgs if a.status and
                                     a.status[0].name.startswith(node.fqn)) >= 2, 20.0,
                         'two diagnostics reports')
        assert len(states) == 0
        step.publish(UInt32(data=7))
        probe.spin_until(lambda: len(states) >= 7, 20.0, '7 joint_states')
        reply = probe.call(Trigger, f'{node.fqn}/step', Trigger.Request())
        assert reply.success and reply.message == ('stepping 1 control period(s) of 0.005 s '
                                                   'to t = 0.04 s')
        probe.spin_until(lambda: len(states) >= 8, 20.0, 'the eighth joint_states')
        n_diag = len(diags)
        probe.spin_until(lambda: len(diags) >= n_diag + 2, 20.0, 'later diagnostics')
        assert [stamp_ns(m) for m in states.msgs] == [k * 5_000_000 for k in range(1, 9)]
        ticks = [c.clock.sec * 10**9 + c.clock.nanosec for c in clock.msgs]
        assert ticks[-8:] == [k * 5_000_000 for k in range(1, 9)]
        # Not paused: ~/step says why it does nothing.
        probe.call(SetBool, f'{node.fqn}/pause', SetBool.Request(data=False))
        reply = probe.call(Trigger, f'{node.fqn}/step', Trigger.Request())
        assert not reply.success
        assert reply.message == ('not paused: ~/step advances a paused simulation '
                                 '(call ~/pause true)')
        assert node.stop(signal.SIGINT) == 0
        assert 'Traceback' not in node.output() and 'FATAL' not in node.output()


def test_sensor_delay_counts_in_steps_in_lockstep(tmp_path: Path) -> None:
    """sensor.delay 5 ms at h = 1 ms: each state is the one of exactly 5 steps before."""
    path = tmp_path / 'delay.mcap'
    params = {'sensor.delay': 0.005, 'publish_rate': 1000.0, 'recording.path': str(path),
              'phi0': 2.0}
    with NodeProcess('lockstep', params) as node, Probe() as probe:
        states = probe.subscribe(JointState, f'{node.namespace}/joint_states')
        probe.spin_until(lambda: len(states) >= 500, 30.0, '500 joint_states')
        assert node.stop(signal.SIGINT) == 0
    rec = read(path)
    pairs = [(t, stamp_ns(m), m.position[0]) for t, m in rec['joint_states']]
    # Published at simulated time t, measured at t - 5 ms (exact on the ns grid).
    assert all(t - s == 5_000_000 for t, s, _ in pairs)
    last = pairs[-1][1]
    run = simulate(PendulumParams(gamma=1.0, n=1.0), 2.0, 0.0, last / 1e9, 1e-3)
    k = np.array([s // 1_000_000 for _, s, _ in pairs])
    np.testing.assert_array_equal(run.phi[k], [p for _, _, p in pairs])
    assert math.isfinite(pairs[0][2])
