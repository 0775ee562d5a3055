"""``pendulum_demo``: the paper's case from the core, printed as a short table (no ROS)."""
from __future__ import annotations

import argparse
import sys

import numpy as np

from .core import PendulumParams, simulate
from .core.analysis import convergence_quotient, linear_exact_solution


def main(argv: list[str] | None = None) -> int:
    """Run x0 = 2 rad, γ = 1, n = 1…5, h = 1 ms over 20 s and print what the paper shows."""
    parser = argparse.ArgumentParser(prog='pendulum_demo', description=main.__doc__)
    parser.add_argument('--gamma', type=float, default=1.0, help='damping γ (default 1)')
    parser.add_argument('--t-end', type=float, default=20.0, help='duration in s (default 20)')
    args = parser.parse_args(argv)
    sol = linear_exact_solution(0.1, 9.8, 0.1)
    print(f'linearised check (eq 30-32): omega = {sol.omega:.9f}, alpha = {sol.alpha:.11f}, '
          f'A = {sol.amplitude:.10f}')
    print(f'paper case: x0 = 2 rad, gamma = {args.gamma}, omega0^2 = 9.8, h = 1 ms, RK4')
    print(f'{"n":>3} {"phi(t_end)":>14} {"E(t_end) [J]":>14} {"balance [J]":>12} '
          f'{"reversals":>9} {"Q median":>9}')
    for n in range(1, 6):
        params = PendulumParams(gamma=args.gamma, n=float(n))
        run = simulate(params, 2.0, 0.0, args.t_end, 1e-3)
        q = convergence_quotient(params, 2.0, 0.0, min(args.t_end, 5.0), 1e-2).q[1:]
        print(f'{n:>3} {run.phi[-1]:>14.6e} {run.energy[-1]:>14.6e} '
              f'{run.residual[-1]:>12.2e} {run.stats.reversals:>9} {np.median(q):>9.3f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
