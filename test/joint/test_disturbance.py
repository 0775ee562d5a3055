"""The disturbance torque pulse: one rule in the joint, in whole steps, as node parameters.

The oracle: with gamma = 0 and g = 0 the joint is a free rotor, phi'' = tau / I, and RK4 is
exact for a torque constant over each step, so a pulse of torque T acting for D seconds changes
the angular momentum I phi' by exactly T D (up to round-off) and moves the angle along the
closed-form parabola; outside the window nothing changes.
"""
from __future__ import annotations

import math
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from pendulum_sim.core import PendulumParams
from pendulum_sim.joint.errors import JointError
from pendulum_sim.joint.joint import (
    MAX_PULSES,
    JointConfig,
    Pulse,
    SimulatedJoint,
    parse_pulses,
    pulses_text,
)
from pendulum_sim.joint.parameters import SPEC_BY_NAME, SPECS, check, joint_config
from pendulum_sim.testing import TestingError, closed_loop
from pendulum_sim.testing.batch import BatchStats, batchable, run_batch
from pendulum_sim.testing.campaign.episode import RUN_COLUMNS, run_episode
from pendulum_sim.testing.campaign.spec import parse_spec
from pendulum_sim.testing.examples import pd, pd_batch
from pendulum_sim.testing.scene import scene_values

H = 1e-3
ROTOR = PendulumParams(m=0.2, l=1.0, inertia=0.2, g=0.0, gamma=0.0, n=1.0)
NAMES = ('disturbance.torque', 'disturbance.start', 'disturbance.duration')


def rotor(torque: float = 0.0, start: int = 0, steps: int = 0, **changes: object
          ) -> SimulatedJoint:
    base: dict[str, object] = {'params': ROTOR, 'h': H, 'phi0': 0.3, 'dphi0': 0.1,
                               'disturbance_torque': torque, 'disturbance_start_step': start,
                               'disturbance_steps': steps}
    base.update(changes)
    return SimulatedJoint(JointConfig(**base))  # type: ignore[arg-type]


def trajectory(j: SimulatedJoint, k: int) -> np.ndarray:
    """Return the (phi, phi') after each of ``k`` single steps."""
    out = np.empty((k, 2))
    for i in range(k):
        j.advance(1)
        out[i] = j.stepper.phi, j.stepper.dphi
    return out


def test_the_parameters_are_live_with_units_ranges_and_no_pulse_by_default() -> None:
    for name in NAMES:
        spec = SPEC_BY_NAME[name]
        assert not spec.read_only and spec.default == 0.0
        assert spec.low is not None and spec.high is not None
    assert [SPEC_BY_NAME[n].unit for n in NAMES] == ['N m', 's', 's']
    values = {s.name: s.default for s in SPECS}
    assert not joint_config(values).has_disturbance


def test_the_window_is_decided_in_whole_steps_of_h() -> None:
    values = {s.name: s.default for s in SPECS}
    values.update({'disturbance.torque': 0.5, 'disturbance.start': 0.1004,
                   'disturbance.duration': 0.2496})
    c = joint_config(values)
    assert (c.disturbance_start_step, c.disturbance_steps) == (100, 250)
    assert [c.disturbance_at(k) for k in (0, 99, 100, 349, 350, 10**6)] == [
        0.0, 0.0, 0.5, 0.5, 0.0, 0.0]
    values['disturbance.duration'] = 0.0004      # rounds to no step: no pulse
    assert not joint_config(values).has_disturbance


def test_the_pulse_changes_the_angular_momentum_by_torque_times_duration() -> None:
    torque, start, steps, total = 0.3, 100, 250, 600
    free = trajectory(rotor(), total)
    kicked = trajectory(rotor(torque, start, steps), total)
    # Nothing before the window: bit for bit.
    assert np.array_equal(kicked[:start], free[:start])
    inertia, a = ROTOR.inertia, torque / ROTOR.inertia
    jump = inertia * (kicked[:, 1] - free[:, 1])
    duration = steps * H
    # After the window the jump is T D, and stays (no torque, no damping, no gravity).
    np.testing.assert_allclose(jump[start + steps - 1:], torque * duration, rtol=0,
                               atol=1e-13)
    # Inside it the momentum grows by T h per step: the pulse acts in exactly `steps` steps.
    k = np.arange(start, start + steps)
    np.testing.assert_allclose(jump[k], torque * (k - start + 1) * H, rtol=0, atol=1e-13)
    # The angle follows the closed form: a parabola in the window, then a line.
    t_after = np.arange(start + steps - 1, total) * H + H   # after i + 1 steps
    closed = 0.3 + 0.1 * t_after + 0.5 * a * duration**2 + a * duration * (
        t_after - (start + steps) * H)
    np.testing.assert_allclose(kicked[start + steps - 1:, 0], closed, rtol=0, atol=1e-12)


