"""Benchmark real n on the work-precision plane: CPU time at equal global error, both sweeps.

Run: ``.venv/bin/python bench/bench_work_precision_real_n.py`` (``--size``, ``--repeats``,
``--png``, ``--paths``). Issue 39, item 6: ``bench_real_n``'s population (:func:`population`:
γ uniform in [0.1, 2], φ0 in [−2, 2] rad, φ'0 in [−3, 3] rad/s, ω0² = 9.8 s⁻², τ = 0), 400
pendulums over 2 s, for the exponent cases (a) n = 1 for all (integer: no reversal grading),
(b) n = 1.5 for all, (c) n uniform in [1, 3], all distinct; on the numpy sweep and the compiled
sweep (``jit=True``), at h = 2 s / N for N = 250 … 4000 (8 ms to 0.5 ms, steps of √2).

The global error of a run is the largest 2-norm error over (φ, φ') of any pendulum at t = 0.4,
0.8, …, 2 s against the independent reference (``reports.reference``: scipy's DOP853 at
rtol 1e-13 restarted at every velocity reversal, none of the core's stepping code; its own
error about 1e-13, so levels down to 1e-10 are measurable). The CPU time of a run is the
process CPU time (every thread's) of one ``sweep`` call, set-up included, the least of
``--repeats`` after a first call that compiles; the time to reach each error level 1e-6 …
1e-10 is interpolated on the curve (log time linear in log error between the two runs around
the level, ``reports.work_precision.time_to_error``; no extrapolation). Printed: every run
(h, error, CPU time, the share of pendulum-steps the careful path took, the order fitted
between successive h), then the table (error level, CPU time of the case and per pendulum,
ratio of the non-integer cases to n = 1, both paths); the figure (error against CPU time,
both paths) goes to ``--png``. Asserts nothing.
"""
from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from pendulum_sim.core import PendulumParams
from pendulum_sim.core.sweep import sweep
from pendulum_sim.reports.reference import reference
from pendulum_sim.reports.work_precision import time_to_error

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_real_n import population  # noqa: E402

