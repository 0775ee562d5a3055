"""Benchmark the controller test bench; print the figures side by side in one run.

(a) in-process episodes: 10 s episodes (h = 1 ms, 100 Hz control, scene controller_test) of
    the example PD law, one after the other: episodes per second;
(b) batched episodes of the same law written with numpy (``pd_batch``), N at a time in
    lockstep, each with its own damping and start: 10 s episodes per second after a warm-up,
    run whole, or with ``--batch-periods`` below 1000 from runs of that many periods and twice
    as many (cost per episode + 1000 × cost per period), beside (a) as a ratio;
(c) ROS episodes (``pendulum_pd_controller`` against ``pendulum_node`` over DDS): the wall
    time of runs of two lengths; the intercept is the per-episode cost beyond the loop (three
    process starts, discovery, the recording), the slope the cost per control period;
(d) Dask overhead: the same in-process campaign episodes (each run, a failing one recorded,
    each row stored) by a plain loop in a process of its own, by ``pendulum_campaign``'s
    executor on its local Dask cluster of one single-threaded worker, and on the same cluster
    with Dask's default configuration (statistical profiler on, 20 ms ticks), in turn for
    ``--rounds`` rounds, wall and CPU time: (dask − loop) / loop per round and the median;
    the cluster's start-up apart; the load average before and after (the machine may be
    shared);
(e) a campaign of a vectorised law at the batched core's speed: ``--vector-episodes`` 10 s
    episodes of ``pd_batch`` (γ and φ0 drawn; with ``--vector-n`` also n ~ uniform(1.2, 1.6)),
    ``pendulum_campaign --workers 1`` end to end (its start-up, the cluster, the episode
    process, metrics, the SQLite store, the table, figures and summary) beside ``run_batch``
    alone on the same episodes' parameters, and their ratio; with ``--vector-jit`` also both
    on the compiled sweep (the campaign's ``jit: true``).

    ROS_DOMAIN_ID=150 .venv/bin/python bench/bench_testbench.py
    ROS_DOMAIN_ID=150 .venv/bin/python bench/bench_testbench.py --skip-ros --skip-campaign

Targets (issue 16): (b) >= 10x (a) at N = 10^4; (d) <= 10 %; (issue 30): (e) >= 0.7x
run_batch and >= 25x (a). Figures to read, not assertions.
"""
from __future__ import annotations

import argparse
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

from pendulum_sim.testing import closed_loop
from pendulum_sim.testing.batch import run_batch
from pendulum_sim.testing.campaign.episode import run_episode
from pendulum_sim.testing.examples import pd, pd_batch
from pendulum_sim.testing.loop import run_in_process
from pendulum_sim.testing.scene import scene_values

EPISODE_PERIODS = 1000   # 10 s at 100 Hz
CAMPAIGN = """
controller: pendulum_sim.testing.examples:{controller}
episodes: {episodes}
seed: 1
periods: {periods}
target: 0.5
parameters:
  gamma: {{distribution: loguniform, low: 0.02, high: 1.0}}
  phi0: {{distribution: uniform, low: 0.6, high: 1.4}}
requirements: ['settling_time < 3.0']
"""


def scenarios(count: int) -> list[dict[str, object]]:
    rng = np.random.default_rng(0)
    base = scene_values('controller_test', {})
    out = []
    for _ in range(count):
        v = dict(base)
        v['gamma'] = float(rng.uniform(0.02, 1.0))
        v['phi0'] = float(rng.uniform(0.6, 1.4))
        out.append(v)
    return out  # type: ignore[return-value]


def scalar_rate(episodes: int) -> float:
    cases = scenarios(episodes)
    run_in_process(pd, cases[0], 10)                       # warm-up
    start = time.perf_counter()
    for v in cases:
        run_in_process(pd, v, EPISODE_PERIODS)             # type: ignore[arg-type]
    return episodes / (time.perf_counter() - start)


