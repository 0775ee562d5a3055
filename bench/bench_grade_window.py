"""Measure what the grading window at reversals costs and buys: error and time against its size.

Run: ``.venv/bin/python bench/bench_grade_window.py`` (``--quick`` for fewer cases). Prints two
tables; asserts nothing. The window is ``reversal.GRADE_WINDOW`` in units of 1/ω0 (1 today):
for a non-integer n < 3 the steps within it of a velocity reversal are taken as graded
substeps (``reversal.graded_mesh``), which keeps RK4's order but costs about
(5/(n+1) − 1) S/h extra substeps per side of each reversal. The script sets the constant
for each row (the package reads it when a problem is made) and measures:

(a) accuracy, RK4 through reversals: the paper's start (x0 = 2 rad, φ'0 = 0, ω0² = 9.8 s⁻²),
    6 s (5 reversals), for n = 0.5, 1.5, 2.5 and γ = 0.2, 1; the error of the final state
    (hypot of φ and φ' errors) at h = 1 ms against the independent reference
    (``reports.reference``: scipy's DOP853 restarted at every reversal, its own error printed),
    the order fitted over h = 10, 5, 2.5 ms, and the Stepper's CPU time at h = 1 ms, each
    beside the window 1 row as a ratio;
(b) speed, the numpy sweep of ``bench_real_n``'s population (N = 2000, γ in [0.1, 2], random
    starts, n = 1.5 for all, h = 1 ms): ns per pendulum-step (process CPU time, best of
    ``--repeats``) and the share of pendulum-steps the careful path took.

Issue 30 reads these: a smaller window is the lever on the numpy and compiled speed of real n,
at the price in error that (a) shows; the figures decide whether a window that depends on the
state at a reversal is worth its numerics change.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

import pendulum_sim.core.reversal as reversal
from pendulum_sim.core import PendulumParams, simulate
from pendulum_sim.core.sweep import sweep
from pendulum_sim.reports.reference import reference

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_real_n import population

WINDOWS = (1.0, 0.5, 0.25, 0.1)
T_END = 6.0
HS = (0.01, 0.005, 0.0025)


def final_error(params: PendulumParams, h: float, ref_phi: float, ref_dphi: float) -> float:
    """Return the final-state error of RK4 at h against the reference's final state."""
    r = simulate(params, 2.0, 0.0, T_END, h)
    return float(math.hypot(r.phi[-1] - ref_phi, r.dphi[-1] - ref_dphi))


def accuracy_rows(exponents: tuple[float, ...], gammas: tuple[float, ...]) -> None:
    """Print (a): error, order and Stepper time against the window."""
    print('(a) RK4 through 5 reversals (x0 = 2 rad, 6 s): final-state error at h = 1 ms, '
          'order fitted over h = 10, 5, 2.5 ms, Stepper CPU at h = 1 ms')
    print(f'{"n":>4} {"gamma":>5} {"ref err":>8} ' + ' '.join(
        f'{"W=" + str(w):>30}' for w in WINDOWS))
    for n in exponents:
        for gamma in gammas:
            params = PendulumParams(gamma=gamma, n=n)
            ref = reference(params, 2.0, 0.0, np.array([0.0, T_END]))
            assert ref is not None
            cells = []
            base_err = base_cpu = math.nan
            for w in WINDOWS:
                reversal.GRADE_WINDOW = w
                t0 = time.process_time()
                err = final_error(params, 1e-3, ref.phi[-1], ref.dphi[-1])
                cpu = time.process_time() - t0
                errs = [final_error(params, h, ref.phi[-1], ref.dphi[-1]) for h in HS]
                order = float(np.polyfit(np.log(HS), np.log(errs), 1)[0])
                if w == WINDOWS[0]:
                    base_err, base_cpu = err, cpu
                cells.append(f'{err:8.1e} x{err / base_err:4.2f} p {order:4.2f} '
                             f'cpu x{cpu / base_cpu:4.2f}')
            print(f'{n:4.1f} {gamma:5.1f} {ref.disagreement:8.1e} '
                  + ' '.join(f'{c:>30}' for c in cells), flush=True)
    reversal.GRADE_WINDOW = 1.0


def speed_rows(size: int, steps: int, repeats: int) -> None:
    """Print (b): the numpy sweep's cost and careful share against the window."""
    print(f'(b) numpy sweep, N = {size}, n = 1.5 for all, {steps} steps of 1 ms: ns per '
          'pendulum-step (CPU, best of repeats), careful share of pendulum-steps')
    pop = population(size, 'n = 1.5 for all')
    base = math.nan
    for w in WINDOWS:
        reversal.GRADE_WINDOW = w
        best = math.inf
        res = None
        for _ in range(repeats):
            t0 = time.process_time()
            res = sweep(**pop, t_end=steps * 1e-3, h=1e-3)
            best = min(best, time.process_time() - t0)
        assert res is not None
        per = best / (size * steps) * 1e9
        if w == WINDOWS[0]:
            base = per
        share = (res.batched + res.handed_back) / (size * steps)
        print(f'W = {w:4}: {per:7.0f} ns per pendulum-step (x{per / base:4.2f}), careful '
              f'{share:6.1%}', flush=True)
    reversal.GRADE_WINDOW = 1.0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='n = 1.5 and γ = 1 alone')
    parser.add_argument('--size', type=int, default=2000)
    parser.add_argument('--steps', type=int, default=300)
    parser.add_argument('--repeats', type=int, default=2)
    args = parser.parse_args()
    if args.quick:
        accuracy_rows((1.5,), (1.0,))
    else:
        accuracy_rows((0.5, 1.5, 2.5), (0.2, 1.0))
    speed_rows(args.size, args.steps, args.repeats)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
