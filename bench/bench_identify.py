"""Benchmark ``identify.compare`` beside a fit by hand: scipy ``least_squares`` over ``solve_ivp``.

Run: ``.venv/bin/python bench/bench_identify.py`` (``--seconds``, ``--rate``, ``--no-jit``).
A record of ``--seconds`` (60) at ``--rate`` (100 Hz) of a quadratic-drag swing (ω0² = 9.8,
γ = 0.15, released from 1 rad, 2 mrad Gaussian noise, 1 mrad quantisation, a 0.03 rad zero
offset). First a warm-up ``compare`` on a 4 s record compiles the core's sweep for the four
laws (printed: it is paid once per process). Then, in the same run:

- ``compare`` over viscous, quadratic, coulomb and power (the simulations of each iteration's
  candidates, every start's Jacobian columns, batched through ``sweep``);
- the by-hand fit a user would write: for each law, ``scipy.optimize.least_squares`` (trf,
  its own 2-point Jacobian) with ``solve_ivp`` (RK45, rtol 1e-8, atol 1e-10, ``t_eval`` the
  samples) as the model, the same six parameters, started from the same first guess as
  ``compare``'s first start, stopped after :data:`MAX_NFEV` evaluations (the Coulomb law's
  sign(φ') makes RK45 crawl at every reversal and at rest).

Prints each law's wall time and RMS residual for both, the totals and the ratio. Asserts
nothing.
"""
from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import least_squares

from pendulum_sim.core import PendulumParams, simulate
from pendulum_sim.identify import LAWS, compare, prepare
from pendulum_sim.identify.fit import _starts

MAX_NFEV = 60
"""Evaluations the by-hand fit may take (each a whole solve_ivp run; 6 per Jacobian)."""


def record(seconds: float, rate: float, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Return a noisy, quantised, offset quadratic-drag swing sampled at ``rate``."""
    run = simulate(PendulumParams.from_omega0_sq(9.8, 0.15, 2.0), 1.0, 0.0, seconds, 1e-3)
    every = round(1.0 / (rate * 1e-3))
    rng = np.random.default_rng(seed)
    t = run.t[::every]
    y = run.phi[::every] + 0.03 + rng.normal(0.0, 2e-3, t.size)
    return t, np.round(y / 1e-3) * 1e-3


def by_hand(law: str, t: np.ndarray, y: np.ndarray) -> tuple[float, float, int]:
    """Fit ``law`` with least_squares over solve_ivp; return (seconds, RMS residual, nfev)."""
    rec = prepare(t, y)
    start = _starts(LAWS[law], rec, {})[0]
    names = ['omega0', 'gamma', 'phi_offset', 'phi0', 'dphi0'] + (['n'] if law == 'power'
                                                                  else [])
    fixed_n = LAWS[law].n
    x0 = np.array([start[k] for k in names])

    def residual(x: np.ndarray) -> np.ndarray:
        om, gam, off, p0, v0 = x[:5]
        n = x[5] if fixed_n is None else fixed_n

        def rhs(_: float, s: np.ndarray) -> list[float]:
            v = s[1]
            damp = gam * math.copysign(1.0, v) if n == 0 else gam * v * abs(v) ** (n - 1)
            return [v, -om * om * math.sin(s[0]) - damp]

        sol = solve_ivp(rhs, (0.0, rec.t[-1]), [p0, v0], method='RK45', rtol=1e-8, atol=1e-10,
                        t_eval=rec.t)
        if not sol.success or sol.y.shape[1] != rec.t.size:
            return np.full(rec.t.size, 1e3)
        return np.asarray(sol.y[0] + off - rec.y)

    lo = [1e-3, 0.0, -np.inf, -np.inf, -np.inf] + ([0.0] if law == 'power' else [])
    began = time.perf_counter()
    res = least_squares(residual, x0, bounds=(lo, np.inf), method='trf', max_nfev=MAX_NFEV)
    took = time.perf_counter() - began
    return took, float(np.sqrt(np.mean(res.fun ** 2))), int(res.nfev)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=60.0)
    parser.add_argument('--rate', type=float, default=100.0)
    parser.add_argument('--no-jit', action='store_true', help='the numpy sweep (no compile)')
    args = parser.parse_args()
    sys.stdout.reconfigure(line_buffering=True)   # type: ignore[union-attr]
    jit = not args.no_jit
    t, y = record(args.seconds, args.rate)
    print(f'# record: {args.seconds:g} s at {args.rate:g} Hz ({t.size} samples), quadratic drag '
          f'(omega0^2 = 9.8, gamma = 0.15), noise 2 mrad, quantum 1 mrad, offset 0.03 rad')
    began = time.perf_counter()
    compare(*record(4.0, args.rate), jit=jit)
    print(f'warm-up compare on a 4 s record (compiles the sweep for 4 laws: once per process): '
          f'{time.perf_counter() - began:.2f} s' + ('' if jit else ' (numpy, nothing compiled)'))
    times: dict[str, float] = {}

    def note(model: str) -> None:
        times[model] = time.perf_counter()

    began = time.perf_counter()
    fits = compare(t, y, jit=jit, progress=note)
    total = time.perf_counter() - began
    marks = [*times.values(), began + total]
    took = {m: marks[i + 1] - marks[i] for i, m in enumerate(times)}
    by = {f.model: f for f in fits}
    print(f'compare ({"compiled" if jit else "numpy"} sweep): {total:.2f} s for 4 laws; ranked '
          + ', '.join(f.model for f in fits))
    hand_total = 0.0
    print(f'{"law":10s} {"identify s":>10s} {"rms rad":>10s} {"iters":>5s}   '
          f'{"scipy s":>9s} {"rms rad":>10s} {"nfev":>5s}   {"speed-up":>8s}')
    for law in LAWS:
        secs, rms, nfev = by_hand(law, t, y)
        hand_total += secs
        f = by[law]
        print(f'{law:10s} {took[law]:10.2f} {f.rms_residual:10.6f} {f.iterations:5d}   '
              f'{secs:9.2f} {rms:10.6f} {nfev:5d}   {secs / took[law]:8.1f}')
    print(f'total: identify.compare {total:.2f} s, least_squares + solve_ivp {hand_total:.2f} s: '
          f'{hand_total / total:.1f}x')


if __name__ == '__main__':
    main()
