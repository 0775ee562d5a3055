"""Storms and extreme settings against the running node, from another process over real DDS.

Each test reproduces one way the node grew without bound, lost requests, logged without limit
or stopped answering, and asserts on counts and conditions: the memory the node holds (its RSS
from /proc), the keys of its diagnostics, the periods taken, the lines logged, and that a
service answers and SIGINT ends the node within a bounded wait.
"""
from __future__ import annotations

import itertools
import signal
from pathlib import Path

import numpy as np
import pytest
from controller_probe import Controller
from diagnostic_msgs.msg import DiagnosticArray
from node_harness import NodeProcess, Probe, diagnostics_of, ready_to_answer
from procfs import rss_kib
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, UInt32
from std_srvs.srv import SetBool, Trigger

SUPPORT = Path(__file__).resolve().parents[1] / 'support'

pytestmark = [pytest.mark.ros, pytest.mark.slow]

BURST = QoSProfile(depth=1000, history=HistoryPolicy.KEEP_ALL,
                   reliability=ReliabilityPolicy.RELIABLE,
                   durability=DurabilityPolicy.VOLATILE)
MIB = 1 << 20


def rss(node: NodeProcess) -> int:
    """Return the node process's resident memory in bytes."""
    assert node.proc is not None
    return rss_kib(node.proc.pid) * 1024


def answers_within(probe: Probe, srv_type: type, name: str, request: object,
                   seconds: float) -> object:
    """Wait for the service to exist, then return its answer, which must come in ``seconds``."""
    client = probe.node.create_client(srv_type, name)
    probe.spin_until(client.service_is_ready, 30.0, f'service {name}')
    ready_to_answer(probe.node, probe.executor, name.rsplit('/', 1)[0])
    future = client.call_async(request)
    probe.spin_until(future.done, seconds, f'the answer of {name}')
    return future.result()


def reports(diags: object, node: NodeProcess) -> list[dict[str, str]]:
    return diagnostics_of(diags.msgs, node.fqn)  # type: ignore[attr-defined]


def test_wrong_joint_names_keep_memory_and_diagnostics_bounded() -> None:
    # Commands are best effort outside synchronous mode: most of the storm arrives.
    params = {'joint_commands_input': True, 'status_line': False}
    with NodeProcess('default', params) as node, Probe() as probe:
        diags = probe.subscribe(DiagnosticArray, '/diagnostics')
        pub = probe.node.create_publisher(JointState, f'{node.namespace}/joint_commands', BURST)
        probe.spin_until(lambda: pub.get_subscription_count() >= 1 and len(reports(diags, node))
                         >= 1, 30.0, 'the node')
        before_rss = rss(node)
        before_keys = len(reports(diags, node)[-1])
        for n in range(30):
            names = [f'wrong_{n}_{i}' for i in range(10_000)]
            pub.publish(JointState(name=names, effort=[0.0] * len(names)))
            probe.spin_for(0.0)
        probe.spin_until(lambda: int(reports(diags, node)[-1]['commands_dropped']) >= 20,
                         60.0, 'the storm counted')
        last = reports(diags, node)[-1]
        dropped = [k for k in last if k.startswith('commands_dropped[')]
        assert dropped == [f"commands_dropped[{node.namespace}/joint_commands: no joint named "
                           "'pendulum_joint']"]
        assert len(last) == before_keys + 1
        assert rss(node) - before_rss < 100 * MIB
        reply = answers_within(probe, SetBool, f'{node.fqn}/pause', SetBool.Request(data=True),
                               1.0)
        assert reply.success  # type: ignore[attr-defined]
        assert node.stop(signal.SIGINT, timeout=2.0) == 0
        out = node.output()
    # One log line, cut short, however many names each message held.
    assert out.count('dropped a command on') == 1
    assert max(len(line) for line in out.splitlines()) < 1000


def test_a_burst_of_step_requests_takes_every_period() -> None:
    params = {'start_paused': True, 'publish_rate': 1000.0, 'status_line': False}
    with NodeProcess('lockstep', params) as node, Probe() as probe:
        diags = probe.subscribe(DiagnosticArray, '/diagnostics')
        step = probe.node.create_publisher(UInt32, f'{node.fqn}/step_periods', BURST)
        probe.spin_until(lambda: step.get_subscription_count() >= 1, 30.0, '~/step_periods')
        for _ in range(1000):
            step.publish(UInt32(data=1))
        # 500 refused requests, then one more period: they are taken in order.
        for _ in range(500):
            step.publish(UInt32(data=0))
        step.publish(UInt32(data=1))
        probe.spin_until(lambda: bool(reports(diags, node))
                         and reports(diags, node)[-1]['steps'] == '1001', 30.0,
                         '1001 periods of one step')
        n = len(reports(diags, node))
        probe.spin_until(lambda: len(reports(diags, node)) >= n + 1, 30.0, 'a later report')
        assert reports(diags, node)[-1]['steps'] == '1001'
        assert node.stop(signal.SIGINT, timeout=2.0) == 0
        out = node.output()
    # The refused requests are logged once (then every 1000th), not 500 times.
    assert out.count('the number of control periods must be >= 1, got 0') == 1


