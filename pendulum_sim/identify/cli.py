"""``pendulum_identify RECORDING``: fit the damping laws to a record and write what they say.

Exit status 0 when the fit is written, 2 on bad input (one line on stderr, nothing written).
"""
from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

from .errors import IdentifyError
from .laws import COMPARED, LAWS

PROG = 'pendulum_identify'


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``pendulum_identify``."""
    parser = argparse.ArgumentParser(
        prog=PROG,
        description='Fit the damping laws (viscous, quadratic, coulomb, power, '
                    'power+coulomb) to a recorded free swing, rank them by BIC, and write '
                    'fit.yaml (a scene), models.csv, fit.png and campaign_parameters.yaml into '
                    '--out.')
    parser.add_argument('recording', metavar='RECORDING',
                        help='a rosbag2 MCAP file (or its folder) or a .csv file')
    parser.add_argument('--out', required=True, metavar='DIR',
                        help='output folder (created; must be empty unless --force)')
    parser.add_argument('--topic', default=None,
                        help='JointState topic (default: the only one, or */joint_states)')
    parser.add_argument('--joint', default=None,
                        help='joint name in the messages (default: the only one)')
    parser.add_argument('--columns', default='t,position',
                        help='CSV columns: their roles in order, t,position[,velocity,effort] '
                             'with _ to skip one (default t,position; a header row, whatever '
                             'it says, is skipped), or header names mapped to roles, e.g. '
                             'time=t,angle=position')
    parser.add_argument('--units', choices=('deg', 'rad'), default='rad',
                        help='unit of the CSV angle and velocity (default rad)')
    parser.add_argument('--models', default=','.join(COMPARED),
                        help=f'laws to compare, of {",".join(LAWS)} (default '
                             f'{",".join(COMPARED)})')
    parser.add_argument('--inertia', type=float, default=None, metavar='KG_M2',
                        help="the joint's inertia, if known: turns the Coulomb deceleration "
                             'into a friction torque and goes into fit.yaml')
    parser.add_argument('--length', type=float, default=None, metavar='M',
                        help='pivot to centre of mass for fit.yaml (default: the equivalent '
                             'simple pendulum, g / omega0^2)')
    parser.add_argument('--g', type=float, default=9.8, metavar='M_S2',
                        help='gravitational acceleration for fit.yaml (default 9.8)')
    parser.add_argument('--no-jit', action='store_true',
                        help="simulate with numpy instead of the core's compiled sweep (no "
                             'compile time: quicker on short records)')
    parser.add_argument('--force', action='store_true', help='write into a non-empty --out')
    parser.add_argument('--no-progress', action='store_true',
                        help='do not show the progress bar on stderr')
    return parser


COMPILING = ('compiling the simulation for this machine (numba, once: later runs load it '
             'from the disk cache)')
"""What the progress line says while numba compiles, the compiled code kept on disk."""
COMPILING_IN_MEMORY = ('compiling the simulation (numba; the jit cache directory cannot be '
                       'written, so every run compiles)')
"""What it says where the cache directory cannot be written."""


class Progress:
    """The progress line on stderr: the law being fitted, and a word while numba compiles."""

    def __init__(self, enabled: bool, total: int) -> None:
        self.enabled = enabled
        self.total = total
        self.done = 0
        self.model = ''
        self.width = 0

    def __call__(self, model: str) -> None:
        """Show that ``model`` is being fitted."""
        self.done += 1
        self.model = model
        self._draw('')

    def compiling(self, cached: bool) -> None:
        """Say that numba compiles (``jit_cache.compiling``): once per machine where cached."""
        self._draw(': ' + (COMPILING if cached else COMPILING_IN_MEMORY))

    def _draw(self, note: str) -> None:
        if not self.enabled:
            return
        bar = '#' * (20 * max(self.done - 1, 0) // max(self.total, 1))
        line = f'{PROG}: [{bar:<20}] fitting {self.model} ({self.done}/{self.total}){note}'
        print(f'\r{line.ljust(self.width)}', end='', file=sys.stderr, flush=True)
        self.width = len(line)


def run(args: argparse.Namespace) -> str:
    """Read, fit and write; return the summary table."""
    from pendulum_sim.core.jit_cache import compiling

    from .fit import compare_records, prepare
    from .inputs import read_record
    from .outputs import (
        Body,
        summary,
        usable,
        write_campaign,
        write_figure,
        write_models,
        write_scene,
    )

    models = [m.strip() for m in args.models.split(',') if m.strip()]
    for m in models:
        if m not in LAWS:
            raise IdentifyError(f'--models takes {", ".join(LAWS)}, got {m!r}')
    for name, value in (('--inertia', args.inertia), ('--length', args.length),
                        ('--g', args.g)):
        if value is not None and not value > 0:
            raise IdentifyError(f'{name} must be > 0, got {value!r}')
    out = Path(args.out)
    if out.exists() and (not out.is_dir() or (any(out.iterdir()) and not args.force)):
        raise IdentifyError(f'--out {out} exists and is not an empty folder; pass a new or '
                            f'empty folder, or --force')
    samples = read_record(args.recording, topic=args.topic, joint=args.joint,
                          columns=args.columns, units=args.units)
    record = prepare(samples.t, samples.position, samples.velocity, samples.effort)
    known = {} if args.inertia is None else {'inertia': args.inertia}
    show = Progress(not args.no_progress, len(models))
    with compiling(show.compiling):
        fits = compare_records([record], models=models, known=known,
                               jit=False if args.no_jit else None, progress=show)[0]
    if not args.no_progress:
        print(file=sys.stderr)
    best = usable(fits)
    if best is None:
        reasons = '; '.join(sorted({w for f in fits for w in f.reasons.values()}))
        raise IdentifyError(f'the record determines no law: {reasons}')
    body = Body(inertia=args.inertia if args.inertia is not None else 0.2, length=args.length,
                g=args.g, inertia_known=args.inertia is not None)
    omega0 = best.params['omega0']
    assert omega0 is not None
    if args.length is not None and args.length > args.g / omega0 ** 2:
        raise IdentifyError(f'--length {args.length!r} m is longer than g / omega0^2 = '
                            f'{args.g / omega0 ** 2:.6g} m: no rigid body swings at omega0 = '
                            f'{omega0:.6g} rad/s with it; pass a shorter one or none')
    # Written to a temporary folder beside --out and moved there whole: nothing on failure.
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=out.parent, prefix='.identify-') as tmp:
        folder = Path(tmp)
        write_scene(folder / 'fit.yaml', best, body, samples.source)
        write_models(folder / 'models.csv', fits)
        write_campaign(folder / 'campaign_parameters.yaml', best, body)
        write_figure(folder / 'fit.png', best)
        out.mkdir(exist_ok=True)
        for item in folder.iterdir():
            shutil.move(str(item), out / item.name)
    return summary(fits) + f'\n\nbest determined law: {best.model}; wrote {out}/'


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    args = build_parser().parse_args(argv)
    try:
        table = run(args)
    except (IdentifyError, OSError) as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 2
    print(table)
    return 0


if __name__ == '__main__':
    sys.exit(main())
