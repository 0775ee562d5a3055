"""Figures: matplotlib imported lazily with the Agg backend; optional.

Without matplotlib every report still writes its tables, and its summary says that the figures
were skipped (:func:`missing_note`).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pendulum_sim.pyplot_agg import pyplot as pyplot

CORE_STYLE = '-'
SCIPY_STYLE = '--'
JIT_STYLE = ':'  # the core's adaptive methods with compiled steps


def have_matplotlib() -> bool:
    """Return True where matplotlib can be imported."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return False
    return True


def missing_note() -> str:
    """Return the note written in place of the figures when matplotlib is missing."""
    return ('**matplotlib is not installed: no figures were drawn.** The CSV tables hold every '
            'number; install matplotlib (`pip install matplotlib`) and re-run for the PNGs.')


def save(fig: Any, out: Path, name: str) -> str:
    """Save and close a figure as ``out/name``; return the file name."""
    fig.tight_layout()
    fig.savefig(out / name, dpi=110)
    pyplot().close(fig)
    return name


def label_axes(ax: Any, xlabel: str, ylabel: str | None = None, title: str | None = None,
               *, fontsize: int = 8, which: str = 'major') -> None:
    """Label an axes, add its legend and a light grid: every report figure's axes finish so."""
    if title is not None:
        ax.set_title(title)
    ax.set_xlabel(xlabel)
    if ylabel is not None:
        ax.set_ylabel(ylabel)
    ax.legend(fontsize=fontsize)
    ax.grid(True, which=which, alpha=0.3)


def _grid(count: int) -> tuple[int, int]:
    cols = min(count, 3)
    return math.ceil(count / cols), cols


def work_precision_figures(out: Path, rows: Sequence[dict[str, Any]],
                           orders: Sequence[dict[str, Any]], cases: Sequence[str]) -> list[str]:
    """Draw error against CPU time and error against h, one panel per case."""
    if not have_matplotlib():
        return []
    plt = pyplot()
    groups: dict[str, list[str]] = {}
    for name in cases:
        key = name.split('_n')[0]
        groups.setdefault(key, []).append(name)
    files = []
    for key, names in groups.items():
        r, c = _grid(len(names))
        fig, axes = plt.subplots(r, c, figsize=(5 * c, 4 * r), squeeze=False)
        for ax, case in zip(axes.flat, names, strict=False):
            sel = [x for x in rows if x['case'] == case]
            # One colour per method: a compiled variant shares its method's, dotted.
            bases = list(dict.fromkeys(x['solver'] for x in sel if not x.get('jit')))
            colours = plt.get_cmap('tab20').colors
            for solver in dict.fromkeys(x['solver'] for x in sel):
                pts = sorted((x['cpu_s'], x['err_max']) for x in sel if x['solver'] == solver
                             and math.isfinite(x['err_max']) and x['err_max'] > 0)
                if not pts:
                    continue
                compiled = any(x.get('jit') for x in sel if x['solver'] == solver)
                base = solver.rsplit('-', 1)[0] if compiled else solver  # 'rodas4-jit'
                style = SCIPY_STYLE if solver.startswith('scipy') else (
                    JIT_STYLE if compiled else CORE_STYLE)
                colour = colours[bases.index(base) % len(colours)]
                ax.loglog([p[0] for p in pts], [p[1] for p in pts], style, marker='.',
                          color=colour, label=solver)
            label_axes(ax, 'CPU time (s)', 'max error over trajectory', case, fontsize=7,
                       which='both')
        for ax in list(axes.flat)[len(names):]:
            ax.axis('off')
        files.append(save(fig, out, f'work_precision_{key}.png'))
        fig, axes = plt.subplots(r, c, figsize=(5 * c, 4 * r), squeeze=False)
        for ax, case in zip(axes.flat, names, strict=False):
            sel = [x for x in rows if x['case'] == case and x['family'] == 'core'
                   and x['param'] == 'h']
            for solver in dict.fromkeys(x['solver'] for x in sel):
                pts = sorted((x['value'], x['err_max']) for x in sel if x['solver'] == solver
                             and x['err_max'] > 0)
                fitted = next((o['fitted'] for o in orders
                               if o['case'] == case and o['solver'] == solver), math.nan)
                ax.loglog([p[0] for p in pts], [p[1] for p in pts], marker='o', ms=3,
                          label=f'{solver} (slope {fitted:.2f})')
            label_axes(ax, 'h (s)', 'max error over trajectory', case, fontsize=7,
                       which='both')
        for ax in list(axes.flat)[len(names):]:
            ax.axis('off')
        files.append(save(fig, out, f'error_vs_h_{key}.png'))
    return files