def test_the_effort_stays_the_actuators_torque_and_the_balance_counts_the_pulse() -> None:
    params = PendulumParams(m=0.2, l=1.0, inertia=0.2, g=9.8, gamma=0.5, n=1.0)
    j = rotor(-0.8, 200, 300, params=params, max_effort=5.0)
    j.command(0.25)
    phi = [j.stepper.phi]
    effort = []
    for _ in range(1000):
        j.advance(1)
        phi.append(j.stepper.phi)
        sample = j.sample()
        assert sample is not None
        effort.append(sample.effort)
    assert effort == [0.25] * 1000 and j.torque == 0.25   # the pulse is not in the effort
    st = j.stepper
    # The input work is the work of actuator and pulse, each over its own steps.
    dphi = np.diff(phi)
    expected = 0.25 * dphi.sum() - 0.8 * dphi[200:500].sum()
    assert st.input_work == pytest.approx(expected, rel=1e-12, abs=1e-15)
    # The balance E - E0 + dissipated - input closes with the pulse in it, not without.
    assert abs(st.residual) < 1e-9
    assert abs(st.residual - 0.8 * dphi[200:500].sum()) > 1e-3


def test_bad_values_are_refused_with_the_value_and_the_rule() -> None:
    with pytest.raises(JointError, match=re.escape(
            'disturbance.torque must be a finite number of N m, got inf')):
        rotor(math.inf, 0, 10)
    values = {s.name: s.default for s in SPECS}
    values['disturbance.start'] = -1.0
    assert check(values) == 'disturbance.start must be a finite number of seconds >= 0, got -1.0'
    with pytest.raises(TestingError, match=re.escape(
            'disturbance.duration must be a finite number of seconds >= 0, got nan')):
        scene_values('controller_test', {'disturbance.duration': math.nan})


def test_several_pulses_add_their_torque_times_duration_to_the_momentum() -> None:
    """The free rotor's momentum after the pulses is the sum of T D, overlapping or not."""
    pulses = parse_pulses('0.3 0.1 0.25; -0.5, 0.2, 0.05;  0.2 0.6 0.1', H)
    assert pulses == (Pulse(0.3, 100, 250), Pulse(-0.5, 200, 50), Pulse(0.2, 600, 100))
    j = rotor(0.1, 0, 20, pulses=pulses)   # the single pulse's key still acts beside them
    assert [j.config.disturbance_at(k) for k in (0, 19, 20, 100, 199, 200, 249, 250, 349,
                                                 350, 600, 699, 700)] == [
        0.1, 0.1, 0.0, 0.3, 0.3, 0.3 - 0.5, 0.3 - 0.5, 0.3, 0.3, 0.0, 0.2, 0.2, 0.0]
    free = rotor()
    j.advance(800)
    free.advance(800)
    jump = ROTOR.inertia * (j.stepper.dphi - free.stepper.dphi)
    assert jump == pytest.approx(0.1 * 0.02 + 0.3 * 0.25 - 0.5 * 0.05 + 0.2 * 0.1, abs=1e-13)


