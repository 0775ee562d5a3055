"""The joint's drive without ROS: the cascaded servo law, its anti-windup and its defaults.

The tracking thresholds are issue 17's: on the default body under gravity a 1 rad/s velocity
command is held within 1 % after 1 s and a position command is reached within 1e-3 rad.
"""
from __future__ import annotations

import math
import re

import pytest
from servo_matrix import eigen_limit, spectral_radius

from pendulum_sim.core import PendulumParams, Stepper
from pendulum_sim.joint.errors import JointError
from pendulum_sim.joint.joint import JointConfig, SimulatedJoint
from pendulum_sim.joint.scenes import find_scene, read_params_file
from pendulum_sim.joint.servo import Servo, ServoGains, loop_refusal

H = 1e-3
# The default scene's body and limits (config/default.yaml).
DEFAULT = read_params_file(find_scene('default'))
BODY = PendulumParams(**{k: float(DEFAULT[k]) for k in ('m', 'l', 'inertia', 'g', 'gamma', 'n')})
MAX_EFFORT = float(DEFAULT['max_effort'])


def drive(interface: str, target: float, seconds: float, **changes: object
          ) -> list[tuple[float, float, float, float]]:
    """Return (t, φ, φ', τ) after each step of a joint commanded ``target`` at t = 0."""
    base: dict[str, object] = {'params': BODY, 'h': H, 'phi0': float(DEFAULT['phi0']),
                               'max_effort': MAX_EFFORT, 'command_interface': interface}
    base.update(changes)
    j = SimulatedJoint(JointConfig(**base))  # type: ignore[arg-type]
    assert j.command(target)
    out = []
    for _ in range(round(seconds / H)):
        j.advance(1)
        st = j.stepper
        out.append((j.time, st.phi, st.dphi, j.torque))
    return out


def test_a_velocity_command_is_held_within_one_percent_after_one_second() -> None:
    run = drive('velocity', 1.0, 4.0)
    worst = max(abs(v - 1.0) for t, _, v, _ in run if t >= 1.0 - 1e-12)
    assert worst <= 0.01
    # The swing passes through angles where gravity pulls hardest (φ = π/2 at t ≈ 1.3 s) and
    # beyond: the feed-forward and the integral hold the speed all the way round.
    assert max(p for _, p, _, _ in run) > math.pi
    assert max(abs(tau) for *_, tau in run) <= MAX_EFFORT


@pytest.mark.parametrize('target', [1.0, -0.5, 2.5])
def test_a_position_command_is_reached_within_a_milliradian(target: float) -> None:
    run = drive('position', target, 4.0)
    assert max(abs(p - target) for t, p, _, _ in run if t >= 2.0 - 1e-12) <= 1e-3
    # No overshoot beyond that either: the position loop is slower than the velocity loop.
    direction = math.copysign(1.0, target - float(DEFAULT['phi0']))
    assert max((p - target) * direction for _, p, _, _ in run) <= 1e-3
    # At rest on target the torque is the gravity torque the drive holds.
    assert run[-1][3] == pytest.approx(BODY.mgl * math.sin(target), abs=1e-6)


def law(interface: str, target: float, gains: ServoGains, max_effort: float = MAX_EFFORT,
        max_velocity: float = 100.0) -> object:
    """Return the documented law as a closure over (φ, φ'), one call a step (written out)."""
    z = [0.0]

    def tau(phi: float, dphi: float) -> float:
        if interface == 'velocity':
            demand = target
        else:
            demand = min(max(gains.position_p * (target - phi), -max_velocity), max_velocity)
        e = demand - dphi
        u = gains.velocity_p * e + gains.velocity_i * z[0]
        if gains.gravity_feedforward:
            u += BODY.m * BODY.g * BODY.l * math.sin(phi)
        out = min(max(u, -max_effort), max_effort)
        if u == out or e * (u - out) < 0.0:
            z[0] += H * e
        return out
    return tau


@pytest.mark.parametrize(('interface', 'target', 'gains'), [
    ('velocity', 1.0, ServoGains()),
    ('velocity', -3.0, ServoGains(velocity_p=1.0, velocity_i=7.0, gravity_feedforward=False)),
    ('position', 2.0, ServoGains()),
    ('position', -1.0, ServoGains(position_p=3.0, velocity_p=0.5, velocity_i=0.0)),
])
def test_the_joint_follows_the_documented_law(interface: str, target: float,
                                              gains: ServoGains) -> None:
    """The joint's steps equal the core stepped with the law written out here, bit for bit."""
    run = drive(interface, target, 3.0, servo=gains)
    tau = law(interface, target, gains)
    st = Stepper(BODY, float(DEFAULT['phi0']), 0.0, H)
    for t, phi, dphi, applied in run:
        torque = tau(st.phi, st.dphi)  # type: ignore[operator]
        st.step(torque)
        assert (st.phi, st.dphi, torque) == (phi, dphi, applied), t


