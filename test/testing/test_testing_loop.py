"""closed_loop: the in-process joint and pendulum_node over DDS decide the same, bit for bit.

The command-line runs start the real ``pendulum_node`` and ``pendulum_pd_controller``
executables in their own processes (real DDS, loopback); the in-process runs call the same law,
:func:`pendulum_sim.controller.pd_law.pd_torque`, against the ROS-free ``SimulatedJoint``.
"""
from __future__ import annotations

import math
import re
import sys
import threading
from functools import partial
from pathlib import Path

import numpy as np
import pytest

from pendulum_sim.controller.pd_law import PDGains, pd_torque
from pendulum_sim.testing import ClosedLoopRun, ControllerFailed, TestingError, closed_loop

PD_CONTROLLER = str(Path(sys.executable).parent / 'pendulum_pd_controller')
FIELDS = ('t', 'position', 'velocity', 'effort', 'command')


def pd_law(gains: PDGains, t: float, position: float, velocity: float) -> float:
    """Return the example controller's answer to one state (what its node publishes)."""
    return pd_torque(gains, position, velocity)


def assert_identical(a: ClosedLoopRun, b: ClosedLoopRun) -> None:
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
        assert getattr(a, name).tobytes() == getattr(b, name).tobytes(), name


@pytest.mark.ros
def test_the_pd_law_in_process_and_as_a_ros_node_give_the_same_trajectory_bit_for_bit() -> None:
    """Two command-line runs at the same time (one domain), each against its in-process twin."""
    cases = {
        'default': (PDGains(), {}, []),
        'stiff, late, damped': (PDGains(kp=9.0, kd=2.0, target=-0.3),
                                {'command_delay': 0.005, 'gamma': 0.5, 'n': 2.0, 'phi0': 0.2},
                                ['--ros-args', '-p', 'kp:=9.0', '-p', 'kd:=2.0',
                                 '-p', 'target:=-0.3']),
    }
    periods = 250
    over_dds: dict[str, ClosedLoopRun] = {}
    errors: list[BaseException] = []

    def run(name: str) -> None:
        _, overrides, args = cases[name]
        try:
            over_dds[name] = closed_loop([PD_CONTROLLER, *args], periods=periods,
                                         overrides=overrides)
        except BaseException as exc:
            errors.append(exc)

    threads = [threading.Thread(target=run, args=(name,)) for name in cases]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert not errors, errors
    for name, (gains, overrides, _) in cases.items():
        local = closed_loop(partial(pd_law, gains), periods=periods, overrides=overrides)
        remote = over_dds[name]
        assert local.t.size == remote.t.size == periods
        assert_identical(local, remote)
        # The answer to state k is the torque of period k: the effort of state k + 1, unless
        # a command delay moves it later.
        if not overrides:
            np.testing.assert_array_equal(local.effort[1:], np.clip(local.command[:-1], -5, 5))
    # The two scenarios differ (the isolation is real, not two copies of one run).
    assert not np.array_equal(over_dds['default'].position, over_dds['stiff, late, damped']
                              .position)
    # The default loop settles at its target from phi0 = 1 rad.
    m = over_dds['default'].metrics(0.5)
    assert m.settling_time < 2.0 and abs(m.steady_state_error) < 1e-3


def test_a_run_has_one_sample_per_period_on_the_stamp_grid() -> None:
    run = closed_loop(partial(pd_law, PDGains()), periods=100)
    np.testing.assert_array_equal(run.t, np.arange(100) * 10_000_000 / 1e9)
    assert run.position[0] == 1.0 and run.velocity[0] == 0.0 and run.effort[0] == 0.0
    assert run.parameters['synchronous'] is True and run.failed is None


