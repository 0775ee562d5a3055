"""Validate a fit on a record it was not fitted to: simulation, k-step prediction, residual tests.

The definitions are those users know from MATLAB's System Identification Toolbox:

- ``compare``'s fit in %: 100 (1 − ‖y − ŷ‖ / ‖y − mean(y)‖) (the normalised RMS error), of
  the simulation (the model run over the whole record from its first state, under the
  recorded effort) and of the k-step-ahead prediction (each predicted sample simulated from
  the measured state k samples earlier: the angle less the fitted sensor zero, and the
  measured velocity, or the local cubic's slope where the record has none);
- ``resid``'s tests: the residuals' autocorrelation at lags 1..M and their cross-correlation
  with the effort at lags −M..M, each normalised to 1 at its own scale, against the 99 %
  band ±2.58/√N of white residuals independent of the input (M = 25, MATLAB's default).

The residuals tested are those of the fit's own method on the new record, the joint's
parameters held: each window of the fit's length simulated from its own state, the states
fitted (one window of the whole record for a fit by one simulation). The simulation's first
state is fitted to the record's first window likewise.
"""
from __future__ import annotations

import csv
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..core.analysis import fit_percent
from .checks import as_array, jit_choice
from .driven import SHARED, DrivenRecord, anchors, grid_step, inputs_for, prepare_driven
from .errors import IdentifyError
from .laws import get_law
from .result import Fit
from .windows import Problem, Series, Windows, cut, simulate, solve

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

LAGS = 25
"""Lags of the residual tests (MATLAB ``resid``'s default M)."""
BAND = 2.58
"""The 99 % two-sided normal quantile: white residuals' correlations stay within ±BAND/√N."""
HORIZON_PERIODS = 0.1
"""The default prediction horizon, in periods 2π/ω0 of the fit."""
STATE_ITERATIONS = 20
"""Iterations of the fit of the windows' states (a linear problem but for the law's kinks)."""


@dataclass(frozen=True)
class Validation:
    """How a fit predicts a record it was not fitted to.

    Attributes
    ----------
    t, measured : ndarray
        The record's times (s) and its angle (rad, unwrapped).
    simulated : ndarray
        The model's angle over the whole record from its fitted first state.
    predicted : ndarray
        The k-step-ahead prediction (NaN for the first k samples, which have none).
    residual : ndarray
        Measured minus the fit's windows re-anchored on this record (the whiteness test's).
    k : int
        The prediction horizon in samples.
    fit_simulation, fit_prediction : float
        Fit in % (NRMSE, MATLAB ``compare``) of the simulation and of the prediction.
    lags, autocorrelation : ndarray
        Lags 0..M and the residuals' autocorrelation there (1 at lag 0).
    cross_lags, cross_correlation : ndarray or None
        Lags −M..M and the residuals' cross-correlation with the effort (None for a record
        without effort).
    band : float
        The 99 % whiteness band 2.58/√N.
    """

    t: FloatArray
    measured: FloatArray
    simulated: FloatArray
    predicted: FloatArray
    residual: FloatArray
    k: int
    fit_simulation: float
    fit_prediction: float
    lags: IntArray
    autocorrelation: FloatArray
    cross_lags: IntArray | None
    cross_correlation: FloatArray | None
    band: float

    @property
    def white(self) -> bool:
        """Return True when at most one autocorrelation at lags 1..M lies outside the band.

        Each lag of white residuals leaves the 99 % band with probability 0.01: one of the 25
        in 22 % of records, two or more in 2.6 % (the test's false alarm).
        """
        return bool(np.count_nonzero(np.abs(self.autocorrelation[1:]) > self.band) <= 1)

    @property
    def independent(self) -> bool | None:
        """Return True when at most one cross-correlation with the effort lies outside the band
        (None for a record without effort); of 2M + 1 = 51 lags, two or more leave it in 9 %
        of records of independent residuals."""
        if self.cross_correlation is None:
            return None
        return bool(np.count_nonzero(np.abs(self.cross_correlation) > self.band) <= 1)


def _fit(y: FloatArray, yhat: FloatArray) -> float:
    """Return the fit in % (``core.analysis.fit_percent``, MATLAB ``compare``'s NRMSE).

    −inf where the prediction is not finite throughout (a simulation that left the record).
    """
    if not np.all(np.isfinite(yhat)):
        return -math.inf
    return fit_percent(y, yhat)


