"""The pytest plugin of the test bench (entry point ``pytest11``): the ``closed_loop`` fixture.

A test reads::

    def test_my_law(closed_loop):
        run = closed_loop(my_law, periods=500)
        assert run.metrics(0.5).settling_time < 3

The fixture is :func:`pendulum_sim.testing.closed_loop`, and it keeps the runs a test makes and
the targets their metrics were asked for. When the test fails, the failure report shows each
run's metrics, and the run's figure (``closed_loop.png``) and recording (``run.mcap``) are left
under the test run's root folder in a folder named after the test (``run-2.png`` ... for the
second run and on).
"""
from __future__ import annotations

import re
from collections.abc import Callable, Generator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from .loop import Law
from .loop import closed_loop as _closed_loop
from .metrics import StepMetrics
from .run import ClosedLoopRun

RUNS_KEY = pytest.StashKey['_Recorded']()


@dataclass(frozen=True)
class ObservedRun(ClosedLoopRun):
    """A run that remembers the targets its metrics were computed for (the last one counts)."""

    targets: list[float] = field(default_factory=list)

    def metrics(self, target: float | None = None, *,
                initial: float | None = None) -> StepMetrics:
        """Return the step metrics, remembering ``target`` for the failure report."""
        result = super().metrics(target, initial=initial)
        if target is not None:
            self.targets.append(float(target))
        return result


@dataclass
class _Recorded:
    runs: list[ObservedRun] = field(default_factory=list)


@pytest.fixture
def closed_loop(request: pytest.FixtureRequest) -> Callable[..., ClosedLoopRun]:
    """Return :func:`pendulum_sim.testing.closed_loop`, keeping the runs for a failure report."""
    recorded = _Recorded()
    request.node.stash[RUNS_KEY] = recorded

    def run(controller: Law | Sequence[str], **kwargs: Any) -> ClosedLoopRun:
        result = _closed_loop(controller, **kwargs)
        observed = ObservedRun(result.t, result.position, result.velocity, result.effort,
                               result.command, result.parameters, result.failed, result.target)
        recorded.runs.append(observed)
        return observed

    return run


def folder_for(root: Path, name: str) -> Path:
    """Return the folder of a test's artefacts: ``root/<test name>`` (path-safe)."""
    return root / re.sub(r'[^A-Za-z0-9_.\-\[\]]+', '_', name)


def _leave(run: ObservedRun, folder: Path, index: int) -> list[str]:
    """Write one run's figure and MCAP into ``folder``; return the report lines."""
    from .record import write_run

    stem = 'run' if index == 0 else f'run-{index + 1}'
    figure = 'closed_loop' if index == 0 else f'closed_loop-{index + 1}'
    target = run.targets[-1] if run.targets else run.target
    lines = [f'run {index + 1}: {run.t.size} periods'
             + (f', stopped early: {run.failed}' if run.failed else '')]
    folder.mkdir(parents=True, exist_ok=True)
    kept = run.with_target(target) if target is not None else run
    try:
        mcap = write_run(kept, folder / f'{stem}.mcap')
        lines.append(f'  recording: {mcap}')
    except Exception as exc:   # the report must not hide the test's own failure
        lines.append(f'  recording not written: {exc}')
    if target is None:
        lines.append('  no metrics: the test asked for none (no target known)')
        return lines
    try:
        metrics = kept.metrics(target)
        lines.append(f'  metrics towards {target:g}:')
        lines.extend(f'    {line}' for line in metrics.text().splitlines())
        png = kept.plot(folder / f'{figure}.png')
        lines.append(f'  figure: {png}')
    except Exception as exc:
        lines.append(f'  no metrics or figure: {exc}')
    return lines


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item,
                              call: pytest.CallInfo[None]) -> Generator[None, Any, None]:
    """On a failed test that used the fixture, report the metrics and leave the artefacts."""
    outcome = yield
    report = outcome.get_result()
    recorded = item.stash.get(RUNS_KEY, None)
    if recorded is None or not recorded.runs or report.when != 'call' or not report.failed:
        return
    folder = folder_for(item.config.rootpath, item.name)
    lines: list[str] = []
    for i, run in enumerate(recorded.runs):
        lines.extend(_leave(run, folder, i))
    report.sections.append(('closed_loop', '\n'.join(lines)))
