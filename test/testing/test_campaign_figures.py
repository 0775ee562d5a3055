"""A campaign's figures show their data at any spread, with tick labels that do not overlap.

Each case is a real campaign (its episodes run in this process, as a worker runs them, with the
vectorised example law in one batch); the figures are asserted on as matplotlib objects after a
draw: the axis limits hold the data, a metric whose values are one number is a marker at that
number, no two tick labels of an axis overlap (their window extents, as drawn), and the note on
point-like scenario spaces is there when, and only when, a declared space is that narrow. The
PNGs are written to the test's folder too, to be looked at.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axis import Axis
from matplotlib.collections import QuadMesh
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle
from matplotlib.text import Text
from matplotlib.ticker import FormatStrFormatter, MaxNLocator

from pendulum_sim.pyplot_agg import pyplot
from pendulum_sim.testing.campaign.episode import run_chunk
from pendulum_sim.testing.campaign.figures import SHOWN_METRICS, metric_figure, pass_rate_figure
from pendulum_sim.testing.campaign.spec import CampaignSpec, parse_spec
from pendulum_sim.testing.campaign.summary import write_summary
from pendulum_sim.testing.figure import readable_ticks

CAMPAIGN = """
controller: pendulum_sim.testing.examples:pd_batch
episodes: {episodes}
seed: 2
periods: 300
target: 0.5
parameters:
{parameters}
requirements: {requirements}
"""
NOTE = 'Nearly point-like scenario: '


def campaign(episodes: int, parameters: str,
             requirements: str) -> tuple[CampaignSpec, list[dict[str, Any]]]:
    """Return the campaign and the rows of all its episodes."""
    spec = parse_spec(CAMPAIGN.format(episodes=episodes, parameters=parameters,
                                      requirements=requirements))
    return spec, run_chunk(spec.text, list(range(episodes)), None)


def column(rows: list[dict[str, Any]], name: str) -> np.ndarray:
    return np.array([r[name] for r in rows], dtype=float)


def shown_labels(axis: Axis) -> list[Any]:
    """The tick labels drawn on ``axis``: non-empty, at ticks inside its view."""
    low, high = sorted(axis.get_view_interval())
    return [t.label1 for t in axis.get_major_ticks()
            if t.label1.get_visible() and t.label1.get_text()
            and low - 1e-9 * (high - low) <= t.get_loc() <= high + 1e-9 * (high - low)]


def overlapping_labels(fig: Figure) -> list[tuple[str, str]]:
    """Return the pairs of tick labels of one axis whose drawn extents overlap."""
    fig.canvas.draw()
    found = []
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            labels = shown_labels(axis)
            boxes = [label.get_window_extent() for label in labels]
            found += [(labels[i].get_text(), labels[j].get_text())
                      for i in range(len(boxes)) for j in range(i + 1, len(boxes))
                      if boxes[i].overlaps(boxes[j])]
    return found


def texts(fig: Figure) -> str:
    """Return every text of the figure (titles, labels, notes, annotations), one per line."""
    return '\n'.join(t.get_text() for t in fig.findobj(Text))


def panels(fig: Figure) -> dict[str, Any]:
    """Return the metric figure's axes by metric name (its title starts with the name)."""
    return {ax.get_title().split(' ')[0]: ax for ax in fig.axes}


def markers(ax: Any) -> list[tuple[float, float]]:
    """Return the points drawn with a marker on ``ax``."""
    return [(float(x), float(y)) for line in ax.get_lines()
            if isinstance(line, Line2D) and line.get_marker() not in (None, 'None', '')
            for x, y in zip(np.asarray(line.get_xdata(), dtype=float),
                            np.asarray(line.get_ydata(), dtype=float), strict=True)]


def inside(ax: Any, x: float, y: float | None = None) -> bool:
    lo, hi = sorted(ax.get_xlim())
    ok = bool(lo < x < hi)
    if y is not None:
        bottom, top = sorted(ax.get_ylim())
        ok = ok and bool(bottom <= y < top)
    return ok


def save(fig: Figure, path: Path) -> None:
    fig.savefig(path, dpi=100)
    pyplot().close(fig)


def assert_each_panel_shows_its_values(fig: Figure, rows: list[dict[str, Any]]) -> None:
    """Every metric's values lie inside its panel's x range, as bars or as a marker."""
    for name, ax in panels(fig).items():
        values = column(rows, name)
        values = values[np.isfinite(values)]
        bars = [p for p in ax.patches if isinstance(p, Rectangle) and p.get_height() > 0]
        if bars:
            assert sum(p.get_height() for p in bars) == values.size
            assert all(inside(ax, p.get_x()) and inside(ax, p.get_x() + p.get_width())
                       for p in bars), name
        else:
            ((x, y),) = markers(ax)
            assert values.min() <= x <= values.max() and y == values.size, name
            assert inside(ax, x, y), name
        assert inside(ax, float(values.min())) and inside(ax, float(values.max())), name


