"""Step-response metrics of a closed-loop run: python-control's ``step_info`` and more.

The step metrics are python-control's ``step_info`` (``control.timeresp.step_info``, itself
MATLAB's ``stepinfo``) on sampled data, computed on the samples as given (no interpolation):

- ``rise_time``: ``t[i90] − t[i10]``, where ``i10`` (``i90``) is the first sample at which the
  response has reached 10 % (90 %) of the step;
- ``settling_time``: the time of the sample after the last one outside the band of 2 % of the
  step around the target (NaN when the last sample is outside);
- ``settling_min`` / ``settling_max``: the extremes of the response from ``i90`` on, widened to
  include the target;
- ``overshoot`` / ``undershoot``: the largest excursion beyond the target / before the start
  (opposite to the step), in % of the step;
- ``peak`` / ``peak_time``: the largest absolute value of the response (of its change from the
  initial value when one is given) and its time;
- ``steady_state_value``: the target (python-control's ``yfinal``).

``initial=None`` (or 0.0) is ``step_info(sysdata=y, T=t, yfinal=target)``. ``initial=y0``
measures the step from ``y0`` (MATLAB's ``stepinfo(y, t, yfinal, yinit)``): the definitions above
applied to ``y − y0`` with final value ``target − y0``, the levels (``settling_min``,
``settling_max``, ``steady_state_value``) given back in the units of ``y``.

The tracking and effort metrics use the trapezoidal rule on the samples:
``steady_state_error = y[-1] − target``, ``iae = ∫|e| dt``, ``ise = ∫e² dt``,
``itae = ∫(t − t0)|e| dt`` with ``e = y − target``, ``max_effort = max|τ|``,
``effort_energy = ∫τ² dt`` and ``saturation_fraction``, the fraction of the samples at which
``|τ|`` is at the joint's torque limit.

:func:`step_metrics_batch` measures many runs on one sample grid at once (a campaign's batch),
each row to the bit as :func:`step_metrics` measures it alone: both run the one
implementation, :func:`_metrics`, on arrays of runs (one row for :func:`step_metrics`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pendulum_sim.core.analysis import outside_settling_band

from .errors import TestingError

FloatArray = NDArray[np.float64]

RISE_LIMITS = (0.1, 0.9)


@dataclass(frozen=True)
class StepMetrics:
    """The verdict on a step response: python-control's ``step_info`` plus error and effort.

    Times in s, levels in the response's unit (rad), ``overshoot`` and ``undershoot`` in % of
    the step, ``iae`` in rad s, ``ise`` in rad² s, ``itae`` in rad s², efforts in N m,
    ``effort_energy`` in N² m² s, ``saturation_fraction`` in [0, 1]. A metric that the run
    does not define (no effort recorded, never settled) is NaN.
    """

    rise_time: float
    settling_time: float
    settling_min: float
    settling_max: float
    overshoot: float
    undershoot: float
    peak: float
    peak_time: float
    steady_state_value: float
    steady_state_error: float
    iae: float
    ise: float
    itae: float
    max_effort: float
    effort_energy: float
    saturation_fraction: float

    def as_dict(self) -> dict[str, float]:
        """Return the metrics as ``{field name: value}`` in field order."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def text(self) -> str:
        """Return the metrics one per line, ``name = value``, for logs and reports."""
        return '\n'.join(f'{k} = {v:.6g}' for k, v in self.as_dict().items())


METRIC_NAMES: tuple[str, ...] = tuple(f.name for f in fields(StepMetrics))


def _vector(name: str, values: ArrayLike) -> FloatArray:
    arr = np.asarray(values, dtype=np.float64)
    if arr.ndim != 1 or arr.size < 2:
        raise TestingError(f'{name} must be a 1-D array of at least 2 samples, got shape '
                           f'{arr.shape}')
    if not np.all(np.isfinite(arr)):
        bad = int(np.flatnonzero(~np.isfinite(arr))[0])
        raise TestingError(f'{name} must be finite, got {arr[bad]} at index {bad}')
    return arr


