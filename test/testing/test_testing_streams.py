"""Many episodes' random streams over arrays: numpy's own generators' numbers, to the bit."""
from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from pendulum_sim.testing.campaign.scenarios import (
    STREAMS_FROM,
    episode_rng,
    episode_scenario,
    episode_scenarios,
)
from pendulum_sim.testing.campaign.spec import parse_spec
from pendulum_sim.testing.campaign.streams import Streams
from pendulum_sim.testing.errors import TestingError

# Seeds and episode numbers of one 32-bit word and of two (SeedSequence hashes a second word
# of the seed into the pool, and mixes a key's second word in after it), 0 and the largest.
EDGES = [(0, 0), (1, 1), (2**32 - 1, 2**32 - 1), (2**32, 2**32), (2**63 - 1, 7),
         (2**64 - 1, 2**40 + 3), (12345, 2**33)]


def seeds_and_episodes(count: int) -> tuple[list[int], list[int]]:
    rng = np.random.default_rng(2024)
    seeds = [*(s for s, _ in EDGES), *(int(x) for x in rng.integers(0, 2**63 - 1, count))]
    episodes = [*(e for _, e in EDGES), *(int(x) for x in rng.integers(0, 10**6, count))]
    return seeds, episodes


def test_the_streams_are_numpys_generators_of_each_episode_to_the_bit() -> None:
    seeds, episodes = seeds_and_episodes(200)
    streams = Streams(seeds, episodes)
    theirs = [episode_rng(s, e) for s, e in zip(seeds, episodes, strict=True)]
    # The PCG64 state after seeding: numpy's SeedSequence and srandom, word for word.
    want = [g.bit_generator.state['state']['state'] for g in theirs]
    got = [(int(hi) << 64) | int(lo) for hi, lo in zip(streams._hi, streams._lo, strict=True)]
    assert got == want
    bounds = [(-np.pi, np.pi), (0.0, 1.0), (-1e-300, 5e-301), (3.0, 3.5), (-2e6, 1e6)]
    for low, high in bounds * 3:
        drawn = streams.uniform(low, high)
        assert drawn.tobytes() == np.array([g.uniform(low, high) for g in theirs]).tobytes()


def test_a_batch_of_episodes_draws_what_each_draws_alone() -> None:
    spec = parse_spec(
        'controller: pendulum_sim.testing.examples:pd\nepisodes: 1\nseed: 77\nperiods: 1\n'
        'target: {distribution: uniform, low: -0.5, high: 0.5}\n'
        'parameters:\n'
        '  phi0: {distribution: uniform, low: -3.0, high: 3.0}\n'
        '  gamma: [0.05, 0.2, 1.0]\n'
        '  m: 0.25\n'
        '  friction: {distribution: loguniform, low: 1.0e-4, high: 0.3}\n'
        '  dphi0: {distribution: uniform, low: -1.0, high: 1.0}\n')
    seeds, episodes = seeds_and_episodes(60)
    for count in (STREAMS_FROM - 1, len(seeds)):   # each episode's generator, then arrays
        batch = episode_scenarios(spec, episodes[:count], seeds[:count])
        for k, (seed, i) in enumerate(zip(seeds[:count], episodes[:count], strict=True)):
            alone = episode_scenario(dataclasses.replace(spec, seed=seed), i)
            assert repr(batch.scenario(k)) == repr(alone), (seed, i)
    # Without seeds every episode takes the campaign's.
    batch = episode_scenarios(spec, list(range(40)))
    assert [batch.scenario(i) for i in range(40)] == [episode_scenario(spec, i)
                                                      for i in range(40)]


def test_a_normal_space_is_drawn_by_each_episodes_generator() -> None:
    # numpy draws a normal by rejection: a varying number of outputs, so no arrays.
    spec = parse_spec(
        'controller: pendulum_sim.testing.examples:pd\nepisodes: 1\nseed: 5\nperiods: 1\n'
        'target: 0.5\nparameters:\n  m: {distribution: normal, mean: 0.2, std: 0.01}\n'
        '  phi0: {distribution: uniform, low: 0.0, high: 1.0}\n')
    batch = episode_scenarios(spec, list(range(3 * STREAMS_FROM)))
    assert [batch.scenario(i) for i in range(3 * STREAMS_FROM)] == [
        episode_scenario(spec, i) for i in range(3 * STREAMS_FROM)]


@pytest.mark.parametrize(('seeds', 'episodes', 'message'), [
    ([-1], [0], 'seed must be an integer in [0, 2**64), got -1'),
    ([0], [2**64], 'episode must be an integer in [0, 2**64), got 18446744073709551616'),
    ([0, 1], [0], 'one seed per episode: got 2 seeds for 1 episodes'),
])
def test_streams_refuse_what_a_seed_sequence_cannot_take(seeds: list[int], episodes: list[int],
                                                         message: str) -> None:
    with pytest.raises(TestingError, match=re.escape(message)):
        Streams(seeds, episodes)
