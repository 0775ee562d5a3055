"""The campaign's figures: the metrics' distributions, and the pass rate over the scenario.

Each figure shows its data at any spread. A metric whose values are one number to the
:data:`SIGNIFICANT` digits the summary prints is drawn as a marker at that number, with the
count and the spread written beside it, not as a histogram bar of no width; the axis is kept on
the data, and a requirement far from it (one that would leave the data less than a quarter of
the axis) is written at the panel's edge with an arrow instead of stretching the axis to it.
A scenario dimension whose values differ only beyond those digits is drawn as its offset from
the number they share (``g − 9.8``). Every campaign with a pass rate of 0 % or 100 % gets its
episodes as markers and says so, instead of one flat colour. Tick labels are thinned out until
none overlap (:func:`~pendulum_sim.testing.figure.readable_ticks`).

A scenario dimension declared to vary (a distribution or a list) whose values span less than
:data:`POINT_LIKE` of their size is *point-like*: the campaign ran nearly one scenario there,
as it does over a tight fit's standard errors (``pendulum_identify``'s
``campaign_parameters.yaml``). Both figures and ``summary.md`` say so (:func:`point_like_note`).
matplotlib is imported on first use only.
"""
from __future__ import annotations

import math
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .spec import CampaignSpec, Distribution, Grid, Requirement

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

SIGNIFICANT = 4        # digits of a number in summary.md and in the figures' notes
POINT_LIKE = 0.01      # a varying dimension spanning less than this fraction of its size
REACH = 4.0            # a requirement is drawn on the axis if the axis stays <= REACH x the data
SHOWN_METRICS = {'step': ('rise_time', 'settling_time', 'overshoot', 'steady_state_error',
                          'iae', 'max_effort', 'effort_energy', 'saturation_fraction'),
                 'swing_up': ('swing_up_time', 'settle_time', 'energy', 'effort_energy',
                              'smoothness', 'max_effort', 'saturation_fraction', 'swings')}
"""Per task, the eight metrics whose distributions are drawn."""
REQUIREMENT_COLOUR = 'C3'
# The episodes over the pass-rate map: seen on every colour of the map and on white.
EPISODE_MARKERS = {'passed': {'marker': 'o', 'color': 'k', 'ms': 3},
                   'failed': {'marker': 'X', 'color': 'white', 'markeredgecolor': 'k',
                              'markeredgewidth': 0.8, 'ms': 7}}


def shown(value: float) -> str:
    """Return ``value`` to :data:`SIGNIFICANT` significant digits (as summary.md prints it)."""
    return f'{value:.{SIGNIFICANT}g}'


def one_point(values: NDArray[np.float64]) -> bool:
    """Return True when the finite ``values`` print as one number to SIGNIFICANT digits."""
    return shown(float(values.min())) == shown(float(values.max()))


@dataclass(frozen=True)
class Spread:
    """The values one scenario dimension took over a campaign."""

    name: str
    low: float
    high: float

    @property
    def relative(self) -> float:
        """Return the span over the size of the values, max |value| (0 for all zeros)."""
        size = max(abs(self.low), abs(self.high))
        return 0.0 if size == 0.0 else (self.high - self.low) / size


def numeric_column(rows: Sequence[dict[str, Any]], name: str) -> NDArray[np.float64] | None:
    """Return the column ``name`` as floats, or None when a value is not a number."""
    values = [r[name] for r in rows]
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        return None
    return np.array(values, dtype=float)


def point_like(spec: CampaignSpec, rows: Sequence[dict[str, Any]]) -> list[Spread]:
    """Return the dimensions declared to vary whose values span < POINT_LIKE of their size.

    A dimension varies by declaration when it is a distribution, a list or a grid (a fixed
    value is a constant by choice); its span is measured on the values the episodes drew (the
    drawn ``disturbance.pulses``, a text, is not measured).
    """
    spaces: dict[str, Any] = {**dict(spec.parameters), 'target': spec.target}
    out = []
    for name in spec.scenario_names:
        if not isinstance(spaces.get(name), (Distribution, tuple, Grid)) or not rows:
            continue
        x = numeric_column(rows, name)
        if x is None or not np.all(np.isfinite(x)):
            continue
        spread = Spread(name, float(x.min()), float(x.max()))
        if spread.relative < POINT_LIKE:
            out.append(spread)
    return out


def point_like_note(spreads: Sequence[Spread]) -> str:
    """Return the sentence that says which dimensions are point-like ('' when none is)."""
    if not spreads:
        return ''
    parts = []
    for s in spreads:
        if s.low == s.high:
            parts.append(f'{s.name} only {shown(s.low)}')
        elif shown(s.low) == shown(s.high):
            parts.append(f'{s.name} ≈ {shown(s.low)} (spread {s.high - s.low:.1e}, '
                         f'{s.relative:.1e} of its size)')
        else:
            parts.append(f'{s.name} {shown(s.low)} to {shown(s.high)} '
                         f'({100 * s.relative:.2g} % of its size)')
    return (f'Nearly point-like scenario: {", ".join(parts)}. Spaces this narrow (under '
            f'{100 * POINT_LIKE:g} %) make the episodes nearly one scenario, so their metrics '
            'barely differ.')


