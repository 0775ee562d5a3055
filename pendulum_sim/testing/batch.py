"""Batched in-process episodes: N closed loops of a numpy law stepped in lockstep.

A law declared :func:`~pendulum_sim.testing.vectorised` answers all episodes' states at once,
``(t, position[], velocity[]) -> command[]``; a law with a keyword ``target``
(:mod:`pendulum_sim.testing.target`) is also given ``target[]``, each episode's own. Each
control period the answers are saturated at each episode's ``max_effort`` as
:meth:`SimulatedJoint.command` does, and the N pendulums, each with its own ω0², γ, n,
inertia, advance one period together through the core's vectorized driver, a
:class:`pendulum_sim.core.sweep.Sweep` prepared once and advanced a period at a time (the
Stepper's numerics on arrays: the same decisions, the same results to round-off).

The batch takes the common path of the joint only: effort commands, an ideal sensor, no
command or sensor delay, a command timeout longer than a period, no disturbance pulse or
effort offset, an explicit method the sweep has. An episode outside it, or one the batch
cannot follow exactly (its speed could reach ``max_velocity`` within a period, where the joint
would cut the torque; a non-finite state; a law that raises), is run again by the scalar
joint, which decides for it. The scalar path stays the one implementation of every rule; the
batch is a faster driver of the same one, and ``test/testing/test_testing_batch.py`` holds
them to each other.
"""
from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from pendulum_sim.joint.joint import JointConfig
from pendulum_sim.joint.parameters import joint_config

from .errors import TestingError
from .loop import answer_reason, run_in_process
from .run import ClosedLoopRun
from .scene import Value, epoch_ns
from .target import takes_target

BatchLaw = Callable[[float, Any, Any], Any]


def batchable(values: Mapping[str, Value]) -> str:
    """Return why the episode with parameters ``values`` cannot be batched ('' if it can)."""

    return batchable_config(joint_config(values, epoch_ns(values)))


def batchable_config(c: JointConfig) -> str:
    """Return why the joint configuration ``c`` cannot be batched ('' if it can).

    The batch's one rule (the module docstring): effort commands, an ideal sensor, no
    command or sensor delay, a command timeout longer than a period, no disturbance pulse, no
    effort offset, an explicit method the sweep has. The Gymnasium environments step the same
    joints and refuse the others with this reason (``pendulum_sim.gym``).

    Parameters
    ----------
    c : pendulum_sim.joint.joint.JointConfig
        The simulated joint's configuration (typed ``Any``: the testing package imports the
        node's modules only where it uses them).

    Returns
    -------
    str
        The first condition it fails, in words, or ``''``.
    """
    from pendulum_sim.core.sweep import SWEEP_METHODS

    checks = [
        (c.command_interface == 'effort', f'command_interface is {c.command_interface}'),
        (c.command_delay_steps == 0, 'command_delay is not 0'),
        (c.sensor_delay_steps == 0, 'sensor.delay is not 0'),
        (c.position_noise == 0.0 and c.velocity_noise == 0.0 and c.resolution == 0.0,
         'the sensor is not ideal'),
        (c.timeout_steps == 0 or c.timeout_steps > c.period_steps,
         'command_timeout is shorter than a period'),
        (not c.has_disturbance, 'a disturbance pulse is set'),
        (c.effort_offset == 0.0, 'effort_offset is not 0'),
        (c.method in SWEEP_METHODS, f'integrator {c.method} is not one of '
         f'{", ".join(SWEEP_METHODS)}'),
    ]
    return next((why for ok, why in checks if not ok), '')


def _scalar(law: BatchLaw, target: float | None) -> Callable[[float, float, float], float]:
    """Return the batched law as a scalar one (one-element arrays in, the element out)."""
    extra = {} if target is None else {'target': np.array([target])}

    def one(t: float, position: float, velocity: float) -> Any:
        out = np.asarray(law(t, np.array([position]), np.array([velocity]), **extra))
        return out.reshape(-1).tolist()[0]   # as answered: the scalar loop decides what it is
    return one


def run_batch(law: BatchLaw, episodes: Sequence[Mapping[str, Value]], periods: int,
              targets: Sequence[float] | None = None,
              jit: bool = False) -> list[ClosedLoopRun | TestingError]:
    """Run one episode per parameter set in ``episodes``; return each run or its failure.

    ``targets`` (one per episode) reach a law that takes a keyword ``target`` as an array of
    the live episodes' targets; a law without it gets none. With ``jit`` the batch's pendulums
    are the compiled sweep (``Sweep(..., jit=True)``, numba: the same steps, see
    ``pendulum_sim.core.sweep``); :func:`warm_up_batch` compiles it beforehand.
    """
    from pendulum_sim.core.errors import PendulumError
    from pendulum_sim.core.sweep import Sweep

    results: list[ClosedLoopRun | TestingError | None] = [None] * len(episodes)
    given = (np.array(targets, dtype=float) if targets is not None and takes_target(law)
             else None)
    if given is not None and given.shape != (len(episodes),):
        raise TestingError(f'run_batch needs one target per episode: got {given.size} for '
                           f'{len(episodes)} episodes')
    configs = [joint_config(v, epoch_ns(v)) for v in episodes]
    batch = [i for i, c in enumerate(configs) if not batchable_config(c)]
    if batch:
        first = configs[batch[0]]
        same = (first.h, first.period_steps, first.method, first.guard, first.epoch_ns)
        batch = [i for i in batch if (configs[i].h, configs[i].period_steps, configs[i].method,
                                      configs[i].guard, configs[i].epoch_ns) == same]
    redo = sorted(set(range(len(episodes))) - set(batch))
    if batch:
        prepare = functools.partial(Sweep, jit=True) if jit else Sweep
        redo += _lockstep(law, [configs[i] for i in batch], [episodes[i] for i in batch],
                          None if given is None else given[batch],
                          batch, periods, results, prepare, PendulumError)
    for i in sorted(redo):
        try:
            results[i] = run_in_process(
                _scalar(law, None if given is None else float(given[i])), episodes[i], periods)
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


