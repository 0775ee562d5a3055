"""Recording through the real node process: SIGTERM, SIGKILL, a full disk, and the physics."""
from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from node_harness import ready_to_answer
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from recording_support import (
    assert_same,
    joint_states_on_disk,
    read_independently,
    ros_node,
    spin_until,
)
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from pendulum_sim import __version__
from pendulum_sim.core import PendulumParams, simulate
from pendulum_sim.core.model import energy
from pendulum_sim.recording import load
from pendulum_sim.recording.loader import Recording, TruncatedRecordingWarning

ROOT = Path(__file__).resolve().parents[2]
NODE = Path(sys.executable).parent / 'pendulum_node'
RECORD_YAML = ROOT / 'config' / 'record.yaml'

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def start_node(path: Path, *extra: str, limit: int = 0) -> subprocess.Popen[str]:
    """Start pendulum_node on the record scene, recording to ``path``."""
    def limit_file_size() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    cmd = [str(NODE), '--ros-args', '--params-file', str(RECORD_YAML),
           '-p', f'recording.path:={path}', '-p', 'status_line:=false', *extra]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=os.environ, preexec_fn=limit_file_size if limit else None,
                            start_new_session=True)


def wait_for_size(path: Path, size: int, proc: subprocess.Popen[str],
                  timeout: float = 20.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()
        if path.exists() and path.stat().st_size >= size:
            return
        time.sleep(0.05)
    raise AssertionError(f'{path} did not reach {size} bytes')


def scene_params(rec: Recording) -> PendulumParams:
    s = rec.scene
    return PendulumParams(m=float(s['m']), l=float(s['l']), inertia=float(s['inertia']),
                          g=float(s['g']), gamma=float(s['gamma']), n=float(s['n']))


def epoch_ns(rec: Recording) -> int:
    """Return the stamp of simulated time 0, which the node reports in its diagnostics."""
    assert rec.diagnostics is not None and rec.diagnostics.messages
    pairs = {p.key: p.value for p in rec.diagnostics.messages[0].status[0].values}
    return int(pairs['epoch_ns'])


def set_gamma(node: Any, executor: Any, value: float) -> None:
    client = node.create_client(SetParameters, '/pendulum_node/set_parameters')
    assert client.wait_for_service(timeout_sec=10.0)
    ready_to_answer(node, executor, '/pendulum_node')
    future = client.call_async(SetParameters.Request(parameters=[ParameterMsg(
        name='gamma', value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE,
                                           double_value=value))]))
    assert spin_until(executor, future.done, timeout=10.0)
    assert future.result().results[0].successful


