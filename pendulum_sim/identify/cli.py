"""``pendulum_identify RECORDING ...``: fit the damping laws to records and write what they say.

A free swing (no effort) is fitted as before; a record with effort (``JointState.effort``, a
command stream named by ``--effort-topic``, a CSV's effort column), or several records of one
joint, are fitted driven: the physical joint, its parameters shared by all (``driven.py``).
``--validate OTHER`` validates the best law on a record it was not fitted to
(``validate.py``: ``validation.csv``, ``validate.png``).

Exit status 0 when the fit is written, 2 on bad input (one line on stderr, nothing written).
"""
from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pendulum_sim import arguments

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
    parser.add_argument('recording', metavar='RECORDING', nargs='+',
                        help='a rosbag2 MCAP file (or its folder) or a .csv file; several '
                             'records of one joint are fitted together with their effort')
    arguments.add_out_folder(parser)
    arguments.add_record_options(
        parser, 'CSV columns: their roles in order, t,position[,velocity,effort] with _ to '
        'skip one (default t,position; a header row, whatever it says, is skipped), or header '
        'names mapped to roles, e.g. time=t,angle=position')
    parser.add_argument('--effort-topic', default=None, metavar='TOPIC',
                        help='read the effort from this command stream (std_msgs/Float64 '
                             'like effort_command, or sensor_msgs/JointState like '
                             'joint_commands), each command held to the next, instead of '
                             'JointState.effort')
    parser.add_argument('--window', type=float, default=None, metavar='S',
                        help='with effort: fit over windows of S seconds re-anchored on the '
                             'measurement (default: half a period; a window as long as the '
                             'record is one simulation of it)')
    parser.add_argument('--validate', default=None, metavar='OTHER',
                        help='validate the best law on this record (not fitted): fit %% of '
                             'simulation and k-step prediction, residual tests; writes '
                             'validation.csv and validate.png')
    parser.add_argument('--k', type=int, default=None, metavar='K',
                        help='with --validate: the prediction horizon in samples (default: a '
                             'tenth of a period)')
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
    arguments.add_force(parser)
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


def _check_args(args: argparse.Namespace) -> list[str]:
    """Check the options that need no file; return the models."""
    models = [m.strip() for m in args.models.split(',') if m.strip()]
    for m in models:
        if m not in LAWS:
            raise IdentifyError(f'--models takes {", ".join(LAWS)}, got {m!r}')
    for name, value in (('--inertia', args.inertia), ('--length', args.length),
                        ('--g', args.g), ('--window', args.window)):
        if value is not None and not value > 0:
            raise IdentifyError(f'{name} must be > 0, got {value!r}')
    if args.k is not None and args.validate is None:
        raise IdentifyError('--k is the horizon of --validate; pass --validate OTHER')
    arguments.check_out_folder(Path(args.out), args.force, IdentifyError)
    return models


def _driven_record(path: str, args: argparse.Namespace) -> tuple[Any, bool]:
    """Read ``path``; return its driven record (or its samples) and whether it has effort."""
    from .driven_fit import driven_record
    from .effort import from_commands
    from .inputs import read_record

    samples = read_record(path, topic=args.topic, joint=args.joint, columns=args.columns,
                          units=args.units, effort_topic=args.effort_topic)
    effort: Any = samples.effort
    if samples.commands is not None:
        effort = from_commands(*samples.commands, samples.t, name=args.effort_topic)
    elif effort is not None and not (np.any(effort != 0.0) or np.any(np.isnan(effort))):
        effort = None   # all zero: a free swing
    if effort is None:
        return samples, False
    return driven_record(samples.t, samples.position, effort, velocity=samples.velocity,
                         source=samples.source, joint=samples.joint), True


def run(args: argparse.Namespace) -> str:
    """Read, fit and write; return the summary table."""
    from pendulum_sim.core.jit_cache import compiling

    models = _check_args(args)
    read = [_driven_record(p, args) for p in args.recording]
    show = Progress(not args.no_progress, len(models))
    with compiling(show.compiling):
        fits = _fit(args, models, read, show)
    if not args.no_progress:
        print(file=sys.stderr)
    return _write(args, fits, '; '.join(str(r.source) for r, _ in read))