def influence(spec: CampaignSpec, rows: Sequence[dict[str, Any]]) -> list[tuple[str, float]]:
    """Return the numeric scenario dimensions (parameters, target) that vary, by |correlation
    with passing|, largest first."""
    passed = np.array([float(r['passed']) for r in rows])
    ranked: list[tuple[str, float]] = []
    for name in spec.scenario_names:
        x = numeric_column(rows, name)
        if x is None or np.ptp(x) == 0.0:
            continue
        score = 0.0 if np.ptp(passed) == 0.0 else abs(float(np.corrcoef(x, passed)[0, 1]))
        ranked.append((name, score))
    return sorted(ranked, key=lambda item: -item[1])


def _figure_note(fig: Figure, text: str, width: int) -> float:
    """Write ``text`` along the bottom of ``fig``; return the height it takes (figure units)."""
    if not text:
        return 0.0
    lines = textwrap.fill(text, width)
    fig.text(0.01, 0.01, lines, fontsize=8, ha='left', va='bottom', color='0.25')
    return 0.03 + 0.035 * (lines.count('\n') + 1) * 6.0 / fig.get_figheight()


def _requirements(ax: Axes, requirements: Sequence[Requirement],
                  view: tuple[float, float]) -> tuple[float, float]:
    """Draw the requirements near the data as lines, the others as arrows at the edge; return
    the x view that holds the data and the lines drawn."""
    low, high = view
    width = high - low
    arrows = 0
    for req in requirements:
        reach = (min(low, req.bound), max(high, req.bound))
        if reach[1] - reach[0] <= REACH * width:
            ax.axvline(req.bound, color=REQUIREMENT_COLOUR, ls='--', label=str(req))
            low, high = min(low, req.bound), max(high, req.bound)
            continue
        right = req.bound > high
        ax.annotate(f'{req} →' if right else f'← {req}',
                    xy=(0.98 if right else 0.02, 0.97 - 0.09 * arrows),
                    xycoords='axes fraction', ha='right' if right else 'left', va='top',
                    fontsize=8, color=REQUIREMENT_COLOUR)
        arrows += 1
    pad = 0.05 * (high - low)
    return low - pad, high + pad


