"""An independent optimum of each damping law on a record: a dense scan, then least squares.

The reference the identification's fits are held to (``test_identify_optimum.py``): nothing of
``pendulum_sim`` is used. The model is the one the package fits (Quiroga and Ospina-Henao,
Eur. J. Phys. 38 (2017) 065005, eq 15-16, with a Coulomb friction beside the law)::

    φ'' = −ω0² sin φ − γ sgn(φ') |φ'|^n − f sgn(φ'),     measured = φ + offset

simulated here by a classic RK4 written for this module (numba, one pendulum per thread) at a
step of at most a 400th of the period, landing on every sample time (no interpolation). A
velocity reversal where gravity cannot overcome the friction's largest value (f, and γ for
n = 0) sticks the pendulum for good, as a free swing does.

The search: each law's free exponent and friction take a grid of values; for each, a dense
grid of ω0 (steps that shift the phase at the record's end by a quarter turn, over 0.85-1.35
times the spectral peak) and of the damping's share of gravity is simulated at a coarser step
(a 24th of the period) with the initial state and the offset read off the data; the best
cells, each the best of its region, are then polished by scipy's ``least_squares`` (trf, all
free parameters, the bounds the package uses) at the fine step.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

FloatArray = npt.NDArray[np.float64]

FREE = {'viscous': ('omega0', 'gamma', 'offset', 'phi0', 'dphi0'),
        'quadratic': ('omega0', 'gamma', 'offset', 'phi0', 'dphi0'),
        'coulomb': ('omega0', 'gamma', 'offset', 'phi0', 'dphi0'),
        'power': ('omega0', 'gamma', 'n', 'offset', 'phi0', 'dphi0'),
        'power+coulomb': ('omega0', 'gamma', 'n', 'f', 'offset', 'phi0', 'dphi0')}
"""Each law's free parameters (``f`` is the friction deceleration, f/I in rad/s²)."""
FIXED_N = {'viscous': 1.0, 'quadratic': 2.0, 'coulomb': 0.0}
ORDER = ('omega0', 'gamma', 'n', 'f', 'offset', 'phi0', 'dphi0')
BOUNDS = {'omega0': (1e-3, 1e3), 'gamma': (0.0, 1e3), 'n': (0.0, 6.0), 'f': (0.0, 1e3),
          'offset': (-1e3, 1e3), 'phi0': (-1e3, 1e3), 'dphi0': (-100.0, 100.0)}
"""The package's search bounds (``identify.solver.BOUNDS``), copied: the same feasible set."""
FINE = 100
"""Steps per period of the fine simulation (polish and the reported optimum)."""
COARSE = 24
"""Steps per period of the scan."""
SCAN_N = (0.0, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0)
"""The exponents the scan tries where n is free."""
SCAN_F = (0.0, 0.003, 0.01, 0.03, 0.1)
"""The friction's share of gravity at the swing's amplitude, f / (ω0² A), where f is free."""
SCAN_D = tuple(float(v) for v in np.geomspace(1e-4, 1.0, 13))
"""The damping's share of gravity at the swing's amplitude and speed, γ (A ω0)^n / (ω0² A)."""
POLISH = 6
"""Cells of the scan polished by least squares."""
OMEGA_BASINS = 3
"""Local minima along ω0 the scan keeps for the law's own grid."""
SCAN_SAMPLES = 600
"""Samples of the record the scan compares (spread evenly over it)."""
POLISH_SAMPLES = 1000
"""Samples of the record each start is polished on first (the best two then on all)."""
REFINE = 32
"""Parts a step over a velocity reversal is taken in."""


@numba.njit(inline='always')
def _accel(x: float, v: float, w2: float, gam: float, n: float, f: float) -> float:
    if v == 0.0:
        return -w2 * math.sin(x)
    return -w2 * math.sin(x) - math.copysign(gam * abs(v) ** n + f, v)