def test_the_pulses_parameter_is_read_from_a_scene_and_refused_with_the_reason() -> None:
    values = {s.name: s.default for s in SPECS}
    values['disturbance.pulses'] = '1.0 0.5 0.1; 2.0 1.0 0.0'   # the second has no step
    c = joint_config(values)
    assert c.all_pulses == (Pulse(1.0, 500, 100),) and c.has_disturbance
    assert pulses_text([(1.0, 0.5, 0.1), (-2.0, 1.0, 0.25)]) == '1.0 0.5 0.1; -2.0 1.0 0.25'
    for text, reason in [
            ('1.0 0.5', "disturbance.pulses: pulse 1 must be three numbers 'torque start "
             "duration' (N m, s, s), got '1.0 0.5'"),
            ('1 0 1; x 0 1', "disturbance.pulses: pulse 2 must be three numbers 'torque start "
             "duration' (N m, s, s), got 'x 0 1'"),
            ('inf 0 1', 'disturbance.pulses: pulse 1 torque must be a finite number of N m, '
             'got inf'),
            ('1 -0.5 1', 'disturbance.pulses: pulse 1 start must be a finite number of '
             'seconds >= 0, got -0.5')]:
        values['disturbance.pulses'] = text
        assert check(values) == reason
    values['disturbance.pulses'] = '; '.join(['1 0 1'] * (MAX_PULSES + 1))
    assert check(values) == f'disturbance.pulses holds {MAX_PULSES + 1} pulses; at most ' \
        f'{MAX_PULSES}'


def test_a_live_change_moves_the_window_from_the_next_step() -> None:
    j = rotor()
    j.advance(50)
    j.reconfigure(JointConfig(params=ROTOR, h=H, phi0=0.3, dphi0=0.1, disturbance_torque=0.2,
                              disturbance_start_step=40, disturbance_steps=20))
    before = j.stepper.dphi
    j.advance(20)   # steps 50..69: the window 40..59 has 10 steps left
    assert ROTOR.inertia * (j.stepper.dphi - before) == pytest.approx(0.2 * 10 * H, abs=1e-15)


def test_the_pulse_acts_once_per_run_not_again_after_a_reset() -> None:
    j = rotor(0.3, 100, 250)
    j.advance(400)
    j.reset()    # simulated time goes on at step 400: the window 100..349 is past
    j.advance(400)
    free = rotor()
    free.advance(400)
    assert (j.stepper.phi, j.stepper.dphi) == (free.stepper.phi, free.stepper.dphi)


# ------------------------------------------------------------------ closed loops and campaigns
PULSE = {'disturbance.torque': 1.5, 'disturbance.start': 3.0, 'disturbance.duration': 0.2}


def test_a_closed_loop_run_shows_the_pulse_in_its_trajectory_and_metrics() -> None:
    calm = closed_loop(pd, periods=600)
    hit = closed_loop(pd, periods=600, overrides=PULSE)
    before = calm.t < 3.0 + 1e-9    # the state at t = 3 s is measured before the pulse acts
    assert np.array_equal(hit.position[before], calm.position[before])
    assert np.array_equal(hit.effort[before], calm.effort[before])
    assert not np.array_equal(hit.position[~before], calm.position[~before])
    # The pulse pushes the settled joint off its target in the pulse's direction, and the
    # controller works against it; the error integrals grow, and it settles again later.
    assert hit.position[~before].max() > calm.position[~before].max() + 0.1
    m_calm, m_hit = calm.metrics(0.5), hit.metrics(0.5)
    assert m_hit.settling_max == hit.position[~before].max() > m_calm.settling_max
    assert m_hit.iae > m_calm.iae and m_hit.ise > m_calm.ise and m_hit.itae > m_calm.itae
    assert m_calm.settling_time < 3.0 < m_hit.settling_time < 6.0
    assert hit.effort[~before].min() < calm.effort[~before].min() - 0.1


def test_a_batch_leaves_a_pulse_inside_a_period_to_the_scalar_joint_and_agrees_with_it(
        ) -> None:
    inside = {**PULSE, 'disturbance.start': 3.005}   # half a 10 ms period in
    values = scene_values('controller_test', inside)
    assert batchable(values) == 'a disturbance pulse starts or ends inside a control period'
    [batched] = run_batch(pd_batch, [values], 400)
    scalar = closed_loop(pd_batch_scalar, periods=400, overrides=inside)
    assert not isinstance(batched, TestingError)
    assert np.array_equal(batched.position, scalar.position)


def test_a_batch_steps_pulses_on_period_boundaries_as_the_joint_does() -> None:
    """Pulses that start and end on control periods are the period's extra torque."""
    several = {**PULSE, 'disturbance.pulses': '-1.0 0.5 0.3; 0.7 0.6 1.0'}   # overlapping
    values = scene_values('controller_test', several)
    assert batchable(values) == ''
    calm = scene_values('controller_test')
    batched, unpushed = run_batch(pd_batch, [values, calm], 400)
    scalar = closed_loop(pd_batch_scalar, periods=400, overrides=several)
    assert not isinstance(batched, TestingError) and not isinstance(unpushed, TestingError)
    for name in ('position', 'velocity', 'effort', 'command'):
        assert np.array_equal(getattr(batched, name), getattr(scalar, name)), name
    assert not np.array_equal(batched.position, unpushed.position)


