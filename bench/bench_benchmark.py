"""Benchmark the swing-up benchmark: its criteria as batched campaigns beside one episode at a
time; print the figures side by side in one run.

(a) ``benchmark()`` of the vectorised reference controller (``energy_lqr``) end to end, as
    ``pendulum_benchmark`` runs it: every criterion a campaign (consistency, robustness and
    sensitivity ``--episodes`` each, the torque-limit list of ``--limits``, the
    ``--roa-grid`` squared region of attraction, the nominal run), 10 s episodes at 1 kHz
    physics and 200 Hz control, on a local Dask cluster of ``--workers`` (the core count),
    with ``benchmark.yaml``, the figures and the GIF; wall time;
(b) the same criteria's episodes one at a time in this process, the way the published
    benchmarks run theirs: the same episodes (each campaign's drawn scenario), each a closed
    loop of the law called on one state at a time (``run_in_process``) and measured
    (``swing_up_metrics``); wall time, or with ``--serial-sample K`` the time of the first K
    episodes of each criterion scaled to all of them (said so);
(c) the ratio (b) / (a).

It says first whether the reference LQR gain is on disk (``swing_up_law.lqr``: kept by the
first process that solved it, so later ones need not import python-control): on a machine's
first run each process of (a) pays that import, some 2 s of CPU.

With ``--references`` the reference controllers' results are written to
``pendulum_sim/testing/swing_up/references.yaml`` (what ``benchmark.png`` compares with) and
their ``benchmark.yaml`` and figures kept under ``bench/results/benchmark/``, with the LQR
balance's region of attraction near upright (``lqr_balance_roa.png``).

    .venv/bin/python bench/record.py bench/bench_benchmark.py
    .venv/bin/python bench/bench_benchmark.py --serial-sample 10

Target (issue 38): (a) <= 60 s and (b) / (a) >= 20. Figures to read, not assertions.
"""
from __future__ import annotations

import argparse
import math
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import yaml

from pendulum_sim.testing import benchmark
from pendulum_sim.testing.campaign.scenarios import episode_scenario
from pendulum_sim.testing.campaign.spec import load_controller, parse_spec
from pendulum_sim.testing.errors import TestingError
from pendulum_sim.testing.loop import run_in_process
from pendulum_sim.testing.scene import read_scene, with_overrides
from pendulum_sim.testing.swing_up.criteria import CRITERIA, Settings, campaign_text
from pendulum_sim.testing.swing_up.figures import comparison_figure

ROOT = Path(__file__).resolve().parents[1]
LAW = 'pendulum_sim.testing.examples:energy_lqr'
REFERENCES = {'energy_lqr': 'pendulum_sim.testing.examples:energy_lqr',
              'saturated_pd': 'pendulum_sim.testing.examples:saturated_pd'}


def lqr_kept() -> str:
    """Return whether the reference LQR gain is on disk now (``swing_up_law.lqr_cache_file``)."""
    import numpy as np

    from pendulum_sim.controller.swing_up_law import lqr_cache_file
    from pendulum_sim.testing.examples import SWING_UP

    a, b = SWING_UP.linearised()
    path = lqr_cache_file(a, b, np.diag(SWING_UP.q), np.array([[SWING_UP.r]]))
    return ('on disk: every process reads it (no python-control import)'
            if path is not None and path.is_file() else
            'not on disk: the first processes import python-control and solve it')


def one_at_a_time(settings: Settings, sample: int | None) -> tuple[float, int, int]:
    """Return (seconds, episodes run, episodes in all) of the criteria run one by one."""
    law = load_controller(LAW)
    base = settings.base
    spent, ran, total = 0.0, 0, 0
    for criterion in settings.criteria:
        spec = parse_spec(campaign_text(settings, criterion))
        count = spec.episodes if sample is None else min(sample, spec.episodes)
        began = time.perf_counter()
        for i in range(count):
            drawn = episode_scenario(spec, i)
            values = with_overrides(base, drawn.values)
            try:
                run = run_in_process(law, values, spec.periods)
                run.swing_up_metrics(drawn.target, spec.goal_box)
            except TestingError:
                pass
        took = time.perf_counter() - began
        spent += took * spec.episodes / count
        ran += count
        total += spec.episodes
        print(f'    {criterion:<13} {count:5d} of {spec.episodes:5d} episodes: {took:8.2f} s'
              + ('' if count == spec.episodes else
                 f' (scaled: {took * spec.episodes / count:.1f} s)'), flush=True)
    return spent, ran, total


