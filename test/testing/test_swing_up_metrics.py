"""Swing-up metrics against runs computed by hand, and the batch against the scalar to the bit."""
from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest

from pendulum_sim.core.model import wrap_pi
from pendulum_sim.testing import (
    SwingUpMetrics,
    TestingError,
    swing_up_metrics,
    swing_up_metrics_batch,
)
from pendulum_sim.testing.swing_up.metrics import SWING_UP_NAMES, swing_up_metrics_columns

PI = math.pi


def test_the_fields_are_the_issues_names() -> None:
    assert [f.name for f in dataclasses.fields(SwingUpMetrics)] == [
        'success', 'swing_up_time', 'stays', 'settle_time', 'energy', 'effort_energy',
        'smoothness', 'max_effort', 'saturation_fraction', 'swings']
    with pytest.raises(dataclasses.FrozenInstanceError):
        swing_up_metrics([0, 1], [0, 0], [0, 0], [0, 0]).energy = 1.0  # type: ignore[misc]


def test_a_run_computed_by_hand() -> None:
    # Out, out, in, out (too fast), in one turn later: enters at t = 2 and stays from t = 4.
    t = [0.0, 1.0, 2.0, 3.0, 4.0]
    position = [0.0, 2.0, PI - 0.05, PI + 0.2, PI + 0.02 + 2 * PI]
    velocity = [0.0, 3.0, 0.05, -0.5, 0.01]
    effort = [1.0, -1.0, 0.5, 0.5, 0.0]
    m = swing_up_metrics(t, position, velocity, effort, effort_limit=1.0)
    assert m.success and m.stays
    assert (m.swing_up_time, m.settle_time) == (2.0, 4.0)
    # |tau phi'| = 0, 3, 0.025, 0.25, 0; trapezoids of width 1.
    assert m.energy == pytest.approx(1.5 + 1.5125 + 0.1375 + 0.125, rel=1e-15)
    assert m.effort_energy == pytest.approx(1.0 + 0.625 + 0.25 + 0.125, rel=1e-15)
    # Differences -2, 1.5, 0, -0.5: mean -0.25, deviations +-1.75, +-0.25: sqrt(6.25 / 4).
    assert m.smoothness == pytest.approx(1.25, rel=1e-15)
    assert (m.max_effort, m.saturation_fraction, m.swings) == (1.0, 0.4, 0)


def test_times_count_from_the_first_sample_and_reversals_before_the_entry() -> None:
    # Velocity + 0 - - 0 0 + ... : reversals at samples 3 (across the zero) and 7 (across two).
    velocity = [0.0, 1.0, 0.0, -1.0, -2.0, 0.0, 0.0, 3.0, -0.01, 2.0]
    position = [0.0] * 8 + [PI, PI]
    t = 10.0 + 0.5 * np.arange(10)
    m = swing_up_metrics(t, position, velocity, np.zeros(10))
    assert m.success and not m.stays   # in the box at sample 8 only (sample 9 is too fast)
    assert m.swing_up_time == 4.0 and math.isnan(m.settle_time)
    assert m.swings == 2               # the reversal at sample 8 is the entry, not before it
    assert (m.energy, m.effort_energy, m.smoothness, m.max_effort) == (0.0, 0.0, 0.0, 0.0)
    assert m.saturation_fraction == 0.0   # no limit given: none counted


def test_a_run_that_never_enters() -> None:
    velocity = [0.0, 1.0, -1.0, 1.0, -1.0]
    m = swing_up_metrics(np.arange(5.0), [0.0, 0.5, 1.0, 0.5, 0.0], velocity, [1, -1, 1, -1, 1],
                         effort_limit=0.5)
    assert not m.success and not m.stays
    assert m.swing_up_time == math.inf and math.isnan(m.settle_time)
    assert m.swings == 3 and m.saturation_fraction == 1.0


@pytest.mark.parametrize('phi', [PI, -PI, 3 * PI, -3 * PI, PI + 2 * PI * 7])
def test_upright_is_pi_plus_any_whole_turn(phi: float) -> None:
    m = swing_up_metrics([0.0, 1.0], [0.0, phi], [0.0, 0.0], [0.0, 0.0])
    assert m.success and m.stays and m.swing_up_time == 1.0 and m.settle_time == 1.0
    assert -PI <= float(wrap_pi(phi - PI)) < PI


def test_the_box_is_strict() -> None:
    # goal 0, box (0.5, 0.25): a sample exactly on an edge is outside (binary-exact values).
    t, tau = [0.0, 1.0, 2.0], [0.0, 0.0, 0.0]
    assert not swing_up_metrics(t, [1.0, 0.5, -0.5], [0, 0, 0], tau, goal=0.0,
                                box=(0.5, 0.25)).success
    assert not swing_up_metrics(t, [1.0, 0.0, 0.0], [0, 0.25, -0.25], tau, goal=0.0,
                                box=(0.5, 0.25)).success
    inside = swing_up_metrics(t, [1.0, 0.0, 0.4999], [0, 0.2499, 0], tau, goal=0.0,
                              box=(0.5, 0.25))
    assert inside.stays and inside.settle_time == 1.0


