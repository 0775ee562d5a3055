"""Benchmark a driven ``identify.compare`` beside a fit by hand, and ``validate``.

Run: ``.venv/bin/python bench/bench_identify_driven.py`` (``--seconds``, ``--rate``,
``--max-nfev``, ``--laws``). A driven record of ``--seconds`` (60) at ``--rate`` (200 Hz): the
package's joint (I = 0.2002 kg m², m g l = 1.96 N m, γ = 0.5, n = 1.5, a Coulomb friction of
0.05 N m) under the shipped PD law following 1.2 sin(π t) rad, run by ``testing.run_batch`` on
the compiled sweep (steps of 1 ms), with 2 mrad Gaussian noise on the angle (seed 3) and the
logged effort 0.03 N m below the applied torque (a torque sensor's bias). Printed, in one run:

1. the compile: ``warm_up`` of the exponents the five laws visit, beside a friction (paid once
   per process, from the disk cache after the first; not part of the timings below);
2. ``compare`` over the five laws with the effort (the default windows of half a period), its
   wall time beside the 10 s target, each law's time, RMS residual and iterations;
3. for each law, the fit by hand a user would write: ``scipy.optimize.least_squares`` (trf,
   2-point Jacobian) over ``solve_ivp`` (RK45, rtol 1e-8, atol 1e-10, ``t_eval`` the samples,
   ``max_step`` the sample period so that the held torque is seen) of the same model (the
   effort held over each sample period, the same parameters: I, m g l, γ, n, f, τ_off, the
   sensor zero and the initial state), one simulation of the whole record, started from
   ``compare``'s result moved 10 % (so that it has a fit to do), stopped after ``--max-nfev``
   evaluations; sign(φ') as tanh(φ'/ε), ε = 0.01 rad/s, as a by-hand user would;
4. the two side by side: each law's seconds, the speed-up, and the RMS residual of one
   simulation of the whole record under each one's parameters (the by-hand fit's own
   criterion; ``compare``'s simulated from its first window's fitted state, as ``validate``
   simulates), equal (within 0.1 %) or better;
5. ``validate`` of the best law on a second record of the same length (another seed), its wall
   time beside the 1 s target, and its figures.

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

from pendulum_sim.core.jit import available as jit_available
from pendulum_sim.core.warm_up import warm_up
from pendulum_sim.identify import MODELS, compare, validate
from pendulum_sim.testing.batch import run_batch
from pendulum_sim.testing.examples import pd_batch
from pendulum_sim.testing.scene import scene_values
from pendulum_sim.testing.vector import vectorised

TARGET_COMPARE = 10.0
TARGET_RATIO = 10.0
TARGET_VALIDATE = 1.0
MAX_NFEV = 30
TANH_WIDTH = 0.01
SAME = 1e-3
JOINT = {'gamma': 0.5, 'n': 1.5, 'friction': 0.05}
BIAS = 0.03


@vectorised
def tracking(t: float, position: np.ndarray, velocity: np.ndarray) -> np.ndarray:
    """Return the shipped PD law towards 1.2 sin(π t)."""
    return pd_batch(t, position, velocity, target=1.2 * math.sin(math.pi * t))


def record(seconds: float, rate: float, seed: int) -> dict[str, np.ndarray]:
    """Return a driven record of the joint (t, position with noise, biased effort)."""
    values = scene_values('controller_test', {**JOINT, 'phi0': 1.0, 'publish_rate': rate})
    [run] = run_batch(tracking, [values], round(seconds * rate), jit=jit_available())
    rng = np.random.default_rng(seed)
    return {'t': run.t, 'position': run.position + rng.normal(0.0, 2e-3, run.t.size),
            'effort': run.effort - BIAS}


def simulate_whole(f: object, rec: dict[str, np.ndarray]) -> float:
    """Return the RMS residual of one simulation of the whole record under the fit."""
    v = validate(f, rec)   # type: ignore[arg-type]
    return float(np.sqrt(np.mean((v.simulated - v.measured) ** 2)))


def by_hand(law: str, start: dict[str, float], rec: dict[str, np.ndarray], max_nfev: int
            ) -> tuple[float, float, int]:
    """Fit ``law`` by least_squares over solve_ivp; return seconds, RMS residual, evaluations."""
    t, y, u = rec['t'] - rec['t'][0], rec['position'], rec['effort']
    n_fixed = {'viscous': 1.0, 'quadratic': 2.0, 'coulomb': 0.0}.get(law)
    friction = law in ('coulomb', 'power+coulomb')
    power = law != 'coulomb'
    names = ['inertia', 'mgl', 'effort_offset', 'phi_offset', 'phi0', 'dphi0']
    if power:
        names.append('gamma')
    if n_fixed is None:
        names.append('n')
    if friction:
        names.append('friction')
    x0 = np.array([start[k] for k in names]) * np.array(
        [1.1 if k in ('inertia', 'mgl', 'gamma', 'friction') else 1.0 for k in names])

    def residual(x: np.ndarray) -> np.ndarray:
        p = dict(zip(names, x, strict=True))
        n = p.get('n', n_fixed or 1.0)

        def rhs(tt: float, s: np.ndarray) -> list[float]:
            k = min(max(int(np.searchsorted(t, tt, side='left')), 1), t.size - 1)
            v = s[1]
            smooth = math.tanh(v / TANH_WIDTH)
            torque = u[k] + p['effort_offset'] - p.get('friction', 0.0) * smooth
            if power:
                torque -= p['gamma'] * p['inertia'] * v * abs(v) ** (n - 1) if v else 0.0
            return [v, (torque - p['mgl'] * math.sin(s[0])) / p['inertia']]

        sol = solve_ivp(rhs, (0.0, t[-1]), [p['phi0'], p['dphi0']], method='RK45', rtol=1e-8,
                        atol=1e-10, t_eval=t, max_step=float(t[1] - t[0]))
        if not sol.success or sol.y.shape[1] != t.size:
            return np.full(t.size, 1e3)
        return np.asarray(sol.y[0] + p['phi_offset'] - y)

    lo = [1e-6, 0.0, -np.inf, -np.inf, -np.inf, -np.inf] + [0.0] * (len(names) - 6)
    began = time.perf_counter()
    res = least_squares(residual, x0, bounds=(lo, np.inf), method='trf', max_nfev=max_nfev)
    return time.perf_counter() - began, float(np.sqrt(np.mean(res.fun ** 2))), int(res.nfev)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=60.0)
    parser.add_argument('--rate', type=float, default=200.0)
    parser.add_argument('--max-nfev', type=int, default=MAX_NFEV)
    parser.add_argument('--laws', default=','.join(MODELS))
    args = parser.parse_args()
    sys.stdout.reconfigure(line_buffering=True)   # type: ignore[union-attr]
    laws = args.laws.split(',')
    print(f'# {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} at start')
    rec, other = record(args.seconds, args.rate, 3), record(args.seconds, args.rate, 4)
    print(f'# record: {args.seconds:g} s at {args.rate:g} Hz ({rec["t"].size} samples), the PD '
          f'law following 1.2 sin(pi t); I 0.2002, mgl 1.96, gamma 0.5, n 1.5, friction 0.05, '
          f'effort bias {BIAS}; noise 2 mrad')
    if jit_available():
        secs = warm_up((0.0, 1.0, 1.5, 2.0), friction=True)
        print(f'compile or load from the disk cache (warm_up((0, 1, 1.5, 2), friction=True), '
              f'once per process): {secs:.2f} s, not counted below')
    marks: dict[str, float] = {}

    def note(model: str) -> None:
        marks[model] = time.perf_counter()

    began = time.perf_counter()
    fits = compare(rec['t'], rec['position'], effort=rec['effort'], models=laws,
                   progress=note)
    total = time.perf_counter() - began
    ends = [*marks.values(), began + total]
    took = {m: ends[i + 1] - ends[i] for i, m in enumerate(marks)}
    print(f'compare with effort, {len(laws)} laws, windows of {fits[0].window:.3g} s: '
          f'{total:.2f} s (target <= {TARGET_COMPARE:g} s: '
          f'{"meets" if total <= TARGET_COMPARE else "misses"}); ranked by BIC: '
          + ', '.join(f.model for f in fits))
    print(f'by hand: least_squares(trf, max_nfev={args.max_nfev}) over solve_ivp(RK45, rtol '
          f'1e-8, atol 1e-10, max_step = the sample period), one simulation of the record')
    print(f'{"law":14s} {"compare s":>9s} {"iters":>5s} {"windowed":>9s} {"whole":>9s}   '
          f'{"by hand s":>9s} {"nfev":>5s} {"whole":>9s}   {"speed-up":>8s}  residual')
    by = {f.model: f for f in fits}
    hand_total = 0.0
    for law in laws:
        f = by[law]
        if f.params.get('inertia') is None:
            print(f'{law:14s} not determined: {"; ".join(sorted(set(f.reasons.values())))}')
            continue
        start = {k: float(f.params[k] or 0.0) for k in ('inertia', 'mgl', 'effort_offset',
                                                         'phi_offset', 'phi0', 'dphi0',
                                                         'gamma', 'n', 'friction')}
        ours = simulate_whole(f, rec)
        secs, rms, nfev = by_hand(law, start, rec, args.max_nfev)
        hand_total += secs
        word = ('equal' if abs(ours - rms) <= SAME * rms else
                'better' if ours < rms else 'WORSE')
        print(f'{law:14s} {took[law]:9.2f} {f.iterations:5d} {f.rms_residual:9.5f} '
              f'{ours:9.5f}   {secs:9.2f} {nfev:5d} {rms:9.5f}   {secs / took[law]:8.1f}  '
              f'{word}')
    ratio = hand_total / total
    print(f'total: compare {total:.2f} s, by hand {hand_total:.2f} s: {ratio:.1f}x (target >= '
          f'{TARGET_RATIO:g}x: {"meets" if ratio >= TARGET_RATIO else "misses"})')
    best = fits[0]
    validate(best, other)   # the first call of this process pays its imports
    began = time.perf_counter()
    v = validate(best, other)
    secs = time.perf_counter() - began
    print(f'validate {best.model} on another {args.seconds:g} s record: {secs:.2f} s (target <= '
          f'{TARGET_VALIDATE:g} s: {"meets" if secs <= TARGET_VALIDATE else "misses"}); fit '
          f'{v.fit_simulation:.1f} % simulated, {v.fit_prediction:.1f} % {v.k}-step predicted, '
          f'residuals {"white" if v.white else "not white"}, '
          f'{"independent of" if v.independent else "correlated with"} the effort')
    truth = {'inertia': 0.2002, 'mgl': 1.96, 'gamma': 0.5, 'n': 1.5, 'friction': 0.05,
             'effort_offset': BIAS}
    inside = []
    for k, value in truth.items():
        ci = best.ci95.get(k)
        if best.params.get(k) is not None and ci is not None:
            inside.append(f'{k} {best.params[k]:.4g} '
                          f'{"yes" if ci[0] <= value <= ci[1] else "no"}')
    print('best law, truth inside its 95 % interval: ' + ', '.join(inside))


if __name__ == '__main__':
    main()