def test_extreme_effort_and_velocity_limits_stay_within_the_speed_bound() -> None:
    params = {'max_effort': 1e6, 'max_velocity': 1e6, 'status_line': False}
    with NodeProcess('default', params) as node, Probe() as probe:
        states = probe.subscribe(JointState, f'{node.namespace}/joint_states')
        pub = probe.node.create_publisher(Float64, f'{node.namespace}/effort_command', BURST)
        probe.spin_until(lambda: pub.get_subscription_count() >= 1 and len(states) >= 5, 30.0,
                         'the node')
        n = len(states)
        while len(states) < n + 100:
            pub.publish(Float64(data=1e6))
            probe.spin_for(0.01)
        assert max(abs(m.velocity[0]) for m in states.msgs) <= 1e4
        reply = answers_within(probe, SetBool, f'{node.fqn}/pause', SetBool.Request(data=True),
                               1.0)
        assert reply.success  # type: ignore[attr-defined]
        assert node.stop(signal.SIGINT, timeout=2.0) == 0


def test_a_long_synchronous_period_leaves_services_and_signals_served() -> None:
    params = {'publish_rate': 0.1, 'h': 1e-6, 'status_line': False}
    with NodeProcess('controller_test', params) as node, Controller(
            namespace=node.namespace) as ctrl, Probe() as probe:
        probe.spin_until(lambda: 'answered' in ctrl.output() or 'reaches 1' in ctrl.output(),
                         30.0, 'the controller')
        probe.spin_until(lambda: 'a controller is connected; stepping' in node.output(), 30.0,
                         'the loop')
        reply = answers_within(probe, Trigger, f'{node.fqn}/reset', Trigger.Request(), 1.0)
        assert reply.success  # type: ignore[attr-defined]
        assert node.stop(signal.SIGINT, timeout=2.0) == 0


@pytest.mark.parametrize(('params', 'message'), [
    ({'effort_input': False},
     'synchronous needs a command input to answer each state: set one of effort_input, '
     'joint_commands_input, array_command_input to true'),
    ({'joint_name': 'a\tb'},
     "joint_name must hold no control characters (a URDF or a log would not show them), got "
     "'a\\tb' with '\\t'"),
])
def test_settings_the_node_cannot_run_are_refused_at_start(params: dict[str, object],
                                                           message: str) -> None:
    with NodeProcess('controller_test', params) as node:
        assert node.wait(30.0) == 2
        assert f'pendulum_node: {message}' in node.output()


def writer_of(node: NodeProcess) -> int:
    """Return the pid of the node's recording writer process (its child running the sink)."""
    assert node.proc is not None
    for entry in Path('/proc').iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / 'stat').read_text()
            cmdline = (entry / 'cmdline').read_bytes()
        except OSError:
            continue
        if int(stat.rsplit(')', 1)[1].split()[1]) == node.proc.pid and b'recording.sink' in (
                cmdline):
            return int(entry.name)
    raise AssertionError('no writer process')


def test_sigint_ends_the_node_while_its_writer_is_stopped(tmp_path: Path) -> None:
    import os
    import time

    from pendulum_sim.recording import load

    path = tmp_path / 'stopped.mcap'
    with NodeProcess('default', {'recording.path': str(path), 'status_line': False}) as node, \
            Probe() as probe:
        states = probe.subscribe(JointState, f'{node.namespace}/joint_states')
        probe.spin_until(lambda: len(states) >= 50, 30.0, 'joint_states')
        writer = writer_of(node)
        os.kill(writer, signal.SIGSTOP)
        try:
            assert node.stop(signal.SIGINT, timeout=2.0) == 0
            out = node.output()
        finally:
            os.kill(writer, signal.SIGCONT)
    assert f'the writer process (pid {writer}) is stopped; it finalises the file when it ' \
           'runs again' in out
    # Continued, the writer finishes the file by itself.
    end = time.monotonic() + 30.0
    while Path(f'/proc/{writer}').exists() and b'recording.sink' in Path(
            f'/proc/{writer}/cmdline').read_bytes():
        assert time.monotonic() < end, 'the writer never finished'
        time.sleep(0.05)
    # A few seconds of states fit in the pipe, CLOSE included: the file is whole (a writer
    # that was not handed everything marks the file cut short: test_recording_stop.py).
    assert 'not handed over' not in out
    rec = load(path)
    assert rec.complete and rec.joint_states is not None and len(rec.joint_states.t) >= 50