def autocorrelation(e: FloatArray, lags: int) -> FloatArray:
    """Return r(τ) = Σ e(t) e(t − τ) / Σ e(t)² for τ = 0..lags (``e`` less its mean)."""
    x = e - np.mean(e)
    den = float(x @ x)
    return np.array([float(x[tau:] @ x[:x.size - tau]) / den for tau in range(lags + 1)])


def cross_correlation(e: FloatArray, u: FloatArray, lags: int) -> FloatArray:
    """Return r(τ) = Σ e(t) u(t − τ) / √(Σe² Σu²) for τ = −lags..lags (both less their mean)."""
    x, z = e - np.mean(e), u - np.mean(u)
    den = math.sqrt(float(x @ x) * float(z @ z))
    m = x.size
    out = []
    for tau in range(-lags, lags + 1):
        if tau >= 0:
            out.append(float(x[tau:] @ z[:m - tau]))
        else:
            out.append(float(x[:m + tau] @ z[-tau:]))
    return np.array(out) / den if den > 0 else np.zeros(2 * lags + 1)


def _values(f: Fit) -> dict[str, float]:
    """Return the fit's joint as the shared parameters of a driven model (its ``damping`` γ
    itself, at a reference speed of 1 rad/s), or refuse it."""
    names = [k for k in SHARED if k != 'damping'] + ['gamma']
    params = dict(f.params)
    if params.get('gamma') == 0.0 and params.get('n') is None:
        params['n'] = 1.0   # no damping: the exponent does not act (any n predicts the same)
    missing = [k for k in names if params.get(k) is None]
    if missing:
        why = f.reasons.get(missing[0], 'not determined')
        raise IdentifyError(f'the fit does not determine {", ".join(missing)} ({why}): it '
                            f'cannot predict a driven record')
    values = {k: float(params[k]) for k in names}   # type: ignore[arg-type]
    values['damping'] = values.pop('gamma')
    return values


def _free_inputs(f: Fit) -> tuple[dict[str, float], Any]:
    """Return the shared values and the sweep inputs of a free-swing fit (no torque)."""
    names = ('omega0', 'gamma', 'n', 'phi_offset')
    missing = [k for k in names if f.params.get(k) is None]
    if missing:
        raise IdentifyError(f'the fit does not determine {", ".join(missing)}: it cannot '
                            f'predict a record')
    values = {k: float(f.params[k]) for k in names}   # type: ignore[arg-type]
    acc = f.params.get('friction_accel')
    values['friction_accel'] = float(acc) if f.model == 'power+coulomb' and acc else 0.0

    def inputs(col: dict[str, FloatArray], wins: IntArray, steps: int) -> Any:
        om = col['omega0']
        return (om * om, col['gamma'], col['n'], col['friction_accel'], None,
                col['phi_offset'])
    return values, inputs


def _states(rec: DrivenRecord, win: Windows, offset: float) -> FloatArray:
    vel = anchors(rec)
    return np.column_stack([rec.y[win.start] - offset, vel[win.start]])


def _problem(values: Mapping[str, float], win: Windows, inputs: Any, states: FloatArray,
             scale: float, omega0: float) -> Problem:
    empty = np.zeros(0)
    return Problem(free=(), fixed=dict(values), theta=empty, states=states, scale=empty,
                   state_scale=np.column_stack([np.full(win.count, scale),
                                                np.full(win.count, scale * omega0)]),
                   bounds=(empty, empty), win=win, inputs=inputs)


def _record(record: Any) -> DrivenRecord:
    if isinstance(record, DrivenRecord):
        return record
    if isinstance(record, Mapping):
        t = as_array('t', record.get('t'), None)
        y = np.unwrap(as_array('position', record.get('position'), t.size))
        vel = record.get('velocity')
        v = None if vel is None else as_array('velocity', vel, t.size)
        eff = record.get('effort')
        e = np.zeros(t.size) if eff is None else as_array('effort', eff, t.size)
        return prepare_driven(t, y, v, e)
    raise IdentifyError(f'a record to validate on is a dict with t, position (and effort, '
                        f'velocity) or a prepared driven record, got {type(record).__name__}')


