"""Each episode's scenario, drawn from a seed of its own.

Episode ``i`` draws from ``numpy.random.default_rng(SeedSequence(seed, spawn_key=(i,)))``, the
``i``-th child of the campaign's seed, its parameters in file order: what an episode gets
depends on the seed and its id only, never on which episodes ran before it, where or when.
"""
from __future__ import annotations

import math

import numpy as np

from .spec import CampaignSpec, Distribution, Value


def episode_rng(seed: int, episode: int) -> np.random.Generator:
    """Return the random generator of episode ``episode`` of a campaign seeded ``seed``."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(episode,)))


def scenario(spec: CampaignSpec, episode: int) -> dict[str, Value]:
    """Return the parameter values of episode ``episode`` (names in file order)."""
    rng = episode_rng(spec.seed, episode)
    out: dict[str, Value] = {}
    for name, space in spec.parameters:
        if isinstance(space, Distribution):
            if space.kind == 'uniform':
                out[name] = float(rng.uniform(space.a, space.b))
            elif space.kind == 'normal':
                out[name] = float(rng.normal(space.a, space.b))
            else:
                out[name] = float(math.exp(rng.uniform(math.log(space.a), math.log(space.b))))
        elif isinstance(space, tuple):
            out[name] = space[episode % len(space)]
        else:
            out[name] = space
    return out
