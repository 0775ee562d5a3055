"""One entry point over the three reports: run them into a folder and write ``summary.md``."""
from __future__ import annotations

import dataclasses
import os
import platform
import time
from typing import Any

from . import paper_figures, stability, work_precision
from .errors import ReportError
from .output import Summary, prepare_out_dir
from .plotting import have_matplotlib, missing_note
from .reference import scipy_available

WHATS = ('work-precision', 'stability', 'paper', 'all')


def machine_info() -> str:
    """Return a one-paragraph description of the machine and library versions."""
    import numpy
    cpu = platform.processor() or platform.machine()
    try:
        with open('/proc/cpuinfo', encoding='utf-8') as fh:
            for line in fh:
                if line.startswith('model name'):
                    cpu = line.split(':', 1)[1].strip()
                    break
    except OSError:
        pass
    parts = [f'{cpu}, {os.cpu_count()} logical CPUs', f'{platform.system()} {platform.release()}',
             f'Python {platform.python_version()}', f'numpy {numpy.__version__}']
    if scipy_available():
        import scipy  # type: ignore[import-untyped]
        parts.append(f'scipy {scipy.__version__}')
    else:
        parts.append('scipy not installed')
    if have_matplotlib():
        import matplotlib
        parts.append(f'matplotlib {matplotlib.__version__}')
    else:
        parts.append('matplotlib not installed')
    return '; '.join(parts)


def run_report(what: str, out: str | os.PathLike[str], quick: bool = False, force: bool = False,
               repeats: int | None = None, progress: bool = True,
               command: str | None = None) -> dict[str, Any]:
    """Run ``what`` (one of WHATS) into the folder ``out``; return each report's tables."""
    if what not in WHATS:
        raise ReportError(f'unknown report {what!r}; choose from {", ".join(WHATS)}')
    if repeats is not None and (not isinstance(repeats, int) or repeats < 1):
        raise ReportError(f'repeats must be an integer >= 1, got {repeats!r}')
    path = prepare_out_dir(out, force)
    started = time.perf_counter()
    results: dict[str, Any] = {}
    parts: list[str] = []
    if what in ('work-precision', 'all'):
        grid = work_precision.QUICK if quick else work_precision.FULL
        if repeats is not None:
            grid = dataclasses.replace(grid, repeats=repeats)
        results['work-precision'] = work_precision.run_work_precision(path, grid, progress)
        parts.append(results['work-precision']['summary'])
    if what in ('stability', 'all'):
        sgrid = stability.QUICK if quick else stability.FULL
        results['stability'] = stability.run_stability(path, sgrid, progress)
        parts.append(results['stability']['summary'])
    if what in ('paper', 'all'):
        pgrid = paper_figures.QUICK if quick else paper_figures.FULL
        results['paper'] = paper_figures.run_paper(path, pgrid, progress)
        parts.append(results['paper']['summary'])
    summary = Summary(f'pendulum_report {what}' + (' --quick' if quick else ''))
    summary.section(
        'Run',
        f'Machine: {machine_info()}.',
        f'Command: `{command or f"run_report({what!r}, quick={quick})"}`'
        f'; wall time {time.perf_counter() - started:.1f} s.'
        + ('' if have_matplotlib() else '\n\n' + missing_note()))
    text = summary.text() + '\n' + '\n'.join(_demote(p) for p in parts)
    (path / 'summary.md').write_text(text, encoding='utf-8')
    results['summary_path'] = path / 'summary.md'
    return results


def _demote(markdown: str) -> str:
    """Push every heading one level down, so each report becomes a section of the summary."""
    return '\n'.join('#' + line if line.startswith('#') else line
                     for line in markdown.splitlines())