def stability_heatmaps(out: Path, cells: Sequence[dict[str, Any]],
                       boundaries: dict[float, list[tuple[float, float]]]) -> list[str]:
    """Draw, per n, the (γ, h) plane coloured by what the guard did, with RK4's boundary."""
    if not have_matplotlib():
        return []
    plt = pyplot()
    base = [c for c in cells if c['scenario'] == 'paper']
    ns = sorted({c['n'] for c in base})
    gammas = sorted({c['gamma'] for c in base})
    hs = sorted({c['h'] for c in base})
    r, cols = _grid(len(ns))
    fig, axes = plt.subplots(r, cols, figsize=(5 * cols, 4 * r), squeeze=False)
    from matplotlib.colors import ListedColormap
    cmap = ListedColormap(['#2ca02c', '#ffdd55', '#ff9933', '#d62728'])
    gx, hy = _edges(gammas), _edges(hs)
    for ax, n in zip(axes.flat, ns, strict=False):
        grid = np.full((len(hs), len(gammas)), np.nan)
        for c in base:
            if c['n'] == n:
                grid[hs.index(c['h']), gammas.index(c['gamma'])] = _category(c)
        ax.pcolormesh(gx, hy, grid, cmap=cmap, vmin=-0.5, vmax=3.5, shading='flat')
        bad = [c for c in base if c['n'] == n and c['rk4_unstable_run']]
        ax.plot([c['gamma'] for c in bad], [c['h'] for c in bad], 'kx', ms=7,
                label='unguarded RK4 unstable')
        pts = boundaries.get(n, [])  # drawn in full; the axes clip it
        if pts:
            ax.plot([p[0] for p in pts], [p[1] for p in pts], 'b-', lw=2,
                    label='RK4 boundary h = 2.785/|λ|max')
        ax.set_xscale('log')
        ax.set_yscale('log')
        ax.set_xlim(gx[0], gx[-1])
        ax.set_ylim(hy[0], hy[-1])
        ax.set_xlabel('γ')
        ax.set_ylabel('h (s)')
        ax.set_title(f'n = {n:g}')
        ax.legend(fontsize=6, loc='lower left')
    for ax in list(axes.flat)[len(ns):]:
        ax.axis('off')
    fig.suptitle('Guarded RK4: green plain steps, yellow substeps, orange implicit fallback, '
                 'red energy rejections; x = unguarded RK4 unstable', fontsize=9)
    return [save(fig, out, 'stability_heatmap.png')]


def _edges(values: Sequence[float]) -> list[float]:
    """Return cell edges around log-spaced values (geometric midpoints, padded at the ends)."""
    logs = np.log10(values)
    if len(logs) == 1:
        return [10 ** (logs[0] - 0.5), 10 ** (logs[0] + 0.5)]
    mids = (logs[1:] + logs[:-1]) / 2
    first = logs[0] - (mids[0] - logs[0])
    last = logs[-1] + (logs[-1] - mids[-1])
    return [float(10**x) for x in [first, *mids, last]]


def _category(cell: dict[str, Any]) -> float:
    if cell['energy_rejections'] > 0:
        return 3.0
    if cell['fallbacks'] > 0:
        return 2.0
    if cell['substeps'] > 0:
        return 1.0
    return 0.0