def batched_rate(n: int, periods: int) -> float:
    """Return N batched 10 s episodes per second of wall time.

    With ``periods`` = 1000 the episodes are run whole; with fewer, runs of ``periods`` and
    2 ``periods`` separate the cost per episode (its configuration, its run's arrays) from the
    cost per period, and a 10 s episode costs the first plus 1000 times the second.
    """
    cases = scenarios(n)
    run_batch(pd_batch, cases[:64], 5)                     # warm-up: guard tables, compiles

    def timed(p: int) -> float:
        start = time.perf_counter()
        run_batch(pd_batch, cases, p)                      # type: ignore[arg-type]
        return time.perf_counter() - start

    if periods >= EPISODE_PERIODS:
        return n / timed(EPISODE_PERIODS)
    short, long = timed(periods), timed(2 * periods)
    per_period = (long - short) / periods
    return n / (short - per_period * periods + per_period * EPISODE_PERIODS)


def ros_costs(short: int, long: int) -> tuple[float, float]:
    cmd = [str(Path(sys.executable).parent / 'pendulum_pd_controller')]
    times = {}
    for periods in (short, long):
        best = float('inf')
        for _ in range(2):
            start = time.perf_counter()
            closed_loop(cmd, periods=periods)
            best = min(best, time.perf_counter() - start)
        times[periods] = best
    slope = (times[long] - times[short]) / (long - short)
    return times[short] - slope * short, slope


def dask_overhead(episodes: int, periods: int,
                  rounds: int) -> tuple[dict[str, list[tuple[float, float]]], float]:
    """Return each way's (wall, CPU) seconds per round, and the campaign cluster's start-up.

    Three ways do a campaign's work (each episode run, a failing one recorded, each row
    stored), in turn, round after round (the order rotates), one core each: a plain loop in a
    process of its own; ``pendulum_campaign``'s local cluster of one single-threaded worker
    (``make_client``, with ``CLUSTER_CONFIG``); and the same cluster with Dask's default
    configuration. CPU seconds count every process of the way (the loop's; this process with
    the scheduler, the nanny and the client, and the worker), so they hold still better than
    the wall time when the machine is shared; and the load moves, so compare within a round.
    """
    import psutil
    from distributed import Client, LocalCluster

    from pendulum_sim.testing.campaign.execute import make_client, run_pending
    from pendulum_sim.testing.campaign.spec import parse_spec
    from pendulum_sim.testing.campaign.store import EpisodeStore

    text = CAMPAIGN.format(controller='pd', episodes=episodes, periods=periods)
    spec = parse_spec(text)
    run_episode(text, 0, None)                              # warm-up
    times: dict[str, list[tuple[float, float]]] = {'loop': [], 'campaign': [], 'defaults': []}
    startup = math.nan

    def on_dask(way: str, folder: Path) -> tuple[float, float]:
        nonlocal startup
        start = time.perf_counter()
        if way == 'campaign':
            client = make_client(None, 1)
        else:
            client = Client(LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                         dashboard_address=None, silence_logs=40))
        client.run(run_episode, text, 0, None)              # the worker's warm-up
        if way == 'campaign' and math.isnan(startup):
            startup = time.perf_counter() - start
        try:
            # This process (scheduler, nannies, client, the rows stored) and each worker.
            procs = [psutil.Process(), *(psutil.Process(pid) for pid in
                                         client.run(os.getpid).values())]
            store = EpisodeStore(folder)
            store.create(text, False)
            start, cpu = time.perf_counter(), _cpu_seconds(procs)
            run_pending(spec, store, client, progress=False)
            return time.perf_counter() - start, _cpu_seconds(procs) - cpu
        finally:
            cluster = client.cluster
            client.close()
            cluster.close()

    with tempfile.TemporaryDirectory() as tmp:
        for r in range(rounds):
            ways = list(times)
            for way in ways[r % 3:] + ways[:r % 3]:
                folder = Path(tmp) / f'{way}{r}'
                if way == 'loop':
                    # In a process of its own: this one runs the Dask scheduler's threads.
                    proc = subprocess.run([sys.executable, __file__, '--plain-loop',
                                           str(episodes), str(periods), str(folder)],
                                          capture_output=True, text=True, check=True)
                    wall, cpu = proc.stdout.split()[-2:]
                    times[way].append((float(wall), float(cpu)))
                else:
                    times[way].append(on_dask(way, folder))
    return times, startup