def validate(fit: Fit, record: Any, *, k: int | None = None, jit: bool | None = None
             ) -> Validation:
    """Validate ``fit`` on ``record``: fit % of simulation and k-step prediction, residual tests.

    Parameters
    ----------
    fit : Fit
        A fit of ``fit``/``compare`` (driven, or of a free swing).
    record : dict or DrivenRecord
        The held-out record: ``{'t': ..., 'position': ..., 'effort': ..., 'velocity': ...}``
        (effort in N m over the sample period ending at each stamp; velocity optional) or
        :func:`prepare_driven`'s record.
    k : int, optional
        The prediction horizon in samples (default: a tenth of the fit's period 2π/ω0).
    jit : bool or None
        Simulate with the compiled sweep (None: where numba is installed).

    Returns
    -------
    Validation
    """
    use_jit = jit_choice(jit)
    rec = _record(record)
    omega0 = fit.params.get('omega0')
    if omega0 is None:
        raise IdentifyError('the fit does not determine omega0: it cannot predict a record')
    driven = fit.driven
    if driven:
        values = _values(fit)
        law = get_law(fit.model)
    else:
        if np.any(rec.effort.values != 0.0):
            raise IdentifyError('the fit is of a free swing: it has no torque scale to drive '
                                'the joint with; fit a driven record to predict one')
        values, free_inputs = _free_inputs(fit)
    dt = float(np.median(np.diff(rec.t)))
    if k is None:
        k = max(1, round(HORIZON_PERIODS * 2.0 * math.pi / omega0 / dt))
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not (
            1 <= k < rec.t.size - 1):
        raise IdentifyError(f'k must be a whole number of samples in [1, {rec.t.size - 2}], '
                            f'got {k!r}')
    k = int(k)
    h = grid_step([rec], omega0)
    series = [Series(t=rec.t, y=rec.y, effort=rec.effort, anchor=anchors(rec))]
    scale = max(float(np.max(np.abs(rec.y))), 0.1)
    offset = values['phi_offset']

    def inputs_of(win: Windows) -> Any:
        return inputs_for(law, [rec], win, 1.0) if driven else free_inputs

    # The residuals: the fit's windows (one window for a fit by one simulation), states fitted.
    win = cut(series, fit.window, h)
    res_p = _problem(values, win, inputs_of(win), _states(rec, win, offset), scale, omega0)
    solve([res_p], jit=use_jit, max_iterations=STATE_ITERATIONS)
    if res_p.residual is None:
        raise IdentifyError('the fit cannot simulate this record (the core refuses its '
                            'first states)')
    residual = -res_p.residual
    # The simulation: the whole record from the first window's fitted state.
    whole = cut(series, None, h)
    sim_p = _problem(values, whole, inputs_of(whole), res_p.states[:1].copy(), scale, omega0)
    sim = simulate([sim_p], [(np.zeros((1, 0)), sim_p.states[None])], jit=use_jit)[0]
    simulated = np.full(rec.t.size, np.nan) if sim is None else sim[:, 0]
    predicted = _predict(rec, series, values, inputs_of, h, k, offset, scale, omega0, use_jit)
    m = rec.t.size
    cross_lags = None
    cross = None
    lags = min(LAGS, m - 2)
    if np.any(rec.effort.values != 0.0):
        u = rec.effort.average(np.concatenate(([rec.t[0] - dt], rec.t[:-1])), rec.t)
        cross_lags = np.arange(-lags, lags + 1)
        cross = cross_correlation(residual, u, lags)
    return Validation(
        t=rec.t + rec.t0, measured=rec.y, simulated=simulated, predicted=predicted,
        residual=residual, k=k,
        fit_simulation=_fit(rec.y, simulated) if sim is not None else -math.inf,
        fit_prediction=_fit(rec.y[k:], predicted[k:]),
        lags=np.arange(lags + 1), autocorrelation=autocorrelation(residual, lags),
        cross_lags=cross_lags, cross_correlation=cross, band=BAND / math.sqrt(m))


