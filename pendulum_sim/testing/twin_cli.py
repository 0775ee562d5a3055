"""``pendulum_twin RECORD --scene fit/fit.yaml --controller MODULE:FUNCTION``: check the twin.

Runs the controller against the fitted joint from the record's first state and writes the two
runs side by side (:func:`pendulum_sim.testing.twin_report.twin`). Exit status 0 when the
report is written, 2 on bad input (one line on stderr, nothing written to ``--out``).
"""
from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

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
    parser.add_argument('--out', required=True, metavar='DIR',
                        help='output folder (created; must be empty unless --force)')
    parser.add_argument('--campaign', default=None, metavar='FILE',
                        help='the parameter spaces of the spread (default: '
                             'campaign_parameters.yaml beside the scene, when there is one)')
    parser.add_argument('--episodes', type=int, default=EPISODES, metavar='N',
                        help=f'campaign episodes (default {EPISODES}; 0: no spread)')
    parser.add_argument('--seed', type=int, default=0, help="the campaign's seed (default 0)")
    parser.add_argument('--topic', default=None,
                        help='JointState topic (default: the only one, or */joint_states)')
    parser.add_argument('--joint', default=None,
                        help='joint name in the messages (default: the only one)')
    parser.add_argument('--columns', default='t,position',
                        help='CSV columns in order: t,position[,velocity,effort], _ to skip one '
                             '(default t,position); the header row must name them')
    parser.add_argument('--units', choices=('deg', 'rad'), default='rad',
                        help='unit of the CSV angle and velocity (default rad)')
    parser.add_argument('--force', action='store_true', help='write into a non-empty --out')
    return parser


def run(args: argparse.Namespace) -> str:
    """Check, run the twin, write the report; return its text."""
    from .twin_report import twin

    out = Path(args.out)
    if out.exists() and (not out.is_dir() or (any(out.iterdir()) and not args.force)):
        raise TestingError(f'--out {out} exists and is not an empty folder; pass a new or '
                           f'empty folder, or --force')
    report = twin(args.record, args.scene, args.controller, target=args.target,
                  campaign=args.campaign, episodes=args.episodes, seed=args.seed,
                  topic=args.topic, joint=args.joint, columns=args.columns, units=args.units)
    # Written to a temporary folder beside --out and moved there whole: nothing on failure.
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=out.parent, prefix='.twin-') as tmp:
        report.write(tmp)
        out.mkdir(exist_ok=True)
        for item in Path(tmp).iterdir():
            shutil.move(str(item), out / item.name)
    return report.text() + f'\nwrote {out}/'


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    args = build_parser().parse_args(argv)
    try:
        text = run(args)
    except (TestingError, OSError) as exc:
        line = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        print(f'{PROG}: error: ' + (line if len(line) <= MAX_LINE else
                                    line[:MAX_LINE - 3] + '...'), file=sys.stderr)
        return 2
    print(text)
    return 0


if __name__ == '__main__':
    sys.exit(main())
