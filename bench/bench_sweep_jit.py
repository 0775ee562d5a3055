"""Benchmark the sweep per pendulum-step: numpy, compiled (``jit=True``) and a bare RK4 kernel.

Run: ``.venv/bin/python bench/bench_sweep_jit.py`` (``--size``, ``--steps``). Needs numba (the
``jit`` extra). N pendulums (10^5 by default) with mixed n = 1..5, γ from 0.05 to 1, ω0² = 9.8,
random states, h = 1 ms, τ/I = 0 (so the energy check runs as well): a prepared ``Sweep``
advanced ``--steps`` steps with numpy and compiled, after a warm-up that compiles; beside them
a fair bare compiled RK4 kernel (:func:`bare_rk4`: the pendulums sorted by n, one loop per
exponent with the law as ``explicit.damping_expression`` spells it, integer n as
multiplications, the state in registers over the steps, in parallel over the pendulums as the
compiled sweep runs; no guard, no decisions) over the same pendulums in the same run, the
three in turn for ``--repeats`` rounds. Prints ns per pendulum-step (the best of each), the
ratios, and the compiled sweep's ratio to the bare kernel round by round (median and range).
The compiled sweep's "set-up and first step" is its first use in the process: it compiles the
careful path once and a run per law text (5 texts); ``--first-mix`` (default n = 0, 0.3, 0.5,
1, 1.5, 2, 2.5, 3, 4, 5: 10 texts) times the same first use in a fresh process for that mix
(``--first-use``, the figure alone). Then (``--distinct``, issue 20) a sweep of 2000
pendulums with as many distinct non-integer n from 0.2 to 5: its set-up, how many source texts
that compiled, and its time a step, numpy and compiled. Asserts nothing.
"""
from __future__ import annotations

import argparse
import functools
import math
import os
import platform
import subprocess
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from pendulum_sim.core import codegen
from pendulum_sim.core import jit as core_jit
from pendulum_sim.core.jit import available
from pendulum_sim.core.law import damping_expression
from pendulum_sim.core.sweep import Sweep

BARE_SRC = """\
def kernel(P, V, h, w2, GAMMA, n, steps):
    for i in prange(P.shape[0]):
        x = P[i]
        y = V[i]
        gamma = GAMMA[i]
        for _ in range(steps):
            v = y
            a1 = -({law}) - w2 * sin(x)
            x2 = x + 0.5 * h * y
            v = y + 0.5 * h * a1
            y2 = v
            a2 = -({law}) - w2 * sin(x2)
            x3 = x + 0.5 * h * y2
            v = y + 0.5 * h * a2
            y3 = v
            a3 = -({law}) - w2 * sin(x3)
            x4 = x + h * y3
            v = y + h * a3
            y4 = v
            a4 = -({law}) - w2 * sin(x4)
            x = x + h / 6.0 * (y + 2.0 * y2 + 2.0 * y3 + y4)
            y = y + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
        P[i] = x
        V[i] = y
"""


def bare_rk4(n_values: list[float]) -> dict[float, Callable[..., None]]:
    """Return a fair bare compiled RK4 run per exponent: ``kernel(P, V, h, w2, GAMMA, n, k)``.

    What a competent engineer writes for this batch: the pendulums sorted by n, one loop per
    exponent with the law ``explicit.damping_expression`` spells (integer n as
    multiplications, no power), the state in registers over the steps, in parallel over the
    pendulums (``prange``), no fast-math; no guard, no decisions, no recording.
    """
    import numba

    out: dict[float, Callable[..., None]] = {}
    for n in n_values:
        env: dict[str, Any] = {'sin': math.sin, 'copysign': math.copysign, 'sqrt': math.sqrt,
                               'prange': numba.prange}
        law = damping_expression(n, scalar=True)
        assert 'sign(' not in law.replace('copysign(', ''), law  # n = 0 is not benchmarked
        exec(compile(BARE_SRC.format(law=law), f'<bare n={n}>', 'exec'), env)
        out[n] = numba.njit(parallel=True)(env['kernel'])
    return out


def distinct(count: int, steps: int) -> None:
    """Print the set-up and the time a step of a sweep of ``count`` distinct exponents."""
    rng = np.random.default_rng(20)
    n = rng.uniform(0.2, 5.0, count)
    gamma, p0, v0 = rng.uniform(0.05, 1.0, count), rng.uniform(-2, 2, count), rng.uniform(
        -3, 3, count)
    print(f'# {count} pendulums with distinct n in [0.2, 5], gamma in [0.05, 1], h = 1 ms')
    for name, jit in (('numpy', False), ('compiled', True)):
        texts = codegen._code.cache_info().misses
        t0 = time.perf_counter()
        sw = Sweep(9.8, gamma, n, p0, v0, 1e-3, jit=jit)
        setup = time.perf_counter() - t0
        texts = codegen._code.cache_info().misses - texts
        t0 = time.perf_counter()
        sw.advance(1e-3)                                    # compiles with jit
        first = time.perf_counter() - t0
        per = best(functools.partial(sw.advance, steps * 1e-3), 3) / steps
        print(f'{name:8s}: set-up {setup:.2f} s ({texts} new source texts), first step '
              f'{first:.2f} s, then {per * 1e3:.2f} ms a step', flush=True)


TEN_TEXTS = '0,0.3,0.5,1,1.5,2,2.5,3,4,5'
"""The 10-text mix of ``--first-mix``: each exponent a law text of its own."""


