"""The node's ROS-free parts under hostile inputs: joint, commands, parameters, drivers, stats."""
from __future__ import annotations

import dataclasses
import math

import pytest
from joint_fixtures import PARAMS, H, joint  # the joint every ROS-free test starts from

from pendulum_sim.core.model import MAX_SPEED
from pendulum_sim.joint import commands
from pendulum_sim.joint.commands import Drops
from pendulum_sim.joint.drivers import RealTimeDriver, SyncDriver, make_driver, wake_period
from pendulum_sim.joint.exchange import Gate, SyncExchange
from pendulum_sim.joint.joint import SimulatedJoint
from pendulum_sim.joint.parameters import SPECS, check, start_epoch_ns
from pendulum_sim.joint.realtime import WakeStats
from pendulum_sim.joint.telemetry import Telemetry


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
        j.reconfigure(dataclasses.replace(config, sensor_delay_steps=delay))
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
    driver = SyncDriver(j, ex, lambda with_clock: True, lambda level, text: None, 0,
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



def test_a_synchronous_state_held_back_by_the_sensor_delay_is_not_waited_for() -> None:
    """sensor.delay 25 ms, 10 ms periods: the states at 0, 10 and 20 ms cannot go out; the
    driver advances through them at once with the command held (no sync_timeout, even with
    the stop action), and the first answer answers the first state that went out."""
    clock = FakeClock()
    j = joint(period_steps=10, sensor_delay_steps=25)
    ex = SyncExchange(Gate(), 10**12, 'stop')
    samples: list[tuple[int, int]] = []     # (step when published, the measurement's stamp)

    def publish(with_clock: bool) -> bool:
        sample = j.sample()
        if sample is not None:
            samples.append((j.steps, sample.stamp_ns))
        return sample is not None

    driver = SyncDriver(j, ex, publish, lambda level, text: None, 0, lambda: (True, 1),
                        'waiting', clock=clock)
    for _ in range(4):
        driver.wake(0, 10**9)
    assert samples == [(30, 5_000_000)] and j.steps == 30
    assert ex.awaiting is not None and ex.awaiting.index == 0 and ex.stats['timeouts'] == 0
    assert driver.command(2.0, None, 0) == 30_000_000    # recorded at the publication stamp
    assert j.steps == 40 and j.target == 2.0 and samples[-1] == (40, 15_000_000)


# ---------------------------------------------------------------- what the node only wires
def test_the_service_replies_say_what_happened_and_when() -> None:
    from pendulum_sim.joint.replies import pause_reply, reset_reply, step_reply

    assert reset_reply({'phi0': 0.3, 'dphi0': 0.0}, 1.25, None) == (
        'reset to phi = 0.3 rad, dphi = 0.0 rad/s at t = 1.25 s (simulated time goes on)')
    assert reset_reply({'phi0': 0.3, 'dphi0': 0.0}, 1.25, 'non-finite state') == (
        'reset to phi = 0.3 rad, dphi = 0.0 rad/s at t = 1.25 s (simulated time goes on) '
        '(was stopped: non-finite state)')
    assert pause_reply(True, True, 2.0) == 'paused at t = 2 s'
    assert pause_reply(False, False, 2.0) == 'already running at t = 2 s'
    j = joint(period_steps=10)
    j.advance(25)                       # half-way through period 2
    # 3 periods after a budget of 2: from the start of period 2 to the end of period 6.
    assert step_reply(j, 2, 3) == 'stepping 3 control period(s) of 0.01 s to t = 0.07 s'


def test_a_live_change_is_refused_by_the_whole_set_then_by_the_running_joint() -> None:
    from pendulum_sim.joint.parameters import joint_config, refusal

    values = defaults(phi0=0.3)
    j = SimulatedJoint(joint_config(values, 0))  # type: ignore[arg-type]
    assert refusal(values, [('gamma', 0.5)], j) is None  # type: ignore[arg-type]
    reason = refusal(values, [('integrator', 'euler2')], j)  # type: ignore[arg-type]
    assert reason is not None and reason.startswith('integrator must be one of ')
    assert reason.endswith(", got 'euler2'")
    assert refusal(values, [('unknown', 1.0)], j) is None  # type: ignore[arg-type]


def test_each_driver_applies_the_live_parameters_of_its_mode() -> None:
    from pendulum_sim.joint.parameters import joint_config

    values = defaults(publish_rate=100.0, lockstep=True)
    j = SimulatedJoint(joint_config(values, 0))  # type: ignore[arg-type]
    rt = RealTimeDriver(j, Gate(), lambda c: True, lambda level, text: None, 0, 1.0,
                        lockstep=True, clock=FakeClock())
    rt.reconfigure({**values, 'real_time_factor': 0.0, 'gamma': 0.25}, {'real_time_factor',
                                                                         'gamma'}, 0)
    assert rt.asap and j.config.params.gamma == 0.25
    ex = SyncExchange(Gate(), 10**9, 'hold')
    sync = SyncDriver(j, ex, lambda c: True, lambda level, text: None, 0, lambda: (True, 1),
                      'waiting', clock=FakeClock())
    sync.reconfigure({**values, 'sync_timeout': 0.25, 'sync_timeout_action': 'stop'},
                     {'sync_timeout', 'sync_timeout_action'}, 0)
    assert (ex.timeout_ns, ex.action) == (250_000_000, 'stop')


def test_a_parameter_storm_reconfigures_the_joint_once_a_wake_with_the_last_values() -> None:
    """Parameter sets are only noted; each wake applies all noted since the last at once.

    1000 sets between two wakes used to reconfigure the joint 1000 times in the parameter
    callbacks, between the ticks; now the wake reconfigures once, with the last values, before
    it steps, and the set counts from the step at which it arrived.
    """
    from pendulum_sim.joint.parameters import joint_config, merged

    clock = FakeClock()
    values = defaults(publish_rate=100.0)
    j = SimulatedJoint(joint_config(values, 0))  # type: ignore[arg-type]
    driver = RealTimeDriver(j, Gate(), lambda c: True, lambda level, text: None, 0, 1.0,
                            lockstep=False, clock=clock)
    reconfigured: list[set[str]] = []
    applied = driver.reconfigure

    def counting(v: object, names: set[str], now_ns: int) -> None:
        reconfigured.append(set(names))
        applied(v, names, now_ns)  # type: ignore[arg-type]

    driver.reconfigure = counting  # type: ignore[method-assign]
    current = dict(values)
    for wake in range(1, 4):
        for k in range(1000):
            current = merged(current, [('gamma', 1.0 + k / 1000 + wake)])
            driver.take_parameters(current, {'gamma'})  # type: ignore[arg-type]
            assert j.config.params.gamma != current['gamma']   # noted, not applied
        current = merged(current, [('max_effort', 5.0 + wake)])
        driver.take_parameters(current, {'max_effort'})  # type: ignore[arg-type]
        steps = j.steps
        clock.ns = wake * 10_000_000
        driver.wake(clock.ns, clock.ns + 10_000_000)
        assert j.steps > steps   # the tick went on stepping
        assert reconfigured == [{'gamma', 'max_effort'}] * wake
        assert (j.config.params.gamma, j.config.max_effort) == (1.999 + wake, 5.0 + wake)
    assert (driver.parameter_sets, driver.reconfigures) == (3003, 3)
    clock.ns += 10_000_000
    driver.wake(clock.ns, clock.ns + 10_000_000)   # nothing new: no reconfigure
    assert driver.reconfigures == 3 and len(reconfigured) == 3


def test_a_due_wake_is_served_before_a_queued_parameter_set_and_only_once() -> None:
    """The timer's event can wait behind queued parameter sets; a set first serves the wake
    that is due (the latest on the timer's grid), and the timer's event then finds it taken."""
    ms = 1_000_000
    stats = WakeStats(5 * ms)
    assert stats.overdue(0) is None                   # the first wake is the timer's own
    stats.wake(0, 100)
    assert stats.overdue(4 * ms) is None              # not yet due
    assert stats.overdue(5 * ms) == 5 * ms            # due: served by the set
    stats.wake(5 * ms, 5 * ms)
    assert stats.taken(5 * ms)                        # the timer's event for it: nothing to do
    assert not stats.taken(10 * ms)
    assert stats.overdue(23 * ms) == 20 * ms          # late: the latest due, the rest missed
    stats.wake(20 * ms, 23 * ms)
    assert (stats.wakes, stats.missed) == (3, 2)
    assert stats.taken(15 * ms) and stats.taken(20 * ms) and not stats.taken(25 * ms)
    assert WakeStats(0).overdue(10**12) is None      # no period (as fast as possible, sync)
    assert not WakeStats(0).taken(0)


# ---------------------------------------------------------------- the mode's timer and reports
@pytest.mark.parametrize(('mode', 'period', 'scheduled', 'kind'), [
    ({}, 1.0 / 50.0, True, RealTimeDriver),                              # real time
    ({'lockstep': True}, 1e-3, True, RealTimeDriver),                    # paced lockstep
    ({'lockstep': True, 'real_time_factor': 0.0}, 1e-3, False, RealTimeDriver),   # free
    ({'lockstep': True, 'synchronous': True, 'real_time_factor': 0.0}, 0.02, False,
     SyncDriver),
])
def test_each_mode_has_its_timer_period_and_driver(mode: dict[str, object], period: float,
                                                   scheduled: bool, kind: type) -> None:
    values = defaults(publish_rate=50.0, **mode)
    assert wake_period(values) == (period, scheduled)
    driver = make_driver(values, joint(), Gate(), lambda c: True, lambda level, text: None, 0,
                         lambda: (True, 1), 'waiting')
    assert type(driver) is kind
    if isinstance(driver, SyncDriver):
        assert driver.exchange.timeout_ns == 1_000_000_000 and driver.exchange.action == 'hold'
    else:
        assert driver.lockstep == bool(mode.get('lockstep', False))


def test_a_negative_start_time_anchors_real_time_to_the_wall_clock() -> None:
    wall = 1_700_000_000_123_456_789
    assert start_epoch_ns(defaults(start_time=-1.0), wall) == wall
    assert start_epoch_ns(defaults(start_time=-1.0, lockstep=True), wall) == 0
    assert start_epoch_ns(defaults(start_time=2.5), wall) == 2_500_000_000


def test_a_report_is_due_once_a_second_and_missed_ones_are_not_made_up() -> None:
    j = joint()
    gate = Gate()
    driver = RealTimeDriver(j, gate, lambda c: True, lambda level, text: None, 0, 1.0, False)
    tel = Telemetry(j, driver, gate, Drops(), WakeStats(0), {}, 1.0, start_ns=7)
    s = 1_000_000_000
    assert not tel.report_due(s + 6)
    assert tel.report_due(s + 7)
    assert not tel.report_due(s + 8)
    assert tel.report_due(5 * s + 100)      # three missed: one report, the next at 6 s + 7
    assert not tel.report_due(6 * s + 6)
    assert tel.report_due(6 * s + 7)


def test_friction_is_a_live_physical_parameter_of_the_joint() -> None:
    """friction: validated as the core validates it, live, and the joint sticks under it.

    Set live on a swinging joint it applies from the next step (the state kept); the joint
    then comes to rest inside |m g l sin φ| <= friction and stays there to the bit, and the
    energy terms' dissipated power counts f |φ'| while it moves.
    """
    from pendulum_sim.core.model import dissipated_power
    from pendulum_sim.joint.parameters import joint_config

    assert check(defaults(friction=-0.5)) == 'friction must be >= 0 N m, got -0.5'
    assert check(defaults(friction=math.inf)) == 'friction must be finite, got inf'
    assert check(defaults(friction=0.3, integrator='dopri5')) is None  # every method takes it
    values = defaults(phi0=0.8)
    j = SimulatedJoint(joint_config(values, 0))  # type: ignore[arg-type]
    j.advance(300)
    moving = j.stepper.dphi
    assert moving != 0.0
    f = 0.3
    j.reconfigure(joint_config({**values, 'friction': f}, 0))  # type: ignore[arg-type]
    assert j.stepper.dphi == moving and j.config.params.friction == f
    assert j.terms().dissipated_power == pytest.approx(
        float(dissipated_power(j.config.params.with_changes(friction=0.0), moving))
        + f * abs(moving), rel=1e-12)
    j.advance(6000)
    rest = j.stepper.phi
    assert j.stepper.dphi == 0.0
    params = j.config.params
    assert params.mgl * abs(math.sin(rest)) <= f
    j.advance(500)
    assert (j.stepper.phi, j.stepper.dphi) == (rest, 0.0)