def test_values_all_equal_are_one_marker_per_metric(tmp_path: Path) -> None:
    spec, rows = campaign(5, '  n: [2.0, 2.0]', "['overshoot < 15']")
    fig = metric_figure(spec, rows)
    assert sorted(panels(fig)) == sorted(SHOWN_METRICS['step'])
    for name, ax in panels(fig).items():
        value = rows[0][name]
        assert all(r[name] == value for r in rows)
        assert markers(ax) == [(value, 5.0)], name          # one marker: the value, 5 times
        assert f'all 5 = {value:.4g}' in texts(fig)
        assert inside(ax, value, 5.0)
    assert overlapping_labels(fig) == []
    assert f'{NOTE}n only 2.' in texts(fig)          # a list of one value, declared to vary
    assert pass_rate_figure(spec, rows) is None       # nothing varies: no pass rate to draw
    save(fig, tmp_path / 'metric_distributions.png')
    write_summary(spec, rows, tmp_path, ['metric_distributions.png'])
    summary = (tmp_path / 'summary.md').read_text()
    assert 'No pass rate figure: no numeric scenario dimension varies.' in summary
    assert f'{NOTE}n only 2.' in summary


def test_values_a_billionth_apart_are_markers_and_offset_axes(tmp_path: Path) -> None:
    spec, rows = campaign(12, '  g: {distribution: normal, mean: 9.8, std: 9.8e-9}\n'
                              '  gamma: {distribution: uniform, low: 0.15, high: 0.15000000015}',
                          "['overshoot < 15']")
    iae = column(rows, 'iae')
    assert 0 < np.ptp(iae) < 1e-8 * iae.max()          # the metrics differ, by a billionth
    fig = metric_figure(spec, rows)
    assert_each_panel_shows_its_values(fig, rows)
    ax = panels(fig)['iae']
    ((x, _),) = markers(ax)
    assert f'all 12 ≈ {x:.4g}\n(spread {np.ptp(iae):.1e})' in texts(fig)
    assert overlapping_labels(fig) == []
    note = f'{NOTE}g ≈ 9.8 (spread '
    assert note in texts(fig)
    save(fig, tmp_path / 'metric_distributions.png')

    rate = pass_rate_figure(spec, rows)
    assert rate is not None
    (ax,) = [a for a in rate.axes if a.get_xlabel()]
    # The two dimensions drawn as their offsets from the number they share, in a power of ten
    # that separates them: every episode inside the axes, at its own place.
    points = markers(ax)
    assert len(points) == 12 and len(set(points)) == 12
    assert all(inside(ax, x, y) for x, y in points)
    labels = {ax.get_xlabel(), ax.get_ylabel()}
    assert any(label.startswith('g − 9.8 ($\\times 10^{') for label in labels)
    assert any(label.startswith('gamma − 0.15 ($\\times 10^{') for label in labels)
    assert overlapping_labels(rate) == []
    assert note in texts(rate)
    save(rate, tmp_path / 'pass_rate.png')
    write_summary(spec, rows, tmp_path, [])
    assert note in (tmp_path / 'summary.md').read_text()


def test_a_requirement_far_from_the_data_is_an_arrow_not_an_empty_panel(
        tmp_path: Path) -> None:
    spec, rows = campaign(12, '  m: {distribution: uniform, low: 0.18, high: 0.2}',
                          "['max_effort < 100', 'overshoot < 14']")
    fig = metric_figure(spec, rows)
    assert_each_panel_shows_its_values(fig, rows)
    effort = panels(fig)['max_effort']
    assert max(effort.get_xlim()) < 10                 # the axis stays on the data ...
    assert 'max_effort < 100 →' in [t.get_text() for t in effort.texts]   # ... and says so
    overshoot = panels(fig)['overshoot']
    assert column(rows, 'overshoot').max() < 14        # a requirement near the data: a line
    assert [line.get_xdata()[0] for line in overshoot.get_lines()] == [14.0]
    assert inside(overshoot, 14.0)
    assert overlapping_labels(fig) == []
    assert NOTE not in texts(fig)                     # 10 % of m: not point-like
    save(fig, tmp_path / 'metric_distributions.png')


def test_many_episodes_all_passing_are_markers_not_one_solid_block(tmp_path: Path) -> None:
    spec, rows = campaign(300, '  m: {distribution: uniform, low: 0.18, high: 0.2}\n'
                               '  phi0: {distribution: uniform, low: 0.8, high: 1.2}',
                          "['overshoot < 50']")
    assert all(r['passed'] for r in rows)
    fig = pass_rate_figure(spec, rows)
    assert fig is not None
    assert fig.findobj(QuadMesh) == []                 # no map of a single colour
    (ax,) = fig.axes
    points = markers(ax)
    assert len(points) == 300
    assert all(inside(ax, x, y) for x, y in points)
    assert 'all 300 episodes passed: no boundary between passing and failing' in ax.get_title()
    assert overlapping_labels(fig) == []
    save(fig, tmp_path / 'pass_rate.png')


def test_crowded_tick_labels_are_thinned_until_none_overlap() -> None:
    # The control for the checks above: labels that do overlap are seen to, and fixed.
    fig, ax = pyplot().subplots(figsize=(2.5, 2.0))
    ax.plot([123456.789, 123456.799], [0.0, 1.0])
    ax.xaxis.set_major_locator(MaxNLocator(nbins=12))
    ax.xaxis.set_major_formatter(FormatStrFormatter('%.4f'))
    assert overlapping_labels(fig) != []
    readable_ticks(fig)
    assert overlapping_labels(fig) == []
    assert len(shown_labels(ax.xaxis)) >= 2
    pyplot().close(fig)
