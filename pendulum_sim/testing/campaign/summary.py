"""The campaign's results: the episode table (Parquet and CSV), ``summary.md``, figures.

Table columns: ``episode``, one per scenario parameter (named as the parameter), ``target`` (the
episode's reference, always there, fixed or drawn), one per metric
(named as the :class:`~pendulum_sim.testing.StepMetrics` field), ``passed``, ``reason``, and
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

from ..metrics import METRIC_NAMES
from .episode import RUN_COLUMNS, failure_path
from .spec import CampaignSpec, describe

QUANTILES = (0.05, 0.5, 0.95)
WORST = 10


def columns(spec: CampaignSpec) -> list[str]:
    """Return the table's columns in order."""
    return ['episode', *spec.scenario_names, *METRIC_NAMES, 'passed', 'reason', *RUN_COLUMNS]


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
    table = pa.table({c: [row[c] for row in rows] for c in cols})
    pq.write_table(table, out / 'episodes.parquet')
    written.append(out / 'episodes.parquet')
    return written


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return '–' if math.isnan(value) else f'{value:.4g}'
    return str(value)


def influence(spec: CampaignSpec, rows: list[dict[str, Any]]) -> list[tuple[str, float]]:
    """Return the numeric scenario dimensions (parameters, target) that vary, by |correlation
    with passing|, largest first."""
    passed = np.array([float(r['passed']) for r in rows])
    ranked: list[tuple[str, float]] = []
    for name in spec.scenario_names:
        values = [r[name] for r in rows]
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
            continue
        x = np.array(values, dtype=float)
        if np.ptp(x) == 0.0:
            continue
        score = 0.0 if np.ptp(passed) == 0.0 else abs(float(np.corrcoef(x, passed)[0, 1]))
        ranked.append((name, score))
    return sorted(ranked, key=lambda item: -item[1])


def write_summary(spec: CampaignSpec, rows: list[dict[str, Any]], out: Path,
                  figures: list[str]) -> Path:
    """Write ``summary.md``: pass rate, metric quantiles, the worst episodes, the figures."""
    n = len(rows)
    passed = sum(1 for r in rows if r['passed'])
    lines = [f'# Campaign: {n} episodes, {passed} passed ({100.0 * passed / max(n, 1):.1f} %)',
             '', f'Controller `{spec.controller}`, scene `{spec.scene}`, {spec.periods} control '
             f'periods per episode, target {describe(spec.target)} rad, seed {spec.seed}.', '',
             '## Requirements', '']
    lines += [f'- `{r}`: {sum(1 for row in rows if not r.check(row[r.metric]))} of {n} met'
              for r in spec.requirements] or ['- none (every episode that runs passes)']
    lines += ['', '## Metric quantiles', '',
              '| metric | ' + ' | '.join(f'{100 * q:g} %' for q in QUANTILES) + ' | nan |',
              '|---|' + '---|' * (len(QUANTILES) + 1)]
    for name in METRIC_NAMES:
        x = np.array([r[name] for r in rows], dtype=float)
        finite = x[np.isfinite(x)]
        qs = [float(np.quantile(finite, q)) if finite.size else math.nan for q in QUANTILES]
        lines.append(f'| {name} | ' + ' | '.join(_fmt(v) for v in qs)
                     + f' | {int(np.sum(~np.isfinite(x)))} |')
    worst = sorted(rows, key=lambda r: (r['passed'], -(r['settling_time'] if math.isfinite(
        r['settling_time']) else math.inf), r['episode']))[:WORST]
    lines += ['', f'## The worst episodes (failed first, then the slowest to settle; '
              f'at most {WORST})', '',
              '| episode | ' + ' | '.join(spec.scenario_names)
              + ' | settling_time | overshoot | passed | reason | recording |',
              '|---|' + '---|' * (len(spec.scenario_names) + 5)]
    for r in worst:
        mcap = failure_path(out, r['episode'])
        rec = f'failures/{mcap.name}' if mcap.is_file() else ''
        lines.append(f'| {r["episode"]} | ' + ' | '.join(_fmt(r[p]) for p in
                                                          spec.scenario_names)
                     + f' | {_fmt(r["settling_time"])} | {_fmt(r["overshoot"])} | '
                     f'{"yes" if r["passed"] else "no"} | {r["reason"]} | {rec} |')
    lines += ['', '## Figures', '']
    lines += [f'![{name}](figures/{name})' for name in figures] or ['No figures drawn.']
    lines += ['', f'Rerun one episode bit for bit: `pendulum_campaign --rerun {out} EPISODE`.',
              '']
    path = out / 'summary.md'
    path.write_text('\n'.join(lines), encoding='utf-8')
    return path