def _fit(args: argparse.Namespace, models: list[str], read: list[tuple[Any, bool]],
         show: Progress) -> list[Any]:
    """Fit the laws: driven where a record has effort (or several are given), else free."""
    from .fit import compare_records, prepare

    jit = False if args.no_jit else None
    if len(read) > 1 or any(driven for _, driven in read):
        from .driven_fit import compare_driven

        free = [p for p, (_, driven) in zip(args.recording, read, strict=True) if not driven]
        if free:
            raise IdentifyError(f'{free[0]} has no effort: records are fitted together with '
                                f'their effort (a free swing is fitted alone)')
        if args.inertia is not None:
            raise IdentifyError('--inertia is for a free swing: with effort the inertia is '
                                'fitted')
        records = [r for r, _ in read]
        return compare_driven(records, models=models, window=args.window, jit=jit,
                              progress=show)
    if args.window is not None:
        raise IdentifyError('--window is the window of a fit with effort; a free swing is '
                            'fitted by one simulation of the whole record')
    samples = read[0][0]
    record = prepare(samples.t, samples.position, samples.velocity, samples.effort)
    known = {} if args.inertia is None else {'inertia': args.inertia}
    return compare_records([record], models=models, known=known, jit=jit,
                           progress=show)[0]


def _write(args: argparse.Namespace, fits: list[Any], source: str) -> str:
    """Pick the best law, validate it if asked, and write the outputs into --out.

    ``source`` says where the records were read (written into ``fit.yaml``)."""
    from .outputs import (
        Body,
        summary,
        usable,
        write_campaign,
        write_figure,
        write_models,
        write_scene,
    )
    from .validate import validate, write_validation, write_validation_figure

    best = usable(fits)
    if best is None:
        reasons = '; '.join(sorted({w for f in fits for w in f.reasons.values()}))
        raise IdentifyError(f'the record determines no law: {reasons}')
    if best.driven and best.params.get('inertia') is None:
        raise IdentifyError(best.reasons['inertia'])
    inertia = best.params['inertia'] if best.driven else args.inertia
    body = Body(inertia=inertia if inertia is not None else 0.2, length=args.length,
                g=args.g, inertia_known=inertia is not None)
    omega0 = best.params['omega0']
    assert omega0 is not None
    if args.length is not None and args.length > args.g / omega0 ** 2:
        raise IdentifyError(f'--length {args.length!r} m is longer than g / omega0^2 = '
                            f'{args.g / omega0 ** 2:.6g} m: no rigid body swings at omega0 = '
                            f'{omega0:.6g} rad/s with it; pass a shorter one or none')
    checked = None
    if args.validate is not None:
        other, driven = _driven_record(args.validate, args)
        if not driven:
            other = {'t': other.t, 'position': other.position, 'velocity': other.velocity}
        checked = validate(best, other, k=args.k, jit=False if args.no_jit else None)
    out = Path(args.out)
    with arguments.written_whole(out, '.identify-') as folder:
        write_scene(folder / 'fit.yaml', best, body, source)
        write_models(folder / 'models.csv', fits)
        write_campaign(folder / 'campaign_parameters.yaml', best, body)
        write_figure(folder / 'fit.png', best)
        if checked is not None:
            write_validation(folder / 'validation.csv', checked)
            write_validation_figure(folder / 'validate.png', checked,
                                    f'{best.model} fitted to {source}, validated on '
                                    f'{args.validate}')
    text = summary(fits) + f'\n\nbest determined law: {best.model}; wrote {out}/'
    if checked is not None:
        text += (f'\nvalidated on {args.validate}: fit {checked.fit_simulation:.1f} % '
                 f'(simulation), {checked.fit_prediction:.1f} % ({checked.k}-step '
                 f'prediction); residuals {"white" if checked.white else "not white"}')
    return text


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    args = build_parser().parse_args(argv)
    try:
        table = run(args)
    except (IdentifyError, OSError) as exc:
        return arguments.error_exit(PROG, exc)
    print(table)
    return 0


if __name__ == '__main__':
    sys.exit(main())
