"""What the command-line programs share: argument types (argparse ``type=`` callables), the
option groups several programs take, the ``--out`` folder written whole, and their exits.

An error ends a program with :func:`error_exit` (one line on stderr, exit status 2); Ctrl-C
during a campaign with :func:`interrupted` (exit status 130).
"""
from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

ERROR_EXIT = 2
"""The exit status of input that the program could not run."""
INTERRUPTED_EXIT = 130
"""The exit status after Ctrl-C (128 + SIGINT)."""


def positive_int(text: str) -> int:
    """Parse a whole number >= 1, or say what was given (argparse prefixes the option)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'must be an integer >= 1, got {text!r}') from None
    if value < 1:
        raise argparse.ArgumentTypeError(f'must be an integer >= 1, got {text!r}')
    return value


# ---------------------------------------------------------------- option groups
def add_cluster_options(parser: argparse.ArgumentParser) -> None:
    """Add ``--scheduler ADDRESS`` and ``--workers N``: where a campaign runs on Dask."""
    parser.add_argument('--scheduler', metavar='ADDRESS',
                        help='run on this Dask scheduler, e.g. tcp://host:8786 (default: a '
                        'local cluster)')
    parser.add_argument('--workers', type=positive_int, metavar='N',
                        help='local cluster: worker processes (default: the core count)')


def add_out_folder(parser: argparse.ArgumentParser) -> None:
    """Add ``--out DIR`` (required): the output folder, new or empty unless ``--force``."""
    parser.add_argument('--out', required=True, metavar='DIR',
                        help='output folder (created; must be empty unless --force)')


def add_force(parser: argparse.ArgumentParser) -> None:
    """Add ``--force``: write into a ``--out`` folder that holds files."""
    parser.add_argument('--force', action='store_true',
                        help='write into an existing non-empty --out')


def add_record_options(parser: argparse.ArgumentParser, columns_help: str) -> None:
    """Add what reads a recorded joint: ``--topic``, ``--joint``, ``--columns``, ``--units``.

    ``columns_help`` says how the program reads a CSV's columns.
    """
    parser.add_argument('--topic', default=None,
                        help='JointState topic (default: the only one, or */joint_states)')
    parser.add_argument('--joint', default=None,
                        help='joint name in the messages (default: the only one)')
    parser.add_argument('--columns', default='t,position', help=columns_help)
    parser.add_argument('--units', choices=('deg', 'rad'), default='rad',
                        help='unit of the CSV angle and velocity (default rad)')


# ---------------------------------------------------------------- the --out folder
def check_out_folder(out: Path, force: bool, error: type[Exception]) -> None:
    """Raise ``error`` unless ``out`` is new, an empty folder, or a folder and ``force``."""
    if out.exists() and (not out.is_dir() or (any(out.iterdir()) and not force)):
        raise error(f'--out {out} exists and is not an empty folder; pass a new or empty '
                    f'folder, or --force')


@contextmanager
def written_whole(out: Path, prefix: str) -> Iterator[Path]:
    """Yield a temporary folder beside ``out`` to write into; moved into ``out`` whole.

    Its files go into ``out`` (created) only when the block ends without an exception:
    nothing is written on failure.
    """
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=out.parent, prefix=prefix) as tmp:
        folder = Path(tmp)
        yield folder
        out.mkdir(exist_ok=True)
        for item in folder.iterdir():
            shutil.move(str(item), out / item.name)


# ---------------------------------------------------------------- exits
def error_exit(prog: str, exc: BaseException, max_line: int | None = None) -> int:
    """Print ``prog: error:`` and the first line of ``exc`` on stderr; return 2.

    The line is cut to ``max_line`` characters (ending in ``...``) where that is given; an
    exception without a message is named by its type.
    """
    line = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    if max_line is not None and len(line) > max_line:
        line = line[:max_line - 3] + '...'
    print(f'{prog}: error: {line}', file=sys.stderr)
    return ERROR_EXIT


def interrupted(prog: str) -> int:
    """Say on stderr that a campaign was interrupted (Ctrl-C) and can resume; return 130."""
    print(f'\n{prog}: interrupted; the finished episodes are kept, --resume continues',
          file=sys.stderr)
    return INTERRUPTED_EXIT