def first_use(size: int, mix: list[float]) -> tuple[float, int]:
    """Return the first compiled sweep's set-up and first step (s) and the law texts it ran.

    ``size`` pendulums with n drawn from ``mix``, as the main benchmark draws them.
    """
    rng = np.random.default_rng(0)
    n = rng.choice(mix, size)
    gamma = rng.uniform(0.05, 1.0, size)
    p0, v0 = rng.uniform(-2.5, 2.5, size), rng.uniform(-3.0, 3.0, size)
    kernels = len(core_jit._KERNELS)
    t0 = time.perf_counter()
    Sweep(9.8, gamma, n, p0, v0, 1e-3, jit=True).advance(1e-3)
    return time.perf_counter() - t0, len(core_jit._KERNELS) - kernels


def first_use_fresh(size: int, mix: str) -> str:
    """Return ``--first-use`` run in a fresh process (nothing compiled yet): its printed line."""
    out = subprocess.run([sys.executable, __file__, '--size', str(size), '--first-use', mix],
                         check=True, capture_output=True, text=True)
    return out.stdout.strip()


def best(run: Callable[[], object], repeats: int) -> float:
    """Return the best wall time of ``run()`` over the repeats, in s."""
    out = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        run()
        out = min(out, time.perf_counter() - t0)
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--size', type=int, default=100_000)
    parser.add_argument('--steps', type=int, default=20)
    parser.add_argument('--repeats', type=int, default=5)
    parser.add_argument('--distinct', type=int, default=2000)
    parser.add_argument('--first-mix', default=TEN_TEXTS,
                        help='exponents of a first use timed in a fresh process ("" for none)')
    parser.add_argument('--first-use', default='',
                        help='time only the first compiled sweep of this mix of exponents')
    args = parser.parse_args()
    if not available():
        print('numba is not installed: pip install the jit extra')
        return 1
    if args.first_use:
        sec, texts = first_use(args.size, [float(x) for x in args.first_use.split(',')])
        print(f'sweep, compiled: set-up and first step {sec:.2f} s (n = {args.first_use}: '
              f'{texts} law texts, fresh process)', flush=True)
        return 0
    if args.first_mix:
        print(first_use_fresh(args.size, args.first_mix), flush=True)
    rng = np.random.default_rng(0)
    size, steps, h, w2 = args.size, args.steps, 1e-3, 9.8
    n = rng.choice([1.0, 2.0, 3.0, 4.0, 5.0], size)
    gamma = rng.uniform(0.05, 1.0, size)
    p0, v0 = rng.uniform(-2.5, 2.5, size), rng.uniform(-3.0, 3.0, size)
    print(f'# sweep per pendulum-step: N = {size}, n = 1..5 mixed, {steps} steps of h = 1 ms, '
          f'{platform.processor() or platform.machine()}, {os.cpu_count()} cores', flush=True)
    runs: dict[str, Callable[[], object]] = {}
    for name, compiled in (('numpy', False), ('compiled', True)):
        kernels = len(core_jit._KERNELS)
        t0 = time.perf_counter()
        sw = Sweep(w2, gamma, n, p0, v0, h, jit=compiled)
        sw.advance(h)                                       # warm-up (compiles with jit)
        texts = f' (n = 1..5: {len(core_jit._KERNELS) - kernels} law texts)' if compiled else ''
        print(f'sweep, {name:8s}: set-up and first step {time.perf_counter() - t0:.2f} s'
              f'{texts}', flush=True)
        sw.advance(steps * h)  # a run as timed: compiles what its refused steps call too
        runs[f'sweep, {name}'] = functools.partial(sw.advance, steps * h)
    order = np.argsort(n, kind='stable')
    ns, gs = n[order], gamma[order]
    p, v = p0[order].copy(), v0[order].copy()
    kernels = bare_rk4(sorted(set(ns.tolist())))
    cuts = [(k, np.flatnonzero(ns == k)) for k in kernels]
    pieces = [(kernels[k], slice(int(ix[0]), int(ix[-1]) + 1)) for k, ix in cuts]

    def bare(count: int) -> None:
        for kern, sl in pieces:
            kern(p[sl], v[sl], h, w2, gs[sl], float(ns[sl.start]), count)

    bare(1)                                                 # compiles
    runs['bare compiled RK4'] = functools.partial(bare, steps)
    # In turn, round after round, the best of each: on a shared machine the load moves. The
    # ratio of the compiled sweep to the bare kernel is also taken round by round (the two
    # measured a moment apart), its median and range printed: it moves less than either.
    times = dict.fromkeys(runs, math.inf)
    rounds: list[float] = []
    for _ in range(args.repeats):
        this = {name: best(run, 1) for name, run in runs.items()}
        for name, sec in this.items():
            times[name] = min(times[name], sec)
        rounds.append(this['sweep, compiled'] / this['bare compiled RK4'])
    figures = {}
    for name, sec in times.items():
        figures[name] = sec / (size * steps) * 1e9
        print(f'{name:17s}: {figures[name]:7.1f} ns per pendulum-step', flush=True)
    figures['numpy'] = figures['sweep, numpy']
    figures['compiled'] = figures['sweep, compiled']
    figures['bare'] = figures['bare compiled RK4']
    print(f'compiled sweep / bare kernel = {figures["compiled"] / figures["bare"]:.2f}; '
          f'numpy / compiled sweep = {figures["numpy"] / figures["compiled"]:.2f}')
    print(f'compiled sweep / bare kernel round by round: median {np.median(rounds):.2f} '
          f'(from {min(rounds):.2f} to {max(rounds):.2f}, {len(rounds)} rounds)')
    if args.distinct:
        distinct(args.distinct, 10)
    return 0


if __name__ == '__main__':
    sys.exit(main())
