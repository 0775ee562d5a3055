"""Benchmark ``identify.compare`` beside a fit by hand: scipy ``least_squares`` over ``solve_ivp``.

Run: ``.venv/bin/python bench/bench_identify.py`` (``--seconds``, ``--rate``, ``--no-jit``,
``--max-nfev``). A record of ``--seconds`` (60) at ``--rate`` (100 Hz) simulated by the core
(quadratic drag, ω0² = 9.8, γ = 0.15, released from 1 rad), with 2 mrad Gaussian noise (seed 3),
1 mrad quantisation and a 0.03 rad zero offset. Printed, in one run:

1. the compile: :func:`pendulum_sim.core.warm_up.warm_up` for the exponents of every law
   ``compare`` fits (paid once per process; not part of the timings below);
2. which models ``compare`` offers (all five, ``laws.COMPARED``) and any it refuses, with its
   reason;
3. ``compare`` over every offered model (all five), its wall time beside the 10 s target, on
   the compiled sweep (``power+coulomb`` beside a friction too);
4. for each law, the fit by hand a user would write: ``scipy.optimize.least_squares`` (trf,
   its own 2-point Jacobian) with ``solve_ivp`` (RK45, rtol 1e-8, atol 1e-10, ``t_eval`` the
   samples) as the model, the same parameters, started from ``compare``'s first start, stopped
   after ``--max-nfev`` evaluations (60 by default: 8 to 10 Jacobians). The Coulomb term's
   sign(φ') is written as tanh(φ'/ε), ε = 0.01 rad/s, as a by-hand user would: with a true
   sign RK45 crawls at every reversal;
5. each law's time and RMS residual both ways, why the fit by hand stopped (least_squares'
   status), the speed-up, whether ``compare``'s residual is equal (within 0.1 %) or better,
   and the totals beside the 10x target.

Asserts nothing.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import least_squares

from pendulum_sim.core import PendulumParams, simulate
from pendulum_sim.core.jit import available as jit_available
from pendulum_sim.core.warm_up import warm_up
from pendulum_sim.identify import LAWS, MODELS, IdentifyError, compare, prepare
from pendulum_sim.identify.fit import _starts
from pendulum_sim.identify.laws import get_law

MAX_NFEV = 60
"""Evaluations the by-hand fit may take (each a whole solve_ivp run; 6 or 7 per Jacobian)."""
TANH_WIDTH = 0.01
"""ε of the by-hand fit's smooth sign, tanh(φ'/ε), in rad/s."""
TARGET_SECONDS = 10.0
TARGET_RATIO = 10.0
SAME = 1e-3
"""Residuals within this fraction of each other count as equal."""


def record(seconds: float, rate: float, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Return a noisy, quantised, offset quadratic-drag swing sampled at ``rate``."""
    run = simulate(PendulumParams.from_omega0_sq(9.8, 0.15, 2.0), 1.0, 0.0, seconds, 1e-3)
    every = round(1.0 / (rate * 1e-3))
    rng = np.random.default_rng(seed)
    t = run.t[::every]
    y = run.phi[::every] + 0.03 + rng.normal(0.0, 2e-3, t.size)
    return t, np.round(y / 1e-3) * 1e-3


def offered() -> tuple[list[str], dict[str, str]]:
    """Return the models ``compare`` fits by default and those it refuses, with the reason."""
    refused: dict[str, str] = {}
    for name in MODELS:
        try:
            get_law(name)
        except IdentifyError as exc:
            refused[name] = str(exc)
    return [m for m in MODELS if m in LAWS and m not in refused], refused


STOPPED = {-1: 'failed', 0: 'max_nfev', 1: 'gtol', 2: 'ftol', 3: 'xtol', 4: 'ftol+xtol'}
"""least_squares' status codes, as the table prints why the fit by hand stopped."""


def by_hand(law: str, t: np.ndarray, y: np.ndarray, max_nfev: int
            ) -> tuple[float, float, int, str]:
    """Fit ``law`` with least_squares over solve_ivp.

    Return the seconds, the RMS residual, the evaluations and why it stopped.
    """
    rec = prepare(t, y)
    start = _starts(LAWS[law], rec, {})[0]
    fixed_n = LAWS[law].n
    names = ['omega0', 'gamma', 'phi_offset', 'phi0', 'dphi0']
    if fixed_n is None:
        names.append('n')
    coulomb = law == 'coulomb'
    # power+coulomb: a Coulomb deceleration c = friction / I beside the power law
    extra_friction = bool(getattr(LAWS[law], 'friction', False)) or (
        'coulomb' in law and not coulomb)
    x0 = np.array([float(start.get(k, 0.0) or 0.0) for k in names])
    if extra_friction:
        c0 = start.get('friction_accel', start.get('friction', 0.0)) or 0.0
        names.append('friction_accel')
        x0 = np.append(x0, max(float(c0), 1e-3))

    def residual(x: np.ndarray) -> np.ndarray:
        om, gam, off, p0, v0 = x[:5]
        n = x[5] if fixed_n is None else fixed_n
        c = x[-1] if extra_friction else 0.0

        def rhs(_: float, s: np.ndarray) -> list[float]:
            v = s[1]
            smooth = math.tanh(v / TANH_WIDTH)
            damp = gam * smooth if coulomb else gam * v * abs(v) ** (n - 1) if v else 0.0
            return [v, -om * om * math.sin(s[0]) - damp - c * smooth]

        sol = solve_ivp(rhs, (0.0, rec.t[-1]), [p0, v0], method='RK45', rtol=1e-8, atol=1e-10,
                        t_eval=rec.t)
        if not sol.success or sol.y.shape[1] != rec.t.size:
            return np.full(rec.t.size, 1e3)
        return np.asarray(sol.y[0] + off - rec.y)

    lo = [1e-3, 0.0, -np.inf, -np.inf, -np.inf] + [0.0] * (len(names) - 5)
    began = time.perf_counter()
    res = least_squares(residual, x0, bounds=(lo, np.inf), method='trf', max_nfev=max_nfev)
    took = time.perf_counter() - began
    failed = int(np.sum(np.all(res.fun == 1e3)))
    why = STOPPED.get(int(res.status), str(res.status)) + (' (solve failed)' if failed else '')
    return took, float(np.sqrt(np.mean(res.fun ** 2))), int(res.nfev), why