@numba.njit(inline='always')
def _rk4(x: float, v: float, h: float, w2: float, gam: float, n: float, f: float
         ) -> tuple[float, float]:
    a1 = _accel(x, v, w2, gam, n, f)
    x2, v2 = x + 0.5 * h * v, v + 0.5 * h * a1
    a2 = _accel(x2, v2, w2, gam, n, f)
    x3, v3 = x + 0.5 * h * v2, v + 0.5 * h * a2
    a3 = _accel(x3, v3, w2, gam, n, f)
    x4, v4 = x + h * v3, v + h * a3
    a4 = _accel(x4, v4, w2, gam, n, f)
    return (x + h / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4),
            v + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4))


@numba.njit
def _step(x: float, v: float, h: float, w2: float, gam: float, n: float, f: float,
          stick: float) -> tuple[float, float, bool]:
    """Advance one step; a step over a velocity reversal is taken in REFINE parts.

    The damping's sign changes at a reversal, where RK4 loses its order (the error of the
    step that straddles it is O(h²) for a friction); taken in parts the error is REFINE²
    times smaller. A part that ends a reversal where the friction holds the pendulum sticks
    it for good (returned True).
    """
    x1, v1 = _rk4(x, v, h, w2, gam, n, f)
    if v != 0.0 and v1 != 0.0 and (v1 > 0.0) == (v > 0.0):
        return x1, v1, False
    hs = h / REFINE
    for _ in range(REFINE):
        vs = v
        x, v = _rk4(x, v, hs, w2, gam, n, f)
        if vs != 0.0 and (v == 0.0 or (v > 0.0) != (vs > 0.0)) and abs(
                w2 * math.sin(x)) <= stick:
            return x, 0.0, True
    return x, v, False


@numba.njit(cache=False, parallel=True)
def _simulate(params: FloatArray, t: FloatArray, steps_per_period: float) -> FloatArray:
    """Return the angle (without offset) of each row of ``params`` at the times ``t``.

    A row is ω0, γ, n, f, offset, φ0, φ'0; ``t[0]`` is the initial time.
    """
    k, m = params.shape[0], t.size
    out = np.empty((k, m))
    for r in numba.prange(k):
        w2 = params[r, 0] * params[r, 0]
        gam, n, f = params[r, 1], params[r, 2], params[r, 3]
        stick = f + (gam if n == 0.0 else 0.0)
        hmax = 2.0 * math.pi / params[r, 0] / steps_per_period
        x, v = params[r, 5], params[r, 6]
        stuck = v == 0.0 and abs(w2 * math.sin(x)) <= stick
        out[r, 0] = x
        for i in range(1, m):
            if not stuck and math.isfinite(x):
                dt = t[i] - t[i - 1]
                ns = max(1, math.ceil(dt / hmax))
                for _ in range(ns):
                    x, v, stuck = _step(x, v, dt / ns, w2, gam, n, f, stick)
                    if stuck or not (math.isfinite(x) and math.isfinite(v)):
                        break
            out[r, i] = x
    return out


def simulate(rows: FloatArray, t: FloatArray, steps_per_period: float = FINE) -> FloatArray:
    """Return the model's measured angle (offset included) of each parameter row at ``t``."""
    rows = np.atleast_2d(np.asarray(rows, dtype=np.float64))
    tt = np.asarray(t, dtype=np.float64) - float(t[0])
    return _simulate(rows, tt, float(steps_per_period)) + rows[:, 4:5]


@dataclass(frozen=True)
class Optimum:
    """The lowest residual found for a law: its RMS (rad), parameters and the polished runs."""

    rms: float
    params: dict[str, float]
    polished: tuple[float, ...]


def _full(law: str, free: FloatArray, fixed: dict[str, float]) -> FloatArray:
    values = dict(fixed)
    values.update(zip(FREE[law], (float(v) for v in free), strict=True))
    return np.array([values[k] for k in ORDER])


def rms_of(law: str, t: FloatArray, y: FloatArray, params: dict[str, float]) -> float:
    """Return the RMS residual (rad) of ``params`` (of ``ORDER``) on the record, fine step."""
    row = np.array([params[k] for k in ORDER])
    return float(np.sqrt(np.mean((simulate(row, t)[0] - y) ** 2)))


