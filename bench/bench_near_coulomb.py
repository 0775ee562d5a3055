"""Benchmark near-Coulomb damping against Coulomb friction, per step, Stepper and sweep.

Run: ``.venv/bin/python bench/bench_near_coulomb.py``. Prints a table; asserts nothing.

The case: the paper's pendulum (ω0² = 9.8 s⁻²), γ = 100, from rest at 0.3 rad, h = 1 ms, RK4
with the guard: n = 0 (Coulomb: it sticks) beside n = 0.001 and n = 0.01 (it creeps at the
closed-form speed (|F|/γ)^(1/n)), and n = 0.3. ``Stepper.step()`` in µs per step, and ``sweep``
of 1000 such pendulums in µs per pendulum-step, numpy and, where numba is installed, compiled
(``jit=True``, after a first call that compiles it), each with its ratio to n = 0. Every
figure is the best of five repeats (wall clock, ``time.perf_counter``); the machine and its
load average are printed with them.
"""
from __future__ import annotations

import os
import time

from pendulum_sim.core import PendulumParams, Stepper
from pendulum_sim.core.jit import available
from pendulum_sim.core.sweep import sweep
from pendulum_sim.reports.report import machine_info

W2, GAMMA, PHI0, H = 9.8, 100.0, 0.3, 1e-3
STEPS = 2000
SWEEP_N, SWEEP_STEPS = 1000, 200


def stepper_us(n: float) -> float:
    """Return the best time of one ``Stepper.step()`` in µs."""
    best = float('inf')
    for _ in range(5):
        st = Stepper(PendulumParams.from_omega0_sq(W2, GAMMA, n), PHI0, 0.0, H)
        t0 = time.perf_counter()
        for _ in range(STEPS):
            st.step()
        best = min(best, (time.perf_counter() - t0) / STEPS)
    return best * 1e6


def sweep_us(n: float, jit: bool = False) -> float:
    """Return the best time of a sweep of SWEEP_N such pendulums, in µs per pendulum-step."""
    best = float('inf')
    if jit:
        sweep(W2, GAMMA, n, PHI0, 0.0, H, H, jit=True)  # compile outside the timing
    for _ in range(5):
        t0 = time.perf_counter()
        sweep(W2, GAMMA, n, [PHI0] * SWEEP_N, 0.0, SWEEP_STEPS * H, H, jit=jit)
        best = min(best, (time.perf_counter() - t0) / (SWEEP_N * SWEEP_STEPS))
    return best * 1e6


def main() -> int:
    """Print the table."""
    print(f'machine: {machine_info()}; load average {os.getloadavg()[0]:.2f}')
    print(f'gamma = {GAMMA:g}, from rest at {PHI0} rad, h = {H:g} s, rk4 with the guard')
    jit = available()
    print(f'{"n":>6} {"Stepper us/step":>16} {"x n=0":>7} {"sweep us/pend-step":>19} '
          f'{"x n=0":>7}' + (f' {"jit sweep us/pend-step":>23} {"x n=0":>7}' if jit else ''))
    base_st = base_sw = base_jit = 0.0
    for n in (0.0, 0.001, 0.01, 0.3):
        st, sw = stepper_us(n), sweep_us(n)
        sj = sweep_us(n, jit=True) if jit else 0.0
        if n == 0.0:
            base_st, base_sw, base_jit = st, sw, sj
        line = f'{n:>6g} {st:>16.2f} {st / base_st:>7.2f} {sw:>19.3f} {sw / base_sw:>7.2f}'
        if jit:
            line += f' {sj:>23.4f} {sj / base_jit:>7.2f}'
        print(line)
    if not jit:
        print('numba is not installed: no compiled sweep (the jit extra)')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
