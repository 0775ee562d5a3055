"""The figure of a closed-loop run, and the rule that keeps every test-bench figure readable.

:func:`closed_loop_figure` is the one drawing behind ``plot()`` and ``pendulum_report``: three
panels over time, the angle against the target with the 2 % settling band and the settling
time marked; the angular velocity; the effort with the joint's saturation band (±max_effort)
shaded. :func:`readable_ticks` thins out (and as a last resort turns) the tick labels of a
drawn figure until no two of an axis overlap, judged on their extents as drawn; the campaign's
figures use it too. matplotlib is imported on first use only, on the Agg backend.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Literal, Protocol

import numpy as np
from numpy.typing import NDArray

from pendulum_sim.core.analysis import SETTLING_THRESHOLD

from .metrics import StepMetrics

if TYPE_CHECKING:
    from matplotlib.axis import Axis
    from matplotlib.figure import Figure
    from matplotlib.text import Text

TICK_BINS = (5, 4, 3, 2)   # the most tick intervals tried per axis, until the labels fit
TICK_ROTATION = 35.0       # degrees: the labels of an axis still crowded at two intervals


class Drawn(Protocol):
    """What the figure reads of a run (:class:`~pendulum_sim.testing.run.ClosedLoopRun`)."""

    @property
    def t(self) -> NDArray[np.float64]: ...

    @property
    def position(self) -> NDArray[np.float64]: ...

    @property
    def velocity(self) -> NDArray[np.float64]: ...

    @property
    def effort(self) -> NDArray[np.float64]: ...

    @property
    def max_effort(self) -> float: ...

    def metrics(self, target: float | None = None, *,
                initial: float | None = None) -> StepMetrics: ...


def drawn_tick_labels(axis: Axis) -> list[Text]:
    """Return the tick labels ``axis`` shows (after a draw): non-empty, of ticks in its view."""
    low, high = sorted(axis.get_view_interval())
    span = high - low
    out = []
    for tick in axis.get_major_ticks():
        label = tick.label1
        loc = tick.get_loc()
        if (label.get_visible() and label.get_text() and loc is not None
                and low - 1e-9 * span <= loc <= high + 1e-9 * span):
            out.append(label)
    return out


def labels_overlap(axis: Axis) -> bool:
    """Return True when two of the drawn tick labels of ``axis`` overlap (after a draw)."""
    boxes = [label.get_window_extent() for label in drawn_tick_labels(axis)]
    return any(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1:])


def readable_ticks(fig: Figure) -> None:
    """Thin out the ticks of each linear axis of ``fig`` until no two labels overlap.

    The figure is drawn, and each axis whose labels overlap is given at most 5, 4, 3, then 2
    tick intervals (matplotlib's ``MaxNLocator``, keeping its other settings), drawn again
    after each; labels still crowded at two are turned by :data:`TICK_ROTATION` degrees. Call
    it after the layout.
    """
    from matplotlib.ticker import MaxNLocator

    fig.canvas.draw()
    for ax in fig.axes:
        pairs: tuple[tuple[Axis, Literal['x', 'y']], ...] = (
            (ax.xaxis, 'x'), (ax.yaxis, 'y'))
        for axis, name in pairs:
            if axis.get_scale() != 'linear' or not labels_overlap(axis):
                continue
            for bins in TICK_BINS:
                locator = axis.get_major_locator()
                if isinstance(locator, MaxNLocator):
                    locator.set_params(nbins=bins)
                else:
                    axis.set_major_locator(MaxNLocator(nbins=bins))
                fig.canvas.draw()
                if not labels_overlap(axis):
                    break
            else:
                ax.tick_params(axis=name, labelrotation=TICK_ROTATION)
                if name == 'x':
                    for label in axis.get_ticklabels():
                        label.set_horizontalalignment('right')
                fig.canvas.draw()


def closed_loop_figure(run: Drawn, target: float, path: Path,
                       metrics: StepMetrics | None = None, title: str | None = None) -> Path:
    """Draw ``run`` towards ``target`` as a PNG at ``path``; return the path."""
    from pendulum_sim.pyplot_agg import pyplot

    plt = pyplot()
    m = run.metrics(target) if metrics is None else metrics
    step = abs(target - float(run.position[0]))
    band = SETTLING_THRESHOLD * step
    fig, (ax_a, ax_v, ax_e) = plt.subplots(3, 1, figsize=(8.0, 7.5), sharex=True)
    ax_a.plot(run.t, run.position, color='C0', lw=1.4, label='angle φ')
    ax_a.axhline(target, color='k', lw=1.0, ls='--', label=f'target {target:g} rad')
    ax_a.axhspan(target - band, target + band, color='C2', alpha=0.2,
                 label=f'±{100 * SETTLING_THRESHOLD:g} % settling band')
    if math.isfinite(m.settling_time):
        ax_a.axvline(m.settling_time, color='C2', lw=1.2,
                     label=f'settling time {m.settling_time:.3g} s')
    if m.overshoot > 0:
        ax_a.plot([m.peak_time], [run.position[run.t.searchsorted(m.peak_time)]], 'v',
                  color='C3', label=f'overshoot {m.overshoot:.3g} %')
    ax_a.set_ylabel('angle (rad)')
    ax_a.legend(loc='best', fontsize=8)
    ax_v.plot(run.t, run.velocity, color='C1', lw=1.2)
    ax_v.axhline(0.0, color='k', lw=0.6)
    ax_v.set_ylabel('velocity (rad/s)')
    limit = run.max_effort
    ax_e.step(run.t, run.effort, where='pre', color='C4', lw=1.2, label='effort τ')
    if math.isfinite(limit):
        top = max(limit * 1.15, float(abs(run.effort).max()) * 1.05)
        ax_e.axhspan(limit, top, color='C3', alpha=0.15, label=f'saturation |τ| ≥ {limit:g}')
        ax_e.axhspan(-top, -limit, color='C3', alpha=0.15)
        ax_e.set_ylim(-top, top)
    ax_e.set_ylabel('effort (N m)')
    ax_e.set_xlabel('time (s)')
    ax_e.legend(loc='best', fontsize=8)
    for ax in (ax_a, ax_v, ax_e):
        ax.grid(True, alpha=0.3)
    ax_a.set_title(title or f'closed loop: rise {m.rise_time:.3g} s, settling '
                   f'{m.settling_time:.3g} s, overshoot {m.overshoot:.3g} %, '
                   f'max |τ| {m.max_effort:.3g} N m', fontsize=10)
    fig.tight_layout()
    readable_ticks(fig)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
