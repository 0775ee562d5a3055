"""Synthetic driven records for the identification tests and benchmark: known joint, PD loop.

Each record is a closed loop of the shipped PD law (``pendulum_sim.testing.examples.pd_batch``,
gravity compensation with the default m g l) run by the package's own joint in a batch
(``testing.batch.run_batch`` on the compiled sweep: the node's steps of 1 ms, a command every
10 ms), from a random state, tracking a reference A sin(2π f t) of a random amplitude (a fixed
target would leave the joint at rest, where its damping shows nothing). The joint's inertia,
mass, length, damping law (a non-integer n), Coulomb friction are drawn per record; the record
then carries what a joint with a biased torque sensor and a noisy encoder logs: the position
with Gaussian noise, and the effort less a constant offset (the applied torque is the logged
effort plus ``effort_offset``, the model's τ_off).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pendulum_sim.testing.batch import run_batch
from pendulum_sim.testing.examples import pd_batch
from pendulum_sim.testing.run import ClosedLoopRun
from pendulum_sim.testing.scene import scene_values
from pendulum_sim.testing.vector import vectorised

FREQUENCY = 0.5
"""The reference's frequency, Hz."""
AMPLITUDE = (0.8, 1.6)
"""The range of the reference's amplitude, rad."""


@vectorised
def tracking(t: float, position: np.ndarray, velocity: np.ndarray, *,
             target: np.ndarray) -> np.ndarray:
    """Return the shipped PD law towards ``target`` sin(2π f t) (the amplitude per episode)."""
    return pd_batch(t, position, velocity,
                    target=np.asarray(target) * np.sin(2.0 * np.pi * FREQUENCY * t))


@dataclass(frozen=True)
class Joint:
    """The truth a synthetic driven record was made with."""

    inertia: float
    mgl: float
    gamma: float
    n: float
    friction: float
    effort_offset: float
    m: float
    length: float

    def as_dict(self) -> dict[str, float]:
        """Return the truth keyed as a driven fit's parameters."""
        return {'inertia': self.inertia, 'mgl': self.mgl, 'gamma': self.gamma, 'n': self.n,
                'friction': self.friction, 'effort_offset': self.effort_offset,
                'command_delay': 0.0}


def joints(count: int, seed: int) -> list[Joint]:
    """Return ``count`` random joints (a 0.15-0.3 kg bob 0.5-1 m out, n in 1.2-1.8)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        m, length = rng.uniform(0.15, 0.3), rng.uniform(0.5, 1.0)
        out.append(Joint(inertia=float(m * length ** 2 * rng.uniform(1.0, 1.2)),
                         mgl=float(m * 9.8 * length), gamma=float(rng.uniform(0.3, 1.0)),
                         n=float(rng.uniform(1.2, 1.8)), friction=float(rng.uniform(0.02, 0.08)),
                         effort_offset=float(rng.uniform(-0.1, 0.1)), m=float(m),
                         length=float(length)))
    return out


def runs(truths: list[Joint], seed: int, *, periods: int = 400) -> list[ClosedLoopRun]:
    """Return the closed loops of the joints (10 ms periods), from random states and targets."""
    rng = np.random.default_rng(seed + 1)
    episodes = []
    for j in truths:
        episodes.append(scene_values('controller_test', {
            'm': j.m, 'l': j.length, 'inertia': j.inertia, 'gamma': j.gamma, 'n': j.n,
            'friction': j.friction, 'phi0': float(rng.uniform(-2.5, 2.5)),
            'dphi0': float(rng.uniform(-2.0, 2.0))}))
    targets = rng.uniform(*AMPLITUDE, len(truths)).tolist()
    out = run_batch(tracking, episodes, periods, targets=targets, jit=True)
    for r in out:
        assert isinstance(r, ClosedLoopRun), r
    return out   # type: ignore[return-value]


def records(count: int, seed: int, *, periods: int = 400, noise: float = 2e-3
            ) -> list[tuple[Joint, dict[str, np.ndarray]]]:
    """Return ``count`` records (truth, {'t', 'position', 'effort'}) as a biased joint logs them.

    ``noise`` is the encoder's Gaussian noise (rad); the logged effort is the applied torque
    less the joint's ``effort_offset``.
    """
    truths = joints(count, seed)
    rng = np.random.default_rng(seed + 2)
    out = []
    for j, run in zip(truths, runs(truths, seed, periods=periods), strict=True):
        out.append((j, {'t': run.t.copy(),
                        'position': run.position + rng.normal(0.0, noise, run.t.size),
                        'effort': run.effort - j.effort_offset}))
    return out
