"""Benchmark real n on the work-precision plane: CPU time at equal global error, both sweeps.

Run: ``.venv/bin/python bench/bench_work_precision_real_n.py`` (``--size``, ``--repeats``,
``--png``, ``--paths``). Issue 39, item 6: ``bench_real_n``'s population (:func:`population`:
γ uniform in [0.1, 2], φ0 in [−2, 2] rad, φ'0 in [−3, 3] rad/s, ω0² = 9.8 s⁻², τ = 0), 400
pendulums over 2 s, for the exponent cases n = 1 for all (integer, smooth), integer n = 1..5
mixed (``bench_real_n``'s (a): kinks split at reversals, stiff transients, no grading), n = 1.5
for all and n uniform in [1, 3], all distinct (graded at reversals); on the numpy sweep and the
compiled
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
between successive h), then the tables (per error level the CPU time of the case, 400
pendulums, and its ratio to n = 1; then to the integer exponents mixed; both paths).

The lever (``--no-lever`` leaves it out): the compiled path's n = 1.5 and distinct-n curves
again with the grading window around reversals set for the study, ``reversal.GRADE_WINDOW`` =
0.5, 0.25, 0.1, 0.03 and 0 (no grading: the order falls to n + 1 near reversals) instead of
1, and the issue's candidate window (:func:`window_variants`, κ = 1 and 10), each printed
as a table of its own. The figure (error against CPU time: numpy, compiled, the lever on
n = 1.5) goes to ``--png``. Asserts nothing.
"""
from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

import pendulum_sim.core.problem as problem_module
import pendulum_sim.core.reversal as reversal
from pendulum_sim.core import PendulumParams
from pendulum_sim.core.problem import Problem
from pendulum_sim.core.sweep import sweep
from pendulum_sim.reports.reference import reference
from pendulum_sim.reports.work_precision import time_to_error

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_real_n import population

