"""The example controller's law and settle detector, without ROS.

Oracles: the gravity torque m g l sin φ (eq 11 of Quiroga & Ospina-Henao 2017 with an input
torque), the closed loop integrated by the core's Stepper under a zero-order hold of 10 ms (the
controller_test scene's control period), and the static equilibrium of a PD loop without
compensation, kp (φ_ref − φ) = m g l sin φ, solved independently by bisection.
"""
from __future__ import annotations

import math

import pytest

from pendulum_sim.controller import (
    ControllerError,
    PDGains,
    SettleDetector,
    SettleEvent,
    SettleLimits,
    StepSettling,
    pd_torque,
    wrap_angle,
)
from pendulum_sim.controller.pd_law import REARM_FACTOR
from pendulum_sim.core import PendulumParams, Stepper

BODY = PendulumParams(m=0.2, l=1.0, inertia=0.2, g=9.8, gamma=0.1, n=1.0)
MGL = 0.2 * 9.8 * 1.0


def closed_loop(gains: PDGains, phi0: float, seconds: float, params: PendulumParams = BODY,
                period_steps: int = 10, h: float = 1e-3) -> Stepper:
    """Run the law against the core's pendulum: sample, hold the torque for a period, repeat."""
    st = Stepper(params, phi0, 0.0, h)
    for _ in range(round(seconds / (period_steps * h))):
        st.advance(period_steps, pd_torque(gains, st.phi, st.dphi))
    return st


def test_without_gains_the_torque_is_the_gravity_torque() -> None:
    gains = PDGains(kp=0.0, kd=0.0, mgl=MGL, max_effort=100.0)
    for phi in (-3.0, -1.0, -0.1, 0.0, 0.3, 1.0, 2.5, 7.0):
        for dphi in (-2.0, 0.0, 5.0):
            assert pd_torque(gains, phi, dphi) == MGL * math.sin(phi)


def test_gravity_compensation_holds_a_static_angle() -> None:
    """At rest at 1 rad, kp = kd = 0: the joint stays put for 10 s; without mgl it falls."""
    held = closed_loop(PDGains(kp=0.0, kd=0.0, target=0.0, mgl=MGL), 1.0, 10.0)
    assert abs(held.phi - 1.0) < 1e-9
    assert abs(held.dphi) < 1e-9
    fallen = closed_loop(PDGains(kp=0.0, kd=0.0, target=0.0, mgl=0.0), 1.0, 10.0)
    assert abs(fallen.phi - 1.0) > 0.1


def test_closed_loop_converges_to_the_target_exactly() -> None:
    """With compensation the only equilibrium is the target: no static error."""
    st = closed_loop(PDGains(kp=4.0, kd=1.0, target=0.5, mgl=MGL), 1.0, 20.0)
    assert abs(st.phi - 0.5) < 1e-9
    assert abs(st.dphi) < 1e-9


def test_without_compensation_the_loop_sags_to_the_static_balance() -> None:
    """mgl = 0: the loop rests where kp (target − φ) = m g l sin φ (solved by bisection)."""
    kp, target = 4.0, 0.5
    lo, hi = 0.0, target  # f(lo) > 0 > f(hi) for f(φ) = kp (target − φ) − mgl sin φ
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if kp * (target - mid) - MGL * math.sin(mid) > 0.0:
            lo = mid
        else:
            hi = mid
    st = closed_loop(PDGains(kp=kp, kd=1.0, target=target, mgl=0.0), 1.0, 30.0)
    assert abs(st.phi - lo) < 1e-9
    assert target - lo > 0.1  # the sag is real, so the previous test's exactness means something


@pytest.mark.parametrize(('phi', 'dphi', 'sign'), [
    (0.2, 0.0, 1.0),     # below the target: push up (positive torque raises φ'')
    (0.8, 0.0, -1.0),    # above it: push down
    (0.5, 1.0, -1.0),    # at the target moving up: brake
    (0.5, -1.0, 1.0),    # moving down: brake the other way
])
def test_signs(phi: float, dphi: float, sign: float) -> None:
    gains = PDGains(kp=4.0, kd=1.0, target=0.5, mgl=0.0)
    assert math.copysign(1.0, pd_torque(gains, phi, dphi)) == sign
    assert pd_torque(gains, phi, dphi) == 4.0 * (0.5 - phi) - 1.0 * dphi


def test_wrap_angle() -> None:
    assert wrap_angle(0.0) == 0.0
    assert wrap_angle(1.0) == 1.0
    assert wrap_angle(math.pi + 0.1) == pytest.approx(-math.pi + 0.1, abs=1e-15)
    assert wrap_angle(-math.pi - 0.1) == pytest.approx(math.pi - 0.1, abs=1e-15)
    assert wrap_angle(0.3 + 6 * math.pi) == pytest.approx(0.3, abs=1e-14)
    assert abs(wrap_angle(math.pi)) == pytest.approx(math.pi)
    for x in (-20.0, -7.5, -3.2, 3.2, 9.9, 100.0):
        w = wrap_angle(x)
        assert -math.pi <= w <= math.pi
        assert math.remainder(x - w, math.tau) == pytest.approx(0.0, abs=1e-12)


