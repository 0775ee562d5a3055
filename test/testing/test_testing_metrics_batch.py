"""Step metrics of many runs at once: each row the numbers ``step_metrics`` gives it alone."""
from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from pendulum_sim.core.analysis import SETTLING_THRESHOLD
from pendulum_sim.testing import StepMetrics, TestingError, step_metrics
from pendulum_sim.testing import run as run_module
from pendulum_sim.testing.batch import run_batch
from pendulum_sim.testing.examples import pd_batch
from pendulum_sim.testing.metrics import RISE_LIMITS, step_metrics_batch
from pendulum_sim.testing.run import ClosedLoopRun, runs_metrics
from pendulum_sim.testing.scene import scene_values
from pendulum_sim.testing.vector import vectorised

SIZE = 300


def alone(t: Any, y: Any, target: float, **kwargs: Any) -> StepMetrics | TestingError:
    """Return step_metrics of one run, or the TestingError it raises."""
    try:
        return step_metrics(t, y, target, **kwargs)
    except TestingError as exc:
        return exc


def assert_same(got: StepMetrics | TestingError, want: StepMetrics | TestingError) -> None:
    """Assert the same metrics to the bit (NaN as NaN, the sign of a zero) or the same error."""
    if isinstance(want, TestingError):
        assert isinstance(got, TestingError) and str(got) == str(want)
        return
    assert isinstance(got, StepMetrics)
    for name, value in want.as_dict().items():
        assert repr(getattr(got, name)) == repr(value), name


def edge_rows(t: np.ndarray, rng: np.random.Generator) -> list[dict[str, Any]]:
    """Return runs of every kind the metrics tell apart, and runs step_metrics refuses."""
    lo, hi = RISE_LIMITS
    rows: list[dict[str, Any]] = []

    def add(y: Any, target: float, initial: float, effort: Any = None,
            limit: float = math.inf) -> None:
        tau = rng.normal(0.0, 1.0, t.size) if effort is None else np.asarray(effort, float)
        rows.append({'y': np.asarray(y, dtype=float), 'target': target, 'initial': initial,
                     'effort': tau, 'limit': limit})

    for _ in range(400):   # second-order steps: overshoot or not, up or down, from anywhere
        zeta, wn = float(rng.uniform(0.05, 2.0)), float(rng.uniform(0.5, 15.0))
        y0, target = float(rng.uniform(-2.0, 2.0)), float(rng.uniform(-2.0, 2.0))
        wd = wn * math.sqrt(abs(1.0 - zeta * zeta)) + 1e-9
        shape = 1.0 - np.exp(-zeta * wn * t) * np.cos(wd * t)
        limit = float(rng.choice([math.inf, 0.5, 1.0, 2.0]))
        effort = np.clip(rng.normal(0.0, 1.5, t.size), -limit, limit)   # at the limit, too
        add(y0 + (target - y0) * shape + rng.normal(0.0, 1e-3, t.size), target, y0, effort,
            limit)
    step = 0.8
    add(np.zeros(t.size), step, 0.0)                           # never moves: no rise, no settling
    add(np.full(t.size, step), step, 0.0)                      # in the band from the start
    add(np.where(np.arange(t.size) < 50, 0.0, step), step, 0.0)
    add(np.linspace(0.0, lo * step, t.size), step, 0.0)        # ends exactly at 10 %
    add(np.linspace(0.0, hi * step, t.size), step, 0.0)        # ends exactly at 90 %
    edge = step * (1.0 + SETTLING_THRESHOLD)
    add(np.r_[np.linspace(0.0, edge, t.size - 10), np.full(10, edge)], step, 0.0)
    add(-np.linspace(0.0, 1.0, t.size) * step, step, 0.0)      # the wrong way all along
    add(np.r_[-0.3 * np.ones(20), np.full(t.size - 20, step)], step, 0.0)   # undershoot
    add(np.r_[-0.0, np.zeros(t.size - 1)], -step, -0.0)         # signed zeros, a step down
    add(np.round(rng.normal(0.0, 1.0, t.size), 1), 0.5, 0.0)   # ties for the extremes
    add(np.full(t.size, 1.0), 1.0, 0.0, np.full(t.size, 2.0), 2.0)   # saturated throughout
    add(np.full(t.size, 1.0), 1.0, 0.0, np.zeros(t.size), 0.0)       # a limit of 0
    refused = np.linspace(0.0, 1.0, t.size)
    add(np.r_[refused[:-1], math.nan], 1.0, 0.0)               # step_metrics refuses these:
    add(refused, 1.0, 0.0, np.r_[math.inf, np.zeros(t.size - 1)])
    add(refused, 0.5, 0.5)
    add(refused, math.inf, 0.0)
    add(refused, 1.0, math.nan)
    order = rng.permutation(len(rows))
    return [rows[i] for i in order]