def pd_batch_scalar(t: float, position: float, velocity: float) -> float:
    return float(pd_batch(t, np.array([position]), np.array([velocity]))[0])


CAMPAIGN = """
controller: pendulum_sim.testing.examples:pd
scene: controller_test
episodes: 6
seed: 11
periods: 500
target: 0.5
parameters:
  disturbance.torque: {distribution: uniform, low: -2.0, high: 2.0}
  disturbance.start: 3.0
  disturbance.duration: 0.2
requirements:
  - 'settling_time < 4.5'
"""


def test_a_campaign_varies_the_pulse_like_any_node_parameter(tmp_path: Path) -> None:
    spec = parse_spec(CAMPAIGN)
    rows = [run_episode(spec.text, i, None) for i in range(6)]
    torques = [r['disturbance.torque'] for r in rows]
    assert len(set(torques)) == 6 and all(-2.0 <= x < 2.0 for x in torques)
    for r in rows[:2]:   # each row is the closed loop of its scenario
        run = closed_loop(pd, periods=500, overrides={
            'disturbance.torque': r['disturbance.torque'], 'disturbance.start': 3.0,
            'disturbance.duration': 0.2})
        assert r['iae'] == run.metrics(0.5).iae
    # A harder push costs more error: the error integral grows with |torque|.
    order = np.argsort(np.abs(torques))
    assert np.all(np.diff(np.array([rows[i]['iae'] for i in order])) > 0)
    assert {k for k in rows[0] if k not in RUN_COLUMNS} >= {'episode', *NAMES[:1], 'passed'}


@pytest.mark.ros
def test_the_node_takes_the_pulse_and_records_the_same_trajectory_as_the_joint(
        tmp_path: Path) -> None:
    """pendulum_node (its own process, real DDS) with the pulse parameters, recorded to MCAP."""
    controller = str(Path(sys.executable).parent / 'pendulum_pd_controller')
    remote = closed_loop([controller], periods=400, overrides=PULSE,
                         record=tmp_path / 'pulse.mcap')
    local = closed_loop(pd, periods=400, overrides=PULSE)
    calm = closed_loop(pd, periods=400)
    for name in ('t', 'position', 'velocity', 'effort', 'command'):
        assert getattr(remote, name).tobytes() == getattr(local, name).tobytes(), name
    after = remote.t > 3.0 + 1e-9
    assert np.abs(remote.position[after] - calm.position[after]).max() > 0.01
    assert (tmp_path / 'pulse.mcap').stat().st_size > 0


def test_the_gym_environments_still_refuse_a_pulse() -> None:
    """The batch steps pulses on period boundaries; the environments do not step pulses."""
    from pendulum_sim.gym.errors import GymError
    from pendulum_sim.gym.runner import check as gym_check

    values = scene_values('controller_test', PULSE)
    assert batchable(values) == ''
    with pytest.raises(GymError, match=r'this scene cannot: a disturbance pulse is set$'):
        gym_check(joint_config(values))


def test_a_pushed_joint_near_its_speed_bound_keeps_the_pulses_time() -> None:
    """Near its speed bound the lockstep hands a joint to a SimulatedJoint started from its
    state: its pulses move back by the steps taken, so they act when the joint's do."""
    # The PD settles by 3 s; a push from 4 s drives the joint to its speed bound, where the
    # joint takes its periods, the push still acting.
    several = {'disturbance.pulses': '-0.5 0.5 0.3; 3.0 4.0 0.5', 'max_velocity': 1.0}
    values = scene_values('controller_test', several)
    stats = BatchStats()
    [batched] = run_batch(pd_batch, [values], 500, stats=stats)
    scalar = closed_loop(pd_batch_scalar, periods=500, overrides=several)
    assert not isinstance(batched, TestingError)
    assert stats.lockstep == 1 and stats.periods.by_joint > 0 and stats.periods.swept > 0
    for name in ('position', 'velocity', 'effort', 'command'):
        assert np.array_equal(getattr(batched, name), getattr(scalar, name)), name
