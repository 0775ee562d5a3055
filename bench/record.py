#!/usr/bin/env python3
"""Run one benchmark script and keep what it prints as a results file with its conditions.

Run: ``.venv/bin/python bench/record.py bench/bench_core.py [ARGS...]``. The script's output
goes to the terminal as it comes and to ``bench/results/<script>.txt``, headed by the command,
the date (UTC), the machine (CPU model, cores, kernel), the load average at the start and the
versions of Python and numpy. ``make bench`` runs every benchmark this way; the docs include the
files. The exit code is the script's.
"""
from __future__ import annotations

import datetime
import os
import platform
import subprocess
import sys
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / 'results'


def cpu_model() -> str:
    """Return the CPU model name from /proc/cpuinfo (the platform's guess elsewhere)."""
    try:
        for line in Path('/proc/cpuinfo').read_text(encoding='utf-8').splitlines():
            if line.startswith('model name'):
                return line.split(':', 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def header(command: list[str]) -> str:
    """Return the lines that say what was run, when and where."""
    import numpy

    load = ' / '.join(f'{x:.2f}' for x in os.getloadavg())
    now = datetime.datetime.now(datetime.timezone.utc).strftime('%Y-%m-%d %H:%M UTC')
    return (f'command: {" ".join(command)}\n'
            f'date:    {now}\n'
            f'machine: {cpu_model()}, {os.cpu_count()} cores, {platform.system()} '
            f'{platform.release()}\n'
            f'load:    {load} (1 / 5 / 15 min, at the start)\n'
            f'python:  {platform.python_version()}, numpy {numpy.__version__}\n\n')


def main(argv: list[str]) -> int:
    """Run ``argv`` (a bench script and its arguments) and write its results file."""
    if not argv or not argv[0].endswith('.py'):
        print('usage: record.py bench/SCRIPT.py [ARGS...]', file=sys.stderr)
        return 2
    command = [sys.executable, *argv]
    shown = ['python', *argv]
    RESULTS.mkdir(exist_ok=True)
    out = RESULTS / (Path(argv[0]).stem + '.txt')
    partial = out.with_suffix('.txt.part')
    with open(partial, 'w', encoding='utf-8') as sink:
        sink.write(header(shown))
        sink.flush()
        proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                text=True, bufsize=1)
        assert proc.stdout is not None
        for line in proc.stdout:
            sys.stdout.write(line)
            sink.write(line)
        code = proc.wait()
    if code == 0:
        partial.replace(out)   # a failed run leaves the last good file in place
    else:
        print(f'{argv[0]} exited {code}; output kept in {partial}', file=sys.stderr)
    return code


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
