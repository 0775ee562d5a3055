"""The node's ROS-free parts: schedule, self-measurement, sensor, scenes, parameters, bytes."""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import yaml
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from pendulum_sim.core import PendulumParams
from pendulum_sim.joint.errors import SceneError
from pendulum_sim.joint.parameters import SPEC_BY_NAME, SPECS, check
from pendulum_sim.joint.realtime import RateMeter, Schedule, WakeStats
from pendulum_sim.joint.scenes import available_scenes, find_scene
from pendulum_sim.joint.sensors import SensorModel
from pendulum_sim.joint.status import status_text
from pendulum_sim.joint.urdf import pendulum_urdf
from pendulum_sim.node.declare import descriptor
from pendulum_sim.node.serialized import ClockBytes, Float64Bytes, JointStateBytes

REPO = Path(__file__).resolve().parents[2]
SCENES = ('default', 'paper', 'stiff', 'noisy_sensor', 'lockstep', 'minimal')


# ---------------------------------------------------------------------- the absolute schedule
def test_schedule_counts_steps_from_the_start_not_from_the_last_wake() -> None:
    """Steps due depend only on elapsed wall time: jittery wakes never accumulate drift."""
    h = 1e-3
    sched = Schedule(h, 1.0, now_ns=5_000)
    rng = np.random.default_rng(1)
    wakes = 5_000 + np.cumsum(rng.uniform(0.2e6, 1.8e6, size=10_000)).astype(np.int64)
    steps = 0
    for now in wakes:
        steps = max(steps, sched.due(int(now)))
        lag = (now - 5_000) / 1e9 - steps * h
        assert 0.0 <= lag < h + 1e-12  # within one step of wall time after every wake
    assert steps == math.floor((wakes[-1] - 5_000) / 1e6)


def test_schedule_exact_multiples_and_factor() -> None:
    """An exact multiple of h is due on the dot; the factor scales; rebase keeps the count."""
    sched = Schedule(1e-3, 1.0, now_ns=0)
    assert [sched.due(k * 1_000_000) for k in (0, 1, 7, 700, 699_999)] == [
        0, 1, 7, 700, 699_999]
    assert sched.due(999_999) == 0
    sched.rebase(now_ns=10_000_000, steps=10, rtf=2.5)
    assert sched.due(10_000_000) == 10
    assert sched.due(14_000_000) == 20
    assert sched.lag(14_000_000, 18) == pytest.approx(2.0)


def test_wake_stats_percentiles_overruns_and_missed_wakes() -> None:
    """Latency percentiles from the histogram; late ends are overruns, skipped wakes missed."""
    period = 1_000_000
    stats = WakeStats(period)
    lat_us = [10] * 98 + [250, 900]
    for k, lat in enumerate(lat_us):
        sched = k * period
        stats.wake(sched, sched + lat * 1000)
        stats.done(sched, sched + lat * 1000 + 50_000, 1)
    total = stats.summary()
    assert total.count == 100
    assert total.p50_us == 11.0  # upper edge of the 10 µs bin
    assert total.p99_us == 251.0
    assert total.max_us == 900.0
    assert stats.overruns == 0
    stats.wake(102 * period, 102 * period + 5_000)  # wakes 100 and 101 were skipped
    stats.done(102 * period, 103 * period + 1, 3)
    assert stats.missed == 2
    assert stats.overruns == 1
    assert stats.max_steps == 3
    window, steps_per_wake = stats.window()
    assert window.count == 101
    assert steps_per_wake == pytest.approx(103 / 101)
    assert stats.window()[0].count == 0


def test_rate_meter_excludes_paused_time() -> None:
    """The achieved factor divides simulated time by running wall time only."""
    meter = RateMeter(0)
    meter.advance(1.0)
    meter.pause(1_000_000_000)
    meter.resume(5_000_000_000)
    meter.advance(2.0)
    assert meter.total(6_000_000_000) == pytest.approx(1.5)
    assert meter.running_ns(6_000_000_000) == 2_000_000_000


# ---------------------------------------------------------------------- the sensor
def test_sensor_noise_is_seeded_and_quantised() -> None:
    """The same seed gives the same measurements; angles land on encoder counts."""
    res = 2 * math.pi / 4096
    a = SensorModel(7, 0.01, 0.1, res)
    b = SensorModel(7, 0.01, 0.1, res)
    first = [a.measure(0.3, -1.0) for _ in range(1000)]
    assert first == [b.measure(0.3, -1.0) for _ in range(1000)]
    phi = np.array([p for p, _ in first])
    np.testing.assert_allclose(phi / res, np.round(phi / res), rtol=0, atol=1e-9)
    dphi = np.array([v for _, v in first])
    assert abs(np.mean(dphi) + 1.0) < 4 * 0.1 / math.sqrt(1000)
    assert SensorModel(7).ideal and SensorModel(7).measure(0.3, -1.0) == (0.3, -1.0)
    assert SensorModel(8, 0.01).measure(0.3, 0.0) != SensorModel(7, 0.01).measure(0.3, 0.0)


# ---------------------------------------------------------------------- messages as bytes
def test_serialized_messages_round_trip() -> None:
    """Patched CDR bytes deserialize to exactly the intended messages."""
    js = deserialize_message(JointStateBytes('elbow').pack(1_700_000_000, 999_999_999,
                                                          -3.25, 1e-300, math.pi), JointState)
    assert (js.header.stamp.sec, js.header.stamp.nanosec) == (1_700_000_000, 999_999_999)
    assert js.header.frame_id == ''
    assert list(js.name) == ['elbow']
    assert (list(js.position), list(js.velocity), list(js.effort)) == ([-3.25], [1e-300],
                                                                        [math.pi])
    clock = deserialize_message(ClockBytes().pack(12, 34), Clock)
    assert (clock.clock.sec, clock.clock.nanosec) == (12, 34)
    assert deserialize_message(Float64Bytes().pack(-0.5), Float64).data == -0.5


