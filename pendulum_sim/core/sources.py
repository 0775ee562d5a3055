"""Write the core's generated sources to files, for a reader to review them as code.

The core generates Python from templates and tables (``codegen.fill``, ``explicit.py``,
``law.py``, ``dirk.py``, ``reversal.py``): the compiled sweep's runs (``kernel.kernel_source``),
the Stepper's fast steps (``decisions.fast_step_source``), the laws for an exponent known at
run time and the reversal location. :func:`generated_sources` returns each text under a file
name, the very text that runs; ``python -m pendulum_sim.core.sources --write DIR`` writes them
(a test holds each file to what runs and compiles it).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .decisions import fast_step_source
from .dirk import DAMPING_FORMULA_SOURCE
from .engine import Engine
from .kernel import kernel_source
from .law import POWER_SOURCE, SLOPE_SOURCE
from .methods import METHODS
from .reversal import LOCATE_FORMS, LOCATE_SRC
from .tableaus import Tableau

LAW_TEXTS = (0.0, 0.5, 1.0, 2.0, 3.0, 4.0, 5.0, 1.5)
"""Exponents whose law texts are written: each special spelling up to the paper's n = 5
(``law.power_source``) and 1.5 for the text every other exponent shares."""

SWEEP_GAMMA, SWEEP_W2 = 1.0, 9.8
"""The pendulum whose Stepper fast step is written for each law text (its decisions are those
of its ``Problem``: the reversal test, the grading window, the stiff-transient speed)."""


def _tag(n: float) -> str:
    """Return the file-name tag of the exponent ``n`` (``n1.5``, ``n2``)."""
    return f'n{n:g}'


def generated_sources() -> dict[str, str]:
    """Return every generated source, by file name: the texts the core runs.

    ``kernel_<method>_<n>[_friction].py``: the compiled sweep's run and its functions for the
    explicit methods and each of :data:`LAW_TEXTS` (with a friction beside the law or not);
    ``fast_<method>_<n>.py``: the Stepper's fast step for the pendulum of :data:`SWEEP_GAMMA`,
    :data:`SWEEP_W2` and that exponent; ``laws.py``: the laws for an exponent known at run time
    (the damping slope and power, the stage law); ``locate.py``: the reversal location's forms.
    """
    out: dict[str, str] = {}
    explicit = [m for m in METHODS.values() if m.family.fast_path]
    for meth in explicit:
        tab = meth.tableau
        assert isinstance(tab, Tableau)  # the explicit family's methods are tableaus
        for n in LAW_TEXTS:
            out[f'kernel_{meth.name}_{_tag(n)}.py'] = kernel_source(tab, n)
            out[f'kernel_{meth.name}_{_tag(n)}_friction.py'] = kernel_source(tab, n, True)
            eng = Engine(SWEEP_W2, SWEEP_GAMMA, n, meth)
            out[f'fast_{meth.name}_{_tag(n)}.py'] = fast_step_source(
                tab, n, eng.nonsmooth, eng.reach, eng.v_acc, eng.energy_check)
    out['laws.py'] = '\n\n'.join((SLOPE_SOURCE, POWER_SOURCE, DAMPING_FORMULA_SOURCE))
    out['locate.py'] = '\n\n'.join(
        LOCATE_SRC.format(name=name, params=params, at=at, accel=accel)
        for name, (params, at, accel) in LOCATE_FORMS.items())
    return out


def write_sources(directory: Path) -> list[Path]:
    """Write :func:`generated_sources` into ``directory`` (made if missing); return the files."""
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, text in sorted(generated_sources().items()):
        path = directory / name
        path.write_text(text, encoding='utf-8')
        paths.append(path)
    return paths


def main(argv: list[str] | None = None) -> int:
    """Write the generated sources for review: ``--write DIR``; exit 2 where DIR cannot be."""
    parser = argparse.ArgumentParser(prog='python -m pendulum_sim.core.sources',
                                     description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument('--write', type=Path, required=True, metavar='DIR',
                        help='the directory to write the generated sources into')
    args = parser.parse_args(argv)
    directory: Path = args.write
    if directory.exists() and not directory.is_dir():
        print(f'sources: --write {directory} is not a directory', file=sys.stderr)
        return 2
    try:
        paths = write_sources(directory)
    except OSError as exc:
        print(f'sources: cannot write into {directory}: {exc.strerror}', file=sys.stderr)
        return 2
    print(f'wrote {len(paths)} generated sources into {directory}')
    return 0


__all__ = ['LAW_TEXTS', 'SWEEP_GAMMA', 'SWEEP_W2', 'generated_sources', 'main', 'write_sources']

if __name__ == '__main__':
    sys.exit(main())
