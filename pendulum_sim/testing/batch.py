"""Batched in-process episodes: N closed loops of a numpy law stepped in lockstep.

A law declared :func:`~pendulum_sim.testing.vectorised` answers all episodes' states at once,
``(t, position[], velocity[]) -> command[]``; a law with a keyword ``target``
(:mod:`pendulum_sim.testing.target`) is also given ``target[]``, each episode's own. Each
control period the answers go to a :class:`pendulum_sim.joint.lockstep.Lockstep`, the batched
joints the Gymnasium vector environments step as well: it saturates each at the episode's
``max_effort`` as :meth:`SimulatedJoint.command` does and advances the N pendulums, each with
its own ω0², γ, n, inertia, one period together through the core's vectorized driver (a
:class:`pendulum_sim.core.sweep.Sweep`: the Stepper's numerics on arrays, the same decisions,
the same results to round-off), and hands a joint near its speed bound to the joint itself
for that period.

The episodes of one lockstep share h, the control period, the integrator, the guard and the
start time; a batch of several such groups runs one lockstep for each. An episode off the
lockstep's common path (``batchable_config``: effort commands, an ideal sensor, no command or
sensor delay, a command timeout longer than a period, disturbance pulses on control-period
boundaries only, no effort offset, an explicit method the sweep has), and one the batch cannot
follow exactly (a law that raises, where the batch cannot tell whose state it was; a joint that
stops, whose reason names its time), is run by the scalar joint alone, which decides for it.
:class:`BatchStats` says which episodes ran which way, and why. The scalar path stays the one
implementation of every rule; the batch is a faster driver of the same one, and
``test/testing/test_testing_batch.py`` holds them to each other.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pendulum_sim.joint.joint import JointConfig, stamp_ns
from pendulum_sim.joint.lockstep import Lockstep, LockstepStats, batchable_config, common
from pendulum_sim.joint.parameters import joint_config

from .errors import TestingError
from .loop import answer_reason, run_in_process
from .run import ClosedLoopRun
from .scene import Value, epoch_ns
from .target import takes_target

BatchLaw = Callable[[float, Any, Any], Any]
RAISED = 'the vectorised law raised in the batch (the scalar joint says for whom)'


@dataclass
class BatchStats:
    """How :func:`run_batch` ran its episodes.

    Attributes
    ----------
    lockstep : int
        Episodes run in a lockstep, to their end or to their controller's failure.
    scalar : dict
        Episodes (their index in the batch) run one by one on the scalar joint, with why.
    groups : int
        Locksteps run (one per h, control period, integrator, guard and start time).
    periods : LockstepStats
        The locksteps' periods: swept, taken by a joint near its speed bound, sweeps prepared.
    """

    lockstep: int = 0
    scalar: dict[int, str] = field(default_factory=dict)
    groups: int = 0
    periods: LockstepStats = field(default_factory=LockstepStats)


def batchable(values: Mapping[str, Value]) -> str:
    """Return why the episode with parameters ``values`` cannot be batched ('' if it can)."""

    return batchable_config(joint_config(values, epoch_ns(values)))


def scalar_law(law: BatchLaw, target: float | None) -> Callable[[float, float, float], float]:
    """Return the batched law as a scalar one (one-element arrays in, the element out)."""
    extra = {} if target is None else {'target': np.array([target])}

    def one(t: float, position: float, velocity: float) -> Any:
        out = np.asarray(law(t, np.array([position]), np.array([velocity]), **extra))
        return out.reshape(-1).tolist()[0]   # as answered: the scalar loop decides what it is
    return one


def run_batch(law: BatchLaw, episodes: Sequence[Mapping[str, Value]], periods: int,
              targets: Sequence[float] | None = None, jit: bool = False,
              stats: BatchStats | None = None) -> list[ClosedLoopRun | TestingError]:
    """Run one episode per parameter set in ``episodes``; return each run or its failure.

    ``targets`` (one per episode) reach a law that takes a keyword ``target`` as an array of
    the live episodes' targets; a law without it gets none. With ``jit`` the batch's pendulums
    are the compiled sweep (``Sweep(..., jit=True)``, numba: the same steps, see
    ``pendulum_sim.core.sweep``); :func:`warm_up_batch` compiles it beforehand. ``stats``, when
    given, is filled with how the episodes ran (:class:`BatchStats`).
    """
    stats = BatchStats() if stats is None else stats
    alone: dict[int, str] = {}   # the episodes the scalar joint runs, with why
    results: list[ClosedLoopRun | TestingError | None] = [None] * len(episodes)
    given = (np.array(targets, dtype=float) if targets is not None and takes_target(law)
             else None)
    if given is not None and given.shape != (len(episodes),):
        raise TestingError(f'run_batch needs one target per episode: got {given.size} for '
                           f'{len(episodes)} episodes')
    configs = [joint_config(v, epoch_ns(v)) for v in episodes]
    groups: dict[tuple[Any, ...], list[int]] = {}
    for i, c in enumerate(configs):
        why = batchable_config(c)
        if why:
            alone[i] = why
        else:
            groups.setdefault((*common(c), c.epoch_ns), []).append(i)
    for batch in groups.values():
        stats.groups += 1
        outcome = _lockstep(law, [configs[i] for i in batch], [episodes[i] for i in batch],
                            None if given is None else given[batch], periods, jit,
                            stats.periods)
        for j, i in enumerate(batch):
            if j in outcome.redo:
                alone[i] = outcome.redo[j]
            else:
                results[i] = outcome.results[j]
                stats.lockstep += 1
    stats.scalar.update(alone)
    for i in sorted(alone):
        try:
            results[i] = run_in_process(
                scalar_law(law, None if given is None else float(given[i])), episodes[i], periods)
        except TestingError as exc:
            results[i] = exc
    return [r if r is not None else TestingError('not run') for r in results]


def warm_up_batch(episodes: Sequence[Mapping[str, Value]]) -> float:
    """Compile (or load from the disk cache) the compiled sweep ``run_batch(..., jit=True)``
    takes for these episodes: their damping laws, integrator and friction
    (``pendulum_sim.core.warm_up``); return the seconds. Called before the clock starts.
    """
    from pendulum_sim.core.sweep import SWEEP_METHODS
    from pendulum_sim.core.warm_up import warm_up

    # Read from the node parameters as they stand: run_batch makes the joint configurations.
    by_method: dict[str, list[Mapping[str, Value]]] = {}
    for v in episodes:
        by_method.setdefault(str(v['integrator']), []).append(v)
    seconds = 0.0
    for method, mine in sorted(by_method.items()):
        if method in SWEEP_METHODS:
            seconds += warm_up(sorted({float(v['n']) for v in mine}), method,
                               friction=any(float(v['friction']) > 0.0 for v in mine))
    return seconds


@dataclass
class _Outcome:
    """A lockstep's episodes to run again alone (index: why) and the others' results."""

    redo: dict[int, str]
    results: list[ClosedLoopRun | TestingError | None]


def _lockstep(law: BatchLaw, configs: list[JointConfig], values: list[Mapping[str, Value]],
              targets: Any, periods: int, jit: bool, counted: LockstepStats) -> _Outcome:
    """Run the episodes of one lockstep (one h, period, method, guard and start time).

    Each period the law answers the live episodes' states, its answers are recorded and the
    :class:`~pendulum_sim.joint.lockstep.Lockstep` applies them; an episode whose law
    answered no finite number fails there with the scalar joint's reason.
    """
    first = configs[0]
    h, k = first.h, first.period_steps
    n_ep = len(configs)
    lock = Lockstep(n_ep, jit=jit)
    for j, c in enumerate(configs):
        lock.start(np.array([j]), c)
    outcome = _Outcome({}, [None] * n_ep)
    # Each period's samples in one contiguous row per quantity (every live episode's entry
    # is written; an episode's samples are read up to its last live period only).
    out = np.empty((5, periods, n_ep))
    active = np.ones(n_ep, dtype=bool)
    for step in range(periods):
        live = np.flatnonzero(active)
        if live.size == 0:
            break
        t = stamp_ns(first.epoch_ns, step * k, h) / 1e9
        try:
            extra = {} if targets is None else {'target': targets[live]}
            raw = np.asarray(law(t, lock.phi[live].copy(), lock.vel[live].copy(), **extra))
            if raw.dtype.kind not in 'biuf':   # strings, objects: not commands
                raise TypeError(f'a vectorised law answered {raw.dtype}')
            cmd = raw.astype(float)
        except Exception:
            for j in live.tolist():   # the scalar joint says who raised
                outcome.redo[j] = RAISED
            active[live] = False
            break
        if cmd.shape != live.shape:
            raise TestingError(f'a vectorised law must answer one command per state: got '
                               f'shape {cmd.shape} for {live.size} states')
        bad = ~np.isfinite(cmd)
        for j, value in zip(live[bad].tolist(), cmd[bad].tolist(), strict=True):
            failure = answer_reason(value, t)
            upto = [np.ascontiguousarray(out[r, :step, j]) for r in range(5)]
            failure.run = ClosedLoopRun(upto[0], upto[1], upto[2], upto[3], upto[4],
                                        parameters=dict(values[j]))
            outcome.results[j] = failure
            active[j] = False
        live, cmd = live[~bad], cmd[~bad]
        row = out[:, step]
        row[0, live] = t
        row[1, live] = lock.phi[live]
        row[2, live] = lock.vel[live]
        row[3, live] = lock.effort[live]
        row[4, live] = cmd
        if live.size:
            for j, reason in lock.advance(cmd, live).items():
                # The joint's reason names the time of its own run: the scalar joint's says it.
                outcome.redo[j] = f'the joint stopped in the batch: {reason}'
                active[j] = False
    done = np.flatnonzero(active)
    if done.size:   # one transposing copy: each episode's samples a contiguous row
        kept = out if done.size == n_ep else out[:, :, done]
        rows = np.ascontiguousarray(kept.transpose(0, 2, 1))
        for n, j in enumerate(done.tolist()):
            outcome.results[j] = ClosedLoopRun(rows[0, n], rows[1, n], rows[2, n], rows[3, n],
                                               rows[4, n], parameters=dict(values[j]),
                                               failed=None)
    counted.swept += lock.stats.swept
    counted.by_joint += lock.stats.by_joint
    counted.prepared += lock.stats.prepared
    return outcome


__all__ = ['BatchLaw', 'BatchStats', 'batchable', 'batchable_config', 'run_batch',
           'scalar_law', 'warm_up_batch']
