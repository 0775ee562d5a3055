"""Benchmark the sweep for real n: integer, n = 1.5 for all and all-distinct n, side by side.

Run: ``.venv/bin/python bench/bench_real_n.py`` (``--sizes``, ``--steps``, ``--repeats``,
``--jit``, ``--h``). Issue 30's cases: N pendulums (2000 and 20000 by default), ω0² = 9.8, γ
uniform in [0.1, 2], φ0 in [−2, 2] rad, φ'0 in [−3, 3] rad/s, τ/I = 0 (so the energy check runs),
h = 1 ms (``--h``), 500 steps; the exponents (a) integer n = 1..5 mixed, (b) n = 1.5 for all, (c)
n uniform in [1, 3], all distinct. For each, on the numpy path: ns per pendulum-step (the best of
``--repeats``, set-up included, as ``sweep`` is called), the ratios (b)/(a) and (c)/(b), and the
fraction of pendulum-steps that took the careful path (``SweepResult.batched``, taken by the one
careful step compiled over the refused pendulums, ``careful.careful_each``, plus ``handed_back``,
one by one in Python: for non-integer 0 < n < 3 the careful share is the steps within the grading
window 1/ω0 of a reversal, ``reversal.GRADE_WINDOW``, about half of all steps here, taken
compiled where numba and its disk cache serve; the first call of a process loads them, which the
best of ``--repeats`` leaves out). With ``--jit`` (numba, the ``jit``
extra) also the compiled sweep (after a first call that compiles) beside a bare compiled RK4 kernel
(``bench_sweep_jit.bare_rk4``: per exponent for integer n, the n = 1.5 kernel over all for distinct
n) over the same pendulums, and the first ``jit=True`` sweep of a fresh process twice on one new,
empty cache directory (``jit_cache.py``, ``PENDULUM_SIM_JIT_CACHE``): the first process compiles
(cache cold), the second loads what the first compiled (cache warm); timed in each process from
before its imports to the sweep's end (``--first`` prints these two alone).
Asserts nothing.
"""
from __future__ import annotations

import argparse
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from pendulum_sim.core.sweep import sweep

H = 1e-3


def population(size: int, case: str) -> dict[str, Any]:
    """Return the sweep's arguments for ``size`` pendulums of the exponent case ``case``."""
    rng = np.random.default_rng(0)
    gamma = rng.uniform(0.1, 2.0, size)
    p0 = rng.uniform(-2.0, 2.0, size)
    v0 = rng.uniform(-3.0, 3.0, size)
    n = {'integer n = 1..5': rng.integers(1, 6, size).astype(float),
         'n = 1.5 for all': np.full(size, 1.5),
         'distinct n in [1, 3]': rng.uniform(1.0, 3.0, size)}[case]
    return {'omega0_sq': 9.8, 'gamma': gamma, 'n': n, 'phi0': p0, 'dphi0': v0}


CASES = ('integer n = 1..5', 'n = 1.5 for all', 'distinct n in [1, 3]')


def timed(args: dict[str, Any], steps: int, repeats: int, jit: bool) -> tuple[float, Any]:
    """Return the best seconds of ``repeats`` sweeps and the last result."""
    best = math.inf
    res = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = sweep(**args, t_end=steps * H, h=H, jit=jit)
        best = min(best, time.perf_counter() - t0)
    return best, res


def first_jit_fresh(size: int, cache: str) -> str:
    """Return the first ``jit=True`` sweep of a fresh process on ``cache``, timed in it."""
    code = ('import time; t0 = time.perf_counter(); import sys; sys.path.insert(0, "bench");'
            'from bench_real_n import population; from pendulum_sim.core.sweep import sweep;'
            f'sweep(**population({size}, "distinct n in [1, 3]"), t_end=0.01, h=1e-3, jit=True);'
            'print(f"{time.perf_counter() - t0:.1f}")')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         check=True, cwd=Path(__file__).resolve().parent.parent,
                         env=dict(os.environ, PENDULUM_SIM_JIT_CACHE=cache))
    return out.stdout.strip()


