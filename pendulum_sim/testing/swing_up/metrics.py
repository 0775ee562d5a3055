"""Swing-up metrics of a closed-loop run: into the goal box around upright, and at what cost.

The definitions of the open torque-limited simple-pendulum benchmarks (swing-up time to a
goal box, energy, smoothness; e.g. Wiebe et al., "Open Source Torque-Limited Simple
Pendulum", 2022, and its ``double_pendulum`` successor), on the samples as given (no
interpolation), with ``wrap(x)`` the angle in ``[−π, π)`` equal to ``x`` modulo 2π:

- in the goal box: ``|wrap(φ − goal)| < box[0]`` and ``|φ'| < box[1]`` (strict), so upright
  (``goal = π``) is ``φ = π + 2πk`` for any whole ``k``;
- ``success``: some sample is in the box;
- ``swing_up_time``: ``t[k] − t[0]`` for the first sample ``k`` in the box (``inf`` if none);
- ``stays``: the run is in the box from some sample to its last;
- ``settle_time``: ``t[k] − t[0]`` for the first sample ``k`` of that last stretch (``nan``
  if the run does not stay);
- ``energy``: ``∫|τ φ'| dt`` (J), the actuator's work counted without sign;
- ``effort_energy``: ``∫τ² dt`` (N² m² s);
- ``smoothness``: the population standard deviation (``ddof = 0``) of the consecutive torque
  differences ``τ[k+1] − τ[k]`` (N m);
- ``max_effort``: ``max|τ|``; ``saturation_fraction``: the fraction of the samples at which
  ``|τ|`` is at the torque limit ``effort_limit`` (0 when it is infinite);
- ``swings``: the velocity reversals before the first entry: the samples ``k``, ``0 < k <
  k_in`` (``k_in`` the first sample in the box, or the run's length), whose velocity has the
  sign opposite to the last nonzero velocity before them.

The integrals use the trapezoidal rule on the samples (as
:mod:`pendulum_sim.testing.metrics` does). :func:`swing_up_metrics_batch` measures many runs
on one sample grid at once, each row to the bit as :func:`swing_up_metrics` measures it
alone: both run the one implementation, :func:`_columns`, on arrays of runs.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pendulum_sim.core.model import wrap_pi

from ..errors import TestingError
from ..metrics import _first, _trapezoid, _vector

FloatArray = NDArray[np.float64]

GOAL = math.pi
BOX = (0.1, 0.1)


@dataclass(frozen=True)
class SwingUpMetrics:
    """The verdict on a swing-up run (the module's definitions).

    Times in s from the run's first sample, ``energy`` in J, ``effort_energy`` in
    N² m² s, ``smoothness`` and ``max_effort`` in N m, ``saturation_fraction`` in [0, 1],
    ``swings`` a count.
    """

    success: bool
    swing_up_time: float
    stays: bool
    settle_time: float
    energy: float
    effort_energy: float
    smoothness: float
    max_effort: float
    saturation_fraction: float
    swings: int

    def as_dict(self) -> dict[str, float | bool | int]:
        """Return the metrics as ``{field name: value}`` in field order."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def text(self) -> str:
        """Return the metrics one per line, ``name = value``, for logs and reports."""
        return '\n'.join(f'{k} = {v:.6g}' if isinstance(v, float) else f'{k} = {v}'
                         for k, v in self.as_dict().items())


SWING_UP_NAMES: tuple[str, ...] = tuple(f.name for f in fields(SwingUpMetrics))


def check_box(goal: float, box: Sequence[float]) -> tuple[float, float, float]:
    """Return ``(goal, angle half-width, rate half-width)``, or raise why the box is unusable.

    Raises
    ------
    TestingError
        If ``goal`` is not finite or ``box`` is not two finite numbers > 0.
    """
    if isinstance(goal, bool) or not isinstance(goal, (int, float)) or not math.isfinite(goal):
        raise TestingError(f'goal must be a finite angle (rad), got {goal!r}')
    if isinstance(box, (str, bytes)) or len(box) != 2:
        raise TestingError(f'box must be (angle rad, rate rad/s), two numbers > 0, got {box!r}')
    for name, value in zip(('box[0] (rad)', 'box[1] (rad/s)'), box, strict=True):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
                math.isfinite(value) and value > 0.0):
            raise TestingError(f'{name} must be a finite number > 0, got {value!r}')
    return float(goal), float(box[0]), float(box[1])


