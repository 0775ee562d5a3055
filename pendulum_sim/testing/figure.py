"""The figure of a closed-loop run: the one drawing behind ``plot()`` and ``pendulum_report``.

Three panels over time: the angle against the target with the 2 % settling band and the
settling time marked; the angular velocity; the effort with the joint's saturation band
(±max_effort) shaded. matplotlib is imported here only, on the Agg backend.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from .metrics import SETTLING_THRESHOLD, StepMetrics


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
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
