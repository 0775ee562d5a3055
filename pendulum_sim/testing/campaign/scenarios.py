"""Each episode's scenario, drawn from a seed of its own.

Episode ``i`` draws from ``numpy.random.default_rng(SeedSequence(seed, spawn_key=(i,)))``, the
``i``-th child of the campaign's seed: first its parameters in file order, then its target
(one rule, :func:`draw`, for both). What an episode gets depends on the seed and its id only,
never on which episodes ran before it, where or when. A fixed value draws nothing, so a fixed
target leaves the parameters' draws as they are.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .spec import CampaignSpec, Distribution, Space, Value


@dataclass(frozen=True)
class Scenario:
    """What one episode runs with: its node parameters (file order) and its target (rad)."""

    values: dict[str, Value]
    target: float


def episode_rng(seed: int, episode: int) -> np.random.Generator:
    """Return the random generator of episode ``episode`` of a campaign seeded ``seed``."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(episode,)))


def draw(space: Space, rng: np.random.Generator, episode: int) -> Value:
    """Return episode ``episode``'s value of one scenario dimension.

    A distribution draws from ``rng``; a list gives its entry ``episode`` modulo its length; a
    value is itself.
    """
    if isinstance(space, Distribution):
        if space.kind == 'uniform':
            return float(rng.uniform(space.a, space.b))
        if space.kind == 'normal':
            return float(rng.normal(space.a, space.b))
        return float(math.exp(rng.uniform(math.log(space.a), math.log(space.b))))
    if isinstance(space, tuple):
        return space[episode % len(space)]
    return space


def episode_scenario(spec: CampaignSpec, episode: int) -> Scenario:
    """Return the parameter values and the target of episode ``episode``."""
    rng = episode_rng(spec.seed, episode)
    values = {name: draw(space, rng, episode) for name, space in spec.parameters}
    return Scenario(values, float(draw(spec.target, rng, episode)))


def scenario(spec: CampaignSpec, episode: int) -> dict[str, Value]:
    """Return the parameter values of episode ``episode`` (names in file order)."""
    return episode_scenario(spec, episode).values