def _columns(t: FloatArray, position: FloatArray, velocity: FloatArray, effort: FloatArray,
             goal: FloatArray, box: tuple[float, float],
             limit: FloatArray) -> dict[str, NDArray[np.generic]]:
    """Return every metric of each row (checked samples, shape (N, T)), one array per name.

    The one implementation: :func:`swing_up_metrics` runs it on one row,
    :func:`swing_up_metrics_batch` on many. Every operation is elementwise, or a reduction
    along a row that does not depend on the others, so a row gets the same numbers alone or
    among others.
    """
    n, size = position.shape
    rows = np.arange(n)
    inside = np.abs(wrap_pi(position - goal[:, np.newaxis])) < box[0]
    inside &= np.abs(velocity) < box[1]
    first = _first(inside)
    success = first >= 0
    swing_up_time = np.where(success, t[np.maximum(first, 0)] - t[0], math.inf)
    stays = inside[:, -1].copy()
    # The last stretch starts after the last sample outside (or at 0 when none is).
    outside = ~inside
    last_out = np.where(outside.any(axis=1), size - 1 - outside[:, ::-1].argmax(axis=1), -1)
    start = np.minimum(last_out + 1, size - 1)
    settle_time = np.where(stays, t[start] - t[0], math.nan)
    power = np.abs(effort * velocity)
    energy = _trapezoid(power, t)
    effort_energy = _trapezoid(effort * effort, t)
    steps = np.diff(effort, axis=1)
    mean = steps.sum(axis=1) / steps.shape[1]
    spread = steps - mean[:, np.newaxis]
    smoothness = np.sqrt((spread * spread).sum(axis=1) / steps.shape[1])
    size_tau = np.abs(effort)
    max_effort = size_tau.max(axis=1)
    saturation_fraction = np.where(np.isfinite(limit),
                                   np.mean(size_tau >= limit[:, np.newaxis], axis=1), 0.0)
    # Each sample's sign carried over zero velocities from the last nonzero one.
    sign = np.sign(velocity)
    last_nonzero = np.where(sign != 0.0, np.arange(size), 0)
    np.maximum.accumulate(last_nonzero, axis=1, out=last_nonzero)
    carried = sign[rows[:, np.newaxis], last_nonzero]
    reversal = sign[:, 1:] * carried[:, :-1] < 0.0
    before = np.arange(1, size) < np.where(success, first, size)[:, np.newaxis]
    swings = (reversal & before).sum(axis=1)
    return {'success': success, 'swing_up_time': swing_up_time, 'stays': stays,
            'settle_time': settle_time, 'energy': energy, 'effort_energy': effort_energy,
            'smoothness': smoothness, 'max_effort': max_effort,
            'saturation_fraction': saturation_fraction, 'swings': swings}


def _measured(columns: dict[str, NDArray[np.generic]]) -> list[SwingUpMetrics]:
    """Return the SwingUpMetrics of each row of ``columns``; a NaN is ``math.nan`` itself, so
    that such metrics compare equal."""
    cells = []
    for name in SWING_UP_NAMES:
        values = columns[name].tolist()
        if columns[name].dtype.kind == 'f' and np.isnan(columns[name]).any():
            values = [math.nan if math.isnan(v) else v for v in values]
        cells.append(values)
    return [SwingUpMetrics(*row) for row in zip(*cells, strict=True)]


