"""``pendulum_report <what> --out DIR [--quick] [--force]``: thin plumbing over ``report.py``.

``pendulum_report closed-loop RUN.mcap --out DIR [--target RAD]`` reports one closed-loop run
(``closed_loop.py``).
"""
from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from pendulum_sim.arguments import positive_int

from .errors import ReportError
from .report import WHATS, run_report


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``pendulum_report``."""
    parser = argparse.ArgumentParser(
        prog='pendulum_report',
        description='Work-precision, stability and paper-figure reports for pendulum_sim. '
                    'Writes summary.md, CSV tables and PNG figures into --out. '
                    '(pendulum_report closed-loop RUN.mcap --out DIR: one closed-loop run.)')
    parser.add_argument('what', choices=WHATS,
                        help='which report: work-precision, stability, paper, or all')
    parser.add_argument('--out', required=True, metavar='DIR',
                        help='output folder (created; must be empty unless --force)')
    parser.add_argument('--quick', action='store_true',
                        help='a small grid that runs in seconds (for tests)')
    parser.add_argument('--force', action='store_true',
                        help='write into an existing non-empty --out')
    parser.add_argument('--repeats', type=positive_int, default=None, metavar='N',
                        help='timed repeats per work-precision configuration (default 3, '
                             'quick 1); the minimum is kept')
    parser.add_argument('--no-progress', action='store_true',
                        help='do not print progress lines on stderr')
    return parser


def build_closed_loop_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``pendulum_report closed-loop``."""
    parser = argparse.ArgumentParser(
        prog='pendulum_report closed-loop',
        description='The verdict and figure of one closed-loop run: summary.md with the step '
                    'metrics, metrics.csv and closed_loop.png in --out.')
    parser.add_argument('mcap', metavar='RUN.mcap', help='the recorded run')
    parser.add_argument('--out', required=True, metavar='DIR',
                        help='output folder (created; must be empty unless --force)')
    parser.add_argument('--target', type=float, default=None, metavar='RAD',
                        help="the reference angle (default: the recording's own)")
    parser.add_argument('--force', action='store_true',
                        help='write into an existing non-empty --out')
    return parser


def closed_loop_main(argv: Sequence[str]) -> int:
    """Run ``pendulum_report closed-loop``; return the exit status."""
    from .closed_loop import run_closed_loop_report

    parser = build_closed_loop_parser()
    args = parser.parse_args(argv)
    try:
        result = run_closed_loop_report(args.mcap, args.out, target=args.target,
                                        force=args.force,
                                        command=' '.join(['pendulum_report closed-loop',
                                                          *argv]))
    except ReportError as exc:
        parser.error(str(exc))
    print(f'wrote {result["summary_path"]}', file=sys.stderr)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    args_in = list(sys.argv[1:] if argv is None else argv)
    if args_in[:1] == ['closed-loop']:
        return closed_loop_main(args_in[1:])
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        result = run_report(args.what, args.out, quick=args.quick, force=args.force,
                            repeats=args.repeats, progress=not args.no_progress,
                            command=' '.join(['pendulum_report', *(argv if argv is not None
                                                                   else sys.argv[1:])]))
    except ReportError as exc:
        parser.error(str(exc))
    print(f'wrote {result["summary_path"]}', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