def plain_loop(episodes: int, periods: int, out: str) -> tuple[float, float]:
    """Run a campaign's episodes one after the other here; return the wall and CPU time."""
    from pendulum_sim.testing.campaign.store import EpisodeStore

    text = CAMPAIGN.format(controller='pd', episodes=episodes, periods=periods)
    run_episode(text, 0, None)                              # warm-up, as the worker's
    store = EpisodeStore(Path(out))
    store.create(text, False)
    start, cpu = time.perf_counter(), time.process_time()
    for i in range(episodes):
        store.write([run_episode(text, i, out)])
    return time.perf_counter() - start, time.process_time() - cpu


def vector_campaign(episodes: int, with_n: bool, jit: bool = False) -> tuple[float, float]:
    """Return the episodes per second of run_batch alone and of pendulum_campaign end to end.

    With ``jit`` both on the compiled sweep (the campaign's ``jit: true``; run_batch after
    ``warm_up_batch``, as the campaign's episode process does before its clock starts).
    """
    from pendulum_sim.testing.batch import warm_up_batch
    from pendulum_sim.testing.campaign.episode import episode_values
    from pendulum_sim.testing.campaign.scenarios import episode_scenario
    from pendulum_sim.testing.campaign.spec import parse_spec

    text = CAMPAIGN.format(controller='pd_batch', episodes=episodes, periods=EPISODE_PERIODS)
    if with_n:
        text = text.replace('requirements:', '  n: {distribution: uniform, low: 1.2, '
                            'high: 1.6}\nrequirements:')
    if jit:
        text = text.replace('seed: 1', 'seed: 1\njit: true')
    spec = parse_spec(text)
    drawn = [episode_scenario(spec, i) for i in range(episodes)]
    values = [episode_values(spec, d.values) for d in drawn]
    if jit:
        warm_up_batch(values)
    run_batch(pd_batch, values[:64], 5, targets=[d.target for d in drawn[:64]],   # warm-up
              jit=jit)
    start = time.perf_counter()
    run_batch(pd_batch, values, spec.periods, targets=[d.target for d in drawn], jit=jit)
    alone = episodes / (time.perf_counter() - start)
    del values
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / 'campaign.yaml'
        path.write_text(text)
        start = time.perf_counter()
        proc = subprocess.run([str(Path(sys.executable).parent / 'pendulum_campaign'),
                               str(path), '--out', str(Path(tmp) / 'out'), '--workers', '1',
                               '--no-progress'], capture_output=True, text=True)
        wall = time.perf_counter() - start
        if proc.returncode not in (0, 1):
            raise RuntimeError(proc.stderr)
    return alone, episodes / wall