def _checked(t: ArrayLike, position: ArrayLike, velocity: ArrayLike,
             effort: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Return the samples as arrays, or raise why they cannot be measured."""
    tt = _vector('t', t)
    arrays = [tt]
    for name, values in (('position', position), ('velocity', velocity), ('effort', effort)):
        arr = _vector(name, values)
        if arr.size != tt.size:
            raise TestingError(f'{name} must have the length of t ({tt.size}), got {arr.size}')
        arrays.append(arr)
    if not np.all(np.diff(tt) > 0):
        raise TestingError('t must be strictly increasing')
    return arrays[0], arrays[1], arrays[2], arrays[3]


def swing_up_metrics(t: ArrayLike, position: ArrayLike, velocity: ArrayLike,
                     effort: ArrayLike, *, goal: float = GOAL,
                     box: Sequence[float] = BOX,
                     effort_limit: float = math.inf) -> SwingUpMetrics:
    """Return the swing-up metrics of the samples (the module's definitions).

    Parameters
    ----------
    t, position, velocity, effort : array_like
        Sample times (s, increasing), angle (rad), rate (rad/s) and torque (N m), one length
        of at least 2 samples, finite.
    goal : float
        The angle to swing up to (rad; π is upright, φ = 0 hangs).
    box : (float, float)
        The goal box's half-widths: angle (rad) and rate (rad/s), both > 0.
    effort_limit : float
        The joint's torque limit (N m): ``saturation_fraction`` counts samples at it.

    Raises
    ------
    TestingError
        If the arrays are not finite 1-D arrays of one length with increasing times, or the
        goal or the box is unusable.
    """
    goal, width, rate = check_box(goal, box)
    tt, pos, vel, tau = _checked(t, position, velocity, effort)
    columns = _columns(tt, pos[np.newaxis, :], vel[np.newaxis, :], tau[np.newaxis, :],
                       np.array([goal]), (width, rate), np.array([float(effort_limit)]))
    return _measured(columns)[0]


def swing_up_metrics_batch(t: ArrayLike, position: ArrayLike, velocity: ArrayLike,
                           effort: ArrayLike, *, goal: ArrayLike = GOAL,
                           box: Sequence[float] = BOX, effort_limit: ArrayLike = math.inf
                           ) -> list[SwingUpMetrics | TestingError]:
    """Return :func:`swing_up_metrics` of each row, or the TestingError it raises.

    The same numbers as one call of :func:`swing_up_metrics` per row, computed for all rows
    at once (a campaign's batch of episodes).

    Parameters
    ----------
    t : array_like
        The sample times (s) every row shares, shape (T,).
    position, velocity, effort : array_like
        One run per row, shape (N, T).
    goal : array_like
        The goal, one for all or one per row (rad).
    box : (float, float)
        The goal box, one for all.
    effort_limit : array_like
        The torque limit, one for all or one per row (N m).

    Raises
    ------
    TestingError
        If the box is unusable (every row would refuse it) or the arrays are not 2-D.
    """
    rows = _Rows(t, position, velocity, effort, goal, box, effort_limit)
    out: list[SwingUpMetrics | TestingError | None] = [None] * rows.n
    if rows.columns is not None:
        for i, m in zip(rows.good.tolist(), _measured(rows.columns), strict=True):
            out[i] = m
    for i in np.flatnonzero(~rows.ok).tolist():   # swing_up_metrics says why it refuses the row
        try:
            out[i] = rows.alone(i)
        except TestingError as exc:
            out[i] = exc
    return [m for m in out if m is not None]


def swing_up_metrics_columns(t: ArrayLike, position: ArrayLike, velocity: ArrayLike,
                             effort: ArrayLike, *, goal: ArrayLike = GOAL,
                             box: Sequence[float] = BOX, effort_limit: ArrayLike = math.inf
                             ) -> tuple[dict[str, NDArray[np.generic]], NDArray[np.bool_]]:
    """Return each metric of each row as one array per field, and which rows were measured.

    The numbers :func:`swing_up_metrics_batch` gives (the same arrays, before they become
    :class:`SwingUpMetrics`), for callers that keep them as arrays (the Gymnasium vector
    environment's ``info``): per field an array of N (``success`` and ``stays`` bool,
    ``swings`` int, the others float); a row that :func:`swing_up_metrics` would refuse is
    False in the mask and 0 in every array. Arguments as :func:`swing_up_metrics_batch`.
    """
    rows = _Rows(t, position, velocity, effort, goal, box, effort_limit)
    mask = rows.ok.copy()
    if rows.columns is None:
        full = {name: np.zeros(rows.n, dtype=_DTYPES[name]) for name in SWING_UP_NAMES}
        return full, mask
    if rows.good.size == rows.n:
        return rows.columns, mask
    out = {}
    for name, values in rows.columns.items():
        out[name] = np.zeros(rows.n, dtype=values.dtype)
        out[name][rows.good] = values
    return out, mask


_DTYPES = {name: (bool if name in ('success', 'stays') else np.int64 if name == 'swings'
                  else np.float64) for name in SWING_UP_NAMES}


class _Rows:
    """The rows of a batch, checked: which can be measured, and their columns."""

    def __init__(self, t: ArrayLike, position: ArrayLike, velocity: ArrayLike,
                 effort: ArrayLike, goal: ArrayLike, box: Sequence[float],
                 effort_limit: ArrayLike) -> None:
        _, width, rate = check_box(0.0, box)
        self.box = (width, rate)
        self.t = tt = np.asarray(t, dtype=np.float64)
        pos, vel, tau = (np.asarray(a, dtype=np.float64) for a in (position, velocity, effort))
        self.pos, self.vel, self.tau = pos, vel, tau
        if pos.ndim != 2:
            raise TestingError(f'position must be a 2-D array of one run per row, got shape '
                               f'{pos.shape}')
        self.n = n = pos.shape[0]
        self.goals = np.broadcast_to(np.asarray(goal, dtype=np.float64), (n,))
        self.limit = np.broadcast_to(np.asarray(effort_limit, dtype=np.float64), (n,))
        ok = np.zeros(n, dtype=bool)
        if (tt.ndim == 1 and tt.size >= 2 and pos.shape[1] == tt.size and
                vel.shape == pos.shape and tau.shape == pos.shape and
                bool(np.all(np.isfinite(tt))) and bool(np.all(np.diff(tt) > 0))):
            ok = (np.isfinite(pos).all(axis=1) & np.isfinite(vel).all(axis=1)
                  & np.isfinite(tau).all(axis=1) & np.isfinite(self.goals))
        self.ok = ok
        self.good = good = np.flatnonzero(ok)
        self.columns: dict[str, NDArray[np.generic]] | None = None
        if good.size:
            take = slice(None) if good.size == n else good
            self.columns = _columns(tt, pos[take], vel[take], tau[take], self.goals[take],
                                    self.box, self.limit[take])

    def alone(self, i: int) -> SwingUpMetrics:
        """Return :func:`swing_up_metrics` of row ``i`` (its TestingError says why not)."""
        pos, vel, tau = self.pos, self.vel, self.tau
        return swing_up_metrics(self.t, pos[i],
                                vel[i] if vel.ndim == 2 and i < vel.shape[0] else vel,
                                tau[i] if tau.ndim == 2 and i < tau.shape[0] else tau,
                                goal=float(self.goals[i]), box=self.box,
                                effort_limit=float(self.limit[i]))