def test_the_error_turns_the_short_way_round() -> None:
    """Target 3.0 rad, at −3.0 rad: 0.28 rad away through π, not 6 rad the other way."""
    gains = PDGains(kp=1.0, kd=0.0, target=3.0, mgl=0.0)
    assert pd_torque(gains, -3.0, 0.0) == pytest.approx(6.0 - math.tau)
    assert pd_torque(gains, 3.0 + math.tau, 0.0) == pytest.approx(0.0, abs=1e-15)
    # A full turn later the closed loop settles at target + 2π k, not unwinding every turn.
    st = closed_loop(PDGains(kp=4.0, kd=1.0, target=0.5, mgl=MGL), 0.4 + 2 * math.tau, 20.0)
    assert st.phi == pytest.approx(0.5 + 2 * math.tau, abs=1e-9)


def test_clipping() -> None:
    gains = PDGains(kp=1000.0, kd=0.0, target=0.5, mgl=MGL, max_effort=2.0)
    assert pd_torque(gains, 0.0, 0.0) == 2.0
    assert pd_torque(gains, 1.0, 0.0) == -2.0
    assert pd_torque(gains, 0.5, 0.0) == MGL * math.sin(0.5)  # inside the limit: untouched


@pytest.mark.parametrize(('kwargs', 'message'), [
    ({'kp': -1.0}, 'kp must be >= 0, got -1.0'),
    ({'kd': math.nan}, 'kd must be finite, got nan'),
    ({'target': math.inf}, 'target must be finite, got inf'),
    ({'mgl': -0.5}, 'mgl must be >= 0, got -0.5'),
    ({'max_effort': 0.0}, 'max_effort must be > 0, got 0.0'),
])
def test_bad_gains_are_rejected_with_a_reason(kwargs: dict[str, float], message: str) -> None:
    with pytest.raises(ControllerError, match=f'^{message}$') as info:
        PDGains(**kwargs)
    assert isinstance(info.value, ValueError)


def test_non_finite_state_is_refused() -> None:
    with pytest.raises(ControllerError, match=r'^state must be finite, got phi = nan, '
                                              r'dphi = 0.0$'):
        pd_torque(PDGains(), math.nan, 0.0)


@pytest.mark.parametrize(('kwargs', 'message'), [
    ({'position': 0.0}, 'settle_position_tolerance must be > 0, got 0.0'),
    ({'velocity': -1.0}, 'settle_velocity_tolerance must be > 0, got -1.0'),
    ({'hold': -0.1}, 'settle_hold must be >= 0, got -0.1'),
])
def test_bad_settle_limits(kwargs: dict[str, float], message: str) -> None:
    with pytest.raises(ControllerError, match=f'^{message}$'):
        SettleLimits(**kwargs)


MS = 1_000_000


def test_settle_is_measured_in_stamps_and_reported_once() -> None:
    det = SettleDetector(SettleLimits(position=0.01, velocity=0.01, hold=0.5))
    events = [det.update(k * 10 * MS, 0.0, 0.0) for k in range(50)]  # 0 … 0.49 s inside
    assert set(events) == {SettleEvent.NONE}
    assert det.update(500 * MS, 0.005, -0.005) is SettleEvent.SETTLED
    assert det.settled_at_ns == 500 * MS
    assert det.inside_since_ns == 0
    assert det.update(510 * MS, 0.0, 0.0) is SettleEvent.NONE  # once only
    # Leaving the band by less than REARM_FACTOR times a tolerance (noise) is not news …
    assert det.update(520 * MS, 0.099, 0.0) is SettleEvent.NONE
    assert det.update(530 * MS, 0.0, -0.099) is SettleEvent.NONE
    assert det.settled_at_ns == 500 * MS
    for k in range(54, 110):
        assert det.update(k * 10 * MS, 0.0, 0.0) is SettleEvent.NONE
    # … beyond it (a reset, a push) detection starts over and the next settling is reported.
    assert REARM_FACTOR == 10.0
    assert det.update(1100 * MS, 0.0, 0.101) is SettleEvent.LEFT
    assert det.settled_at_ns is None
    events = [det.update(k * 10 * MS, 0.0, 0.0) for k in range(111, 162)]  # 1.11 … 1.61 s
    assert events[:-1] == [SettleEvent.NONE] * 50
    assert events[-1] is SettleEvent.SETTLED
    assert det.settled_at_ns == 1610 * MS