@pytest.mark.ros
def test_record_writes_an_mcap_that_loads_back_as_the_same_run(tmp_path: Path) -> None:
    from pendulum_sim.testing.record import load_run

    path = tmp_path / 'run.mcap'
    run = closed_loop(partial(pd_law, PDGains()), periods=120, record=path)
    back = load_run(path)
    assert_identical(run, back)
    assert back.parameters['max_effort'] == 5.0 and back.parameters['phi0'] == 1.0
    # The independent reader sees the node's layout.
    from mcap_ros2.reader import read_ros2_messages

    topics = [m.channel.topic for m in read_ros2_messages(str(path))]
    assert topics.count('/joint_states') == topics.count('/effort_command') == 120


def raises(t: float, position: float, velocity: float) -> float:
    if t >= 0.05:
        raise RuntimeError('encoder lost')
    return 0.0


@pytest.mark.parametrize(('law', 'msg'), [
    (raises, 'the controller raised RuntimeError: encoder lost at t = 0.05 s'),
    (lambda t, p, v: math.nan if t > 0.015 else 0.0,
     'the controller returned nan at t = 0.02 s; a command must be finite'),
    (lambda t, p, v: 'full', "the controller returned 'full' at t = 0 s; a command is a number"),
    (lambda t, p, v: '0.5', "the controller returned '0.5' at t = 0 s; a command is a number"),
    (lambda t, p, v: 10**400 if t > 0.015 else 0.0,
     'law raised OverflowError: the controller returned an int of 401 digits at t = 0.02 s, '
     'too large for a float; a command must be finite'),
])
def test_a_failing_controller_fails_the_run_with_the_reason(law: object, msg: str) -> None:
    with pytest.raises(ControllerFailed, match=re.escape(msg)):
        closed_loop(law, periods=50)  # type: ignore[arg-type]


def test_a_failing_controller_leaves_the_run_up_to_the_fault() -> None:
    from pendulum_sim.testing.examples import pd

    def until(t: float, position: float, velocity: float) -> float:
        return pd(t, position, velocity) if t < 0.2 else math.inf

    with pytest.raises(ControllerFailed) as caught:
        closed_loop(until, periods=50)
    run = caught.value.run
    whole = closed_loop(pd, periods=50)
    assert run is not None and run.t.size == 20 and math.isclose(run.t[-1], 0.19)
    for name in ('t', 'position', 'velocity', 'effort', 'command'):
        assert np.array_equal(getattr(run, name), getattr(whole, name)[:20]), name


@pytest.mark.parametrize(('kwargs', 'msg'), [
    ({'periods': 0}, 'periods must be an integer in [1, 10000000], got 0'),
    ({'periods': 1.5}, 'periods must be an integer in [1, 10000000], got 1.5'),
    ({'periods': 5, 'overrides': {'gama': 1.0}},
     "unknown parameter 'gama' in overrides (did you mean 'gamma'?)"),
    ({'periods': 5, 'overrides': {'gamma': 'high'}}, "gamma must be a float, got 'high'"),
    ({'periods': 5, 'overrides': {'m': -1.0}}, 'm must be'),
    ({'periods': 5, 'scene': 'nope'}, "unknown scene 'nope'; known scenes:"),
    ({'periods': 5, 'overrides': {'synchronous': False}},
     'synchronous is fixed for a closed loop (it is True), got False'),
])
def test_bad_runs_are_refused_with_the_reason(kwargs: dict[str, object], msg: str) -> None:
    with pytest.raises(TestingError, match=re.escape(msg)):
        closed_loop(lambda t, p, v: 0.0, **kwargs)  # type: ignore[arg-type]


@pytest.mark.ros
def test_a_controller_that_cannot_start_or_exits_fails_the_run() -> None:
    with pytest.raises(ControllerFailed, match=re.escape(
            "cannot start the controller 'no-such-controller': no such executable")):
        closed_loop(['no-such-controller'], periods=5)
    with pytest.raises(ControllerFailed, match=re.escape(
            'the controller exited with code 3 before the 5 periods were run')):
        closed_loop([sys.executable, '-c', 'import sys; sys.exit(3)'], periods=5)