def test_topics_nobody_took_are_published_to_a_subscriber_that_comes_later() -> None:
    """A publication nobody would receive is skipped; a subscriber that matches later gets
    every topic, energy terms included (which are then computed again)."""
    with NodeProcess('paper', {'status_line': False}) as node, Probe() as probe:
        diags = probe.subscribe(DiagnosticArray, '/diagnostics')
        probe.spin_until(lambda: len(reports(diags, node)) >= 1, 30.0, 'the node running')
        kinetic = probe.subscribe(Float64, f'{node.namespace}/energy_terms/kinetic')
        energy = probe.subscribe(Float64, f'{node.namespace}/energy')
        states = probe.subscribe(JointState, f'{node.namespace}/joint_states')
        probe.spin_until(lambda: min(len(kinetic), len(energy), len(states)) >= 20, 30.0,
                         'every topic')
        assert all(m.data >= 0.0 for m in kinetic.msgs)
        assert node.stop(signal.SIGINT, timeout=2.0) == 0


def test_a_parameter_storm_never_starves_the_tick(tmp_path: Path) -> None:
    """1000 parameter sets per second from another process, at most 10 unanswered.

    Every set is answered and accepted, and recorded in order in the recording's
    /parameter_events; the sets are applied to the joint at most once per wake (the
    ``reconfigures`` count <= ``wakes``, decided by the code, not the clock); the tick goes on
    publishing states that advance simulated time throughout. ``schedule_slips`` is printed,
    not asserted: the code counts a slip when a wake finds more than 10 ms of due work or a
    stall of 0.25 s on the wall clock, which a loaded machine (or a descheduled process)
    produces with or without a storm, so its value would test the machine, not the node.
    """
    import json
    import os
    import subprocess
    import sys

    from parameter_storm import gamma_of

    from pendulum_sim.recording import load

    count = 2000
    path = tmp_path / 'storm.mcap'
    with NodeProcess('default', {'recording.path': str(path), 'status_line': False}) as node, \
            Probe() as probe:
        diags = probe.subscribe(DiagnosticArray, '/diagnostics')
        states = probe.subscribe(JointState, f'{node.namespace}/joint_states')
        probe.spin_until(lambda: len(states) >= 10 and len(reports(diags, node)) >= 1, 30.0,
                         'the node running')
        storm = subprocess.Popen(
            [sys.executable, str(SUPPORT / 'parameter_storm.py'), node.fqn,
             str(count), '1000', '10'], stdout=subprocess.PIPE, text=True,
            env=dict(os.environ))
        assert storm.stdout is not None
        assert storm.stdout.readline().strip() == 'ready'
        before = len(states)
        while storm.poll() is None:
            probe.executor.spin_once(timeout_sec=0.01)
        during = states.msgs[before:]
        result = json.loads(storm.stdout.read())
        probe.spin_until(lambda: int(reports(diags, node)[-1]['parameter_sets']) == count,
                         30.0, 'diagnostics counting every set')
        after = reports(diags, node)[-1]
        assert node.stop(signal.SIGINT, timeout=2.0) == 0

    print(f"storm: {result['answered'] / result['seconds']:.0f} sets/s; schedule_slips "
          f"{after['schedule_slips']}, steps_per_wake_max {after['steps_per_wake_max']}, "
          f"reconfigures {after['reconfigures']} for {count} sets in {after['wakes']} wakes")
    wanted = [gamma_of(k, count) for k in range(count)]
    assert (result['sent'], result['answered'], result['successful']) == (count,) * 3
    assert sorted(result['values']) == wanted
    assert 1 <= int(after['reconfigures']) <= int(after['wakes'])
    # The tick went on during the storm: states kept coming, each further in simulated time.
    assert len(during) >= 10
    stamps = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in during]
    assert all(b > a for a, b in itertools.pairwise(stamps))
    rec = load(path)
    assert rec.complete
    recorded = [p.value.double_value for _, e in rec.parameter_events
                for p in e.changed_parameters if p.name == 'gamma']
    assert recorded == wanted   # every accepted set, in the order the node took them
    assert rec.joint_states is not None
    steps = np.round(rec.joint_states.t / 1e-3)
    assert np.all(np.diff(steps) > 0)