def _cpu_seconds(procs: list[Any]) -> float:
    """Return the user + system CPU seconds the processes (psutil) have used so far."""
    return float(sum(p.cpu_times().user + p.cpu_times().system for p in procs))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--scalar-episodes', type=int, default=20)
    parser.add_argument('--batch-n', type=int, default=10_000)
    parser.add_argument('--batch-periods', type=int, default=EPISODE_PERIODS)
    parser.add_argument('--ros-periods', type=int, nargs=2, default=(20, 4020))
    parser.add_argument('--campaign-episodes', type=int, default=1000)
    parser.add_argument('--campaign-periods', type=int, default=300)
    parser.add_argument('--rounds', type=int, default=3)
    parser.add_argument('--vector-episodes', type=int, default=10_000)
    parser.add_argument('--vector-n', action='store_true',
                        help='(e) also with n drawn (slow until the core batches real n)')
    parser.add_argument('--vector-jit', action='store_true',
                        help='(e) also with jit: true (the compiled sweep, numba)')
    parser.add_argument('--only-vector', action='store_true', help='run (e) alone')
    parser.add_argument('--skip-ros', action='store_true')
    parser.add_argument('--skip-campaign', action='store_true',
                        help='leave out (d), the Dask overhead: (a) and (b) alone')
    parser.add_argument('--plain-loop', nargs=3, metavar=('EPISODES', 'PERIODS', 'OUT'),
                        help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.plain_loop:
        print(*plain_loop(int(args.plain_loop[0]), int(args.plain_loop[1]), args.plain_loop[2]))
        return 0
    print('# controller test bench', flush=True)
    scalar = scalar_rate(args.scalar_episodes)
    print(f'(a) in-process, scalar : {scalar:9.2f} episodes/s (10 s episodes, h = 1 ms, '
          '100 Hz)', flush=True)
    cases = [(False, False), (True, False)] if args.vector_n else [(False, False)]
    if args.vector_jit:
        cases += [(with_n, True) for with_n, _ in cases]
    for with_n, jit in cases:
        load = os.getloadavg()[0]
        alone, campaign = vector_campaign(args.vector_episodes, with_n, jit)
        drawn = 'gamma, phi0 and n' if with_n else 'gamma and phi0'
        drawn += ' drawn, jit: true (compiled sweep)' if jit else ' drawn'
        print(f'(e) {args.vector_episodes} episodes of pd_batch, {drawn} (load average '
              f'{load:.2f} before, {os.getloadavg()[0]:.2f} after): run_batch {alone:8.1f} '
              f'episodes/s, pendulum_campaign --workers 1 end to end {campaign:8.1f} '
              f'episodes/s = {campaign / alone:.2f} x run_batch = {campaign / scalar:.1f} x (a)',
              flush=True)
    if args.only_vector:
        return 0
    for n in sorted({1000, args.batch_n}):
        rate = batched_rate(n, args.batch_periods)
        how = ('whole' if args.batch_periods >= EPISODE_PERIODS else
               f'from {args.batch_periods} and {2 * args.batch_periods} periods')
        print(f'(b) batched, N = {n:6d}: {rate:9.2f} episodes/s  = {rate / scalar:5.2f} x (a)'
              f'  (10 s episodes, {how})', flush=True)
    if not args.skip_ros:
        fixed, per = ros_costs(*args.ros_periods)
        print(f'(c) ROS episode: {fixed:.3f} s per episode beyond the loop (process starts, '
              f'discovery, recording); {1e3 * per:.3f} ms per control period '
              f'({1 / per:.0f} periods/s)', flush=True)
    if args.skip_campaign:
        return 0
    load = os.getloadavg()[0]
    times, startup = dask_overhead(args.campaign_episodes, args.campaign_periods, args.rounds)
    print(f'(d) {args.campaign_episodes} episodes of {args.campaign_periods} periods, one core '
          f'each, {args.rounds} rounds (load average {load:.2f} before, '
          f'{os.getloadavg()[0]:.2f} after; cluster start-up {startup:.2f} s):', flush=True)
    labels = {'loop': 'plain loop', 'campaign': 'Dask, campaign configuration',
              'defaults': 'Dask, Dask defaults'}
    for what, k in (('wall', 0), ('CPU', 1)):
        for way, label in labels.items():
            x = [t[k] for t in times[way]]
            line = f'    {what:4s} {label:29s}: ' + ', '.join(f'{v:6.2f}' for v in x) + ' s'
            if way != 'loop':
                ratios = [d[k] / lp[k] - 1.0 for lp, d in zip(times['loop'], times[way],
                                                               strict=True)]
                line += ('; overhead per round ' + ', '.join(f'{100 * r:+.1f}' for r in ratios)
                         + f' %, median {100 * statistics.median(ratios):+.1f} %')
            print(line, flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