def _predict(rec: DrivenRecord, series: list[Series], values: Mapping[str, float],
             inputs_of: Any, h: float, k: int, offset: float, scale: float, omega0: float,
             jit: bool) -> FloatArray:
    """Return the k-step-ahead prediction: sample i simulated from the measured state at i − k."""
    m = rec.t.size
    starts = np.arange(m - k)
    ends = starts + k
    spans = rec.t[ends] - rec.t[starts]
    steps = max(1, math.ceil(float(np.max(spans)) / h - 1e-9))
    grid = np.arange(steps + 1) * h
    kk = np.clip(np.searchsorted(grid, spans, side='right') - 1, 0, steps - 1)
    s = (spans - grid[kk]) / h
    w = np.stack([2 * s**3 - 3 * s**2 + 1, (s**3 - 2 * s**2 + s) * h, -2 * s**3 + 3 * s**2,
                  (s**3 - s**2) * h])
    win = Windows(record=np.zeros(starts.size, dtype=np.int64), start=starts,
                  stop=ends + 1, t0=rec.t[starts], h=h, steps=steps,
                  row_window=np.arange(starts.size, dtype=np.int64),
                  bounds=np.arange(starts.size + 1, dtype=np.int64), k=kk, w=w,
                  y=rec.y[ends])
    vel = series[0].anchor
    states = np.column_stack([rec.y[starts] - offset, vel[starts]])
    p = _problem(values, win, inputs_of(win), states, scale, omega0)
    pred = simulate([p], [(np.zeros((1, 0)), states[None])], jit=jit)[0]
    out = np.full(m, np.nan)
    if pred is not None:
        out[ends] = pred[:, 0]
    return out


def write_validation(path: Path, v: Validation) -> None:
    """Write ``validation.csv``: one row per figure (quantity, lag, value)."""
    with path.open('w', newline='') as fh:
        w = csv.writer(fh)
        w.writerow(['quantity', 'lag', 'value'])
        w.writerow(['fit_simulation_percent', '', repr(v.fit_simulation)])
        w.writerow(['fit_prediction_percent', '', repr(v.fit_prediction)])
        w.writerow(['prediction_steps', '', v.k])
        w.writerow(['samples', '', v.t.size])
        w.writerow(['band99', '', repr(v.band)])
        w.writerow(['residual_rms', '', repr(float(np.sqrt(np.mean(v.residual ** 2))))])
        w.writerow(['white', '', v.white])
        if v.independent is not None:
            w.writerow(['independent_of_effort', '', v.independent])
        for lag, r in zip(v.lags.tolist(), v.autocorrelation.tolist(), strict=True):
            w.writerow(['residual_autocorrelation', lag, repr(r)])
        if v.cross_lags is not None and v.cross_correlation is not None:
            for lag, r in zip(v.cross_lags.tolist(), v.cross_correlation.tolist(), strict=True):
                w.writerow(['residual_effort_crosscorrelation', lag, repr(r)])


def write_validation_figure(path: Path, v: Validation, title: str = '') -> None:
    """Write ``validate.png``: measured and predicted angle, residuals, correlation plots."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(10, 8))
    grid = fig.add_gridspec(3, 2, height_ratios=[3, 1.4, 1.6])
    top = fig.add_subplot(grid[0, :])
    top.plot(v.t, v.measured, '.', ms=2, color='0.4', label='measured')
    top.plot(v.t, v.simulated, '-', lw=1, color='C0',
             label=f'simulated (fit {v.fit_simulation:.1f} %)')
    top.plot(v.t, v.predicted, '-', lw=1, color='C1',
             label=f'{v.k}-step prediction (fit {v.fit_prediction:.1f} %)')
    top.set_ylabel('angle (rad)')
    top.legend(loc='upper right', fontsize=8)
    if title:
        top.set_title(title, fontsize=10)
    mid = fig.add_subplot(grid[1, :], sharex=top)
    mid.plot(v.t, v.residual, '.', ms=2, color='C3')
    mid.axhline(0.0, color='0.5', lw=0.5)
    mid.set_ylabel('residual (rad)')
    mid.set_xlabel('t (s)')
    left = fig.add_subplot(grid[2, 0])
    left.stem(v.lags, v.autocorrelation, basefmt=' ')
    left.axhspan(-v.band, v.band, color='C2', alpha=0.2, label='99 % band')
    left.set_title('residual autocorrelation', fontsize=9)
    left.set_xlabel('lag (samples)')
    left.legend(fontsize=8)
    right = fig.add_subplot(grid[2, 1])
    if v.cross_lags is not None and v.cross_correlation is not None:
        right.stem(v.cross_lags, v.cross_correlation, basefmt=' ')
        right.axhspan(-v.band, v.band, color='C2', alpha=0.2)
        right.set_title('residual-effort cross-correlation', fontsize=9)
        right.set_xlabel('lag (samples)')
    else:
        right.text(0.5, 0.5, 'no effort in the record', ha='center', va='center')
        right.set_axis_off()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


__all__ = ['BAND', 'LAGS', 'Validation', 'autocorrelation', 'cross_correlation',
           'validate', 'write_validation', 'write_validation_figure']
