"""Benchmark the compiled steps (``jit=True``) against the generated Python steps, side by side.

Run: ``.venv/bin/python bench/bench_jit.py``. Needs numba (the ``jit`` extra). Prints, for every
adaptive method: the compile time of its two steps (plain and branch law), µs per step called
from Python for the generated and the compiled step and their ratio; then ``simulate`` of the
γ = 1000 creep (x0 = 2, 10 s, outputs every 0.1 s) at a tight tolerance both ways, with the
ratio and whether the two runs agree to the last bit. Asserts nothing.
"""
from __future__ import annotations

import functools
import os
import platform
import sys
import time
from collections.abc import Callable

import numpy as np

from pendulum_sim.core import METHODS, PendulumParams, simulate
from pendulum_sim.core.embedded import pair_steps
from pendulum_sim.core.jit import available
from pendulum_sim.core.simulate import Trajectory

ADAPTIVE = [name for name, m in METHODS.items() if m.kind == 'adaptive']
ARGS = (2.0, -0.1, 0.01, 0.0, 9.8, 1000.0, -1.0)  # (φ, φ', h, a_in, ω0², γ, s): the creep


def per_step(fn: Callable[..., object], calls: int, repeats: int = 5) -> float:
    """Return the best µs per call of ``fn(*ARGS)`` over the repeats."""
    best = float('inf')
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn(*ARGS)
        best = min(best, time.perf_counter() - t0)
    return best / calls * 1e6


def cpu_of(run: Callable[[], object], repeats: int = 3) -> float:
    """Return the best CPU time of ``run()`` in ms."""
    best = float('inf')
    for _ in range(repeats):
        t0 = time.process_time()
        run()
        best = min(best, time.process_time() - t0)
    return best * 1e3


def main() -> None:
    """Print the table."""
    if not available():
        sys.exit("bench_jit needs numba: pip install 'pendulum_sim[jit]'")
    import numba

    print(f'machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, '
          f'Python {platform.python_version()}, numba {numba.__version__}, load average '
          f'{os.getloadavg()[0]:.2f} at start')
    n = 2.0
    print(f'1. one embedded step (n = {n:g}, branch law, the γ = 1000 creep), µs per call')
    print(f'   {"method":<9} {"compile s":>9} {"python":>8} {"compiled":>9} {"ratio":>6}')
    for name in ADAPTIVE:
        tab = METHODS[name].tableau
        python = pair_steps(tab, n)[1]
        t0 = time.perf_counter()
        compiled = pair_steps(tab, n, jit=True)[1]
        compile_s = time.perf_counter() - t0
        py, jt = per_step(python, 20000), per_step(compiled, 20000)
        print(f'   {name:<9} {compile_s:9.2f} {py:8.2f} {jt:9.2f} {py / jt:6.1f}')
    print('2. simulate(γ = 1000, n = 2, x0 = 2, 10 s, h = 0.1 s), CPU ms (best of 3)')
    print(f'   {"method":<9} {"rtol":>6} {"python":>8} {"compiled":>9} {"ratio":>6}  same bits')
    p = PendulumParams(gamma=1000.0, n=n)
    for name in ADAPTIVE:
        for rtol in (1e-8, 1e-11):
            def run(jit: bool, name: str = name, rtol: float = rtol) -> Trajectory:
                return simulate(p, 2.0, 0.0, 10.0, 0.1, name, rtol=rtol, atol=rtol * 1e-2,
                                jit=jit)
            a, b = run(False), run(True)
            same = np.array_equal(a.state, b.state) and a.stats == b.stats
            py, jt = (cpu_of(functools.partial(run, jit)) for jit in (False, True))
            print(f'   {name:<9} {rtol:6.0e} {py:8.2f} {jt:9.2f} {py / jt:6.1f}  '
                  f'{"yes" if same else "NO"}')


if __name__ == '__main__':
    main()