def step_info(t: FloatArray, y: FloatArray, yfinal: float) -> dict[str, float]:
    """Return python-control's ``step_info`` of a SISO time series (same names, lower case).

    The step is from 0 to ``yfinal`` (which must be finite and not 0).
    """
    info = _step_info(t, y[np.newaxis, :], np.array([float(yfinal)]))
    return {name: float(column[0]) for name, column in info.items()}


def _first(hit: NDArray[np.bool_]) -> NDArray[np.intp]:
    """Return each row's first True column, -1 where a row has none."""
    return np.where(hit.any(axis=1), hit.argmax(axis=1), -1)


def _trapezoid(y: FloatArray, t: FloatArray) -> FloatArray:
    """Return ``numpy.trapezoid(y, t, axis=-1)``: the same operations, in place (bit for bit)."""
    s = y[:, 1:] + y[:, :-1]
    s *= np.diff(t)
    s /= 2.0
    total: FloatArray = s.sum(axis=-1)
    return total


def _step_info(t: FloatArray, y: FloatArray, yfinal: FloatArray) -> dict[str, FloatArray]:
    """Return :func:`step_info` of each row of ``y`` (shape (N, len(t))) towards ``yfinal[i]``.

    The one implementation of the step-response fields: :func:`step_metrics` runs it on one
    row, :func:`step_metrics_batch` on many. Every operation is elementwise, or a reduction
    along a row that does not depend on the others, so a row gets the same numbers alone or
    among others (``test/testing/test_testing_metrics.py`` holds them to it).
    """
    lo, hi = RISE_LIMITS
    n, size = y.shape
    rows = np.arange(n)
    sgn = np.copysign(1.0, yfinal)
    signed = sgn[:, np.newaxis] * y
    # The first sample with sgn (y - p yfinal) >= 0, compared as sgn y >= sgn p yfinal: a
    # rounded difference has the sign of the exact one, and is 0 only for equal numbers.
    i_lo = _first(signed >= (sgn * (lo * yfinal))[:, np.newaxis])
    i_hi = _first(signed >= (sgn * (hi * yfinal))[:, np.newaxis])
    rise_time = np.where((i_lo >= 0) & (i_hi >= 0), t[i_hi] - t[i_lo], math.nan)
    outside = outside_settling_band(y, yfinal[:, np.newaxis])
    settled = np.where(outside.any(axis=1), size - outside[:, ::-1].argmax(axis=1), 0)
    settling_time = np.where(settled < size, t[np.minimum(settled, size - 1)], math.nan)
    # Each row's extremes from i_hi on: segments [row start + i_hi, next row start) of the
    # flat samples (min and max are exact in any order).
    reached = i_hi >= 0
    starts = rows * size + np.where(reached, i_hi, 0)
    cuts = np.empty(2 * n - 1, dtype=np.intp)
    cuts[0::2], cuts[1::2] = starts, rows[1:] * size
    flat = y.reshape(-1)
    low = np.minimum.reduceat(flat, cuts)[0::2]
    high = np.maximum.reduceat(flat, cuts)[0::2]
    settling_min = np.where(reached, np.minimum(low, yfinal), math.nan)
    settling_max = np.where(reached, np.maximum(high, yfinal), math.nan)
    dy_os = np.abs(signed.max(axis=1)) - np.abs(yfinal)
    overshoot = np.where(dy_os > 0, np.abs(100.0 * dy_os / yfinal), 0.0)
    y_us = y[rows, signed.argmin(axis=1)]
    undershoot = np.where(sgn * y_us < 0, -100.0 * y_us / yfinal, 0.0)
    k = np.abs(y).argmax(axis=1)
    return {'rise_time': rise_time, 'settling_time': settling_time,
            'settling_min': settling_min, 'settling_max': settling_max,
            'overshoot': overshoot, 'undershoot': undershoot, 'peak': np.abs(y[rows, k]),
            'peak_time': t[k], 'steady_state_value': yfinal.copy()}


