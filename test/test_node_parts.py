"""The node's ROS-free parts under hostile inputs: joint, commands, parameters, drivers, stats."""
from __future__ import annotations

import math

import pytest

from pendulum_sim.core import PendulumParams
from pendulum_sim.core.model import MAX_SPEED
from pendulum_sim.node import commands
from pendulum_sim.node.drivers import RealTimeDriver, SyncDriver
from pendulum_sim.node.exchange import Gate, SyncExchange
from pendulum_sim.node.joint import JointConfig, SimulatedJoint
from pendulum_sim.node.parameters import SPECS, check
from pendulum_sim.node.realtime import WakeStats

PARAMS = PendulumParams(m=0.2, l=1.0, inertia=0.2, g=9.8, gamma=0.1, n=1.0)
H = 1e-3


def joint(**changes: object) -> SimulatedJoint:
    base: dict[str, object] = {'params': PARAMS, 'h': H, 'phi0': 0.3, 'max_effort': 5.0}
    base.update(changes)
    return SimulatedJoint(JointConfig(**base))  # type: ignore[arg-type]


def defaults(**changes: object) -> dict[str, object]:
    values: dict[str, object] = {s.name: s.default for s in SPECS}
    values.update(changes)
    return values


# ---------------------------------------------------------------- the joint
def test_a_sensor_delay_changed_live_back_and_forth_never_crashes() -> None:
    """sensor.delay 0.01 -> 0 -> 0.01 used to raise IndexError in sample()."""
    j = joint(sensor_delay_steps=10)
    j.advance(50)
    assert j.sample() is not None
    config = j.config
    for delay in (0, 10):
        j.reconfigure(JointConfig(**{**config.__dict__, 'sensor_delay_steps': delay}))
        j.advance(5)
        sample = j.sample()
        if delay:
            assert sample is None              # the delay line fills again first
            j.advance(10)
            sample = j.sample()
            assert sample is not None and sample.stamp_ns == (j.steps - 10) * 1_000_000
        else:
            assert sample is not None and sample.stamp_ns == j.steps * 1_000_000


def test_no_torque_drives_the_joint_past_the_core_speed_bound() -> None:
    """max_effort and max_velocity at 1e6 (in range) used to spin the joint to 1e6 rad/s."""
    j = joint(max_effort=1e6, max_velocity=1e6, phi0=0.0)
    j.command(1e6)
    j.advance(2000)
    assert abs(j.stepper.dphi) <= MAX_SPEED
    assert j.counters.limited > 0 and j.failed is None


def test_the_velocity_limit_holds_within_one_step_of_torque() -> None:
    j = joint(max_effort=1e3, max_velocity=50.0, phi0=0.0)
    j.command(1e3)
    peak = 0.0
    for _ in range(500):
        j.advance(1)
        peak = max(peak, abs(j.stepper.dphi))
    # Torque drives it no faster than 50 rad/s; past that only gravity adds speed, at most
    # what falling through 2 l gives (w0^2 = m g l / I = 9.8 s^-2), plus one step of it.
    w0_sq = PARAMS.m * PARAMS.g * PARAMS.l / PARAMS.inertia
    assert 49.0 < peak <= math.sqrt(50.0**2 + 4.0 * w0_sq) + w0_sq * H


# ---------------------------------------------------------------- commands
def test_drop_reasons_are_a_bounded_set_whatever_the_names() -> None:
    """Each distinct list of wrong names used to add a diagnostics key and a log line."""
    drops = commands.Drops()
    lines = []
    for n in range(30):
        names = [f'wrong_{n}_{i}' for i in range(10_000)]
        decoded = commands.from_joint_state('pendulum_joint', 'effort', names, [0.0] * 10_000,
                                            0, 0)
        line = drops.drop('/ns/joint_commands', decoded.reason, decoded.detail)
        if line is not None:
            lines.append(line)
    assert drops.counts == {"/ns/joint_commands: no joint named 'pendulum_joint'": 30}
    assert len(lines) == 1 and len(lines[0]) < 400
    assert lines[0].startswith("dropped a command on /ns/joint_commands: no joint named "
                               "'pendulum_joint', names ['wrong_0_0', ")
    assert lines[0].endswith('... (1 so far)')


