"""The simulated joint without ROS: commands, timeouts, delays and stamps counted in steps."""
from __future__ import annotations

import math

import pytest
from joint_fixtures import PARAMS, H, joint

from pendulum_sim.core import Stepper
from pendulum_sim.joint.errors import JointError
from pendulum_sim.joint.joint import (
    ServoGains,
    SimulatedJoint,
    energy_terms,
    steps_of,
    timeout_steps,
)


def torques(j: SimulatedJoint, k: int) -> list[float]:
    out = []
    for _ in range(k):
        j.advance(1)
        out.append(j.torque)
    return out


@pytest.mark.parametrize(('seconds', 'steps'), [(0.0, 0), (0.005, 5), (0.0054, 5),
                                                (0.0056, 6), (0.7, 700)])
def test_durations_round_to_steps(seconds: float, steps: int) -> None:
    assert steps_of('sensor.delay', seconds, H) == steps


def test_a_positive_timeout_is_at_least_one_step() -> None:
    assert timeout_steps(0.0004, H) == 1   # rounds to 0, which would mean "hold for ever"
    assert timeout_steps(0.0, H) == 0
    assert timeout_steps(0.5, H) == 500
    with pytest.raises(JointError, match=r'^command_timeout must be a finite number of '
                       r'seconds >= 0, got nan$'):
        timeout_steps(math.nan, H)


def test_effort_saturates_holds_and_times_out_in_steps() -> None:
    j = joint(timeout_steps=4)
    assert j.command(7.5)
    assert j.counters.saturated == 1
    assert torques(j, 6) == [5.0, 5.0, 5.0, 5.0, 0.0, 0.0]
    assert j.counters.timeouts == 1
    assert not j.command(math.nan) and not j.command(-math.inf)
    assert j.counters.rejected_nonfinite == 2 and j.counters.received == 1
    # A zero timeout holds for ever.
    j = joint(timeout_steps=0)
    j.command(-1.0)
    assert set(torques(j, 300)) == {-1.0}


def test_command_delay_is_exactly_its_steps() -> None:
    j = joint(command_delay_steps=3)
    j.command(2.0)
    assert torques(j, 5) == [0.0, 0.0, 0.0, 2.0, 2.0]


def test_the_trajectory_equals_the_core_under_the_same_torques() -> None:
    j = joint(timeout_steps=0)
    ref = Stepper(PARAMS, 0.3, 0.0, H)
    for k in range(50):
        if k % 10 == 0:
            j.command(0.1 * k - 2.0)
        tau = j.target
        j.advance(1)
        ref.step(tau)
        assert (j.stepper.phi, j.stepper.dphi) == (ref.phi, ref.dphi)


def test_sensor_delay_gives_the_state_of_d_steps_ago_stamped_then() -> None:
    d = 5
    j = joint(sensor_delay_steps=d, epoch_ns=1_000_000_000)
    free = joint()
    truth = [(free.stamp_ns(), free.stepper.phi, free.stepper.dphi)]
    for _ in range(20):
        free.advance(1)
        truth.append((free.stamp_ns(), free.stepper.phi, free.stepper.dphi))
    for k in range(1, 21):
        j.advance(1)
        s = j.sample()
        if k < d + 1:
            assert s is None   # nothing measured d steps ago yet (the start is not sampled)
            continue
        assert s is not None
        assert s.stamp_ns == 1_000_000_000 + (k - d) * 1_000_000
        assert (s.position, s.velocity) == truth[k - d][1:]


def test_sensor_noise_is_seeded_and_quantised() -> None:
    a = joint(sensor_seed=7, position_noise=0.01, velocity_noise=0.1, resolution=0.001)
    b = joint(sensor_seed=7, position_noise=0.01, velocity_noise=0.1, resolution=0.001)
    for _ in range(10):
        a.advance(3)
        b.advance(3)
        sa, sb = a.sample(), b.sample()
        assert sa == sb
        assert sa is not None and sa.position != a.stepper.phi
        assert abs(sa.position / 0.001 - round(sa.position / 0.001)) < 1e-6
    # A resolution finer than double spacing leaves the angle as it is (no overflow).
    c = joint(resolution=1e-320)
    c.advance(1)
    s = c.sample()
    assert s is not None and s.position == c.stepper.phi


def test_reset_keeps_time_going() -> None:
    j = joint(epoch_ns=0)
    j.advance(250)
    before = j.stamp_ns()
    j.command(1.0)
    assert j.reset() is None
    assert j.steps == 250 and j.stamp_ns() == before
    assert (j.stepper.phi, j.stepper.dphi, j.target) == (0.3, 0.0, 0.0)
    j.advance(1)
    assert j.stamp_ns() == before + 1_000_000


def test_position_and_velocity_servos_reach_their_targets() -> None:
    j = joint(command_interface='position', phi0=0.0, position_min=-1.0, position_max=0.5)
    j.command(0.8)                    # beyond position_max: limited to 0.5
    assert j.target == 0.5 and j.counters.limited == 1
    j.advance(5000)
    # The drive reaches the limited target under gravity (feed-forward and integral).
    assert abs(j.stepper.phi - 0.5) < 1e-9
    # Without gravity, damping or integral the velocity loop is first order:
    # φ'' = kv/I (v - φ').
    v = joint(command_interface='velocity', phi0=0.0, max_velocity=3.0, timeout_steps=0,
              params=PARAMS.with_changes(gamma=0.0, g=0.0),
              servo=ServoGains(velocity_p=2.0, velocity_i=0.0))
    v.command(10.0)                   # limited to max_velocity
    assert v.target == 3.0
    v.advance(1)
    assert v.torque == 5.0            # kv * 3 = 6 N m, saturated at max_effort
    v.advance(2999)                   # 3 s = 30 time constants of I/kv = 0.1 s
    assert abs(v.stepper.dphi - 3.0) < 1e-9


def test_effort_cannot_drive_past_max_velocity() -> None:
    j = joint(params=PARAMS.with_changes(gamma=0.0, g=0.0), phi0=0.0, max_velocity=2.0,
              timeout_steps=0)
    j.command(5.0)
    j.advance(3000)
    # Torque stops once the speed reaches the limit: one step's worth past it at most.
    assert 2.0 <= j.stepper.dphi <= 2.0 + 5.0 / 0.2 * H + 1e-12
    assert j.counters.limited > 0


def test_energy_terms_refuse_non_finite_states() -> None:
    terms = energy_terms(PARAMS, 2.0, 0.0)
    assert terms.energy == pytest.approx(PARAMS.mgl * (1 - math.cos(2.0)), rel=1e-15)
    with pytest.raises(JointError, match=r'^the state phi = 0.0, dphi = 1e\+200 '):
        energy_terms(PARAMS, 0.0, 1e200)


def test_bad_configs_say_why() -> None:
    with pytest.raises(JointError, match=r"^command_interface must be one of effort, "
                       r"velocity, position, got 'torque'$"):
        joint(command_interface='torque')
    with pytest.raises(JointError, match=r'^position_min must be < position_max, got 1.0 and '
                       r'0.0$'):
        joint(position_min=1.0, position_max=0.0)