def _metrics(t: FloatArray, y: FloatArray, target: FloatArray, y0: FloatArray,
             effort: FloatArray | None, effort_limit: FloatArray) -> dict[str, FloatArray]:
    """Return every metric of each row of ``y`` (checked samples), one array per name.

    The one implementation of the metrics (see :func:`_step_info`).
    """
    info = _step_info(t, y - y0[:, np.newaxis], target - y0)
    for name in ('settling_min', 'settling_max', 'steady_state_value'):
        info[name] += y0
    e = y - target[:, np.newaxis]
    info['steady_state_error'] = e[:, -1].copy()
    info['ise'] = _trapezoid(e * e, t)
    np.abs(e, out=e)
    info['iae'] = _trapezoid(e, t)
    e *= t - t[0]
    info['itae'] = _trapezoid(e, t)
    if effort is None:
        nan = np.full(y.shape[0], math.nan)
        info['max_effort'], info['effort_energy'], info['saturation_fraction'] = nan, nan, nan
    else:
        info['effort_energy'] = _trapezoid(effort * effort, t)
        size = np.abs(effort)
        info['max_effort'] = size.max(axis=1)
        info['saturation_fraction'] = np.where(
            np.isfinite(effort_limit), np.mean(size >= effort_limit[:, np.newaxis], axis=1),
            0.0)
    return {name: info[name] for name in METRIC_NAMES}


def _measured(columns: dict[str, FloatArray]) -> list[StepMetrics]:
    """Return the StepMetrics of each row of ``columns`` (:func:`_metrics`); a metric the run
    does not define is ``math.nan`` itself, so that such metrics compare equal."""
    cells = []
    for column in columns.values():
        values = column.tolist()
        if np.isnan(column).any():
            values = [math.nan if math.isnan(v) else v for v in values]
        cells.append(values)
    return [StepMetrics(*row) for row in zip(*cells, strict=True)]


def _checked(t: ArrayLike, y: ArrayLike, target: float, initial: float | None,
             effort: ArrayLike | None) -> tuple[FloatArray, FloatArray, float, FloatArray | None]:
    """Return the samples as arrays and the initial value, or raise why they cannot be measured."""
    tt = _vector('t', t)
    yy = _vector('y', y)
    if yy.size != tt.size:
        raise TestingError(f't and y must have the same length, got {tt.size} and {yy.size}')
    if not np.all(np.diff(tt) > 0):
        raise TestingError('t must be strictly increasing')
    if not math.isfinite(target):
        raise TestingError(f'target must be finite, got {target}')
    y0 = 0.0 if initial is None else float(initial)
    if not math.isfinite(y0):
        raise TestingError(f'initial must be finite, got {initial}')
    if target == y0:
        raise TestingError(f'target {target} equals the initial value {y0}: a step of zero '
                           'size has no rise or settling time')
    if effort is None:
        return tt, yy, y0, None
    tau = _vector('effort', effort)
    if tau.size != tt.size:
        raise TestingError(f'effort must have the length of t ({tt.size}), got {tau.size}')
    return tt, yy, y0, tau