@pytest.mark.parametrize(('kwargs', 'message'), [
    ({'box': (0.0, 0.1)}, 'box[0] (rad) must be a finite number > 0, got 0.0'),
    ({'box': (0.1, -1.0)}, 'box[1] (rad/s) must be a finite number > 0, got -1.0'),
    ({'box': (0.1, math.inf)}, 'box[1] (rad/s) must be a finite number > 0, got inf'),
    ({'box': (0.1,)}, 'box must be (angle rad, rate rad/s), two numbers > 0, got (0.1,)'),
    ({'goal': math.nan}, 'goal must be a finite angle (rad), got nan'),
])
def test_a_bad_goal_or_box_is_refused(kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(TestingError) as info:
        swing_up_metrics([0, 1], [0, 0], [0, 0], [0, 0], **kwargs)
    assert str(info.value) == message


def test_bad_samples_are_refused_with_the_reason() -> None:
    with pytest.raises(TestingError, match=r'^velocity must be finite, got nan at index 1$'):
        swing_up_metrics([0, 1], [0, 0], [0, math.nan], [0, 0])
    with pytest.raises(TestingError, match=r'^effort must have the length of t \(2\), got 3$'):
        swing_up_metrics([0, 1], [0, 0], [0, 0], [0, 0, 0])
    with pytest.raises(TestingError, match=r'^t must be strictly increasing$'):
        swing_up_metrics([0, 0], [0, 0], [0, 0], [0, 0])


def alone(*args: Any, **kwargs: Any) -> SwingUpMetrics | TestingError:
    try:
        return swing_up_metrics(*args, **kwargs)
    except TestingError as exc:
        return exc


def test_the_batch_gives_each_row_the_numbers_it_gets_alone() -> None:
    rng = np.random.default_rng(38)
    size = 400
    t = np.linspace(0.0, 4.0, size)
    rows = []
    for i in range(300):
        # A swing that grows into upright at a random time, with noise near the box's edges.
        grow = np.clip(t / rng.uniform(0.5, 5.0), 0.0, 1.0)
        position = PI * grow * np.cos(rng.uniform(1, 8) * t * (1 - grow)) + rng.normal(
            0, 0.05, size) + 2 * PI * rng.integers(-2, 3)
        velocity = np.gradient(position, t) * rng.uniform(0.01, 1.0)
        velocity[rng.random(size) < 0.05] = 0.0
        effort = np.clip(rng.normal(0, 1, size), -1.0, 1.0)
        if i % 50 == 7:
            velocity[size // 2] = math.nan   # refused alone, so refused in the batch
        rows.append((position, velocity, effort))
    position, velocity, effort = (np.stack([r[k] for r in rows]) for k in range(3))
    goals = rng.choice([PI, -PI, 0.0], len(rows))
    limits = rng.choice([1.0, math.inf], len(rows))
    got = swing_up_metrics_batch(t, position, velocity, effort, goal=goals, box=(0.2, 0.5),
                                 effort_limit=limits)
    kinds = set()
    for i, m in enumerate(got):
        want = alone(t, position[i], velocity[i], effort[i], goal=float(goals[i]),
                     box=(0.2, 0.5), effort_limit=float(limits[i]))
        if isinstance(want, TestingError):
            assert isinstance(m, TestingError) and str(m) == str(want)
            kinds.add('refused')
            continue
        assert isinstance(m, SwingUpMetrics)
        assert [repr(v) for v in m.as_dict().values()] == [
            repr(v) for v in want.as_dict().values()], i
        kinds.add((want.success, want.stays))
    # The rows cover every verdict the metrics tell apart.
    assert kinds == {'refused', (False, False), (True, False), (True, True)}
    assert all(type(m.success) is bool and type(m.swings) is int
               for m in got if isinstance(m, SwingUpMetrics))
    # The same numbers as arrays, a refused row masked out and 0.
    columns, measured = swing_up_metrics_columns(t, position, velocity, effort, goal=goals,
                                                 box=(0.2, 0.5), effort_limit=limits)
    assert measured.tolist() == [isinstance(m, SwingUpMetrics) for m in got]
    for name in SWING_UP_NAMES:
        want = np.array([getattr(m, name) if isinstance(m, SwingUpMetrics) else 0
                         for m in got], dtype=columns[name].dtype)
        assert columns[name].tobytes() == want.tobytes(), name


def test_the_batch_refuses_a_bad_box_once() -> None:
    with pytest.raises(TestingError, match=r'^box\[0\] \(rad\) must be a finite number > 0, '
                       r'got -0.1$'):
        swing_up_metrics_batch([0, 1], [[0, 0]], [[0, 0]], [[0, 0]], box=(-0.1, 0.1))
