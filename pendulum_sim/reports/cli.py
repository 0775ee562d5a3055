"""``pendulum_report <what> --out DIR [--quick] [--force]``: thin plumbing over ``report.py``.

``pendulum_report closed-loop RUN.mcap --out DIR [--target RAD]`` reports one closed-loop run
(``closed_loop.py``); ``pendulum_report animate RECORDING.mcap --out run.gif [--goal RAD]
[--fps N] [--size PIXELS]`` draws a recorded run as an animated GIF with the frames the
Gymnasium environments render (the angle, the torque bar, the goal ray).
"""
from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from pendulum_sim.arguments import add_force, add_out_folder, error_exit, positive_int

from .errors import ReportError
from .report import WHATS, run_report


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``pendulum_report``."""
    parser = argparse.ArgumentParser(
        prog='pendulum_report',
        description='Work-precision, stability and paper-figure reports for pendulum_sim. '
                    'Writes summary.md, CSV tables and PNG figures into --out. '
                    '(pendulum_report closed-loop RUN.mcap --out DIR: one closed-loop run; '
                    'pendulum_report animate RECORDING.mcap --out run.gif: its animation.)')
    parser.add_argument('what', choices=WHATS,
                        help='which report: work-precision, stability, paper, or all')
    add_out_folder(parser)
    parser.add_argument('--quick', action='store_true',
                        help='a small grid that runs in seconds (for tests)')
    add_force(parser)
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
    add_out_folder(parser)
    parser.add_argument('--target', type=float, default=None, metavar='RAD',
                        help="the reference angle (default: the recording's own)")
    add_force(parser)
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


def build_animate_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``pendulum_report animate``."""
    parser = argparse.ArgumentParser(
        prog='pendulum_report animate',
        description='Draw a recorded closed-loop run as an animated GIF, in real time: the '
                    'pendulum at each measured angle, the torque bar and the goal ray.')
    parser.add_argument('mcap', metavar='RECORDING.mcap', help='the recorded run')
    parser.add_argument('--out', required=True, metavar='FILE.gif', help='the GIF to write')
    parser.add_argument('--goal', type=float, default=None, metavar='RAD',
                        help="the angle drawn as the goal ray (default: the recording's "
                        'target, none without one)')
    parser.add_argument('--fps', type=positive_int, default=25, metavar='N',
                        help='frames per second of simulated time (default 25)')
    parser.add_argument('--size', type=positive_int, default=200, metavar='PIXELS',
                        help='frame width and height (default 200, at least 32)')
    parser.add_argument('--force', action='store_true', help='replace an existing FILE.gif')
    return parser


def animate_main(argv: Sequence[str]) -> int:
    """Run ``pendulum_report animate``; return the exit status."""
    from pendulum_sim.testing.errors import TestingError
    from pendulum_sim.testing.record import load_run
    from pendulum_sim.testing.swing_up.animation import write_gif

    args = build_animate_parser().parse_args(argv)
    out = Path(args.out)
    try:
        if out.suffix.lower() != '.gif':
            raise TestingError(f"--out must name a .gif file, got '{out}'")
        if out.exists() and not args.force:
            raise TestingError(f"--out '{out}' exists; --force replaces it")
        if not out.parent.is_dir():
            raise TestingError(f"--out: the folder '{out.parent}' does not exist")
        if args.size < 32:
            raise TestingError(f'--size must be at least 32 pixels, got {args.size}')
        run = load_run(args.mcap)
        if run.t.size == 0:
            raise TestingError(f'{args.mcap} holds no answered state to draw')
        write_gif(run, out, goal=args.goal, fps=float(args.fps), size=args.size)
    except TestingError as exc:
        return error_exit('pendulum_report animate', exc)
    print(f'wrote {out} ({run.t[-1] - run.t[0]:.3f} s of the run)', file=sys.stderr)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    args_in = list(sys.argv[1:] if argv is None else argv)
    if args_in[:1] == ['closed-loop']:
        return closed_loop_main(args_in[1:])
    if args_in[:1] == ['animate']:
        return animate_main(args_in[1:])
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