def record_references(args: argparse.Namespace) -> None:
    """Benchmark each reference controller; keep the results where the figure reads them."""
    keep = ROOT / 'bench' / 'results' / 'benchmark'
    keep.mkdir(parents=True, exist_ok=True)
    found: dict[str, dict[str, float | None]] = {}
    results = {}
    for name, law in REFERENCES.items():
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / name
            result = benchmark(law, out=out, episodes=args.episodes, roa_grid=args.roa_grid,
                               limits=args.limits, workers=args.workers, seed=args.seed)
            print(f'\n# {name}\n{result.table()}', flush=True)
            found[law] = {k: (None if v is None else float(v)) for k, v in
                          result.values.items()}
            results[name] = result
            for item in ('benchmark.yaml', 'benchmark.png', 'roa.png', 'swing_up.gif'):
                if (out / item).is_file():
                    shutil.copy(out / item, keep / f'{name}_{item}')
    with tempfile.TemporaryDirectory() as tmp:   # the LQR alone: a region worth a map
        out = Path(tmp) / 'lqr'
        span = ((math.pi - 1.2, math.pi + 1.2), (-3.0, 3.0))
        benchmark('pendulum_sim.testing.examples:lqr_balance', out=out, criteria=('roa',),
                  roa_grid=args.roa_grid, roa_span=span, workers=args.workers, seed=args.seed)
        shutil.copy(out / 'roa.png', keep / 'lqr_balance_roa.png')
    target = ROOT / 'pendulum_sim' / 'testing' / 'swing_up' / 'references.yaml'
    target.write_text("# The reference controllers' swing-up benchmark results (written by "
                      'bench/bench_benchmark.py --references):\n# what benchmark.png sets '
                      'a controller beside.\n' + yaml.safe_dump(found, sort_keys=False),
                      encoding='utf-8')
    for name, result in results.items():   # each beside the others, now recorded
        comparison_figure(result, keep / f'{name}_benchmark.png')
    print(f'\nwrote {target.relative_to(ROOT)} and bench/results/benchmark/')


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--episodes', type=int, default=100)
    parser.add_argument('--roa-grid', type=int, default=50)
    parser.add_argument('--limits', type=int, default=20)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--workers', type=int, default=os.cpu_count() or 1)
    parser.add_argument('--serial-sample', type=int, default=None, metavar='K',
                        help='time the first K episodes of each criterion one by one and '
                        'scale (default: run them all)')
    parser.add_argument('--skip-serial', action='store_true')
    parser.add_argument('--references', action='store_true',
                        help="record the reference controllers' results instead")
    args = parser.parse_args()
    if args.references:
        record_references(args)
        return 0
    print(f'# swing-up benchmark of {LAW}: consistency, robustness, sensitivity '
          f'{args.episodes} episodes each, {args.limits} torque limits, a {args.roa_grid} x '
          f'{args.roa_grid} region of attraction, the nominal run; 10 s episodes, h = 1 ms, '
          f'200 Hz control')
    print(f'the reference LQR gain: {lqr_kept()}')
    with tempfile.TemporaryDirectory() as tmp:
        began = time.perf_counter()
        result = benchmark(LAW, out=Path(tmp) / 'out', episodes=args.episodes,
                           roa_grid=args.roa_grid, limits=args.limits, workers=args.workers,
                           seed=args.seed)
        batched = time.perf_counter() - began
    episodes = sum(int(c['episodes']) for c in result.criteria.values())
    print(result.table())
    print(f'(a) benchmark(), {args.workers} local workers, end to end: {batched:8.2f} s '
          f'({episodes} episodes, cluster start-up, figures and GIF included)', flush=True)
    if args.skip_serial:
        return 0
    settings = Settings(controller=LAW, episodes=args.episodes, roa_grid=args.roa_grid,
                        limits=args.limits, seed=args.seed, base=read_scene('swing_up'),
                        criteria=CRITERIA)
    print('(b) one episode at a time in this process:')
    serial, ran, total = one_at_a_time(settings, args.serial_sample)
    how = 'measured' if ran == total else f'scaled from {ran} of {total} episodes'
    print(f'(b) total: {serial:8.2f} s ({how})')
    print(f'(c) (b) / (a) = {serial / batched:.1f} x' if batched > 0 else '(c) -')
    return 0 if math.isfinite(serial) else 1


if __name__ == '__main__':
    sys.exit(main())