def test_the_integral_does_not_wind_up_while_saturated() -> None:
    servo = Servo(ServoGains(velocity_p=1.0, velocity_i=10.0, gravity_feedforward=False), BODY,
                  max_effort=2.0, max_velocity=100.0, h=H)
    for _ in range(1000):       # 5 rad/s of error asks 5 N m: saturated at 2, pushed further
        assert servo.torque('velocity', 5.0, 0.0, 0.0) == 2.0
    assert servo.integral == 0.0
    # Saturated by the integral (u = -1 + 10 * 0.5 = 4 N m): an error that pulls out of
    # saturation is integrated at once.
    servo.integral = 0.5
    assert servo.torque('velocity', 0.0, 0.0, 1.0) == 2.0
    assert servo.integral == 0.5 - H
    # Unsaturated: u = kv e + ki z, and z grows by h e.
    servo.reset()
    assert servo.torque('velocity', 0.5, 0.0, 0.0) == 0.5
    assert servo.torque('velocity', 0.5, 0.0, 0.0) == 0.5 + 10.0 * 0.5 * H


def test_saturation_recovers_without_windup_overshoot() -> None:
    """A torque limit below what the step asks: the position is still reached, no overshoot."""
    run = drive('position', 1.2, 8.0, max_effort=2.5)
    assert any(abs(tau) == 2.5 for *_, tau in run)
    assert max(p for _, p, _, _ in run) <= 1.2 + 1e-3
    assert abs(run[-1][1] - 1.2) <= 1e-3


def test_without_feedforward_or_integral_the_drive_balances_gravity() -> None:
    """P-only velocity loop, no feed-forward: the classic stall kv kpos (x − φ) = m g l sin φ."""
    gains = ServoGains(position_p=10.0, velocity_p=2.0, velocity_i=0.0,
                       gravity_feedforward=False)
    phi = drive('position', 1.0, 8.0, servo=gains)[-1][1]
    assert 20.0 * (1.0 - phi) == pytest.approx(BODY.mgl * math.sin(phi), abs=1e-6)
    assert abs(phi - 1.0) > 0.05


def test_a_reset_forgets_the_integral_and_live_gains_keep_it() -> None:
    j = SimulatedJoint(JointConfig(params=BODY, h=H, phi0=0.3, max_effort=MAX_EFFORT,
                                   command_interface='position'))
    j.command(1.0)
    j.advance(500)
    torque = j.torque
    j.reconfigure(JointConfig(params=BODY, h=H, phi0=0.3, max_effort=MAX_EFFORT,
                              command_interface='position', servo=ServoGains(velocity_i=0.0)))
    j.advance(1)
    assert j.torque != torque
    j.reset()
    j.command(0.3)
    j.advance(1)
    # From rest at the target with the integral forgotten: only the gravity feed-forward.
    assert j.torque == BODY.m * BODY.g * BODY.l * math.sin(0.3)


def test_bad_gains_say_why() -> None:
    with pytest.raises(JointError, match=re.escape('servo.velocity_i must be a finite number '
                                                   '>= 0, got -1.0')):
        ServoGains(velocity_i=-1.0)
    with pytest.raises(JointError, match=re.escape('servo.position_p must be a finite number '
                                                   '>= 0, got nan')):
        ServoGains(position_p=math.nan)


@pytest.mark.parametrize(('interface', 'dphi0'), [('position', 0.0), ('velocity', 0.5)])
def test_before_any_command_the_drive_holds_the_initial_state(interface: str,
                                                              dphi0: float) -> None:
    """The held command starts as the URDF's initial_value: φ0 (position), φ'0 (velocity)."""
    j = SimulatedJoint(JointConfig(params=BODY, h=H, phi0=0.3, dphi0=dphi0,
                                   max_effort=MAX_EFFORT, command_interface=interface))
    assert j.target == {'position': 0.3, 'velocity': dphi0}[interface]
    worst = 0.0
    for _ in range(2000):
        j.advance(1)
        st = j.stepper
        worst = max(worst, abs(st.phi - 0.3) if interface == 'position'
                    else abs(st.dphi - dphi0) / dphi0)
    # Gravity is fed forward; the damping torque (γ I φ' = 0.01 N m at 0.5 rad/s) is not, so
    # the speed dips until the integral holds it: within 1 %, and within 1e-3 rad at rest.
    assert worst <= (1e-3 if interface == 'position' else 0.01)
    j.reset()
    assert j.target == {'position': 0.3, 'velocity': dphi0}[interface]


