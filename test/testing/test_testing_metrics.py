"""Step metrics: python-control's ``step_info`` itself, closed forms, the step from y0, effort."""
from __future__ import annotations

import math
import re

import numpy as np
import pytest

from pendulum_sim.testing import StepMetrics, TestingError, step_metrics
from pendulum_sim.testing.metrics import METRIC_NAMES

control = pytest.importorskip('control')

STEP_INFO_NAMES = {'rise_time': 'RiseTime', 'settling_time': 'SettlingTime',
                   'settling_min': 'SettlingMin', 'settling_max': 'SettlingMax',
                   'overshoot': 'Overshoot', 'undershoot': 'Undershoot', 'peak': 'Peak',
                   'peak_time': 'PeakTime', 'steady_state_value': 'SteadyStateValue'}


def second_order(zeta: float, wn: float, t: np.ndarray) -> np.ndarray:
    """Return the unit-step response of wn² / (s² + 2 ζ wn s + wn²) in closed form."""
    if zeta < 1.0:
        wd = wn * math.sqrt(1.0 - zeta * zeta)
        phase = math.acos(zeta)
        return 1.0 - np.exp(-zeta * wn * t) * np.sin(wd * t + phase) / math.sqrt(
            1.0 - zeta * zeta)
    if zeta == 1.0:
        return 1.0 - np.exp(-wn * t) * (1.0 + wn * t)
    r = math.sqrt(zeta * zeta - 1.0)
    s1, s2 = -wn * (zeta - r), -wn * (zeta + r)
    return 1.0 + (s2 * np.exp(s1 * t) - s1 * np.exp(s2 * t)) / (s1 - s2)


def close(a: float, b: float) -> bool:
    """Return True for equal values within 1e-9 relative (NaN equals NaN)."""
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return abs(a - b) <= 1e-9 * max(abs(a), abs(b)) or a == b


def test_the_fields_are_the_issues_names() -> None:
    assert METRIC_NAMES == (
        'rise_time', 'settling_time', 'settling_min', 'settling_max', 'overshoot',
        'undershoot', 'peak', 'peak_time', 'steady_state_value', 'steady_state_error', 'iae',
        'ise', 'itae', 'max_effort', 'effort_energy', 'saturation_fraction')
    m = step_metrics([0.0, 1.0], [0.0, 1.0], 1.0)
    with pytest.raises(AttributeError):
        m.overshoot = 0.0  # type: ignore[misc]


def test_agrees_with_python_control_on_200_random_second_order_responses() -> None:
    rng = np.random.default_rng(20261202)
    compared = 0
    for _ in range(200):
        zeta = float(rng.uniform(0.05, 2.0))
        wn = float(rng.uniform(0.5, 20.0))
        gain = float(rng.choice([-1.0, 1.0]) * rng.uniform(0.2, 5.0))
        tf = float(rng.uniform(6.0, 12.0)) / (zeta * wn) if zeta < 1 else 20.0 / wn * zeta
        t = np.linspace(0.0, tf, int(rng.integers(200, 3000)))
        y = gain * second_order(zeta, wn, t) + rng.normal(0.0, 1e-3 * abs(gain), t.size)
        target = gain * float(rng.uniform(0.95, 1.05))
        ours = step_metrics(t, y, target)
        theirs = control.step_info(y, timepts=t, final_output=target)
        for name, key in STEP_INFO_NAMES.items():
            assert close(getattr(ours, name), float(theirs[key])), (name, ours, theirs)
            compared += 1
    assert compared == 200 * 9


def test_closed_form_second_order_overshoot_and_peak_time() -> None:
    wn = 4.0
    for zeta in (0.1, 0.3, 0.5, 0.7, 0.9):
        wd = wn * math.sqrt(1.0 - zeta * zeta)
        h = 1e-5
        t = np.arange(0.0, 30.0 / (zeta * wn), h)
        m = step_metrics(t, second_order(zeta, wn, t), 1.0)
        overshoot = 100.0 * math.exp(-zeta * math.pi / math.sqrt(1.0 - zeta * zeta))
        # Sampled at h: the peak is off by at most (h wd)²/2 of the excursion, t by h/2.
        assert abs(m.overshoot - overshoot) <= 100.0 * (h * wd) ** 2
        assert abs(m.peak_time - math.pi / wd) <= h / 2 + 1e-12
        assert abs(m.peak - (1.0 + overshoot / 100.0)) <= (h * wd) ** 2
        assert m.steady_state_value == 1.0
        assert 0.0 <= m.undershoot <= 1e-12      # y(0) = 0 up to round-off, never below
        # The envelope bounds the settling time: 1 + e^(-ζ wn t)/sqrt(1-ζ²) crosses 1.02 at
        # t_env, after which the response never leaves the 2 % band.
        t_env = -math.log(0.02 * math.sqrt(1.0 - zeta * zeta)) / (zeta * wn)
        assert m.settling_time <= t_env + h
        assert abs(second_order(zeta, wn, np.array([m.settling_time - h]))[0] - 1.0) >= 0.02