def _lockstep(law: BatchLaw, configs: list[Any], values: list[Mapping[str, Value]],
              targets: Any, ids: list[int], periods: int,
              results: list[Any], prepare: Any, pendulum_error: type[Exception]) -> list[int]:
    """Step the episodes ``ids`` together; store their runs; return the ids to redo.

    The live episodes' pendulums are one prepared :class:`~pendulum_sim.core.sweep.Sweep`,
    advanced a period at a time under the period's torques; it is prepared again only when
    the set of live episodes changes.
    """
    first = configs[0]
    h, k = first.h, first.period_steps
    n_ep = len(ids)
    om2 = np.array([c.params.omega0_sq for c in configs])
    gam = np.array([c.params.gamma for c in configs])
    nn = np.array([c.params.n for c in configs])
    fr = np.array([c.params.friction_accel for c in configs])   # f/I: the Stepper's float
    inv_i = np.array([1.0 / c.params.inertia for c in configs])
    limit = np.array([c.max_effort for c in configs])
    vmax = np.array([c.max_velocity for c in configs])
    # The most speed a period can add: gravity and the largest torque (damping only slows).
    reach = k * h * (om2 + limit * inv_i)
    phi = np.array([c.phi0 for c in configs])
    vel = np.array([c.dphi0 for c in configs])
    tau = np.zeros(n_ep)
    out = np.full((5, n_ep, periods), np.nan)
    active = np.ones(n_ep, dtype=bool)
    redo: list[int] = []
    prepared: Any = None
    prepared_for = np.empty(0, dtype=np.int64)
    for step in range(periods):
        t = (first.epoch_ns + step * k * round(h * 1e9)) / 1e9 if _whole_ns(h) else math.nan
        if math.isnan(t):
            return ids
        live = np.flatnonzero(active)
        if live.size == 0:
            break
        risky = live[np.abs(vel[live]) + reach[live] >= vmax[live]]
        if risky.size:
            active[risky] = False
            redo.extend(ids[j] for j in risky.tolist())
            live = np.flatnonzero(active)
            if live.size == 0:
                break
        try:
            extra = {} if targets is None else {'target': targets[live]}
            raw = np.asarray(law(t, phi[live].copy(), vel[live].copy(), **extra))
            if raw.dtype.kind not in 'biuf':   # strings, objects: not commands
                raise TypeError(f'a vectorised law answered {raw.dtype}')
            cmd = raw.astype(float)
        except Exception:
            redo.extend(ids[j] for j in live.tolist())   # the scalar joint says who raised
            active[live] = False
            break
        if cmd.shape != live.shape:
            raise TestingError(f'a vectorised law must answer one command per state: got '
                               f'shape {cmd.shape} for {live.size} states')
        bad = ~np.isfinite(cmd)
        for j, value in zip(live[bad].tolist(), cmd[bad].tolist(), strict=True):
            failure = answer_reason(value, t)
            upto = [np.ascontiguousarray(out[r, j, :step]) for r in range(5)]
            failure.run = ClosedLoopRun(upto[0], upto[1], upto[2], upto[3], upto[4],
                                        parameters=dict(values[j]))
            results[ids[j]] = failure
            active[j] = False
        live, cmd = live[~bad], cmd[~bad]
        out[0, live, step] = t
        out[1, live, step] = phi[live]
        out[2, live, step] = vel[live]
        out[3, live, step] = tau[live]
        out[4, live, step] = cmd
        tau[live] = np.minimum(np.maximum(cmd, -limit[live]), limit[live])
        try:
            ain = tau[live] * inv_i[live]
            if prepared is None or not np.array_equal(live, prepared_for):
                prepared = prepare(om2[live], gam[live], nn[live], phi[live], vel[live], h,
                                   method=first.method, torque=ain, guard=first.guard,
                                   friction=fr[live])
                prepared_for = live
                res = prepared.advance(k * h)
            else:
                res = prepared.advance(k * h, ain)
        except pendulum_error:
            redo.extend(ids[j] for j in live.tolist())
            active[live] = False
            break
        phi[live], vel[live] = res.phi, res.dphi
        broken = live[~(np.isfinite(res.phi) & np.isfinite(res.dphi))]
        if broken.size:
            active[broken] = False
            redo.extend(ids[j] for j in broken.tolist())
    for j in np.flatnonzero(active).tolist():
        t_j, p_j, v_j, e_j, c_j = (np.ascontiguousarray(out[r, j]) for r in range(5))
        results[ids[j]] = ClosedLoopRun(t_j, p_j, v_j, e_j, c_j, parameters=dict(values[j]),
                                        failed=None)
    return redo


def _whole_ns(h: float) -> bool:
    """Return True when h is a whole number of nanoseconds (the joint's exact stamp grid)."""
    return abs(h * 1e9 - round(h * 1e9)) < 1e-6


__all__ = ['BatchLaw', 'batchable', 'batchable_config', 'run_batch', 'warm_up_batch']