T_END = 2.0
RECORDS = 5  # the error is read at t = 0.4, 0.8, ..., 2 s
STEPS = (250, 350, 500, 700, 1000, 1400, 2000, 2800, 4000)  # h = 2 s / N: 8 ms ... 0.5 ms
LEVELS = (1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
CASES = {'n = 1 (integer)': lambda size: np.full(size, 1.0),
         'integer n = 1..5': lambda size: population(size, 'integer n = 1..5')['n'],
         'n = 1.5 for all': lambda size: np.full(size, 1.5),
         'distinct n in [1, 3]': lambda size: population(size, 'distinct n in [1, 3]')['n']}
PATHS = ('numpy', 'jit')
LEVER_CASES = ('n = 1.5 for all', 'distinct n in [1, 3]')
WINDOWS = (0.5, 0.25, 0.1, 0.03, 0.0)  # reversal.GRADE_WINDOW, today 1; 0: no grading
KAPPAS = (1.0, 10.0)  # the candidate window's constant
ORIGINAL_POST = Problem.__post_init__
RESULTS = Path(__file__).resolve().parent / 'results'


def case_args(size: int, case: str) -> dict[str, Any]:
    """Return the sweep's arguments for ``size`` pendulums of ``case``."""
    args = population(size, 'n = 1.5 for all')
    args['n'] = CASES[case](size)
    return args


def references(args: dict[str, Any]) -> tuple[tuple[np.ndarray, np.ndarray], float]:
    """Return the reference (φ, φ') at the record times (shape (RECORDS + 1, N)), its CPU s."""
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
    return (phi, dphi), time.process_time() - t0


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


Curves = dict[tuple[str, str], list[dict[str, Any]]]


def curve(path: str, case: str, args: dict[str, Any], refs: tuple[np.ndarray, np.ndarray],
          repeats: int, label: str = '') -> list[dict[str, Any]]:
    """Run one case on one path at every h, print each run, return its (h, error, CPU) rows."""
    size = len(args['n'])
    rows: list[dict[str, Any]] = []
    for steps in STEPS:
        cpu, res = run(args, steps, path == 'jit', repeats)
        err = float(np.max(np.hypot(res.phi_record - refs[0], res.dphi_record - refs[1])))
        order = (math.log(rows[-1]['err_max'] / err) / math.log(steps / rows[-1]['steps'])
                 if rows else math.nan)
        rows.append({'steps': steps, 'cpu_s': cpu, 'err_max': err})
        careful = (res.batched + res.handed_back) / (size * steps)
        share = f'careful path {careful:6.1%} of steps, ' if path == 'numpy' else ''
        print(f'{path:5s} {case + label:34s} h = {1e3 * T_END / steps:6.3f} ms: error '
              f'{err:8.2e}, order {order:5.2f}, CPU {1e3 * cpu:8.1f} ms '
              f'({1e6 * cpu / size:7.1f} us a pendulum), {share}'
              f'{np.sum(res.reversals) / size:.1f} reversals a pendulum', flush=True)
    return rows


def table(curves: Curves, size: int, rows: list[tuple[str, str]], title: str,
          base: str = 'n = 1 (integer)') -> dict[str, float]:
    """Print the time to each error level of each (path, case) row and its ratio to ``base``.

    Returns the largest ratio of each row (over the levels both curves reach).
    """
    print(f'\n{title}\nCPU time to reach the error level (ms for {size} pendulums over '
          f'{T_END:g} s), and the ratio to {base} on the same path')
    print(f'{"path":5s} {"case":38s} ' + ' '.join(f'{lv:>16.0e}' for lv in LEVELS))
    worst: dict[str, float] = {}
    for path, case in rows:
        cells = []
        for level in LEVELS:
            t = time_to_error(curves[(path, case)], level)
            ratio = t / time_to_error(curves[(path, base)], level)
            if math.isfinite(ratio):
                worst[f'{path} {case}'] = max(worst.get(f'{path} {case}', 0.0), ratio)
            cells.append(f'{1e3 * t:7.1f} x{ratio:6.2f}')
        print(f'{path:5s} {case:38s} ' + ' '.join(f'{c:>16s}' for c in cells), flush=True)
    return worst


def window_variants() -> list[tuple[str, Callable[[], None]]]:
    """Return the grading windows the lever study sets: (label, set it) pairs.

    ``reversal.GRADE_WINDOW`` scaled (the window S = W/ω0 of every pendulum), and the issue's
    candidate S = (γ c_n |φ''|^(n−1) / (κ ω0⁴))^(1/(4−n)), c_n = |n(n−1)(n−2)(n−3)| (the
    coefficient of the t^(n−4) fourth derivative of the damping next to a reversal, where
    φ' ≈ φ'' t), at the largest |φ''| a reversal can have without input (ω0²: the widest the
    state-dependent window gets for n > 1), capped at today's 1/ω0. The candidate is set for
    the study only (``Problem.reach`` replaced after it is made); the package keeps 1/ω0.
    """
    def scaled(w: float) -> Callable[[], None]:
        def put() -> None:
            reversal.GRADE_WINDOW = w
        return put

    def candidate(kappa: float) -> Callable[[], None]:
        def reach(prob: Problem) -> float:
            n, w0 = prob.n, prob.omega0
            c_n = abs(n * (n - 1.0) * (n - 2.0) * (n - 3.0))
            s = (prob.gamma * c_n * prob.w2 ** (n - 1.0) / (kappa * w0 ** 4)) ** (1.0 / (4.0 - n))
            return min(prob.reach, s)

        def put() -> None:
            def post(prob: Problem) -> None:
                ORIGINAL_POST(prob)
                if prob.reach > 0.0:
                    object.__setattr__(prob, 'reach', reach(prob))
            problem_module.Problem.__post_init__ = post  # type: ignore[method-assign]
        return put

    return [*((f'W = {w:g}/omega0' if w else 'no grading', scaled(w)) for w in WINDOWS),
            *((f'candidate S, kappa = {k:g}', candidate(k)) for k in KAPPAS)]


def restore() -> None:
    """Put the package's grading window back (W = 1, no candidate)."""
    reversal.GRADE_WINDOW = 1.0
    problem_module.Problem.__post_init__ = ORIGINAL_POST  # type: ignore[method-assign]


def figure(curves: Curves, png: Path, paths: tuple[str, ...], lever: list[str]) -> None:
    """Write the work-precision figure: error against CPU time per path, and the lever."""
    from pendulum_sim.pyplot_agg import pyplot

    plt = pyplot()
    panels = [*paths, *(['lever'] if lever else [])]
    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 4.4), squeeze=False)
    for ax, panel in zip(axes[0], panels, strict=True):
        if panel == 'lever':
            keys = [('jit', next(iter(CASES))), ('jit', LEVER_CASES[0])] + [
                ('jit', c) for c in lever]
            title = 'jit: the grading window (n = 1.5)'
        else:
            keys = [(panel, c) for c in CASES]
            title = f'{panel} sweep' + (' (jit=True)' if panel == 'jit' else '')
        for (path, case), marker in zip(keys, 'oDs^v<>p*hX', strict=False):
            rows = curves[(path, case)]
            ax.loglog([1e3 * r['cpu_s'] for r in rows], [r['err_max'] for r in rows],
                      marker=marker, ms=4, label=case.replace(f'{LEVER_CASES[0]}, ', ''))
        for level in LEVELS:
            ax.axhline(level, color='grey', lw=0.5, alpha=0.5)
        ax.set_title(title)
        ax.set_xlabel('CPU time of the case (ms)')
        ax.set_ylabel('global error, max over pendulums')
        ax.legend(fontsize=7)
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
    parser.add_argument('--no-lever', action='store_true',
                        help='leave out the grading-window study (compiled path)')
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
    curves: Curves = {}
    lever: list[str] = []
    study = 'jit' in paths and not args.no_lever
    for case in CASES:
        pop = case_args(args.size, case)
        refs, ref_cpu = references(pop)
        print(f'# {case}: reference (DOP853 restarted at reversals) {ref_cpu:.1f} s CPU',
              flush=True)
        for path in paths:
            curves[(path, case)] = curve(path, case, pop, refs, args.repeats)
        if study and case in LEVER_CASES:
            for label, put in window_variants():
                put()
                try:
                    key = f'{case}, {label}'
                    curves[('jit', key)] = curve('jit', case, pop, refs, args.repeats,
                                                 f', {label}')
                finally:
                    restore()
                if case == LEVER_CASES[0]:
                    lever.append(key)
    worst = table(curves, args.size, [(p, c) for p in paths for c in CASES],
                  'The package (grading window 1/omega0)')
    if study:
        table(curves, args.size, [k for k in curves if k[0] == 'jit' and k[1] not in CASES],
              'The lever (compiled path): the grading window set for the study')
    mixed = table(curves, args.size, [(p, c) for p in paths for c in LEVER_CASES],
                  'The same against the integer exponents mixed', 'integer n = 1..5')
    print()
    for key in (f'{p} {c}' for p in paths for c in LEVER_CASES):
        print(f'{key}: at most {worst[key]:.2f}x n = 1 and {mixed[key]:.2f}x integer n = 1..5 '
              f'at equal error (over the levels both reach)')
    figure(curves, Path(args.png), paths, lever)
    return 0


if __name__ == '__main__':
    sys.exit(main())