def test_a_recorded_run_is_the_core_trajectory_and_sigterm_finalises(tmp_path: Path) -> None:
    path = tmp_path / 'run.mcap'
    proc = start_node(path)
    sent = [0.5, 9.0]           # 9.0 is saturated at max_effort by the node, recorded as sent
    with ros_node('recording_test') as (node, executor):
        joint_states: list[JointState] = []
        node.create_subscription(JointState, '/joint_states', joint_states.append, 100)
        # 1.5 s free swing (diagnostics report the epoch once a second), then inputs.
        assert spin_until(executor, lambda: len(joint_states) >= 300, timeout=30.0)
        commands = node.create_publisher(Float64, '/effort_command', 10)
        assert spin_until(executor, lambda: commands.get_subscription_count() > 0, 10.0)
        # The publisher sees the node's reader before that reader sees the publisher (DDS
        # discovery is per side), so a first command can still be dropped: repeat the first one
        # until the joint applies it; from then on every command is delivered (reliable QoS).
        published: list[float] = []
        for value, applied in zip(sent, (0.5, 5.0), strict=True):
            for _ in range(50):
                commands.publish(Float64(data=value))
                published.append(value)
                if spin_until(executor, lambda a=applied: bool(joint_states)
                              and list(joint_states[-1].effort) == [a], timeout=0.2):
                    break
            assert list(joint_states[-1].effort) == [applied]
        set_gamma(node, executor, 0.25)
        spin_until(executor, lambda: False, timeout=0.5)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err

    rec = load(path)                       # no TruncatedRecordingWarning: finalised
    assert rec.complete and rec.problems == ()
    assert_same(rec, load(path, fast=False))   # the fast decoder on the node's own bytes
    assert rec.scene['recording.path'] == str(path) and rec.scene['gamma'] == '0.1'
    assert rec.metadata['pendulum_sim'] == {'version': __version__}
    summary, decoded = read_independently(path)
    assert summary is not None and summary.statistics.message_count == len(decoded)
    assert {c.topic for c in summary.channels.values()} == {
        '/joint_states', '/energy', '/effort_command', '/diagnostics', '/parameter_events'}

    # Inputs: the commands as received, the parameter change as an event.
    assert rec.effort_command is not None
    received = list(rec.effort_command.value)    # a suffix of what was published, in order
    assert received == published[len(published) - len(received):]
    assert [v for i, v in enumerate(received) if i == 0 or v != received[i - 1]] == sent
    gammas = [p.value.double_value for _, e in rec.parameter_events
              for p in e.changed_parameters if p.name == 'gamma']
    assert gammas == [0.25]

    # Physics: until the first command, the recording is the core's trajectory, step for step.
    js = rec.joint_states
    assert js is not None and rec.energy is not None
    h = float(rec.scene['h'])
    h_ns = round(h * 1e9)
    offsets = js.stamp_ns - epoch_ns(rec)
    assert np.all(offsets % h_ns == 0)                     # every stamp on the h grid
    np.testing.assert_array_equal(js.header_stamp_ns, js.stamp_ns)
    steps = offsets // h_ns
    free = js.stamp_ns < rec.effort_command.stamp_ns[0]
    assert free.sum() >= 200
    params = scene_params(rec)
    run = simulate(params, float(rec.scene['phi0']), float(rec.scene['dphi0']),
                   t_end=int(steps[free][-1]) * h, h=h, method=rec.scene['integrator'])
    np.testing.assert_allclose(js.position[free], run.phi[steps[free]], rtol=0, atol=1e-12)
    np.testing.assert_allclose(js.velocity[free], run.dphi[steps[free]], rtol=0, atol=1e-12)
    assert np.all(js.effort[free] == 0.0)
    # Energy at the same stamps (SIGTERM may have cut the last tick between the two topics).
    both = np.isin(js.stamp_ns, rec.energy.stamp_ns) & free
    assert both.sum() >= free.sum() - 1
    np.testing.assert_allclose(rec.energy.value[np.isin(rec.energy.stamp_ns, js.stamp_ns[both])],
                               energy(params, js.position[both], js.velocity[both]),
                               rtol=0, atol=1e-12)
    # After the commands: the applied (saturated) torque shows in the effort field.
    assert set(np.unique(js.effort[~free])) >= {0.5, 5.0}


def test_sigkill_mid_run_keeps_every_message_already_on_disk(
        tmp_path: Path) -> None:
    path = tmp_path / 'killed.mcap'
    proc = start_node(path, '-p', 'publish_rate:=1000.0')
    wait_for_size(path, 20_000, proc)
    deadline = time.monotonic() + 30.0
    on_disk = 0
    while on_disk < 1000 and time.monotonic() < deadline:   # chunks the writer closed
        assert proc.poll() is None, proc.communicate()
        on_disk = joint_states_on_disk(path)
        time.sleep(0.05)
    assert on_disk >= 1000, f'{path} held {on_disk} joint_states after 30 s'
    os.killpg(proc.pid, signal.SIGKILL)   # the node and its recording's writer process
    proc.communicate(timeout=10)
    with pytest.warns(TruncatedRecordingWarning, match='is truncated'):
        rec = load(path)
    js = rec.joint_states
    assert js is not None and len(js.t) >= on_disk   # the kill lost only the open chunk
    # What is there is sound: in order, on the h grid, and the core's trajectory.
    h_ns = round(float(rec.scene['h']) * 1e9)
    offsets = js.stamp_ns - epoch_ns(rec)
    assert np.all(np.diff(offsets) > 0) and np.all(offsets % h_ns == 0)
    steps = offsets // h_ns
    run = simulate(scene_params(rec), float(rec.scene['phi0']), float(rec.scene['dphi0']),
                   t_end=int(steps[-1]) * h_ns * 1e-9, h=h_ns * 1e-9,
                   method=rec.scene['integrator'])
    np.testing.assert_allclose(js.position, run.phi[steps], rtol=0, atol=1e-12)