def test_decoding_reads_the_interface_field_and_stamp_0_is_a_stamp() -> None:
    ok = commands.from_joint_state('j', 'velocity', ['a', 'j'], [1.0, 2.5], 0, 0)
    assert ok == commands.Decoded(2.5, 0)
    short = commands.from_joint_state('j', 'velocity', ['a', 'j'], [1.0], 3, 4)
    assert short.reason == "no velocity for joint 'j'"
    assert short.detail == '1 velocity values for 2 names'
    assert commands.from_array([1.0, 2.0]) == commands.Decoded(
        0.0, None, 'expected 1 value (one joint)', 'got 2')
    assert commands.from_array([1.5]) == commands.Decoded(1.5, None)


# ---------------------------------------------------------------- parameters
@pytest.mark.parametrize('name', ['a\tb', 'a\nb', 'a\x00b', 'a\x01b'])
def test_a_joint_name_with_a_control_character_is_refused(name: str) -> None:
    control = next(c for c in name if c not in 'ab')
    assert check(defaults(joint_name=name)) == (
        f'joint_name must hold no control characters (a URDF or a log would not show them), '
        f'got {name!r} with {control!r}')


def test_synchronous_mode_without_a_command_input_is_refused() -> None:
    values = defaults(lockstep=True, synchronous=True, effort_input=False)
    assert check(values) == ('synchronous needs a command input to answer each state: set one '
                             'of effort_input, joint_commands_input, array_command_input to '
                             'true')
    assert check({**values, 'array_command_input': True}) is None


# ---------------------------------------------------------------- drivers and statistics
def test_lockstep_as_fast_as_possible_counts_no_overruns() -> None:
    stats = WakeStats(0)
    for k in range(5):
        stats.wake(k * 1000, k * 1000)
        stats.done(k * 1000, k * 1000 + 10_000_000, 100)
    assert stats.wakes == 5 and stats.overruns == 0


class FakeClock:
    def __init__(self) -> None:
        self.ns = 0

    def __call__(self) -> int:
        return self.ns


def test_stepping_while_paused_counts_its_wall_time_in_the_real_time_factor() -> None:
    """Stepping a paused run used to report a factor of 10 345 (no wall time counted)."""
    clock = FakeClock()
    j = joint(period_steps=10)
    gate = Gate(paused=True)
    published: list[bool] = []
    driver = RealTimeDriver(j, gate, published.append, lambda level, text: None, 0, 1.0,
                            lockstep=True, clock=clock)
    clock.ns = 5_000_000_000                      # paused for 5 s: not counted
    gate.step(100)
    driver.gate_changed(clock.ns)
    while gate.open:
        clock.ns += 1_000_000                     # each wake: 1 ms of wall time, one period
        driver.wake(clock.ns, clock.ns)
    assert len(published) == 100 and j.steps == 1000
    # 1 s simulated over 0.1 s of wall time while the budget ran: 10x.
    assert driver.rate.total(clock.ns + 10**12) == pytest.approx(10.0, rel=1e-9)


def test_one_long_synchronous_period_is_advanced_over_many_wakes() -> None:
    """A long period (publish_rate 0.1 at h = 1e-6 is 1e7 steps) used to be advanced in one
    callback, blocking ~/reset and SIGINT for tens of seconds."""
    clock = FakeClock()
    j = joint(h=1e-5, period_steps=200_000)
    gate = Gate()
    ex = SyncExchange(gate, 10**12, 'hold')
    driver = SyncDriver(j, ex, lambda with_clock: None, lambda level, text: None, 0,
                        lambda: (True, 1), 'waiting', clock=clock)
    driver.wake(0, 0)                                   # state 0 out
    ticks = iter(range(1, 10**9))

    def advancing() -> int:                             # each look at the clock: 1 ms later
        clock.ns = next(ticks) * 1_000_000
        return clock.ns

    driver.clock = advancing
    assert driver.command(1.0, None, 0) == 0            # the answer to state 0
    wakes = 1
    while j.steps < 200_000:
        assert ex.stepping
        start = advancing()
        driver.wake(start, start + 10_000_000)          # 10 ms of work per wake at most
        wakes += 1
    assert not ex.stepping and ex.awaiting is not None and ex.awaiting.step == 200_000
    assert wakes > 10

