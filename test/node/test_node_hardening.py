"""Adversarial inputs to the running node, from another process over real DDS.

Each test reproduces one way the node used to crash, publish inf or stall, and asserts the
reasoned rejection or the bounded behaviour that replaced it.
"""
from __future__ import annotations

import math
import signal
from pathlib import Path

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from node_harness import NodeProcess, Probe, all_finite, diagnostics_of, ready_to_answer
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from pendulum_sim.joint.parameters import SPECS, check

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def finite_states(states: list[JointState]) -> bool:
    return all(all_finite([*m.position, *m.velocity, *m.effort]) for m in states)


def test_overflowing_states_are_refused_with_the_reason() -> None:
    """dphi0 = 1e200 then ~/reset, and n = 10 with dphi0 = 1e100, used to raise OverflowError."""
    with NodeProcess('default') as node, Probe() as probe:
        states = probe.subscribe(JointState, f'{node.namespace}/joint_states')
        energy = probe.subscribe(Float64, f'{node.namespace}/energy')
        probe.spin_until(lambda: len(states) >= 5, 20.0, 'joint_states')
        r = probe.set_parameters(node.fqn, {'dphi0': 1e200})
        assert not r[0].successful
        assert r[0].reason == ('dphi0 must be within +-10000 rad/s (the state bound that keeps '
                               'energy and damping finite), got 1e+200')
        r = probe.set_parameters(node.fqn, {'dphi0': 1e100})
        assert not r[0].successful and r[0].reason.endswith('got 1e+100')
        # The fastest start allowed, with the strongest damping law: it runs, finite.
        assert all(x.successful for x in probe.set_parameters(node.fqn, {'dphi0': 1e4}))
        assert all(x.successful for x in probe.set_parameters(node.fqn, {'n': 10.0}))
        reset = probe.call(Trigger, f'{node.fqn}/reset', Trigger.Request())
        assert reset.success
        n0 = len(states)
        probe.spin_until(lambda: len(states) >= n0 + 50, 20.0, 'joint_states after the reset')
        assert finite_states(states.msgs) and all_finite(m.data for m in energy.msgs)
        assert node.stop(signal.SIGINT) == 0
        out = node.output()
    assert 'Traceback' not in out and 'OverflowError' not in out


def test_a_resolution_finer_than_doubles_runs() -> None:
    """sensor.resolution = 1e-320 (inside the declared range) used to overflow in rounding."""
    with NodeProcess('default') as node, Probe() as probe:
        states = probe.subscribe(JointState, f'{node.namespace}/joint_states')
        probe.spin_until(lambda: len(states) >= 5, 20.0, 'joint_states')
        assert probe.set_parameters(node.fqn, {'sensor.resolution': 1e-320})[0].successful
        n0 = len(states)
        probe.spin_until(lambda: len(states) >= n0 + 50, 20.0, 'joint_states')
        assert finite_states(states.msgs)
        assert node.stop(signal.SIGINT) == 0


@pytest.mark.parametrize('params', [
    {'real_time_factor': 10000.0},
    {'h': 1.0e-6},
    {'n': 0.001, 'gamma': 100.0},
])
def test_bounded_work_per_wake_keeps_the_node_responsive(params: dict[str, float]) -> None:
    """More work than the wall clock allows: publication, parameters and services go on, the
    schedule slips (counted) and the achieved factor is reported."""
    with NodeProcess('default', params) as node, Probe() as probe:
        states = probe.subscribe(JointState, f'{node.namespace}/joint_states')
        diags = probe.subscribe(DiagnosticArray, '/diagnostics')
        probe.spin_until(lambda: len(states) >= 100, 30.0, '100 joint_states')
        # Parameters and services are served meanwhile.
        assert probe.get_parameters(node.fqn, ['gamma'])['gamma'] == params.get('gamma', 0.1)
        assert probe.call(Trigger, f'{node.fqn}/reset', Trigger.Request()).success
        n0 = len(states)
        probe.spin_until(lambda: len(states) >= n0 + 100, 30.0, '100 more joint_states')
        probe.spin_until(lambda: len(diagnostics_of(diags.msgs, node.fqn)) >= 2, 20.0,
                         'diagnostics')
        report = diagnostics_of(diags.msgs, node.fqn)[-1]
        assert math.isfinite(float(report['real_time_factor_achieved']))
        assert node.stop(signal.SIGINT) == 0
        out = node.output()
    assert finite_states(states.msgs)
    if 'real_time_factor' in params or 'h' in params:
        # 1e4 simulated seconds per second, or a million steps per second of wall time, do not
        # fit in one core here: the node says so and slips instead of freezing.
        assert int(report['schedule_slips']) > 0
        assert 'cannot keep real_time_factor' in out


def test_a_short_command_timeout_is_one_step_not_for_ever() -> None:
    """command_timeout = 0.0004 s at h = 1 ms used to round to 0 steps: hold for ever."""
    with NodeProcess('default', {'command_timeout': 0.0004}) as node, Probe() as probe:
        ns = node.namespace
        diags = probe.subscribe(DiagnosticArray, '/diagnostics')
        cmd = probe.node.create_publisher(Float64, f'{ns}/effort_command', 10)
        probe.spin_until(lambda: cmd.get_subscription_count() >= 1, 20.0, 'effort_command')

        def report() -> dict[str, str]:
            found = diagnostics_of(diags.msgs, node.fqn)
            return found[-1] if found else {}

        for _ in range(100):   # best effort: send until one arrives
            cmd.publish(Float64(data=1.0))
            try:
                probe.spin_until(lambda: report().get('command_timeouts', '0') != '0', 1.5)
                break
            except AssertionError:
                continue
        assert report()['command_timeouts'] != '0'
        assert float(report()['torque']) == 0.0
        assert node.stop(signal.SIGINT) == 0


def test_a_hundred_concurrent_resets_are_all_answered() -> None:
    with NodeProcess('default') as node, Probe() as probe:
        # One client that keeps all 100 requests (a client's own default queue keeps 10).
        deep = QoSProfile(depth=100, history=HistoryPolicy.KEEP_LAST,
                          reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)
        client = probe.node.create_client(Trigger, f'{node.fqn}/reset', qos_profile=deep)
        probe.spin_until(client.service_is_ready, 20.0, '~/reset')
        ready_to_answer(probe.node, probe.executor, node.fqn)
        futures = [client.call_async(Trigger.Request()) for _ in range(100)]
        probe.spin_until(lambda: all(f.done() for f in futures), 60.0, '100 answers')
        assert all(f.result().success for f in futures)
        assert node.stop(signal.SIGINT) == 0


def test_a_joint_name_with_a_nul_arrives_cut_at_the_nul(tmp_path: Path) -> None:
    # What the parameter reference says: rcl passes C strings, so the node only ever sees the
    # name up to the NUL (and so cannot refuse it); without rclpy the NUL is refused.
    params = tmp_path / 'nul.yaml'
    params.write_text('/**:\n  ros__parameters:\n    joint_name: "pend\\0x"\n')
    with NodeProcess('default', params_file=params) as node, Probe() as probe:
        states = probe.subscribe(JointState, f'{node.namespace}/joint_states')
        probe.spin_until(lambda: len(states) >= 1, 30.0, 'a state')
        assert list(states.msgs[0].name) == ['pend']
        assert node.stop(signal.SIGINT) == 0
    assert check({**{s.name: s.default for s in SPECS}, 'joint_name': 'pend\x00x'}) == (
        "joint_name must hold no control characters (a URDF or a log would not show them), "
        "got 'pend\\x00x' with '\\x00'")