# ---------------------------------------------------------------- the sampled loop's limits
def run_law(gains: ServoGains, params: PendulumParams, target: float, steps: int) -> list[float]:
    """Return φ after each step of the core stepped with the written-out law (no limits)."""
    tau = law('position', target, gains, max_effort=math.inf, max_velocity=math.inf)
    st = Stepper(params, 0.0, 0.0, H)
    out = []
    for _ in range(steps):
        st.step(tau(st.phi, st.dphi))  # type: ignore[operator]
        out.append(st.phi)
    return out


def test_position_gains_beyond_the_sampled_loops_limit_are_refused_with_the_limit() -> None:
    """position_p 1e6 used to be taken and the joint ran away (to ~1e3 rad) without a word."""
    limit = eigen_limit(ServoGains(), BODY.inertia, H)
    # The limit is real: just below it the loop settles on the target, just above it the
    # same law on the same core runs away (no damping; gravity is fed forward).
    still = PendulumParams(m=BODY.m, l=BODY.l, inertia=BODY.inertia, g=BODY.g, gamma=0.0, n=1.0)
    for factor, ratio in ((0.9, 0.1), (1.1, 10.0)):   # the error decays, or grows, tenfold
        run = run_law(ServoGains(position_p=factor * limit), still, 1e-3, 4000)
        first, last = (max(abs(p - 1e-3) for p in part) for part in (run[:100], run[-100:]))
        assert (last < ratio * first) if ratio < 1.0 else (last > ratio * first), factor
    expected = (f'servo.position_p 1e+06 1/s makes the position servo unstable at h = 0.001 s '
                f'(its loop is sampled every step, inertia {BODY.inertia:g} kg m^2): it must '
                f'be below {limit:.6g} 1/s with the other gains as set')
    with pytest.raises(JointError, match=re.escape(expected)):
        drive('position', 1.0, 0.001, servo=ServoGains(position_p=1e6))
    drive('position', 1.0, 0.001, servo=ServoGains(position_p=0.98 * limit))   # taken


@pytest.mark.parametrize(('gains', 'name', 'value', 'relation', 'bound', 'unit'), [
    # The velocity loop's limits in closed form: velocity_p < 2 I/h + h velocity_i/2,
    # velocity_i < velocity_p/h (Jury's conditions on λ² − (2 − a) λ + (1 − a + b)).
    (ServoGains(velocity_p=1e6), 'velocity_p', '1e+06', 'below',
     2 * BODY.inertia / H + H * 20.0 / 2, 'N m s/rad'),
    (ServoGains(velocity_i=1e6), 'velocity_i', '1e+06', 'below', 4.0 / H, 'N m/rad'),
    (ServoGains(velocity_p=0.0), 'velocity_p', '0', 'above', H * 20.0, 'N m s/rad'),
])
def test_velocity_gains_beyond_the_sampled_loops_limits_are_refused(
        gains: ServoGains, name: str, value: str, relation: str, bound: float,
        unit: str) -> None:
    expected = (f'servo.{name} {value} {unit} makes the velocity servo unstable at h = 0.001 s '
                f'(its loop is sampled every step, inertia {BODY.inertia:g} kg m^2): it must be '
                f'{relation} '
                f'{bound:.6g} {unit} with the other gains as set')
    with pytest.raises(JointError, match=re.escape(expected)):
        drive('velocity', 1.0, 0.001, servo=gains)


@pytest.mark.parametrize('gains', [ServoGains(), ServoGains(0.0, 0.0, 0.0),
                                   ServoGains(velocity_i=0.0), ServoGains(position_p=0.0)])
def test_stable_and_uncorrected_loops_are_taken(gains: ServoGains) -> None:
    """A gain of 0 leaves a state uncorrected (a root at 1), not growing: taken."""
    for interface in ('velocity', 'position'):
        assert loop_refusal(gains, BODY.inertia, H, interface) is None
        run = drive(interface, 0.5, 0.01, servo=gains)
        assert len(run) == 10
        assert all(math.isfinite(x) for row in run for x in row)
        assert max(abs(tau) for *_, tau in run) <= MAX_EFFORT
    # The written-out position loop has no root outside the unit circle (one on it where a
    # gain is 0): what is uncorrected stays, nothing grows.
    assert spectral_radius(gains, BODY.inertia, H) <= 1.0 + 1e-9
