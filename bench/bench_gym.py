"""Benchmark the vector environment against Gymnasium's Pendulum-v1 at the same N, one run.

For N = 1, 64, 1024, 16384 (``--sizes``): environment steps per second (N per call of
``step``) of

(a) ``gymnasium.make_vec('pendulum_sim/DampedPendulum-v0', num_envs=N,
    vectorization_mode='vector_entry_point')``: RK4 at h = 1 ms with the guard and reversal
    handling, 10 substeps per 10 ms control period, all N in one batched core call
    (``Sweep``), random torques in the action space;
(b) the same with episodes of 10 steps, so that every 10th step autoresets every
    environment (drawing their episodes from the campaign spaces together, over arrays, and
    preparing the sweep anew);
(c) ``gymnasium.make_vec('Pendulum-v1', num_envs=N, vectorization_mode='sync')``
    (``SyncVectorEnv``: N ``PendulumEnv``, one explicit Euler step of 50 ms each);
(d) Pendulum-v1's vector entry point, where Gymnasium registers one.

Each figure times whole ``step`` calls after a reset and a warm-up, for at least
``--seconds`` of wall time; (a) / (c) and (b) / (c) are printed beside them, and how the
vector env's periods were taken in (b) (``Lockstep.stats``: in the sweep, by a joint near its
speed bound). Targets: (a) >= 5 x (c) at N >= 1024 (issue 28); (b) >= 5 x (c) at N >= 1024,
resets batched like steps (issue 38). Figures to read, not assertions.

    .venv/bin/python bench/bench_gym.py
    .venv/bin/python bench/record.py bench/bench_gym.py
"""
from __future__ import annotations

import argparse
import time
from typing import Any

import gymnasium
import numpy as np

import pendulum_sim.gym  # noqa: F401  (registers the environments)

SIZES = (1, 64, 1024, 16384)


def rate(env: Any, seconds: float, seed: int = 0) -> float:
    """Return environment steps per second of ``env`` (a vector env) under random actions.

    ``env`` is reset and stepped once before the clock starts, then stepped on.
    """
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    space = env.action_space
    actions = [rng.uniform(space.low, space.high).astype(space.dtype) for _ in range(8)]
    for a in actions[:3]:   # warm-up: first calls, caches
        env.step(a)
    calls = 0
    start = time.perf_counter()
    while True:
        env.step(actions[calls % len(actions)])
        calls += 1
        elapsed = time.perf_counter() - start
        if elapsed >= seconds and calls >= 3:
            return calls * env.num_envs / elapsed


def main() -> None:
    """Print the figures for each N side by side."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--sizes', type=int, nargs='+', default=list(SIZES))
    parser.add_argument('--seconds', type=float, default=2.0,
                        help='wall time per figure (default 2)')
    args = parser.parse_args()
    ours = gymnasium.spec('pendulum_sim/DampedPendulum-v0')
    peer = gymnasium.spec('Pendulum-v1')
    print('# Gymnasium vector environments: environment steps per second')
    print(f'(a) pendulum_sim/DampedPendulum-v0, vector entry point: RK4, h = 1 ms, 10 substeps '
          f'per 10 ms step, episodes of {ours.max_episode_steps} steps')
    print('(b) the same, episodes of 10 steps (every 10th step resets all N)')
    print('(c) Pendulum-v1, SyncVectorEnv: one Euler step of 50 ms per step')
    try:
        gymnasium.make_vec('Pendulum-v1', num_envs=2, vectorization_mode='vector_entry_point')
        has_entry = True
    except gymnasium.error.Error as exc:
        has_entry = False
        print(f'(d) Pendulum-v1, vector entry point: none registered '
              f'(vector_entry_point={peer.vector_entry_point}; gymnasium says: {exc})')
    print(f'gymnasium {gymnasium.__version__}, numpy {np.__version__}')
    for n in args.sizes:
        a = rate(gymnasium.make_vec('pendulum_sim/DampedPendulum-v0', num_envs=n,
                                    vectorization_mode='vector_entry_point'), args.seconds)
        short = gymnasium.make_vec('pendulum_sim/DampedPendulum-v0', num_envs=n,
                                   vectorization_mode='vector_entry_point', max_episode_steps=10)
        b = rate(short, args.seconds)
        taken = short.unwrapped.runner.pendulums.stats
        c = rate(gymnasium.make_vec('Pendulum-v1', num_envs=n, vectorization_mode='sync'),
                 args.seconds)
        line = (f'N = {n:5d}: (a) {a:12,.0f}  (b) {b:12,.0f}  (c) {c:12,.0f} steps/s  '
                f'(a)/(c) = {a / c:6.2f} x  (b)/(c) = {b / c:6.2f} x')
        if has_entry:
            d = rate(gymnasium.make_vec('Pendulum-v1', num_envs=n,
                                        vectorization_mode='vector_entry_point'), args.seconds)
            line += f'  (d) {d:12,.0f}  (a)/(d) = {a / d:6.2f} x'
        print(line, flush=True)
        print(f'          (b) periods: {taken.swept:,} in the sweep, {taken.by_joint} by a joint, '
              f'{taken.prepared} sweeps prepared', flush=True)


if __name__ == '__main__':
    main()