def _metric_panel(ax: Axes, name: str, column: NDArray[np.float64],
                  requirements: Sequence[Requirement]) -> None:
    """Draw one metric's values: a histogram, or a marker where they are one number."""
    from matplotlib.ticker import MaxNLocator, ScalarFormatter

    finite = column[np.isfinite(column)]
    ax.set_title(f'{name} ({column.size - finite.size} nan)', fontsize=9)
    ax.yaxis.set_major_locator(MaxNLocator(nbins=5, integer=True))
    if not finite.size:
        ax.text(0.5, 0.5, f'no value: all {column.size} nan', transform=ax.transAxes,
                ha='center', va='center', fontsize=8)
        ax.set_xticks([])
        return
    low, high = float(finite.min()), float(finite.max())
    if one_point(finite):
        centre = float(np.median(finite))
        ax.vlines(centre, 0, finite.size, color='C0', lw=2)
        ax.plot([centre], [finite.size], 'o', color='C0', ms=7)
        ax.set_ylim(0, finite.size * 1.4)
        said = (f'all {finite.size} = {shown(centre)}' if low == high else
                f'all {finite.size} ≈ {shown(centre)}\n(spread {high - low:.1e})')
        ax.text(0.03, 0.97, said, transform=ax.transAxes, ha='left', va='top', fontsize=8)
        half = 0.05 * abs(centre) or 0.05
        view = (centre - half, centre + half)
    else:
        counts, _, _ = ax.hist(finite, bins=min(30, max(5, finite.size // 5)), color='C0')
        ax.set_ylim(0, float(np.max(counts)) * 1.3)   # room above the bars for the labels
        view = (low, high)
    ax.set_xlim(*_requirements(ax, requirements, view))
    if any(r.metric == name for r in requirements) and ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7, loc='upper right')
    formatter = ScalarFormatter(useOffset=False, useMathText=True)
    formatter.set_powerlimits((-3, 4))
    ax.xaxis.set_major_formatter(formatter)
    ax.xaxis.set_major_locator(MaxNLocator(nbins=5))


def metric_figure(spec: CampaignSpec, rows: Sequence[dict[str, Any]]) -> Figure:
    """Return the figure of the metrics' distributions with the requirements."""
    from pendulum_sim.pyplot_agg import pyplot

    from ..figure import readable_ticks

    plt = pyplot()
    fig: Figure
    fig, axes = plt.subplots(2, 4, figsize=(13, 6))
    for ax, name in zip(axes.flat, SHOWN_METRICS[spec.task], strict=True):
        column = np.array([r[name] for r in rows], dtype=float)
        _metric_panel(ax, name, column, [r for r in spec.requirements if r.metric == name])
    fig.suptitle(f'Metric distributions over {len(rows)} episodes')
    bottom = _figure_note(fig, point_like_note(point_like(spec, rows)), 170)
    fig.tight_layout(rect=(0.0, bottom, 1.0, 1.0))
    readable_ticks(fig)
    return fig


def _scenario_axis(name: str,
                   rows: Sequence[dict[str, Any]]) -> tuple[NDArray[np.float64], str]:
    """Return a numeric dimension's values to plot and its axis label.

    Values that print as one number are drawn as their offset from it, in units of a power
    of ten written in the label (``g − 9.8 (×10⁻⁸)``): ticks that tell them apart.
    """
    column = numeric_column(rows, name)
    assert column is not None   # influence() ranks numeric dimensions only
    if not one_point(column):
        return column, name
    centre = float(shown(float(np.median(column))))
    offset = column - centre
    power = math.floor(math.log10(float(np.abs(offset).max())))
    return offset / 10.0 ** power, f'{name} − {shown(centre)} ($\\times 10^{{{power}}}$)'


def pass_rate_figure(spec: CampaignSpec, rows: Sequence[dict[str, Any]]) -> Figure | None:
    """Return the figure of the pass rate over the two most influential scenario dimensions
    (None when no numeric dimension varies)."""
    from matplotlib.ticker import MaxNLocator, ScalarFormatter

    from pendulum_sim.pyplot_agg import pyplot

    from ..figure import readable_ticks

    ranked = influence(spec, rows)
    if not ranked:
        return None
    plt = pyplot()
    passed = np.array([bool(r['passed']) for r in rows])
    n, good = len(rows), int(passed.sum())
    uniform = good in (0, n)
    fig: Figure
    fig, ax = plt.subplots(figsize=(6.5, 5))
    x, x_label = _scenario_axis(ranked[0][0], rows)
    if len(ranked) >= 2:
        y, y_label = _scenario_axis(ranked[1][0], rows)
        if not uniform:
            bins = max(2, min(10, int(math.sqrt(n / 2))))
            total, xe, ye = np.histogram2d(x, y, bins=bins)
            hit, _, _ = np.histogram2d(x, y, bins=(xe, ye), weights=passed.astype(float))
            with np.errstate(invalid='ignore', divide='ignore'):
                rate = np.where(total > 0, hit / total, np.nan)
            mesh = ax.pcolormesh(xe, ye, 100 * rate.T, cmap='RdYlGn', vmin=0, vmax=100)
            fig.colorbar(mesh, ax=ax, label='pass rate (%) of the episodes in a cell')
        ax.set_ylabel(y_label)
    else:
        y = np.where(passed, 100.0, 0.0)
        if not uniform:
            bins = max(2, min(20, n // 5))
            total_1, edges = np.histogram(x, bins=bins)
            hit_1, _ = np.histogram(x, bins=edges, weights=passed.astype(float))
            with np.errstate(invalid='ignore', divide='ignore'):
                ax.stairs(100 * np.where(total_1 > 0, hit_1 / total_1, np.nan), edges,
                          color='k', label='pass rate in a bin')
        ax.set_ylim(-8, 108)
        ax.set_ylabel('pass rate (%); markers: the episodes')
    for mask, what in ((passed, 'passed'), (~passed, 'failed')):
        if mask.any():
            ax.plot(x[mask], y[mask], ls='none', label=f'{int(mask.sum())} {what}',
                    **EPISODE_MARKERS[what])
    ax.set_xlabel(x_label)
    ax.legend(fontsize=8, loc='best')
    title = (f'pass rate {100 * good / n:.1f} % ({good} of {n}) over the most influential '
             'parameters')
    if uniform:
        title += (f'\nall {n} episodes {"passed" if good else "failed"}: no boundary between '
                  'passing and failing to show')
    ax.set_title(title, fontsize=10)
    for axis in (ax.xaxis, ax.yaxis):
        formatter = ScalarFormatter(useOffset=False, useMathText=True)
        formatter.set_powerlimits((-3, 4))
        axis.set_major_formatter(formatter)
        axis.set_major_locator(MaxNLocator(nbins=5))
    bottom = _figure_note(fig, point_like_note(point_like(spec, rows)), 95)
    fig.tight_layout(rect=(0.0, bottom, 1.0, 1.0))
    readable_ticks(fig)
    return fig


def write_figures(spec: CampaignSpec, rows: list[dict[str, Any]], out: Path) -> list[str]:
    """Draw the metric distributions and the pass rate into ``out/figures``; return the names.

    Nothing is drawn without matplotlib; the pass rate is not drawn when no numeric scenario
    dimension varies.
    """
    try:
        from pendulum_sim.pyplot_agg import pyplot
        plt = pyplot()
    except ImportError:
        return []
    folder = out / 'figures'
    folder.mkdir(exist_ok=True)
    names = []
    for name, fig in (('metric_distributions.png', metric_figure(spec, rows)),
                      ('pass_rate.png', pass_rate_figure(spec, rows))):
        if fig is None:
            continue
        fig.savefig(folder / name, dpi=100)
        plt.close(fig)
        names.append(name)
    return names
