"""Benchmark the core's work-precision against scipy's solve_ivp, side by side, in one run.

Run: ``.venv/bin/python bench/bench_work_precision.py [--cases paper_g1000_n2,...] [--repeats N]``.
Prints, for every case and error level 1e-3 … 1e-12, the CPU time the core's best method and
scipy's best method (RK45, DOP853, Radau, LSODA) need to reach the level, their ratio and
whether it meets the target of issue 10 (ratio ≤ 0.5), then the count over all measurable
pairs, and the same count with the core's generated Python steps only (where numba is
installed the adaptive methods also run with compiled steps, ``-jit``). Asserts nothing.

The study is the one of ``pendulum_report work-precision`` (``reports/work_precision.py``: the
paper's 15 cases and the stiff one, the independent reference, CPU time as the minimum of
repeats after a warm-up); its CSV tables and figures go to a temporary folder (``--out`` to
keep them). A level is measurable when it is at least 10× the reference's own disagreement.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import sys
import tempfile
from pathlib import Path

from pendulum_sim.reports.reference import scipy_available
from pendulum_sim.reports.work_precision import (
    FULL,
    TARGET_RATIO,
    all_cases,
    run_work_precision,
    target_count,
)


def main() -> None:
    """Run the study and print the ratio table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    names = [c.name for c in all_cases(FULL.t_end)]
    parser.add_argument('--cases', default='', metavar='A,B',
                        help='comma-separated case names (default: all 16): ' + ', '.join(names))
    parser.add_argument('--repeats', type=int, default=FULL.repeats, metavar='N',
                        help=f'timed repeats per configuration (default {FULL.repeats})')
    parser.add_argument('--out', default='', metavar='DIR',
                        help='keep the CSV tables and figures here (default: a temporary folder)')
    args = parser.parse_args()
    cases = tuple(c for c in args.cases.split(',') if c)
    unknown = sorted(set(cases) - set(names))
    if unknown:
        parser.error(f'unknown case(s): {", ".join(unknown)}')
    if args.repeats < 1:
        parser.error(f'--repeats must be >= 1, got {args.repeats}')
    if not scipy_available():
        sys.exit('bench_work_precision needs scipy (the peer and the reference): '
                 "pip install -e '.[peers]'")
    grid = dataclasses.replace(FULL, cases=cases, repeats=args.repeats)
    print(f'machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, '
          f'Python {platform.python_version()}, load average '
          f'{os.getloadavg()[0]:.2f} at start')
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(args.out) if args.out else Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        result = run_work_precision(out, grid, progress=True)
    rows = result['levels']
    print(f'{"case":<16} {"level":>7} {"core best":<10} {"core ms":>8} {"scipy best":<13} '
          f'{"scipy ms":>9} {"ratio":>6}  met')
    for r in rows:
        if not r['measurable']:
            continue
        print(f'{r["case"]:<16} {r["level"]:>7.0e} {r["core_best"]:<10} '
              f'{1e3 * r["core_cpu_s"]:>8.3f} {r["scipy_best"]:<13} '
              f'{1e3 * r["scipy_cpu_s"]:>9.3f} {r["ratio"]:>6.3f}  '
              f'{"yes" if r["target_met"] else "NO"}')
    met, counted = target_count(rows)
    print(f'target (core ≤ {TARGET_RATIO:g} × scipy at every level): met on {met} of '
          f'{counted} measurable (case, level) pairs')
    if result['python_levels']:
        met, counted = target_count(result['python_levels'])
        print(f'the same with the generated Python steps only (no -jit variants): met on {met} '
              f'of {counted}')
    else:
        print('the compiled steps did not run (numba not installed): Python steps only')


if __name__ == '__main__':
    main()