# ---------------------------------------------------------------------- scenes and parameters
def test_scenes_are_found_and_bad_names_say_why() -> None:
    """Every required scene resolves; unknown or malformed names are refused by name."""
    assert set(SCENES) <= set(available_scenes())
    for name in SCENES:
        assert find_scene(name) == REPO / 'config' / f'{name}.yaml'
    with pytest.raises(SceneError) as err:
        find_scene('nosuch')
    assert str(err.value).startswith("unknown scene 'nosuch'; known scenes: ")
    assert 'default, ' in str(err.value)
    with pytest.raises(SceneError, match=r"^scene file 'missing\.yaml' does not exist$"):
        find_scene('missing.yaml')
    with pytest.raises(SceneError, match=r"^scene must be a name like default or a \.yaml "
                                         r"path, got '\.\./etc'$"):
        find_scene('../etc')


@pytest.mark.parametrize('scene', SCENES)
def test_scene_files_declare_known_parameters_of_the_right_type(scene: str) -> None:
    """A scene sets only declared parameters, each with its declared type, and passes check."""
    data = yaml.safe_load((REPO / 'config' / f'{scene}.yaml').read_text())
    values = data['/**']['ros__parameters']
    for name, value in values.items():
        spec = SPEC_BY_NAME[name]
        assert type(value) is type(spec.default), f'{scene}: {name} = {value!r}'
        if spec.low is not None and spec.high is not None:
            assert spec.low <= value <= spec.high
    merged = {s.name: s.default for s in SPECS} | values
    assert check(merged) is None


@pytest.mark.parametrize(('changes', 'reason'), [
    ({'m': 0.0}, 'm must be > 0 kg, got 0.0'),
    ({'inertia': -1.0}, 'inertia must be > 0 kg m^2, got -1.0'),
    ({'g': math.nan}, 'g must be finite, got nan'),
    ({'phi0': math.inf}, 'phi0 must be finite, got inf'),
    ({'integrator': 'rk45'},
     'integrator must be one of dop853, dopri5, euler, extrap6, extrap8, midpoint, rk4, rodas4, '
     "sdirk2, sdirk3, got 'rk45'"),
    ({'joint_name': ' '}, "joint_name must be a non-empty name, got ' '"),
    ({'real_time_factor': 0.0}, 'real_time_factor must be > 0 unless lockstep is true, got 0.0'),
    ({'real_time_factor': 0.0, 'lockstep': True}, None),
    # Velocity or position commands start without switching effort input off.
    ({'command_interface': 'velocity', 'joint_commands_input': True}, None),
    ({'command_interface': 'position', 'array_command_input': True}, None),
    ({'command_interface': 'velocity'},
     "command_interface 'velocity' takes commands on joint_commands or commands: set "
     'joint_commands_input or array_command_input to true (effort_command carries N m, effort '
     'only)'),
    ({'position_min': -1.0},
     'position_min and position_max must be both finite (a revolute joint) or both infinite (a '
     'continuous joint), got -1.0 and inf: a URDF joint has no one-sided limit'),
    ({'position_min': -1.0, 'position_max': 1.0}, None),
    ({'servo.velocity_i': math.nan}, 'servo.velocity_i must be a finite number >= 0, got nan'),
    ({'servo.position_p': -2.0}, 'servo.position_p must be a finite number >= 0, got -2.0'),
    ({'servo.gravity_feedforward': False, 'servo.velocity_i': 0.0}, None),
])
def test_parameter_check_reasons(changes: dict[str, object], reason: str | None) -> None:
    """Cross-parameter validation names the value and the rule."""
    values = {s.name: s.default for s in SPECS} | changes
    assert check(values) == reason


def test_read_only_parameters_say_so() -> None:
    """Every read-only parameter's description tells the user it is fixed; live ones do not."""
    for spec in SPECS:
        desc = descriptor(spec)
        assert desc.read_only == spec.read_only
        assert ('Read-only' in desc.description) == spec.read_only, spec.name
    assert {s.name for s in SPECS if not s.read_only} >= {'gamma', 'n', 'real_time_factor'}
    assert descriptor(SPEC_BY_NAME['gamma']).floating_point_range[0].from_value == 0.0


# ---------------------------------------------------------------------- URDF and status
def test_urdf_matches_the_parameters() -> None:
    """One continuous joint with the scene's name; the link's mass and COM from the params."""
    params = PendulumParams(m=0.5, l=0.8, inertia=0.4)
    root = ET.fromstring(pendulum_urdf(params, 'swing'))
    (joint,) = root.findall('joint')
    assert joint.get('name') == 'swing' and joint.get('type') == 'continuous'
    inertial = root.find("link[@name='pendulum_link']/inertial")
    assert inertial is not None
    assert float(inertial.find('mass').get('value')) == 0.5  # type: ignore[union-attr]
    assert inertial.find('origin').get('xyz') == '0 0 -0.8'  # type: ignore[union-attr]
    # Parallel axes: I_com = I - m l^2 = 0.4 - 0.32.
    i_com = float(inertial.find('inertia').get('ixx'))  # type: ignore[union-attr]
    assert i_com == pytest.approx(0.08)


def test_status_text() -> None:
    """The live line shows t, phi, E and the factor."""
    assert status_text(1.5, -0.25, 0.125, 0.9994, True) == (
        'pendulum_node  t=     1.500 s  phi=-0.2500 rad  E=0.125000 J  RTF=0.999  [paused]')
