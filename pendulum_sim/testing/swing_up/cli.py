"""``pendulum_benchmark``: the swing-up benchmark of a controller, each criterion a campaign.

::

    pendulum_benchmark CONTROLLER --out DIR [--task swing_up] [--scene SCENE]
                       [--episodes N] [--seed S] [--duration SECONDS] [--criteria A,B,...]
                       [--goal-box RAD RAD_PER_S] [--torque-limit N_M] [--roa-grid N]
                       [--limits N] [--scheduler ADDRESS | --workers N] [--resume] [--jit]
                       [--no-progress]

CONTROLLER is ``module:function`` (a law, vectorised or not) or a command line in one
argument (``'pendulum_swing_up_controller --ros-args -p k_energy:=5.0'``). The results go to
``DIR/benchmark.yaml`` and a table on stdout. Exit status: 0 when the benchmark ran (whatever
the controller scored), 2 for input that no benchmark could run (one line on stderr says
why, and nothing is written to ``--out``), 130 after Ctrl-C (``--resume`` continues).
"""
from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from pendulum_sim.arguments import (
    add_cluster_options,
    error_exit,
    interrupted,
    positive_int,
)

from ..errors import CampaignError
from .criteria import CRITERIA, LIMITS, ROA_GRID

PROG = 'pendulum_benchmark'
MAX_LINE = 400


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``pendulum_benchmark``."""
    parser = argparse.ArgumentParser(
        prog=PROG, description='Benchmark a swing-up controller: swing-up time, energy, '
        'smoothness, consistency, robustness, sensitivity, the smallest torque limit, call '
        'rate and region of attraction, each criterion a campaign on Dask.')
    parser.add_argument('controller', metavar='CONTROLLER',
                        help='module:function, or a command line in one argument')
    parser.add_argument('--out', required=True, metavar='DIR',
                        help='output folder (new or empty, or with --resume)')
    parser.add_argument('--task', default='swing_up', metavar='TASK',
                        help='the task (swing_up, the default and the one there is)')
    parser.add_argument('--scene', default='swing_up', metavar='SCENE',
                        help='the joint: a scene name or parameter file (default swing_up)')
    parser.add_argument('--episodes', type=positive_int, default=100, metavar='N',
                        help='episodes of consistency, robustness and sensitivity each '
                        '(default 100)')
    parser.add_argument('--seed', type=int, default=0, metavar='S', help='seed (default 0)')
    parser.add_argument('--duration', type=float, default=10.0, metavar='SECONDS',
                        help='simulated seconds per episode (default 10)')
    parser.add_argument('--criteria', default=','.join(CRITERIA), metavar='A,B,...',
                        help=f'the criteria to run (default all: {",".join(CRITERIA)})')
    parser.add_argument('--goal-box', type=float, nargs=2, default=(0.1, 0.1),
                        metavar=('RAD', 'RAD_PER_S'),
                        help='the goal box around upright (default 0.1 0.1)')
    parser.add_argument('--torque-limit', type=float, default=None, metavar='N_M',
                        help="the torque limit (default: the scene's max_effort)")
    parser.add_argument('--roa-grid', type=positive_int, default=ROA_GRID, metavar='N',
                        help=f'start states per axis of the region of attraction (default '
                        f'{ROA_GRID})')
    parser.add_argument('--limits', type=positive_int, default=LIMITS, metavar='N',
                        help=f'torque limits tried for the smallest one (default {LIMITS})')
    add_cluster_options(parser)
    parser.add_argument('--resume', action='store_true',
                        help='continue the interrupted benchmark in --out')
    parser.add_argument('--jit', action='store_true',
                        help="a vectorised law's batches on the compiled sweep (numba)")
    parser.add_argument('--no-progress', action='store_true', help='no progress bar')
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    args = build_parser().parse_args(argv)
    from .benchmark import benchmark

    criteria = tuple(c.strip() for c in args.criteria.split(',') if c.strip())
    try:
        result = benchmark(args.controller, out=args.out, task=args.task, scene=args.scene,
                           duration=args.duration, episodes=args.episodes, seed=args.seed,
                           goal_box=tuple(args.goal_box), torque_limit=args.torque_limit,
                           criteria=criteria, roa_grid=args.roa_grid, limits=args.limits,
                           scheduler=args.scheduler, workers=args.workers,
                           resume=args.resume, progress=not args.no_progress, jit=args.jit)
    except CampaignError as exc:
        return error_exit(PROG, exc, MAX_LINE)
    except KeyboardInterrupt:
        return interrupted(PROG)
    print(result.table())
    print(f'wrote {result.out / "benchmark.yaml"}', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
