"""``pendulum_report closed-loop RUN.mcap --out DIR``: the verdict and picture of one run.

Reads a closed-loop recording (made by ``pendulum_node`` in synchronous mode, by
``closed_loop(..., record=...)`` or by a campaign), draws the run's figure with the same
function as :meth:`ClosedLoopRun.plot <pendulum_sim.testing.run.ClosedLoopRun.plot>` and writes
``summary.md`` with every step metric and ``metrics.csv``.
"""
from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

from .errors import ReportError
from .output import Summary, fmt, markdown_table, prepare_out_dir, write_csv

FIGURE = 'closed_loop.png'


def run_closed_loop_report(mcap: str | os.PathLike[str], out: str | os.PathLike[str], *,
                           target: float | None = None, force: bool = False,
                           command: str = '') -> dict[str, Any]:
    """Write the report of the run in ``mcap`` into ``out``; return what was written.

    ``target`` is the reference; without it the recording's own (a ``closed_loop`` metadata
    record) is used.

    Raises
    ------
    ReportError
        If the recording cannot be read, holds no closed loop or says no target and none is
        given, or ``out`` cannot be written.
    """
    from pendulum_sim.testing.errors import TestingError
    from pendulum_sim.testing.figure import closed_loop_figure
    from pendulum_sim.testing.record import load_run

    path = Path(mcap)
    if not path.is_file():
        raise ReportError(f"recording '{path}' does not exist")
    try:
        run = load_run(path)
    except TestingError as exc:
        raise ReportError(str(exc)) from None
    chosen = target if target is not None else run.target
    if chosen is None:
        raise ReportError(f'{path} does not say its target; give it with --target')
    if not math.isfinite(chosen):
        raise ReportError(f'--target must be finite, got {chosen}')
    try:
        metrics = run.metrics(chosen)
    except TestingError as exc:
        raise ReportError(f'{path}: {exc}') from None
    folder = prepare_out_dir(out, force)
    closed_loop_figure(run, chosen, folder / FIGURE, metrics,
                       title=f'{path.name}: towards {chosen:g} rad')
    rows = [{'metric': k, 'value': v} for k, v in metrics.as_dict().items()]
    write_csv(folder / 'metrics.csv', rows, ['metric', 'value'])
    summary = Summary(f'Closed loop: {path.name}')
    if command:
        summary.section('Run', f'Command: `{command}`')
    summary.section(
        'The run',
        f'{run.t.size} control periods from t = {fmt(float(run.t[0]))} s to '
        f'{fmt(float(run.t[-1]))} s; angle from {fmt(float(run.position[0]))} rad towards the '
        f'target {fmt(chosen)} rad; torque limit max_effort = {fmt(run.max_effort)} N m.')
    summary.section('Metrics', "Definitions: docs/reference/metrics.md (python-control's "
                    '`step_info`, the step measured from the first angle).',
                    markdown_table(rows, ['metric', 'value'], digits=6))
    summary.section('Figure', f'![closed loop]({FIGURE})')
    summary.write(folder / 'summary.md')
    return {'summary_path': folder / 'summary.md', 'figure': folder / FIGURE,
            'metrics': metrics}