def write_figures(spec: CampaignSpec, rows: list[dict[str, Any]], out: Path) -> list[str]:
    """Draw the metric distributions and the pass rate over the two most influential params."""
    try:
        from pendulum_sim.pyplot_agg import pyplot
        plt = pyplot()
    except ImportError:
        return []
    folder = out / 'figures'
    folder.mkdir(exist_ok=True)
    names: list[str] = []
    shown = ('rise_time', 'settling_time', 'overshoot', 'steady_state_error', 'iae',
             'max_effort', 'effort_energy', 'saturation_fraction')
    fig, axes = plt.subplots(2, 4, figsize=(13, 6))
    for ax, name in zip(axes.flat, shown, strict=True):
        x = np.array([r[name] for r in rows], dtype=float)
        finite = x[np.isfinite(x)]
        if finite.size:
            ax.hist(finite, bins=min(30, max(5, finite.size // 5)), color='C0')
        ax.set_title(f'{name} ({x.size - finite.size} nan)', fontsize=9)
        limit = [r for r in spec.requirements if r.metric == name]
        for req in limit:
            ax.axvline(req.bound, color='C3', ls='--', label=str(req))
            ax.legend(fontsize=7)
    fig.suptitle(f'Metric distributions over {len(rows)} episodes')
    fig.tight_layout()
    fig.savefig(folder / 'metric_distributions.png', dpi=100)
    plt.close(fig)
    names.append('metric_distributions.png')
    ranked = influence(spec, rows)
    if ranked:
        passed = np.array([float(r['passed']) for r in rows])
        fig, ax = plt.subplots(figsize=(6.5, 5))
        x = np.array([r[ranked[0][0]] for r in rows], dtype=float)
        if len(ranked) >= 2:
            y = np.array([r[ranked[1][0]] for r in rows], dtype=float)
            bins = max(2, min(10, int(math.sqrt(len(rows) / 2))))
            total, xe, ye = np.histogram2d(x, y, bins=bins)
            good, _, _ = np.histogram2d(x, y, bins=(xe, ye), weights=passed)
            with np.errstate(invalid='ignore', divide='ignore'):
                rate = np.where(total > 0, good / total, np.nan)
            mesh = ax.pcolormesh(xe, ye, 100 * rate.T, cmap='RdYlGn', vmin=0, vmax=100)
            fig.colorbar(mesh, ax=ax, label='pass rate (%)')
            ax.scatter(x, y, c=np.where(passed > 0, 'k', 'r'), s=6)
            ax.set_ylabel(ranked[1][0])
        else:
            bins = max(2, min(20, len(rows) // 5))
            total, xe = np.histogram(x, bins=bins)
            good, _ = np.histogram(x, bins=xe, weights=passed)
            with np.errstate(invalid='ignore', divide='ignore'):
                ax.stairs(100 * np.where(total > 0, good / total, np.nan), xe)
            ax.set_ylabel('pass rate (%)')
        ax.set_xlabel(ranked[0][0])
        ax.set_title('pass rate over the most influential parameters', fontsize=10)
        fig.tight_layout()
        fig.savefig(folder / 'pass_rate.png', dpi=100)
        plt.close(fig)
        names.append('pass_rate.png')
    return names


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