def test_closed_form_first_order_rise_time_is_ln_9_over_a() -> None:
    a, h = 2.0, 1e-5
    t = np.arange(0.0, 10.0, h)
    m = step_metrics(t, 1.0 - np.exp(-a * t), 1.0)
    assert abs(m.rise_time - math.log(9.0) / a) <= 2 * h
    assert abs(m.settling_time - math.log(50.0) / a) <= h
    assert m.overshoot == 0.0 and m.settling_max == 1.0


def test_initial_value_measures_the_step_from_y0() -> None:
    rng = np.random.default_rng(7)
    for _ in range(50):
        zeta, wn = float(rng.uniform(0.1, 1.5)), float(rng.uniform(1.0, 10.0))
        y0, target = float(rng.uniform(-2, 2)), float(rng.uniform(-2, 2))
        t = np.linspace(0.0, 40.0 / (zeta * wn), 2000)
        y = y0 + (target - y0) * second_order(zeta, wn, t)
        ours = step_metrics(t, y, target, initial=y0)
        # MATLAB's stepinfo(y, t, yfinal, yinit): python-control's definitions on y - y0.
        theirs = control.step_info(y - y0, timepts=t, final_output=target - y0)
        for name, key in STEP_INFO_NAMES.items():
            expected = float(theirs[key])
            if name in ('settling_min', 'settling_max', 'steady_state_value'):
                expected += y0
            assert close(getattr(ours, name), expected), name
        # The overshoot of a normalised response does not depend on where the step starts.
        unit = step_metrics(t, second_order(zeta, wn, t), 1.0)
        assert abs(ours.overshoot - unit.overshoot) <= 1e-9 * max(1.0, unit.overshoot)
        assert ours.rise_time == unit.rise_time


def test_initial_zero_is_python_controls_step_info() -> None:
    t = np.linspace(0.0, 10.0, 1001)
    y = second_order(0.3, 2.0, t)
    assert step_metrics(t, y, 1.0, initial=0.0) == step_metrics(t, y, 1.0)


def test_tracking_and_effort_metrics_against_integrals_in_closed_form() -> None:
    a = 3.0
    t = np.linspace(0.0, 5.0, 500_001)
    y = 1.0 - np.exp(-a * t)
    tau = np.minimum(2.0, 4.0 * np.exp(-a * t))          # saturated while 4 e^(-at) >= 2
    m = step_metrics(t, y, 1.0, effort=tau, effort_limit=2.0)
    e5 = math.exp(-a * 5.0)
    assert m.steady_state_error == pytest.approx(-e5, rel=1e-12)
    assert m.iae == pytest.approx((1 - e5) / a, rel=1e-9)
    assert m.ise == pytest.approx((1 - e5 ** 2) / (2 * a), rel=1e-9)
    assert m.itae == pytest.approx((1 - e5 * (1 + 5 * a)) / a ** 2, rel=1e-9)
    assert m.max_effort == 2.0
    ts = math.log(2.0) / a                                  # saturated for t <= ts
    energy = 4.0 * ts + 16.0 * (math.exp(-2 * a * ts) - math.exp(-2 * a * 5.0)) / (2 * a)
    assert m.effort_energy == pytest.approx(energy, rel=1e-9)
    assert m.saturation_fraction == pytest.approx(ts / 5.0, abs=1e-5)
    no_effort = step_metrics(t, y, 1.0)
    assert math.isnan(no_effort.max_effort) and math.isnan(no_effort.effort_energy)


def test_never_settled_is_nan() -> None:
    t = np.linspace(0.0, 1.0, 11)
    m = step_metrics(t, t, 2.0)          # still rising at the end, 50 % of the way
    assert math.isnan(m.settling_time) and math.isnan(m.rise_time)
    assert isinstance(m, StepMetrics)


@pytest.mark.parametrize(('args', 'kwargs', 'msg'), [
    (([0.0, 1.0], [0.0, 1.0], 0.0), {}, 'target 0.0 equals the initial value 0.0: a step of '
     'zero size has no rise or settling time'),
    (([0.0, 1.0], [0.0, 1.0], 0.5), {'initial': 0.5}, 'target 0.5 equals the initial value '
     '0.5: a step of zero size has no rise or settling time'),
    (([0.0, 1.0, 2.0], [0.0, 1.0], 1.0), {}, 't and y must have the same length, got 3 and 2'),
    (([0.0, 1.0], [0.0, math.nan], 1.0), {}, 'y must be finite, got nan at index 1'),
    (([0.0, 0.0], [0.0, 1.0], 1.0), {}, 't must be strictly increasing'),
    (([0.0], [0.0], 1.0), {}, 't must be a 1-D array of at least 2 samples, got shape (1,)'),
    (([0.0, 1.0], [0.0, 1.0], math.inf), {}, 'target must be finite, got inf'),
    (([0.0, 1.0], [0.0, 1.0], 1.0), {'effort': [1.0]},
     'effort must be a 1-D array of at least 2 samples, got shape (1,)'),
])
def test_bad_input_is_refused_with_the_reason(args: tuple[object, ...],
                                              kwargs: dict[str, object], msg: str) -> None:
    with pytest.raises(TestingError, match=re.escape(msg)):
        step_metrics(*args, **kwargs)  # type: ignore[arg-type]
