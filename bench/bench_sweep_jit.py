"""Benchmark the sweep per pendulum-step: numpy, compiled (``jit=True``) and a bare RK4 kernel.

Run: ``.venv/bin/python bench/bench_sweep_jit.py`` (``--size``, ``--steps``). Needs numba (the
``jit`` extra). N pendulums (10^5 by default) with mixed n = 1..5, γ from 0.05 to 1, ω0² = 9.8,
random states, h = 1 ms, τ/I = 0 (so the energy check runs as well): a prepared ``Sweep``
advanced ``--steps`` steps with numpy and compiled, after a warm-up that compiles; beside them
a bare compiled RK4 kernel (one loop over the pendulums, the law γ v|v|^(n−1) with a power, no
guard, no decisions) over the same arrays in the same run, the three in turn for ``--repeats``
rounds. Prints ns per pendulum-step (the best of each) and the ratios. Asserts nothing.
"""
from __future__ import annotations

import argparse
import functools
import math
import os
import platform
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from pendulum_sim.core.jit import available
from pendulum_sim.core.sweep import Sweep


def bare_rk4() -> Callable[..., None]:
    """Return a plain compiled RK4 loop: ``kernel(p, v, h, w2, gamma, n, steps)`` in place."""
    import numba

    def law(p: float, v: float, w2: float, gamma: float, n: float) -> float:
        return -math.copysign(gamma * abs(v) ** n, v) - w2 * math.sin(p)

    acc: Any = numba.njit(law)

    @numba.njit
    def kernel(p: np.ndarray, v: np.ndarray, h: float, w2: float, gamma: np.ndarray,
               n: np.ndarray, steps: int) -> None:
        for i in range(p.shape[0]):
            x, y, g, k = p[i], v[i], gamma[i], n[i]
            for _ in range(steps):
                a1 = acc(x, y, w2, g, k)
                x2, y2 = x + 0.5 * h * y, y + 0.5 * h * a1
                a2 = acc(x2, y2, w2, g, k)
                x3, y3 = x + 0.5 * h * y2, y + 0.5 * h * a2
                a3 = acc(x3, y3, w2, g, k)
                x4, y4 = x + h * y3, y + h * a3
                a4 = acc(x4, y4, w2, g, k)
                x = x + h / 6.0 * (y + 2.0 * y2 + 2.0 * y3 + y4)
                y = y + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
            p[i], v[i] = x, y

    return kernel  # type: ignore[no-any-return]


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
    args = parser.parse_args()
    if not available():
        print('numba is not installed: pip install the jit extra')
        return 1
    rng = np.random.default_rng(0)
    size, steps, h, w2 = args.size, args.steps, 1e-3, 9.8
    n = rng.choice([1.0, 2.0, 3.0, 4.0, 5.0], size)
    gamma = rng.uniform(0.05, 1.0, size)
    p0, v0 = rng.uniform(-2.5, 2.5, size), rng.uniform(-3.0, 3.0, size)
    print(f'# sweep per pendulum-step: N = {size}, n = 1..5 mixed, {steps} steps of h = 1 ms, '
          f'{platform.processor() or platform.machine()}, {os.cpu_count()} cores', flush=True)
    runs: dict[str, Callable[[], object]] = {}
    for name, jit in (('numpy', False), ('compiled', True)):
        t0 = time.perf_counter()
        sw = Sweep(w2, gamma, n, p0, v0, h, jit=jit)
        sw.advance(h)                                       # warm-up (compiles with jit)
        print(f'sweep, {name:8s}: set-up and first step {time.perf_counter() - t0:.2f} s',
              flush=True)
        runs[f'sweep, {name}'] = functools.partial(sw.advance, steps * h)
    kernel = bare_rk4()
    p, v = p0.copy(), v0.copy()
    kernel(p, v, h, w2, gamma, n, 1)                        # compiles
    runs['bare compiled RK4'] = lambda: kernel(p, v, h, w2, gamma, n, steps)
    # In turn, round after round, the best of each: on a shared machine the load moves.
    times = dict.fromkeys(runs, math.inf)
    for _ in range(args.repeats):
        for name, run in runs.items():
            times[name] = min(times[name], best(run, 1))
    figures = {}
    for name, sec in times.items():
        figures[name] = sec / (size * steps) * 1e9
        print(f'{name:17s}: {figures[name]:7.1f} ns per pendulum-step', flush=True)
    figures['numpy'] = figures['sweep, numpy']
    figures['compiled'] = figures['sweep, compiled']
    figures['bare'] = figures['bare compiled RK4']
    print(f'compiled sweep / bare kernel = {figures["compiled"] / figures["bare"]:.2f}; '
          f'numpy / compiled sweep = {figures["numpy"] / figures["compiled"]:.2f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