def step_metrics(t: ArrayLike, y: ArrayLike, target: float, *, initial: float | None = None,
                 effort: ArrayLike | None = None,
                 effort_limit: float = math.inf) -> StepMetrics:
    """Return the step-response, tracking and effort metrics of the samples ``(t, y)``.

    Parameters
    ----------
    t, y : array_like
        Sample times (s, increasing) and the response (rad), same length, finite.
    target : float
        The value the response should reach (python-control's ``yfinal``).
    initial : float, optional
        The value the step starts from; None or 0.0 is python-control's ``step_info``.
    effort : array_like, optional
        The torque applied at each sample (N m); without it the effort metrics are NaN.
    effort_limit : float
        The joint's torque limit (N m): ``saturation_fraction`` counts samples at it.

    Raises
    ------
    TestingError
        If the arrays are not finite 1-D arrays of one length with increasing times, or the
        step has zero size (``target`` equal to the initial value).
    """
    tt, yy, y0, tau = _checked(t, y, target, initial, effort)
    columns = _metrics(tt, yy[np.newaxis, :], np.array([float(target)]), np.array([y0]),
                       None if tau is None else tau[np.newaxis, :],
                       np.array([float(effort_limit)]))
    return _measured(columns)[0]


def step_metrics_batch(t: ArrayLike, y: ArrayLike, target: ArrayLike, *,
                       initial: ArrayLike | None = None, effort: ArrayLike | None = None,
                       effort_limit: ArrayLike = math.inf) -> list[StepMetrics | TestingError]:
    """Return :func:`step_metrics` of each row of ``y``, or the TestingError it raises.

    The same numbers as one call of :func:`step_metrics` per row, computed for all rows at
    once (a campaign's batch of episodes).

    Parameters
    ----------
    t : array_like
        The sample times (s) every row shares, shape (T,).
    y : array_like
        The responses, one row per run, shape (N, T).
    target : array_like
        Each row's target, shape (N,).
    initial : array_like, optional
        Each row's initial value, shape (N,); None measures every step from 0.
    effort : array_like, optional
        The torques, shape (N, T); without them the effort metrics are NaN.
    effort_limit : array_like
        The torque limit, one for all or one per row (N m).

    Returns
    -------
    list of StepMetrics or TestingError
        One per row: a row :func:`step_metrics` refuses gets the error it raises.
    """
    tt = np.asarray(t, dtype=np.float64)
    yy = np.asarray(y, dtype=np.float64)
    if yy.ndim != 2:
        raise TestingError(f'y must be a 2-D array of one run per row, got shape {yy.shape}')
    n = yy.shape[0]
    goal = np.broadcast_to(np.asarray(target, dtype=np.float64), (n,))
    y0 = (np.zeros(n) if initial is None else
          np.broadcast_to(np.asarray(initial, dtype=np.float64), (n,)))
    tau = None if effort is None else np.asarray(effort, dtype=np.float64)
    limit = np.broadcast_to(np.asarray(effort_limit, dtype=np.float64), (n,))
    # Rows that meet step_metrics' conditions are measured together; any other row is
    # handed to step_metrics, which says why it refuses it (its checks are the ones).
    ok = np.zeros(n, dtype=bool)
    if (tt.ndim == 1 and tt.size >= 2 and yy.shape[1] == tt.size and
            bool(np.all(np.isfinite(tt))) and bool(np.all(np.diff(tt) > 0)) and
            (tau is None or tau.shape == yy.shape)):
        ok = (np.isfinite(yy).all(axis=1) & np.isfinite(goal) & np.isfinite(y0)
              & (goal != y0))
        if tau is not None:
            ok &= np.isfinite(tau).all(axis=1)
    out: list[StepMetrics | TestingError | None] = [None] * n
    good = np.flatnonzero(ok)
    if good.size:
        take = slice(None) if good.size == n else good   # all rows: no copies
        columns = _metrics(tt, yy[take], goal[take], y0[take],
                           None if tau is None else tau[take], limit[take])
        for i, m in zip(good.tolist(), _measured(columns), strict=True):
            out[i] = m
    for i in np.flatnonzero(~ok).tolist():
        try:
            out[i] = step_metrics(tt, yy[i], float(goal[i]),
                                  initial=None if initial is None else float(y0[i]),
                                  effort=None if tau is None else tau[i],
                                  effort_limit=float(limit[i]))
        except TestingError as exc:
            out[i] = exc
    return [m for m in out if m is not None]