def test_a_full_disk_stops_the_recording_not_the_simulation(tmp_path: Path) -> None:
    path = tmp_path / 'full.mcap'
    limit = 24 * 1024
    proc = start_node(path, limit=limit)
    with ros_node('full_disk_test') as (node, executor):
        received: list[JointState] = []
        node.create_subscription(JointState, '/joint_states', received.append, 100)
        assert spin_until(executor, lambda: len(received) > 0, timeout=30.0)
        # Run on until the recording has hit the limit, then some more.
        deadline = time.monotonic() + 30.0
        while path.stat().st_size < limit and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        assert path.stat().st_size <= limit
        count = len(received)
        assert spin_until(executor, lambda: len(received) >= count + 200, timeout=10.0)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    assert f'recording {path} stopped: File too large' in err
    with pytest.warns(TruncatedRecordingWarning):
        rec = load(path)
    assert rec.joint_states is not None and len(rec.joint_states.t) > 0
    last_recorded = rec.joint_states.stamp_ns[-1]
    stamps = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in received]
    assert max(stamps) > last_recorded + 500_000_000      # it went on after the error


def test_a_reset_is_recorded_and_the_run_loads_as_two_segments(tmp_path: Path) -> None:
    path = tmp_path / 'reset.mcap'
    proc = start_node(path, '-p', 'effort_input:=false')
    with ros_node('reset_recording_test') as (node, executor):
        joint_states: list[JointState] = []
        node.create_subscription(JointState, '/joint_states', joint_states.append, 100)
        assert spin_until(executor, lambda: len(joint_states) >= 100, timeout=30.0)
        client = node.create_client(Trigger, '/pendulum_node/reset')
        assert client.wait_for_service(timeout_sec=10.0)
        ready_to_answer(node, executor, '/pendulum_node')
        future = client.call_async(Trigger.Request())
        assert spin_until(executor, future.done, timeout=10.0)
        answer = future.result()
        assert answer is not None and answer.success
        count = len(joint_states)
        assert spin_until(executor, lambda: len(joint_states) >= count + 100, timeout=30.0)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err

    rec = load(path)
    assert rec.complete and len(rec.resets) == 1 and len(rec.segments) == 2
    assert rec.reset_messages == (answer.message,)
    reset_ns = int(rec.resets[0])
    js = rec.joint_states
    assert js is not None
    # Simulated time goes on through the reset: stamps never go back, in write order; the
    # reset state is published at the reset stamp (the last state before it may share it).
    assert np.all(np.diff(js.stamp_ns) >= 0)
    first, second = (s.joint_states for s in rec.segments)
    assert first is not None and second is not None
    assert np.all(np.diff(first.stamp_ns) > 0) and np.all(np.diff(second.stamp_ns) > 0)
    assert len(first.t) >= 100 and len(second.t) >= 100
    assert first.stamp_ns[-1] <= reset_ns == second.stamp_ns[0]
    assert second.position[0] == float(rec.scene['phi0'])
    assert second.velocity[0] == float(rec.scene['dphi0'])
    np.testing.assert_array_equal(np.concatenate([first.position, second.position]),
                                  js.position)
    # After the reset the state starts over from the initial state at the reset stamp: the
    # second segment is the core's trajectory from (phi0, dphi0), step for step.
    h_ns = round(float(rec.scene['h']) * 1e9)
    steps = (second.stamp_ns - reset_ns) // h_ns
    assert np.all((second.stamp_ns - reset_ns) % h_ns == 0)
    run = simulate(scene_params(rec), float(rec.scene['phi0']), float(rec.scene['dphi0']),
                   t_end=int(steps[-1]) * h_ns * 1e-9, h=h_ns * 1e-9,
                   method=rec.scene['integrator'])
    np.testing.assert_allclose(second.position, run.phi[steps], rtol=0, atol=1e-12)
    np.testing.assert_allclose(second.velocity, run.dphi[steps], rtol=0, atol=1e-12)
    assert rec.energy is not None and rec.segments[1].energy is not None
    assert rec.segments[1].energy.stamp_ns[0] >= reset_ns