def spectral_omega(t: FloatArray, y: FloatArray) -> float:
    """Return the angular frequency of the record's spectral peak (resampled uniform, padded)."""
    m = max(4096, 1 << math.ceil(math.log2(8 * t.size)))
    u = np.linspace(t[0], t[-1], t.size)
    z = np.interp(u, t, y) - np.mean(y)
    z = z * np.hanning(z.size)
    spec = np.abs(np.fft.rfft(z, m))
    freq = np.fft.rfftfreq(m, (u[1] - u[0]))
    k = int(np.argmax(spec[1:])) + 1
    return float(2.0 * math.pi * freq[k])


def start_state(t: FloatArray, y: FloatArray, omega: float) -> tuple[float, float, float]:
    """Return the offset, φ0 and φ'0 read off the data (centre, first sample, slope there)."""
    half = y[t >= t[0] + 0.5 * (t[-1] - t[0])]
    offset = 0.5 * float(np.max(half) + np.min(half))
    k = max(3, int(np.searchsorted(t, t[0] + 0.1 * 2.0 * math.pi / omega)))
    c = np.polyfit(t[:k] - t[0], y[:k], 2)
    return offset, float(c[2]) - offset, float(c[1])


def _grid(omegas: FloatArray, ns: tuple[float, ...], fs: tuple[float, ...], amp: float,
          state: tuple[float, float, float]) -> FloatArray:
    """Return the parameter rows of the grid (n, friction share, damping share, ω0)."""
    offset, phi0, dphi0 = state
    n, f, d, w = np.meshgrid(np.array(ns), np.array(fs), np.array(SCAN_D), omegas,
                             indexing='ij')
    gam = d * w * w * amp / (amp * w) ** n
    rows = [w, gam, n, f * w * w * amp, np.full_like(w, offset), np.full_like(w, phi0),
            np.full_like(w, dphi0)]
    return np.stack(rows, axis=-1)


def _misfit(grid: FloatArray, t: FloatArray, y: FloatArray) -> FloatArray:
    """Return the mean square misfit of each cell of ``grid`` at ``SCAN_SAMPLES`` samples."""
    sub = np.unique(np.linspace(0, t.size - 1, min(t.size, SCAN_SAMPLES)).astype(np.int64))
    pred = simulate(grid.reshape(-1, len(ORDER)), t[sub], COARSE)
    cost = np.mean((pred - y[sub]) ** 2, axis=1)
    return np.nan_to_num(cost, nan=np.inf).reshape(grid.shape[:-1])


def _local_minima(cost: FloatArray) -> npt.NDArray[np.int64]:
    """Return the flat indices of the cells no neighbour undercuts, best first."""
    padded = np.pad(cost, 1, constant_values=np.inf)
    local = np.isfinite(cost)
    centre = [slice(1, -1)] * cost.ndim
    for axis in range(cost.ndim):
        for shift in (-1, 1):
            moved = list(centre)
            moved[axis] = slice(1 + shift, padded.shape[axis] - 1 + shift)
            local &= cost <= padded[tuple(moved)]
    cells = np.flatnonzero(local.ravel())
    return cells[np.argsort(cost.ravel()[cells])]


def _scan(law: str, t: FloatArray, y: FloatArray) -> list[FloatArray]:
    """Return the starts of the polish: the scan's best local minima.

    First ω0 against the damping share under viscous damping: the frequency that keeps the
    swing in phase over the record hardly depends on the damping law (it shifts it in second
    order), so the best ``OMEGA_BASINS`` local minima along ω0 are kept; then the law's grid
    (exponent, friction and damping shares) at each of them and its two neighbours. The
    ``POLISH`` best local minima of that grid are the starts.
    """
    w_peak = spectral_omega(t, y)
    state = start_state(t, y, w_peak)
    amp = float(np.max(np.abs(y - state[0])))
    step = 0.5 * math.pi / float(t[-1] - t[0])
    omegas = np.arange(0.85 * w_peak, 1.35 * w_peak + step, step)
    profile = _misfit(_grid(omegas, (1.0,), (0.0,), amp, state), t, y).min(axis=(0, 1, 2))
    basins = _local_minima(profile)[:OMEGA_BASINS]
    near = np.unique(np.clip(np.concatenate([basins - 1, basins, basins + 1]), 0,
                             omegas.size - 1))
    ns = (FIXED_N[law],) if law in FIXED_N else SCAN_N
    fs = SCAN_F if law == 'power+coulomb' else (0.0,)
    grid = _grid(omegas[near], ns, fs, amp, state)
    chosen = _local_minima(_misfit(grid, t, y))[:POLISH]
    flat = grid.reshape(-1, len(ORDER))
    return [np.array([dict(zip(ORDER, flat[i], strict=True))[k] for k in FREE[law]])
            for i in chosen]