T_END = 2.0
RECORDS = 5  # the error is read at t = 0.4, 0.8, ..., 2 s
STEPS = (250, 350, 500, 700, 1000, 1400, 2000, 2800, 4000)  # h = 2 s / N: 8 ms ... 0.5 ms
LEVELS = (1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
CASES = {'n = 1 (integer)': lambda size: np.full(size, 1.0),
         'integer n = 1..5': lambda size: population(size, 'integer n = 1..5')['n'],
         'n = 1.5 for all': lambda size: np.full(size, 1.5),
         'distinct n in [1, 3]': lambda size: population(size, 'distinct n in [1, 3]')['n']}
PATHS = ('numpy', 'jit')
RESULTS = Path(__file__).resolve().parent / 'results'


def case_args(size: int, case: str) -> dict[str, Any]:
    """Return the sweep's arguments for ``size`` pendulums of ``case``."""
    args = population(size, 'n = 1.5 for all')
    args['n'] = CASES[case](size)
    return args


def references(args: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, float]:
    """Return the reference φ and φ' at the record times (shape (RECORDS + 1, N)), its time."""
    t_out = np.linspace(0.0, T_END, RECORDS + 1)
    size = len(args['n'])
    phi = np.empty((RECORDS + 1, size))
    dphi = np.empty((RECORDS + 1, size))
    t0 = time.process_time()
    for i in range(size):
        params = PendulumParams.from_omega0_sq(args['omega0_sq'], float(args['gamma'][i]),
                                               float(args['n'][i]))
        ref = reference(params, float(args['phi0'][i]), float(args['dphi0'][i]), t_out,
                        cross_check=False)
        if ref is None:
            raise RuntimeError(f'no reference for pendulum {i}')
        phi[:, i], dphi[:, i] = ref.phi, ref.dphi
    return phi, dphi, time.process_time() - t0


def run(args: dict[str, Any], steps: int, jit: bool, repeats: int) -> tuple[float, Any]:
    """Return the least CPU time of ``repeats`` sweeps of ``steps`` steps, and the result."""
    h = T_END / steps
    kwargs = dict(args, t_end=T_END, h=h, jit=jit, record_every=steps // RECORDS)
    res = sweep(**kwargs)  # compiles (jit) or loads the compiled careful steps
    best = math.inf
    for _ in range(repeats):
        t0 = time.process_time()
        res = sweep(**kwargs)
        best = min(best, time.process_time() - t0)
    return best, res


def measure(size: int, repeats: int, paths: tuple[str, ...]) -> dict[tuple[str, str], list[
        dict[str, Any]]]:
    """Run every case, path and h; print each run; return the rows by (path, case)."""
    curves: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for case in CASES:
        args = case_args(size, case)
        ref_phi, ref_dphi, ref_cpu = references(args)
        print(f'# {case}: reference (DOP853 restarted at reversals) {ref_cpu:.1f} s CPU',
              flush=True)
        for path in paths:
            rows: list[dict[str, Any]] = []
            for steps in STEPS:
                cpu, res = run(args, steps, path == 'jit', repeats)
                err = float(np.max(np.hypot(res.phi_record - ref_phi,
                                            res.dphi_record - ref_dphi)))
                careful = (res.batched + res.handed_back) / (size * steps)
                order = (math.log(rows[-1]['err_max'] / err)
                         / math.log(steps / rows[-1]['steps'])) if rows else math.nan
                rows.append({'steps': steps, 'cpu_s': cpu, 'err_max': err})
                share = (f'careful path {careful:6.1%} of steps, ' if path == 'numpy' else '')
                print(f'{path:5s} {case:22s} h = {1e3 * T_END / steps:6.3f} ms: error '
                      f'{err:8.2e}, order {order:5.2f}, CPU {1e3 * cpu:8.1f} ms '
                      f'({1e6 * cpu / size:7.1f} us a pendulum), {share}'
                      f'{np.sum(res.reversals) / size:.1f} reversals a pendulum', flush=True)
            curves[(path, case)] = rows
    return curves


def table(curves: dict[tuple[str, str], list[dict[str, Any]]], size: int,
          paths: tuple[str, ...]) -> None:
    """Print the time to each error level per case and path, and the ratio to integer n."""
    base = next(iter(CASES))
    print(f'\nCPU time to reach the error level (ms for {size} pendulums over {T_END:g} s; '
          f'us a pendulum), and the ratio to {base}')
    print(f'{"path":5s} {"level":>7s} ' + ' '.join(f'{c:>32s}' for c in CASES))
    worst: dict[str, float] = {}
    for path in paths:
        for level in LEVELS:
            t_base = time_to_error(curves[(path, base)], level)
            cells = []
            for case in CASES:
                t = time_to_error(curves[(path, case)], level)
                ratio = t / t_base
                if case != base and math.isfinite(ratio):
                    worst[path] = max(worst.get(path, 0.0), ratio)
                cells.append(f'{1e3 * t:8.1f} ms {1e6 * t / size:7.1f} us x{ratio:5.2f}')
            print(f'{path:5s} {level:7.0e} ' + ' '.join(f'{c:>32s}' for c in cells), flush=True)
    for path, ratio in worst.items():
        print(f'{path}: the non-integer cases cost at most {ratio:.2f}x n = 1 at equal error '
              f'(levels {LEVELS[0]:g} ... {LEVELS[-1]:g} rad)')


def figure(curves: dict[tuple[str, str], list[dict[str, Any]]], png: Path,
           paths: tuple[str, ...]) -> None:
    """Write the work-precision figure: global error against CPU time, one panel per path."""
    from pendulum_sim.pyplot_agg import pyplot

    plt = pyplot()
    fig, axes = plt.subplots(1, len(paths), figsize=(5.5 * len(paths), 4.2), squeeze=False)
    for ax, path in zip(axes[0], paths, strict=True):
        for case, marker in zip(CASES, 'oDs^', strict=True):
            rows = curves[(path, case)]
            ax.loglog([1e3 * r['cpu_s'] for r in rows], [r['err_max'] for r in rows],
                      marker=marker, label=case)
        for level in LEVELS:
            ax.axhline(level, color='grey', lw=0.5, alpha=0.5)
        ax.set_title(f'{path} sweep' + (' (jit=True)' if path == 'jit' else ''))
        ax.set_xlabel('CPU time of the case (ms)')
        ax.set_ylabel('global error, max over pendulums (rad, rad/s)')
        ax.legend(fontsize=8)
        ax.grid(True, which='both', alpha=0.3)
    fig.tight_layout()
    png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png, dpi=110)
    plt.close(fig)
    print(f'figure: {png}')


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--size', type=int, default=400, help='pendulums (default 400)')
    parser.add_argument('--repeats', type=int, default=3, help='timed repeats (default 3)')
    parser.add_argument('--paths', default='numpy,jit', help='numpy,jit (default both)')
    parser.add_argument('--png', default=str(RESULTS / 'work_precision_real_n.png'),
                        help='the figure (default bench/results/work_precision_real_n.png)')
    args = parser.parse_args()
    paths = tuple(p for p in args.paths.split(',') if p)
    if not paths or set(paths) - set(PATHS):
        parser.error(f'--paths must name numpy and/or jit, got {args.paths!r}')
    if args.size < 1 or args.repeats < 1:
        parser.error(f'--size and --repeats must be >= 1, got {args.size}, {args.repeats}')
    print(f'# {args.size} pendulums, {T_END:g} s, tau = 0, '
          f'{platform.processor() or platform.machine()}, {os.cpu_count()} cores, load '
          f'{os.getloadavg()[0]:.2f}', flush=True)
    curves = measure(args.size, args.repeats, paths)
    table(curves, args.size, paths)
    figure(curves, Path(args.png), paths)
    return 0


if __name__ == '__main__':
    sys.exit(main())
