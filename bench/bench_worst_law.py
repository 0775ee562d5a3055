"""Benchmark the Stepper's cost per step over the laws the joint accepts, worst cases first.

Run: ``.venv/bin/python bench/bench_worst_law.py [--quick]``. Prints a table; asserts nothing.

The joint steps one ``Stepper`` at h = 1 ms (its default, the node's 1 kHz). Its cost per step
depends on the law: the guard's substeps, reversals split in the step, Coulomb rest, stiff
transients. The grid: n in {0, 0.001, 0.01, 0.05, 0.1, 0.2, 0.3, 0.5, 1, 1.5, 2, 3, 5}, γ in
{0.1, 1, 10, 100}, a Coulomb friction of 0 or 0.05 N m (f/I = 0.25 rad/s², the paper's body:
m = 0.2 kg, l = 1 m, I = 0.2 kg m², g = 9.8), each from three starts: at rest off the bottom
(0.3 rad, it creeps or sticks), moving (0.3 rad, 1 rad/s: it reverses), and kicked (0.3 rad,
30 rad/s: a stiff transient for n > 1). Each case runs 2 s (2000 steps) after a warm-up step;
its figure is the best of three repeats of the mean CPU time per step (``time.process_time``),
and the slowest single step of the best repeat. The budget: 250 µs a step, a quarter of a core
at 1 kHz. The table lists every case over the budget and the ten slowest, then the median.
"""
from __future__ import annotations

import argparse
import itertools
import statistics
import time

from pendulum_sim.core import PendulumParams, Stepper
from pendulum_sim.reports.report import machine_info

H = 1e-3
BUDGET_US = 250.0
EXPONENTS = (0.0, 0.001, 0.01, 0.05, 0.1, 0.2, 0.3, 0.5, 1.0, 1.5, 2.0, 3.0, 5.0)
GAMMAS = (0.1, 1.0, 10.0, 100.0)
FRICTIONS = (0.0, 0.05)
STARTS = {'rest': (0.3, 0.0), 'moving': (0.3, 1.0), 'kicked': (0.3, 30.0)}


def case_us(n: float, gamma: float, friction: float, phi0: float, dphi0: float, steps: int
            ) -> tuple[float, float]:
    """Return (best mean µs per step, slowest step of that repeat in µs)."""
    params = PendulumParams(m=0.2, l=1.0, inertia=0.2, g=9.8, gamma=gamma, n=n,
                            friction=friction)
    best, worst = float('inf'), float('inf')
    for _ in range(3):
        st = Stepper(params, phi0, dphi0, H)
        st.step()
        slowest = 0.0
        t0 = time.process_time()
        for _ in range(steps):
            s0 = time.process_time()
            st.step()
            slowest = max(slowest, time.process_time() - s0)
        mean = (time.process_time() - t0) / steps
        if mean < best:
            best, worst = mean, slowest
    return best * 1e6, worst * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='200 steps a case instead of 2000')
    args = parser.parse_args()
    steps = 200 if args.quick else 2000
    print(machine_info())
    print(f'Stepper at h = {H * 1e3:g} ms, {steps} steps a case, budget {BUDGET_US:g} us/step')
    rows = []
    for n, gamma, friction, (start, (phi0, dphi0)) in itertools.product(
            EXPONENTS, GAMMAS, FRICTIONS, STARTS.items()):
        mean, slowest = case_us(n, gamma, friction, phi0, dphi0, steps)
        rows.append((mean, slowest, n, gamma, friction, start))
    rows.sort(reverse=True)
    header = f'{"n":>6} {"gamma":>6} {"f (N m)":>8} {"start":>7} {"us/step":>9} {"slowest":>9}'
    over = [r for r in rows if r[0] > BUDGET_US]
    print(f'\n{len(rows)} cases; {len(over)} over the budget of {BUDGET_US:g} us/step')
    print('\nslowest ten:')
    print(header)
    for mean, slowest, n, gamma, friction, start in rows[:10]:
        flag = '  over' if mean > BUDGET_US else ''
        print(f'{n:>6g} {gamma:>6g} {friction:>8g} {start:>7} {mean:>9.1f} {slowest:>9.1f}'
              f'{flag}')
    print(f'\nmedian {statistics.median(r[0] for r in rows):.1f} us/step; worst '
          f'{rows[0][0]:.1f} us/step (n = {rows[0][2]:g}, gamma = {rows[0][3]:g}, '
          f'friction = {rows[0][4]:g} N m, {rows[0][5]})')


if __name__ == '__main__':
    main()