def optimum(law: str, t: FloatArray, y: FloatArray,
            seeds: tuple[dict[str, float], ...] = ()) -> Optimum:
    """Return the lowest RMS residual ``law`` reaches on the record, from the scan's cells.

    ``seeds`` (parameter dicts of ``ORDER``, e.g. the optima of nested laws) are polished too.
    """
    fixed = {'n': FIXED_N.get(law, 0.0), 'f': 0.0}
    names = FREE[law]
    lo = np.array([BOUNDS[k][0] for k in names])
    hi = np.array([BOUNDS[k][1] for k in names])
    starts = _scan(law, t, y)
    for seed in seeds:
        starts.append(np.clip(np.array([seed[k] for k in names]), lo, hi))

    def fitted(free: FloatArray, tt: FloatArray, yy: FloatArray, nfev: int) -> FloatArray:
        def residual(x: FloatArray) -> FloatArray:
            r = simulate(_full(law, x, fixed), tt)[0] - yy
            return np.where(np.isfinite(r), r, 10.0)

        def jacobian(x: FloatArray) -> FloatArray:
            steps = 1.5e-8 * np.maximum(np.abs(x), 1.0)
            steps = np.where(x + steps > hi, -steps, steps)
            rows = np.array([_full(law, x + s, fixed) for s in
                             np.vstack([np.zeros(x.size), np.diag(steps)])])
            pred = simulate(rows, tt)
            return np.asarray(((pred[1:] - pred[0]) / steps[:, None]).T)

        sol = least_squares(residual, np.clip(free, lo, hi), jac=jacobian, bounds=(lo, hi),
                            x_scale='jac', method='trf', ftol=1e-10, xtol=1e-10, gtol=1e-10,
                            max_nfev=nfev)
        return np.asarray(sol.x)

    # Every start on an even subset of the samples, then the best two on the whole record.
    sub = np.unique(np.linspace(0, t.size - 1, min(t.size, POLISH_SAMPLES)).astype(np.int64))
    first = [fitted(x0, t[sub], y[sub], 60) for x0 in starts]
    misfit = [float(np.mean((simulate(_full(law, x, fixed), t[sub])[0] - y[sub]) ** 2))
              for x in first]
    finals = [fitted(first[i], t, y, 200) for i in np.argsort(misfit)[:2]]
    rms = [float(np.sqrt(np.mean((simulate(_full(law, x, fixed), t)[0] - y) ** 2)))
           for x in finals]
    k = int(np.argmin(rms))
    params = dict(zip(ORDER, _full(law, finals[k], fixed).tolist(), strict=True))
    return Optimum(rms=rms[k], params=params, polished=tuple(rms))


NESTED = {'viscous': (), 'quadratic': (), 'coulomb': (),
          'power': ('viscous', 'quadratic', 'coulomb'),
          'power+coulomb': ('viscous', 'quadratic', 'coulomb', 'power')}
"""The laws each law nests (their optima are points of its own parameter space)."""


def optima(t: FloatArray, y: FloatArray) -> dict[str, Optimum]:
    """Return every law's optimum, each nesting law seeded with the optima of those it nests."""
    out: dict[str, Optimum] = {}
    for law in FREE:
        out[law] = optimum(law, t, y, tuple(out[k].params for k in NESTED[law]))
    return out

