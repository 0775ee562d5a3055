"""Each episode's scenario, drawn from a seed of its own.

Episode ``i`` draws from ``numpy.random.default_rng(SeedSequence(seed, spawn_key=(i,)))``, the
``i``-th child of the campaign's seed: first its parameters in file order, then its target,
then each disturbance pulse's torque, start and duration (one rule, :func:`draw`, for all).
What an episode gets depends on the seed and its id only, never on which episodes ran before
it, where or when. A fixed value (or a grid, or a list) draws nothing, so a fixed target leaves
the parameters' draws as they are.

:func:`episode_scenarios` draws many episodes at once (a vector environment's autoreset): the
same values, from the same generators taken over arrays (:mod:`.streams`).
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .spec import PULSES, CampaignSpec, Distribution, Grid, Space, TargetSpace, Value
from .streams import Streams

STREAMS_FROM = 16
"""Episodes from which :func:`episode_scenarios` draws over arrays (a :class:`Streams` costs
what about a dozen of numpy's generators cost to make; fewer episodes make their own)."""


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
    grid its value of ``episode`` (:meth:`~.spec.Grid.value`); a value is itself.
    """
    if isinstance(space, Distribution):
        if space.kind == 'uniform':
            return float(rng.uniform(space.a, space.b))
        if space.kind == 'normal':
            return float(rng.normal(space.a, space.b))
        return float(math.exp(rng.uniform(math.log(space.a), math.log(space.b))))
    if isinstance(space, tuple):
        return space[episode % len(space)]
    if isinstance(space, Grid):
        return space.value(episode)
    return space


def episode_scenario(spec: CampaignSpec, episode: int) -> Scenario:
    """Return the parameter values and the target of episode ``episode``."""
    rng = episode_rng(spec.seed, episode)
    values = {name: draw(space, rng, episode) for name, space in spec.parameters}
    target = float(draw(spec.target, rng, episode))
    if spec.disturbances:
        from pendulum_sim.joint.joint import pulses_text

        values[PULSES] = pulses_text([
            (float(draw(torque, rng, episode)), float(draw(start, rng, episode)),
             float(draw(duration, rng, episode)))
            for torque, start, duration in spec.disturbances])
    return Scenario(values, target)


def scenario(spec: CampaignSpec, episode: int) -> dict[str, Value]:
    """Return the parameter values of episode ``episode`` (names in file order)."""
    return episode_scenario(spec, episode).values


@dataclass(frozen=True)
class ScenarioColumns:
    """Many episodes' scenarios as columns: each parameter's values (file order), the targets."""

    values: dict[str, list[Value] | NDArray[np.float64]]
    target: NDArray[np.float64]

    def scenario(self, k: int) -> Scenario:
        """Return the scenario of the ``k``-th episode of the columns."""
        return Scenario({name: _item(col[k]) for name, col in self.values.items()},
                        float(self.target[k]))


def _item(value: object) -> Value:
    return value.item() if isinstance(value, np.generic) else value  # type: ignore[return-value]


def episode_scenarios(spec: CampaignSpec, episodes: Sequence[int],
                      seeds: Sequence[int] | None = None) -> ScenarioColumns:
    """Return the scenarios of ``episodes`` at once, each what :func:`episode_scenario` gives.

    ``seeds`` (one per episode, default the campaign's seed for all) seed each episode's
    stream as the campaign's seed does. Uniform and log-uniform draws are taken over arrays
    from :class:`~.streams.Streams`, each episode's own stream; where a space is normal (numpy
    draws it by rejection, a varying number of outputs) or the episodes are fewer than
    :data:`STREAMS_FROM`, each episode's own generator draws it.
    """
    seeds = [spec.seed] * len(episodes) if seeds is None else list(seeds)
    spaces = [space for _, space in spec.parameters] + [spec.target]
    draws = [s for s in spaces if isinstance(s, Distribution)]
    if (len(episodes) < STREAMS_FROM or any(s.kind == 'normal' for s in draws)
            or spec.disturbances):   # the pulses are drawn episode by episode
        each = [episode_scenario(dataclasses.replace(spec, seed=seed), i)
                for seed, i in zip(seeds, episodes, strict=True)]
        return ScenarioColumns({name: [e.values[name] for e in each]
                                for name in spec.scenario_names if name != 'target'},
                               np.array([e.target for e in each], dtype=np.float64))
    streams = Streams(seeds, list(episodes)) if draws else None
    values = {name: _draw_many(space, streams, episodes) for name, space in spec.parameters}
    target = np.asarray(_draw_many(spec.target, streams, episodes), dtype=np.float64)
    return ScenarioColumns(values, target)


def _draw_many(space: Space | TargetSpace, streams: Streams | None, episodes: Sequence[int]
               ) -> list[Value] | NDArray[np.float64]:
    """Return :func:`draw` of one dimension for each episode, one draw from each stream."""
    if isinstance(space, Distribution):
        assert streams is not None
        if space.kind == 'uniform':
            return streams.uniform(space.a, space.b)
        # math's exp, as draw takes it (numpy's may differ in the last bit)
        return np.array([math.exp(x) for x in
                         streams.uniform(math.log(space.a), math.log(space.b)).tolist()])
    if isinstance(space, tuple):
        return [space[i % len(space)] for i in episodes]
    if isinstance(space, Grid):
        return [space.value(i) for i in episodes]
    return [space] * len(episodes)
