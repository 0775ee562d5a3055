"""Benchmark the sweep's careful path: numpy (Engine.careful in Python) and compiled.

Run: ``.venv/bin/python bench/bench_sweep_careful.py`` (``--size``, ``--steps``). Needs numba (the
``jit`` extra). Four populations of N pendulums (2000 by default) whose steps the fast path
refuses, each the careful path's own work: a stiff viscous γ = 10⁴ (n = 1, h = 20 ms: every step
the L-stable fallback), a quadratic γ = 10³ from rest (n = 2, h = 20 ms: the guard's substeps and
reversal splits), Euler with a small γ (n = 2, γ = 10⁻³, h = 50 ms: energy redos and projections)
and damping-dominated transients (n = 2.5, γ = 10, h = 20 ms, from 20-40 rad/s: the
error-controlled DOP853 substeps of ``stiff.stiff_cover`` until the transient has decayed, then the
fast path). For each: the first compiled call (it compiles), then ns per pendulum-step of a
prepared ``Sweep`` advanced ``--steps`` steps with numpy and compiled (the best of ``--repeats``),
their ratio, the steps handed back to ``Engine.careful`` and what the careful path counted. Asserts
nothing.
"""
from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time

import numpy as np

from pendulum_sim.core.jit import available
from pendulum_sim.core.sweep import Sweep

# (name, method, γ, n, h, φ0 range, φ'0 range)
POPULATIONS = [
    ('fallback: n = 1, gamma = 1e4, rk4', 'rk4', 1e4, 1.0, 2e-2, (0.5, 1.5), (2.0, 4.0)),
    ('substeps: n = 2, gamma = 1e3, rk4', 'rk4', 1e3, 2.0, 2e-2, (1.5, 2.5), (0.0, 0.0)),
    ('energy redo: n = 2, gamma = 1e-3, euler', 'euler', 1e-3, 2.0, 5e-2, (0.3, 3.0),
     (0.0, 5.0)),
    ('stiff transient: n = 2.5, gamma = 10, rk4', 'rk4', 10.0, 2.5, 2e-2, (0.5, 1.5),
     (20.0, 40.0)),
]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--size', type=int, default=2000)
    parser.add_argument('--steps', type=int, default=40)
    parser.add_argument('--repeats', type=int, default=3)
    args = parser.parse_args()
    if not available():
        print('numba is not installed: pip install the jit extra')
        return 1
    size, steps = args.size, args.steps
    print(f'# careful path per pendulum-step: N = {size}, {steps} steps, '
          f'{platform.processor() or platform.machine()}, {os.cpu_count()} cores', flush=True)
    rng = np.random.default_rng(0)
    for name, method, gamma, n, h, prange, vrange in POPULATIONS:
        p0 = rng.uniform(*prange, size)
        v0 = rng.uniform(*vrange, size)
        per: dict[str, float] = {}
        for label, jit in (('numpy', False), ('compiled', True)):
            t0 = time.perf_counter()
            Sweep(9.8, gamma, n, p0[:2], v0[:2], h, method=method, jit=jit).advance(h)
            first = time.perf_counter() - t0
            out = math.inf
            for _ in range(args.repeats):
                sw = Sweep(9.8, gamma, n, p0, v0, h, method=method, jit=jit)
                t0 = time.perf_counter()
                res = sw.advance(steps * h)
                out = min(out, time.perf_counter() - t0)
            per[label] = out / (size * steps) * 1e9
            counted = {k: int(getattr(res, k).sum()) for k in
                       ('substeps', 'fallbacks', 'reversals', 'energy_rejections',
                        'projections')}
            print(f'{name:42s} {label:8s}: first call {first:6.2f} s, '
                  f'{per[label]:10.0f} ns per pendulum-step, handed back {res.handed_back:7d}, '
                  f'{counted}', flush=True)
        print(f'{name:42s} numpy / compiled: {per["numpy"] / per["compiled"]:.0f}x', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