def first_jit_figures(size: int) -> None:
    """Print the first ``jit=True`` sweep of a fresh process, cache cold, then cache warm."""
    with tempfile.TemporaryDirectory() as cache:
        print(f'first jit=True sweep of a fresh process, cache cold (distinct n, N = {size}): '
              f'{first_jit_fresh(size, cache)} s', flush=True)
        print(f'first jit=True sweep of a second process, cache warm (distinct n, N = {size}): '
              f'{first_jit_fresh(size, cache)} s', flush=True)


def main() -> int:
    global H
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--sizes', type=int, nargs='+', default=[2000, 20000])
    parser.add_argument('--steps', type=int, default=500)
    parser.add_argument('--repeats', type=int, default=2)
    parser.add_argument('--jit', action='store_true')
    parser.add_argument('--h', type=float, default=H, help='the step in s (default 1 ms)')
    parser.add_argument('--first', action='store_true',
                        help='print the first jit=True sweeps of fresh processes alone')
    args = parser.parse_args()
    H = args.h
    if args.first:
        first_jit_figures(2000)
        return 0
    print(f'# sweep, h = {H * 1e3:g} ms, {args.steps} steps, tau = 0, '
          f'{platform.processor() or platform.machine()}, {os.cpu_count()} cores', flush=True)
    for size in args.sizes:
        per: dict[str, float] = {}
        for case in CASES:
            pop = population(size, case)
            sec, res = timed(pop, args.steps, args.repeats, False)
            per[case] = sec / (size * args.steps) * 1e9
            steps = size * args.steps
            print(f'N = {size:6d} {case:22s} numpy   : {per[case]:8.0f} ns per pendulum-step, '
                  f'careful path {(res.batched + res.handed_back) / steps:6.1%} of steps '
                  f'(compiled {res.batched / steps:6.2%}, in Python '
                  f'{res.handed_back / steps:6.2%})', flush=True)
        print(f'N = {size:6d} numpy: n = 1.5 / integer = {per[CASES[1]] / per[CASES[0]]:.2f}, '
              f'distinct / n = 1.5 = {per[CASES[2]] / per[CASES[1]]:.2f}', flush=True)
        if args.jit:
            sys.path.insert(0, str(Path(__file__).resolve().parent))
            from bench_sweep_jit import bare_rk4

            for case in CASES:
                pop = population(size, case)
                sweep(**pop, t_end=H, h=H, jit=True)  # compiles
                sec, res = timed(pop, args.steps, args.repeats, True)
                comp = sec / (size * args.steps) * 1e9
                # The bare kernel per exponent; for distinct n the n = 1.5 one over all (the
                # same power call a step: its cost does not depend on the exponent's value).
                nn = pop['n'] if case == CASES[0] else np.full(size, 1.5)
                order = np.argsort(nn, kind='stable')
                kernels = bare_rk4(sorted(set(nn.tolist())))
                vals, starts = np.unique(nn[order], return_index=True)
                ends = [*starts[1:].tolist(), size]

                def bare(count: int, pop: dict[str, Any] = pop, order: Any = order,
                         kernels: Any = kernels, vals: Any = vals, starts: Any = starts,
                         ends: list[int] = ends) -> None:
                    P, V = pop['phi0'][order].copy(), pop['dphi0'][order].copy()
                    G = pop['gamma'][order]
                    for val, a, b in zip(vals.tolist(), starts.tolist(), ends, strict=True):
                        kernels[val](P[a:b], V[a:b], H, 9.8, G[a:b], val, count)

                bare(1)  # compiles
                best = math.inf
                for _ in range(args.repeats):
                    t0 = time.perf_counter()
                    bare(args.steps)
                    best = min(best, time.perf_counter() - t0)
                ref = best / (size * args.steps) * 1e9
                print(f'N = {size:6d} {case:22s} compiled: {comp:8.0f} ns per pendulum-step, '
                      f'bare compiled RK4 {ref:6.0f} ns, ratio {comp / ref:.2f}, handed back '
                      f'{res.handed_back}', flush=True)
    if args.jit:
        first_jit_figures(2000)
    return 0


if __name__ == '__main__':
    sys.exit(main())