def test_leaving_the_band_restarts_the_hold() -> None:
    det = SettleDetector(SettleLimits(position=0.01, velocity=0.01, hold=0.5))
    for k in range(40):
        det.update(k * 10 * MS, 0.0, 0.0)
    det.update(400 * MS, 0.0, 0.02)  # too fast: out
    for k in range(41, 91):  # 0.41 … 0.90 s: 0.49 s inside
        assert det.update(k * 10 * MS, 0.0, 0.0) is SettleEvent.NONE
    assert det.update(910 * MS, 0.0, 0.0) is SettleEvent.SETTLED
    assert det.inside_since_ns == 410 * MS


def test_time_going_back_restarts_detection() -> None:
    det = SettleDetector(SettleLimits(hold=0.0))
    assert det.update(5 * MS, 0.0, 0.0) is SettleEvent.SETTLED
    assert det.update(0, 1.0, 0.0) is SettleEvent.RESTARTED
    assert det.settled_at_ns is None
    assert det.update(1 * MS, 0.0, 0.0) is SettleEvent.SETTLED


def readme_run() -> tuple[list[int], list[float], list[float]]:
    """Return the stamps (ns), angles and rates of the README's run: the example gains from
    1 rad towards 0.5 rad on the controller_test scene, 400 periods (the test bench's run)."""
    from pendulum_sim.testing import closed_loop as run_closed_loop

    gains = PDGains(kp=4.0, kd=1.0, target=0.5)
    run = run_closed_loop(lambda t, x, v: pd_torque(gains, x, v), periods=400)
    return [round(t * 1e9) for t in run.t], run.position.tolist(), run.velocity.tolist()


def test_the_step_settling_time_so_far_is_the_metrics_settling_time_of_the_run_so_far() -> None:
    # The oracle is the test bench's own metric, computed offline on each prefix of the run:
    # the online tracker must give the same sample's stamp after every state (None for NaN).
    from pendulum_sim.testing.metrics import step_metrics

    stamps, phi, _ = readme_run()
    step = StepSettling()
    for k, (stamp, x) in enumerate(zip(stamps, phi, strict=True)):
        step.update(stamp, x, 0.5)
        if k == 0:
            continue
        times = [s / 1e9 for s in stamps[:k + 1]]
        settling = step_metrics(times, phi[:k + 1], 0.5, initial=phi[0]).settling_time
        got = None if step.since_ns is None else step.since_ns / 1e9
        assert (got is None and math.isnan(settling)) or got == settling, k
    assert step.since_ns == 1_300_000_000   # the README's "settled in 1.30 s"
    assert step.text() == (
        'step-response settling time t = 1.300 s so far (within 2 % of the step from 1 rad '
        'to 0.5 rad since; the settling_time of python-control step_info, as '
        'pendulum_sim.testing measures it)')


def test_the_controllers_rule_and_the_step_settling_time_differ_on_the_readme_run() -> None:
    # Two measures of one response, each what it says: the hold rule (|error| and |rate|
    # below 0.01 for 0.5 s of stamps) later than the 2 % band of the 0.5 rad step.
    stamps, phi, dphi = readme_run()
    det, step = SettleDetector(SettleLimits()), StepSettling()
    settled_at = None
    for stamp, x, v in zip(stamps, phi, dphi, strict=True):
        step.update(stamp, x, 0.5)
        if det.update(stamp, wrap_angle(x - 0.5), v) is SettleEvent.SETTLED:
            settled_at = stamp
            break
    # Independently: the first stamp 0.5 s into a stretch with both errors below 0.01.
    start = None
    for stamp, x, v in zip(stamps, phi, dphi, strict=True):
        start = (start if start is not None else stamp) if abs(x - 0.5) < 0.01 and abs(
            v) < 0.01 else None
        if start is not None and stamp - start >= 500 * MS:
            break
    assert settled_at == stamp == 2_670 * MS and det.inside_since_ns == start == 2_170 * MS
    assert step.since_ns == 1_300 * MS


def test_a_new_step_starts_after_time_goes_back_or_on_restart() -> None:
    step = StepSettling()
    assert step.text() == 'no step-response settling time: no state yet'
    step.update(0, 1.0, 0.5)
    assert step.text() == ('no step-response settling time yet: the angle is not within 2 % '
                           'of the step from 1 rad to 0.5 rad')
    step.update(10 * MS, 0.509, 0.5)                   # within 2 % of 0.5 rad: 0.01 rad
    assert step.since_ns == 10 * MS
    step.update(20 * MS, 0.511, 0.5)                   # out again
    assert step.since_ns is None
    step.update(0, 0.7, 0.5)                           # a reset: a new step, from 0.7 rad
    assert step.start == 0.7 and step.since_ns is None
    step.update(10 * MS, 0.5039, 0.5)                  # 2 % of 0.2 rad is 0.004 rad
    assert step.since_ns == 10 * MS
    step.restart()                                     # a new target
    step.update(20 * MS, 0.5, 0.5)
    assert step.text() == ('no step-response settling time: the step from 0.5 rad to 0.5 rad '
                           'has zero size')