def test_a_batch_measures_each_row_as_step_metrics_does_alone() -> None:
    rng = np.random.default_rng(20261205)
    t = np.cumsum(rng.uniform(0.005, 0.02, SIZE))   # uneven steps
    rows = edge_rows(t, rng)
    y = np.array([r['y'] for r in rows])
    targets = [r['target'] for r in rows]
    initials = [r['initial'] for r in rows]
    efforts = np.array([r['effort'] for r in rows])
    limits = [r['limit'] for r in rows]
    got = step_metrics_batch(t, y, targets, initial=initials, effort=efforts,
                             effort_limit=limits)
    assert len(got) == len(rows)
    for i, r in enumerate(rows):
        assert_same(got[i], alone(t, r['y'], r['target'], initial=r['initial'],
                                  effort=r['effort'], effort_limit=r['limit']))
    kinds = {type(m) for m in got}
    assert kinds == {StepMetrics, TestingError}
    measured = [m for m in got if isinstance(m, StepMetrics)]
    for name in ('rise_time', 'settling_time', 'settling_min'):   # undefined ones among them
        assert any(math.isnan(getattr(m, name)) for m in measured), name
    assert any(m.undershoot > 0 for m in measured) and any(m.overshoot > 0 for m in measured)
    assert any(0 < m.saturation_fraction < 1 for m in measured)
    # Without an initial value or an effort: from 0, the effort metrics NaN.
    plain = step_metrics_batch(t, y, targets)
    for i, r in enumerate(rows):
        assert_same(plain[i], alone(t, r['y'], r['target']))


def test_times_step_metrics_refuses_refuse_every_row_with_its_reason() -> None:
    y = np.array([[0.0, 1.0, 1.0], [0.0, 0.5, 1.0]])
    for t in ([0.0, 1.0, 1.0], [0.0, 1.0], [0.0, math.nan, 2.0]):
        got = step_metrics_batch(t, y, [1.0, 1.0])
        for i in range(2):
            assert_same(got[i], alone(t, y[i], 1.0))
            assert isinstance(got[i], TestingError)
    with pytest.raises(TestingError, match='one run per row'):
        step_metrics_batch([0.0, 1.0], [0.0, 1.0], 1.0)


@vectorised
def nan_when_low(t: float, position: Any, velocity: Any) -> Any:
    """Answer the example torques, NaN for an angle below 0.45 rad after 0.2 s."""
    tau = pd_batch(t, position, velocity)
    return np.where((position < 0.45) & (t > 0.2), math.nan, tau)


def test_runs_are_measured_together_as_each_alone(monkeypatch: pytest.MonkeyPatch) -> None:
    # A batch's runs (one sample grid), runs cut short by a failure (their own lengths) and a
    # run of one sample (refused): each the numbers, or the error, of run.metrics(target),
    # measured a few blocks at a time.
    monkeypatch.setattr(run_module, 'BLOCK', 64)
    rng = np.random.default_rng(3)
    episodes = [scene_values('controller_test', {
        'gamma': float(rng.uniform(0.05, 1.5)), 'phi0': float(rng.uniform(-0.5, 1.8)),
        'max_effort': float(rng.choice([0.3, 2.0, 6.0]))}) for _ in range(500)]
    results = run_batch(nan_when_low, episodes, 200)
    runs = [r if isinstance(r, ClosedLoopRun) else r.run for r in results]  # type: ignore[attr-defined]
    assert all(isinstance(r, ClosedLoopRun) for r in runs)
    sizes = {r.t.size for r in runs}   # type: ignore[union-attr]
    assert 200 in sizes and len(sizes) > 2
    assert sum(r.t.size == 200 for r in runs) > 64   # type: ignore[union-attr]
    one = ClosedLoopRun(*(np.zeros(1) for _ in range(5)))
    runs.append(one)
    targets = [float(x) for x in rng.uniform(-0.5, 1.5, len(runs))]
    got = runs_metrics(runs, targets)   # type: ignore[arg-type]
    for run, target, m in zip(runs, targets, got, strict=True):
        try:
            want: StepMetrics | TestingError = run.metrics(target)   # type: ignore[union-attr]
        except TestingError as exc:
            want = exc
        assert_same(m, want)
    assert isinstance(got[-1], TestingError)
