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
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import TestingError

FloatArray = NDArray[np.float64]

SETTLING_THRESHOLD = 0.02
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


def _trapezoid(y: FloatArray, t: FloatArray) -> float:
    return float(np.trapezoid(y, t))


def step_info(t: FloatArray, y: FloatArray, yfinal: float) -> dict[str, float]:
    """Return python-control's ``step_info`` of a SISO time series (same names, lower case).

    The step is from 0 to ``yfinal`` (which must be finite and not 0).
    """
    lo, hi = RISE_LIMITS
    sgn = math.copysign(1.0, yfinal)
    i_lo = int(np.flatnonzero(sgn * (y - lo * yfinal) >= 0)[0]) if np.any(
        sgn * (y - lo * yfinal) >= 0) else -1
    i_hi = int(np.flatnonzero(sgn * (y - hi * yfinal) >= 0)[0]) if np.any(
        sgn * (y - hi * yfinal) >= 0) else -1
    rise_time = float(t[i_hi] - t[i_lo]) if i_lo >= 0 and i_hi >= 0 else math.nan
    outside = np.flatnonzero(np.abs(y / yfinal - 1.0) >= SETTLING_THRESHOLD)
    settled = int(outside[-1]) + 1 if outside.size else 0
    settling_time = float(t[settled]) if settled < t.size else math.nan
    if i_hi >= 0:
        settling_min = min(float(y[i_hi:].min()), yfinal)
        settling_max = max(float(y[i_hi:].max()), yfinal)
    else:
        settling_min = settling_max = math.nan
    dy_os = abs(float((sgn * y).max())) - abs(yfinal)
    overshoot = abs(100.0 * dy_os / yfinal) if dy_os > 0 else 0.0
    y_us = float(y[int((sgn * y).argmin())])
    undershoot = -100.0 * y_us / yfinal if sgn * y_us < 0 else 0.0
    k = int(np.abs(y).argmax())
    return {'rise_time': rise_time, 'settling_time': settling_time,
            'settling_min': settling_min, 'settling_max': settling_max,
            'overshoot': overshoot, 'undershoot': undershoot, 'peak': float(abs(y[k])),
            'peak_time': float(t[k]), 'steady_state_value': float(yfinal)}


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
    info = step_info(tt, yy - y0, target - y0)
    for name in ('settling_min', 'settling_max', 'steady_state_value'):
        info[name] += y0
    e = yy - target
    if effort is None:
        max_effort = energy = saturation = math.nan
    else:
        tau = _vector('effort', effort)
        if tau.size != tt.size:
            raise TestingError(f'effort must have the length of t ({tt.size}), got '
                               f'{tau.size}')
        max_effort = float(np.abs(tau).max())
        energy = _trapezoid(tau * tau, tt)
        saturation = (float(np.mean(np.abs(tau) >= effort_limit))
                      if math.isfinite(effort_limit) else 0.0)
    return StepMetrics(
        **info, steady_state_error=float(e[-1]), iae=_trapezoid(np.abs(e), tt),
        ise=_trapezoid(e * e, tt), itae=_trapezoid((tt - tt[0]) * np.abs(e), tt),
        max_effort=max_effort, effort_energy=energy, saturation_fraction=saturation)
