"""``pendulum_twin RECORD --scene fit/fit.yaml --controller MODULE:FUNCTION``: check the twin.

Runs the controller against the fitted joint from the record's first state and writes the two
runs side by side (:func:`pendulum_sim.testing.twin_report.twin`). Exit status 0 when the
report is written, 2 on bad input (one line on stderr, nothing written to ``--out``).
"""
from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from pendulum_sim import arguments

from .errors import TestingError

PROG = 'pendulum_twin'
MAX_LINE = 300


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``pendulum_twin``."""
    from .twin_report import EPISODES, SPREAD

    parser = argparse.ArgumentParser(
        prog=PROG,
        description='Run a controller against the fitted joint (a scene, as pendulum_identify '
                    "writes fit.yaml) from a record's first state for the record's length, and "
                    "compare the recorded run with its twin: the angle's fit in % (NRMSE), and "
                    'with --target the step metrics of both, their difference and whether each '
                    f'recorded metric lies in the central {100 * SPREAD:g} % of a campaign over '
                    'campaign_parameters.yaml. Writes twin.csv, twin.yaml and twin.png into '
                    '--out.')
    parser.add_argument('record', metavar='RECORD',
                        help='the recorded run: a rosbag2 MCAP file (or its folder) or a .csv')
    parser.add_argument('--scene', required=True,
                        help='the fitted joint: a scene file (fit/fit.yaml) or a scene name')
    parser.add_argument('--controller', required=True, metavar='MODULE:FUNCTION',
                        help='the law (t, position, velocity) -> command that ran the joint')
    parser.add_argument('--target', type=float, default=None, metavar='RAD',
                        help='the reference: compare the step metrics (a law with a keyword '
                             'target gets it)')
    arguments.add_out_folder(parser)
    parser.add_argument('--campaign', default=None, metavar='FILE',
                        help='the parameter spaces of the spread (default: '
                             'campaign_parameters.yaml beside the scene, when there is one)')
    parser.add_argument('--episodes', type=int, default=EPISODES, metavar='N',
                        help=f'campaign episodes (default {EPISODES}; 0: no spread)')
    parser.add_argument('--seed', type=int, default=0, help="the campaign's seed (default 0)")
    arguments.add_record_options(
        parser, 'CSV columns in order: t,position[,velocity,effort], _ to skip one (default '
        't,position); the header row must name them')
    arguments.add_force(parser)
    return parser


def run(args: argparse.Namespace) -> str:
    """Check, run the twin, write the report; return its text."""
    from .twin_report import twin

    out = Path(args.out)
    arguments.check_out_folder(out, args.force, TestingError)
    report = twin(args.record, args.scene, args.controller, target=args.target,
                  campaign=args.campaign, episodes=args.episodes, seed=args.seed,
                  topic=args.topic, joint=args.joint, columns=args.columns, units=args.units)
    with arguments.written_whole(out, '.twin-') as folder:
        report.write(folder)
    return report.text() + f'\nwrote {out}/'


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    args = build_parser().parse_args(argv)
    try:
        text = run(args)
    except (TestingError, OSError) as exc:
        return arguments.error_exit(PROG, exc, MAX_LINE)
    print(text)
    return 0


if __name__ == '__main__':
    sys.exit(main())