def exponents(models: list[str]) -> tuple[float, ...]:
    """Return one exponent per spelling of the damping law the models simulate."""
    out = {0.0, 1.0, 2.0}
    if any(LAWS[m].n is None for m in models):
        out.add(1.5)        # every non-integer n: the power law's search visits them
    return tuple(sorted(out))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=60.0)
    parser.add_argument('--rate', type=float, default=100.0)
    parser.add_argument('--max-nfev', type=int, default=MAX_NFEV)
    parser.add_argument('--no-jit', action='store_true', help='the numpy sweep (no compile)')
    args = parser.parse_args()
    sys.stdout.reconfigure(line_buffering=True)   # type: ignore[union-attr]
    jit = not args.no_jit and jit_available()
    t, y = record(args.seconds, args.rate)
    print(f'# {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} at start')
    print(f'# record: {args.seconds:g} s at {args.rate:g} Hz ({t.size} samples), quadratic drag '
          f'(omega0^2 = 9.8, gamma = 0.15, n = 2), noise 2 mrad, quantum 1 mrad, offset 0.03 rad')
    models, refused = offered()
    print(f'models compare offers: {", ".join(models)}')
    for name, why in refused.items():
        print(f'refused: {name}: {why}')
    if jit:
        friction = any(LAWS[m].friction for m in models)   # power+coulomb: its own texts
        secs = warm_up(exponents(models), friction=friction)
        print(f'compile or load from the disk cache (first call; warm_up({exponents(models)}, '
              f'friction={friction}), once per process): {secs:.2f} s, not counted below')
    else:
        print('compile: none (numpy sweep; --no-jit or numba missing)')

    marks: dict[str, float] = {}

    def note(model: str) -> None:
        marks[model] = time.perf_counter()

    began = time.perf_counter()
    fits = compare(t, y, models=models, jit=jit, progress=note)
    total = time.perf_counter() - began
    ends = [*marks.values(), began + total]
    took = {m: ends[i + 1] - ends[i] for i, m in enumerate(marks)}
    by = {f.model: f for f in fits}
    verdict = 'meets' if total <= TARGET_SECONDS else 'misses'
    print(f'compare ({"compiled" if jit else "numpy"} sweep), {len(models)} models: '
          f'{total:.2f} s (target <= {TARGET_SECONDS:g} s: {verdict}); ranked by BIC: '
          + ', '.join(f.model for f in fits))
    print(f'by hand: least_squares(trf, max_nfev={args.max_nfev}) over solve_ivp(RK45, '
          f'rtol 1e-8, atol 1e-10); sign(v) as tanh(v / {TANH_WIDTH:g} rad/s)')
    print(f'{"law":14s} {"compare s":>9s} {"rms rad":>10s} {"iters":>5s}   {"by hand s":>9s} '
          f'{"rms rad":>10s} {"nfev":>5s} {"stopped":>9s}   {"speed-up":>8s}  residual')
    hand_total = 0.0
    worse = []
    for law in models:
        secs, rms, nfev, why = by_hand(law, t, y, args.max_nfev)
        hand_total += secs
        f = by[law]
        same = f.rms_residual <= rms * (1.0 + SAME)
        if not same:
            worse.append(law)
        word = ('equal' if abs(f.rms_residual - rms) <= SAME * rms else
                'better' if same else 'WORSE')
        print(f'{law:14s} {took[law]:9.2f} {f.rms_residual:10.6f} {f.iterations:5d}   '
              f'{secs:9.2f} {rms:10.6f} {nfev:5d} {why:>9s}   {secs / took[law]:8.1f}  {word}')
    ratio = hand_total / total
    print(f'total: compare {total:.2f} s, by hand {hand_total:.2f} s: {ratio:.1f}x '
          f'(target >= {TARGET_RATIO:g}x: {"meets" if ratio >= TARGET_RATIO else "misses"}); '
          f'residual equal or better for {len(models) - len(worse)} of {len(models)} laws'
          + (f' (worse: {", ".join(worse)})' if worse else ''))


if __name__ == '__main__':
    main()
