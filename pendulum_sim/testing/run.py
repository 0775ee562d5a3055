"""``ClosedLoopRun``: the samples of one closed-loop run, its metrics and its figure.

What :func:`~pendulum_sim.testing.loop.closed_loop` returns on either path (in-process or over
DDS), what :mod:`~pendulum_sim.testing.record` writes to MCAP and reads back, and what a
campaign episode keeps. It holds no way of running a controller, so every module that makes or
reads a run imports it from here, below the loop.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from .errors import TestingError
from .metrics import StepMetrics, step_metrics, step_metrics_batch
from .scene import Value, finite_limit
from .swing_up.metrics import BOX, GOAL, SwingUpMetrics, swing_up_metrics, swing_up_metrics_batch

FloatArray = NDArray[np.float64]

BLOCK = 32   # runs measured together by runs_metrics (a block of samples stays in the cache)


@dataclass(frozen=True)
class ClosedLoopRun:
    """The samples of one closed-loop run and what it was run with.

    Attributes
    ----------
    t, position, velocity, effort, command : numpy arrays
        One entry per control period: the state's stamp (s), the measured angle (rad) and rate
        (rad/s), the torque applied in the step before it (N m), and the controller's answer.
    parameters : dict
        The node parameters of the run (scene, overrides and the closed-loop settings).
    failed : str or None
        Why the simulation stopped early (the joint's reason), or None.
    target : float or None
        The reference the run was made with, when the caller gave one.

    ``metrics()`` and ``plot()`` without a target use the last target either was given for this
    run (``run.metrics(0.3)`` then ``run.plot(path)`` draws the run towards 0.3), else
    ``target``.
    """

    t: FloatArray
    position: FloatArray
    velocity: FloatArray
    effort: FloatArray
    command: FloatArray
    parameters: dict[str, Value] = field(default_factory=dict)
    failed: str | None = None
    target: float | None = None
    # The last target metrics() or plot() was given, in a list since the run is frozen; not
    # part of the run's value (two runs of the same samples are equal whatever they were asked).
    _given: list[float] = field(default_factory=list, init=False, repr=False, compare=False)

    @property
    def max_effort(self) -> float:
        """Return the joint's torque limit of the run (N m, inf when unknown)."""
        value = self.parameters.get('max_effort', math.inf)
        return float(value)

    def _target(self, target: float | None) -> float:
        """Return ``target``; without it the last one given, else the run's own."""
        if target is not None:
            return float(target)
        if self._given:
            return self._given[0]
        if self.target is None:
            raise TestingError('no target: give metrics(target) or plot(path, target=...)')
        return float(self.target)

    def metrics(self, target: float | None = None, *,
                initial: float | None = None) -> StepMetrics:
        """Return the step metrics of the angle towards ``target`` (rad).

        The step is measured from ``initial``, by default the first measured angle (the run
        starts at rest at ``phi0``, not at 0 as a textbook step response).
        """
        if self.t.size < 2:
            raise TestingError(f'a run of {self.t.size} sample(s) has no step metrics')
        chosen = self._target(target)
        measured = step_metrics(self.t, self.position, chosen,
                                initial=float(self.position[0]) if initial is None else initial,
                                effort=self.effort, effort_limit=finite_limit(self.parameters))
        self._given[:] = [chosen]   # measured: a target the run can be drawn towards
        return measured

    def swing_up_metrics(self, goal: float = GOAL,
                         box: Sequence[float] = BOX) -> SwingUpMetrics:
        """Return the swing-up metrics of the run towards ``goal`` (rad; π is upright).

        ``box`` is the goal box's angle (rad) and rate (rad/s) half-widths;
        ``saturation_fraction`` counts the samples at the run's torque limit.
        """
        return swing_up_metrics(self.t, self.position, self.velocity, self.effort, goal=goal,
                                box=box, effort_limit=finite_limit(self.parameters))

    def plot(self, path: str | Path, *, target: float | None = None) -> Path:
        """Draw the run's figure (angle, velocity, effort; settling band and time) to ``path``.

        Without ``target``, the run is drawn towards the last target ``metrics()`` or ``plot()``
        was given, else towards the run's own.
        """
        from .figure import closed_loop_figure

        chosen = self._target(target)
        drawn = closed_loop_figure(self, chosen, Path(path))
        self._given[:] = [chosen]
        return drawn

    def with_target(self, target: float) -> ClosedLoopRun:
        """Return the same run with its reference set."""
        return ClosedLoopRun(self.t, self.position, self.velocity, self.effort, self.command,
                             dict(self.parameters), self.failed, float(target))


M = TypeVar('M')


def _measure_runs(runs: Sequence[ClosedLoopRun], alone: Callable[[int], M],
                  together: Callable[[FloatArray, list[int]], list[M | TestingError]]
                  ) -> list[M | TestingError]:
    """Return ``alone(i)`` (or the TestingError it raises) of each run, computed by
    ``together(t, block)`` for blocks of up to :data:`BLOCK` runs that share their sample
    times, as a batch's runs do; any other run alone."""
    out: list[M | TestingError | None] = [None] * len(runs)
    groups: dict[int, list[int]] = {}
    times: dict[int, FloatArray] = {}
    for i, run in enumerate(runs):
        size = run.t.size
        # A subclass may measure otherwise (the pytest plugin's remembers the targets).
        if type(run) is ClosedLoopRun and size >= 2 and (
                size not in times or np.array_equal(run.t, times[size])):
            times.setdefault(size, run.t)
            groups.setdefault(size, []).append(i)
            continue
        try:
            out[i] = alone(i)
        except TestingError as exc:
            out[i] = exc
    for size, members in groups.items():
        for a in range(0, len(members), BLOCK):
            block = members[a:a + BLOCK]
            for i, m in zip(block, together(times[size], block), strict=True):
                out[i] = m
    measured: list[M | TestingError] = []
    for each in out:
        assert each is not None  # every run is measured above, alone or in its block
        measured.append(each)
    return measured


def runs_metrics(runs: Sequence[ClosedLoopRun],
                 targets: Sequence[float]) -> list[StepMetrics | TestingError]:
    """Return ``run.metrics(target)`` of each run, or the TestingError it raises.

    The same numbers, computed together
    (:func:`~pendulum_sim.testing.metrics.step_metrics_batch`) for the runs that share their
    sample times, as a batch's runs do, :data:`BLOCK` at a time; any other run alone.
    """
    def together(t: FloatArray, block: list[int]) -> list[StepMetrics | TestingError]:
        position = np.stack([runs[i].position for i in block])
        return step_metrics_batch(
            t, position, [float(targets[i]) for i in block],
            initial=position[:, 0], effort=np.stack([runs[i].effort for i in block]),
            effort_limit=[finite_limit(runs[i].parameters) for i in block])

    return _measure_runs(runs, lambda i: runs[i].metrics(targets[i]), together)


def runs_swing_up_metrics(runs: Sequence[ClosedLoopRun], goals: Sequence[float],
                          box: Sequence[float] = BOX) -> list[SwingUpMetrics | TestingError]:
    """Return ``run.swing_up_metrics(goal, box)`` of each run, or the TestingError it raises.

    The same numbers, computed together
    (:func:`~pendulum_sim.testing.swing_up.metrics.swing_up_metrics_batch`) for the runs that
    share their sample times, :data:`BLOCK` at a time; any other run alone.
    """
    def together(t: FloatArray, block: list[int]) -> list[SwingUpMetrics | TestingError]:
        return swing_up_metrics_batch(
            t, np.stack([runs[i].position for i in block]),
            np.stack([runs[i].velocity for i in block]),
            np.stack([runs[i].effort for i in block]),
            goal=[float(goals[i]) for i in block], box=box,
            effort_limit=[finite_limit(runs[i].parameters) for i in block])

    return _measure_runs(runs, lambda i: runs[i].swing_up_metrics(goals[i], box), together)
