"""The benchmark's figures: its results beside the reference controllers', and the region of
attraction as a map.

``benchmark.png`` has one panel per result (:data:`~.criteria.KEYS`): a bar for the
controller benchmarked and one for each shipped reference controller, from
``references.yaml`` beside this module (their ``benchmark.yaml`` results, recorded by
``bench/bench_benchmark.py --references``). ``roa.png`` marks each start state of the grid
green where the episode swung up (entered the goal box and stayed) and grey where it did
not, with the area in the title and the controller's own linearised estimate (an ellipse,
``roa_estimate``) drawn over it when it has one. Both need matplotlib; without it they are
not drawn (None).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from .criteria import KEYS, UNITS, Settings

REFERENCES = Path(__file__).with_name('references.yaml')


def references() -> dict[str, dict[str, Any]]:
    """Return the shipped reference controllers' results, ``{controller: {key: value}}``."""
    if not REFERENCES.is_file():
        return {}
    data = yaml.safe_load(REFERENCES.read_text(encoding='utf-8')) or {}
    return {str(k): v for k, v in data.items() if isinstance(v, dict)}


def _pyplot() -> Any:
    try:
        from pendulum_sim.pyplot_agg import pyplot
    except ImportError:
        return None
    return pyplot()


def comparison_figure(result: Any, path: Path) -> Path | None:
    """Draw ``benchmark.png``: each result beside the reference controllers'; return its path."""
    plt = _pyplot()
    if plt is None:
        return None
    mine = str(result.settings.get('controller'))
    named = [(f'{mine} (this run)', result.values)]
    named += [(name, values) for name, values in references().items() if name != mine]
    fig, axes = plt.subplots(3, 3, figsize=(12, 8.5))
    colours = [f'C{i}' for i in range(len(named))]
    for ax, key in zip(axes.flat, KEYS, strict=True):
        heights = []
        for _, values in named:
            v = values.get(key)
            heights.append(float(v) if v is not None and math.isfinite(float(v)) else math.nan)
        x = np.arange(len(named))
        ax.bar(x, np.nan_to_num(heights, nan=0.0), color=colours)
        for xi, h in zip(x, heights, strict=True):
            ax.annotate('n/a' if math.isnan(h) else f'{h:.3g}', (xi, 0 if math.isnan(h) else h),
                        ha='center', va='bottom', fontsize=8)
        ax.set_xticks(x, [str(i + 1) for i in range(len(named))])
        ax.set_title(f'{key} ({UNITS[key]})', fontsize=10)
        ax.margins(y=0.2)
    fig.legend([plt.Rectangle((0, 0), 1, 1, color=c) for c in colours],
               [f'{i + 1}: {n}' for i, (n, _) in enumerate(named)], loc='lower center',
               ncol=1, fontsize=8, frameon=False)
    fig.suptitle('Swing-up benchmark: this controller beside the reference controllers')
    fig.tight_layout(rect=(0, 0.04 + 0.025 * len(named), 1, 0.96))
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def roa_figure(settings: Settings, rows: list[dict[str, Any]], area: float | None,
               estimate: Any, path: Path) -> Path | None:
    """Draw ``roa.png`` from the ``roa`` campaign's rows; return its path."""
    plt = _pyplot()
    if plt is None:
        return None
    n = settings.roa_grid
    (a0, a1), (r0, r1) = settings.roa_span
    grid = np.full((n, n), np.nan)   # [rate row, angle column]
    for r in rows:
        i = int(r['episode'])
        grid[i // n, i % n] = 1.0 if r['passed'] else 0.0
    fig, ax = plt.subplots(figsize=(7, 5.5))
    from matplotlib.colors import ListedColormap

    ax.imshow(grid, origin='lower', extent=(a0, a1, r0, r1), aspect='auto',
              cmap=ListedColormap(['0.8', 'tab:green']), vmin=0, vmax=1,
              interpolation='nearest')
    handles = [plt.Rectangle((0, 0), 1, 1, color='tab:green', label='swings up and stays'),
               plt.Rectangle((0, 0), 1, 1, color='0.8', label='does not')]
    if estimate is not None:
        phi, rate = ellipse_points(estimate)
        for shift in (-2 * math.pi, 0.0, 2 * math.pi):   # every copy of upright in view
            line, = ax.plot(phi + shift, rate, color='k', lw=1.5)
        line.set_label(f'linearised estimate (area {estimate.area():.3g} rad²/s)')
        handles.append(line)
        ax.set_xlim(a0, a1)
        ax.set_ylim(r0, r1)
    ax.set_xlabel('start angle φ0 (rad; π is upright)')
    ax.set_ylabel("start rate φ0' (rad/s)")
    shown = '-' if area is None else f'{area:.4g}'
    ax.set_title(f'Region of attraction: area {shown} rad²/s ({n} × {n} start states)',
                 fontsize=10)
    ax.legend(handles=handles, loc='upper right', fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def ellipse_points(estimate: Any, count: int = 200) -> tuple[np.ndarray, np.ndarray]:
    """Return the boundary ``xᵀ S x = level`` of an ellipse estimate, around its centre."""
    values, vectors = np.linalg.eigh(np.asarray(estimate.matrix, dtype=float))
    theta = np.linspace(0.0, 2.0 * math.pi, count)
    unit = np.stack([np.cos(theta), np.sin(theta)])
    points = vectors @ (np.sqrt(estimate.level / values)[:, np.newaxis] * unit)
    return points[0] + estimate.center[0], points[1] + estimate.center[1]
