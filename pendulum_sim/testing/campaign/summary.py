"""The campaign's results: the episode table (Parquet and CSV), ``summary.md``, the figures
(drawn by :mod:`~pendulum_sim.testing.campaign.figures`).

Table columns: ``episode``, one per scenario parameter (named as the parameter), ``target`` (the
episode's reference, always there, fixed or drawn), one per metric
(named as the :class:`~pendulum_sim.testing.StepMetrics` field, or the
:class:`~pendulum_sim.testing.SwingUpMetrics` field for ``task: swing_up``), ``passed``,
``reason``, and
the columns that say where and when the episode ran (``worker_host``, ``worker_pid``,
``wall_time_s``).
"""
from __future__ import annotations

import csv
import math
import threading
from pathlib import Path
from typing import Any

import numpy as np

from .episode import RUN_COLUMNS, failure_path
from .figures import point_like, point_like_note, shown, write_figures
from .spec import CampaignSpec, describe

QUANTILES = (0.05, 0.5, 0.95)
WORST = 10
# Per task: the metric the worst episodes are sorted by (largest first) and one shown beside.
WORST_BY = {'step': ('settling_time', 'overshoot'), 'swing_up': ('swing_up_time', 'energy')}



def columns(spec: CampaignSpec) -> list[str]:
    """Return the table's columns in order."""
    return ['episode', *spec.scenario_names, *spec.metric_names, 'passed', 'reason',
            *RUN_COLUMNS]


def _cell(value: Any) -> str:
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        return repr(value)
    return str(value)


def write_table(spec: CampaignSpec, rows: list[dict[str, Any]], out: Path) -> list[Path]:
    """Write ``episodes.csv`` and ``episodes.parquet``; return their paths."""
    cols = columns(spec)
    csv_path = out / 'episodes.csv'
    with csv_path.open('w', newline='', encoding='utf-8') as fh:
        writer = csv.writer(fh)
        writer.writerow(cols)
        for row in rows:
            writer.writerow([_cell(row[c]) for c in cols])
    written = [csv_path]
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return written
    table = pa.table({c: _arrow_column(pa, [row[c] for row in rows]) for c in cols})
    pq.write_table(table, out / 'episodes.parquet')
    written.append(out / 'episodes.parquet')
    return written


def _arrow_column(pa: Any, values: list[Any]) -> Any:
    """Return the values as an Arrow array; a NaN among booleans (a swing-up's ``success``
    of an episode that was not measured) is a null there."""
    try:
        return pa.array(values)
    except (pa.ArrowInvalid, pa.ArrowTypeError):
        return pa.array(values, from_pandas=True)


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return '–' if math.isnan(value) else shown(value)
    return str(value)


def write_summary(spec: CampaignSpec, rows: list[dict[str, Any]], out: Path,
                  figures: list[str]) -> Path:
    """Write ``summary.md``: pass rate, metric quantiles, the worst episodes, the figures."""
    n = len(rows)
    passed = sum(1 for r in rows if r['passed'])
    lines = [f'# Campaign: {n} episodes, {passed} passed ({100.0 * passed / max(n, 1):.1f} %)',
             '', f'Controller `{spec.controller}`, scene `{spec.scene}`, {spec.periods} control '
             f'periods per episode, target {describe(spec.target)} rad, seed {spec.seed}.', '']
    note = point_like_note(point_like(spec, rows))
    lines += [note, ''] if note else []
    lines += ['## Requirements', '']
    lines += [f'- `{r}`: {sum(1 for row in rows if not r.check(row[r.metric]))} of {n} met'
              for r in spec.requirements] or ['- none (every episode that runs passes)']
    lines += ['', '## Metric quantiles', '',
              '| metric | ' + ' | '.join(f'{100 * q:g} %' for q in QUANTILES) + ' | nan |',
              '|---|' + '---|' * (len(QUANTILES) + 1)]
    for name in spec.metric_names:
        x = np.array([r[name] for r in rows], dtype=float)
        finite = x[np.isfinite(x)]
        qs = [float(np.quantile(finite, q)) if finite.size else math.nan for q in QUANTILES]
        lines.append(f'| {name} | ' + ' | '.join(_fmt(v) for v in qs)
                     + f' | {int(np.sum(~np.isfinite(x)))} |')
    slow, other = WORST_BY[spec.task]
    worst = sorted(rows, key=lambda r: (r['passed'], -(r[slow] if math.isfinite(
        r[slow]) else math.inf), r['episode']))[:WORST]
    lines += ['', f'## The worst episodes (failed first, then the slowest by {slow}; '
              f'at most {WORST})', '',
              '| episode | ' + ' | '.join(spec.scenario_names)
              + f' | {slow} | {other} | passed | reason | recording |',
              '|---|' + '---|' * (len(spec.scenario_names) + 5)]
    for r in worst:
        mcap = failure_path(out, r['episode'])
        rec = f'failures/{mcap.name}' if mcap.is_file() else ''
        lines.append(f'| {r["episode"]} | ' + ' | '.join(_fmt(r[p]) for p in
                                                          spec.scenario_names)
                     + f' | {_fmt(r[slow])} | {_fmt(r[other])} | '
                     f'{"yes" if r["passed"] else "no"} | {r["reason"]} | {rec} |')
    lines += ['', '## Figures', '']
    lines += [f'![{name}](figures/{name})' for name in figures] or ['No figures drawn.']
    if figures and 'pass_rate.png' not in figures:
        lines += ['', 'No pass rate figure: no numeric scenario dimension varies.']
    lines += ['', f'Rerun one episode bit for bit: `pendulum_campaign --rerun {out} EPISODE`.',
              '']
    path = out / 'summary.md'
    path.write_text('\n'.join(lines), encoding='utf-8')
    return path


def _import_writers() -> None:
    """Import what :func:`write_results` writes with (pyarrow, matplotlib), when installed."""
    try:
        import pyarrow.parquet  # noqa: F401
    except ImportError:
        pass
    try:
        from pendulum_sim.pyplot_agg import pyplot

        pyplot()
    except ImportError:
        pass


def import_writers() -> threading.Thread:
    """Start importing what :func:`write_results` writes with, in a thread; return it.

    A campaign's process mostly waits for its episodes: the imports (a third of a second for
    matplotlib) are done meanwhile instead of after the last episode.
    """
    thread = threading.Thread(target=_import_writers, name='import-writers', daemon=True)
    thread.start()
    return thread


def write_results(spec: CampaignSpec, rows: list[dict[str, Any]], out: Path) -> None:
    """Write the table, the figures and the summary of a finished campaign."""
    write_table(spec, rows, out)
    figures = write_figures(spec, rows, out)
    write_summary(spec, rows, out, figures)
