"""N simulated joints stepped a control period at a time together, in one batched core call.

The batched closed loop's joint half, one for the test bench's batches
(:func:`pendulum_sim.testing.batch.run_batch`, a campaign of a vectorised law) and the
Gymnasium vector environments (:mod:`pendulum_sim.gym`): each caller asks its controller for
the N commands of a period, :meth:`Lockstep.advance` applies them.

Each joint is a :class:`~pendulum_sim.joint.joint.SimulatedJoint` of the common path
(:func:`batchable_config`: effort commands, an ideal sensor, no delays or effort offset,
disturbance pulses on control-period boundaries, an explicit method the sweep has). A
disturbance acts on the pendulum as the joint applies it: each period's torque
(``JointConfig.disturbance_at`` at the period's first step, counted from the joint's start)
is added to the command's, and is not in the effort. A period saturates each command at the joint's
``max_effort`` as :meth:`SimulatedJoint.command` does and advances the pendulums together
through one prepared :class:`pendulum_sim.core.sweep.Sweep` (the Stepper's numerics on
arrays: the same decisions, the same results to round-off), prepared again only when the set
of joints it holds changes or a joint is started.

The joint's own rules decide everywhere the sweep cannot follow it exactly. A joint whose speed
could reach its speed bound within the period (:func:`~pendulum_sim.joint.joint.speed_bound`,
where the joint would limit its torque) takes that period in a SimulatedJoint started from its
state (kept while it stays there), as does every joint of a period the sweep refuses and a
joint the sweep leaves non-finite; a joint that fails there ends with the joint's reason.
:class:`LockstepStats` counts the periods each way, so a batch that silently leaves the sweep
shows in its counters.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pendulum_sim.core import PendulumError
from pendulum_sim.core.sweep import SWEEP_METHODS, Sweep

from .errors import JointError
from .joint import JointConfig, SimulatedJoint, speed_bound

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
Common = tuple[float, int, str, bool]
_NEVER = np.iinfo(np.int64).max   # a period no joint reaches


def batchable_config(c: JointConfig) -> str:
    """Return why the joint configuration ``c`` cannot be stepped in a lockstep ('' if it can).

    The lockstep's one rule: effort commands, an ideal sensor, no command or sensor delay, a
    command timeout longer than a period, disturbance pulses (if any) that start and end on
    control-period boundaries (so each period's disturbance is one torque), no effort offset,
    an explicit method the sweep has. The test bench runs the other episodes one by one on the
    scalar joint; the Gymnasium environments refuse the other scenes with this reason (and
    scenes with a pulse: an environment's reset starts its time again).

    Returns
    -------
    str
        The first condition it fails, in words, or ``''``.
    """
    checks = [
        (c.command_interface == 'effort', f'command_interface is {c.command_interface}'),
        (c.command_delay_steps == 0, 'command_delay is not 0'),
        (c.sensor_delay_steps == 0, 'sensor.delay is not 0'),
        (c.position_noise == 0.0 and c.velocity_noise == 0.0 and c.resolution == 0.0,
         'the sensor is not ideal'),
        (c.timeout_steps == 0 or c.timeout_steps > c.period_steps,
         'command_timeout is shorter than a period'),
        (all(p.start_step % c.period_steps == 0 and p.steps % c.period_steps == 0
             for p in c.all_pulses),
         'a disturbance pulse starts or ends inside a control period'),
        (c.effort_offset == 0.0, 'effort_offset is not 0'),
        (c.method in SWEEP_METHODS, f'integrator {c.method} is not one of '
         f'{", ".join(SWEEP_METHODS)}'),
    ]
    return next((why for ok, why in checks if not ok), '')


def common(config: JointConfig) -> Common:
    """Return what every joint of one lockstep shares: h, steps a period, method, guard."""
    return (config.h, config.period_steps, config.method, config.guard)


def common_text(c: Common) -> str:
    """Return a :func:`common` in words."""
    h, k, method, guard = c
    return f'h = {h:g} s, {k} steps a period, {method}, guard {guard}'


@dataclass
class LockstepStats:
    """How a lockstep took its joints' periods.

    Attributes
    ----------
    swept : int
        Joint-periods the prepared sweep took (one per joint per period).
    by_joint : int
        Joint-periods a SimulatedJoint took: near the speed bound, in a period the sweep
        refused, or after the sweep left the joint non-finite.
    prepared : int
        Sweeps prepared (at the first period, after a start, when the swept set changed).
    """

    swept: int = 0
    by_joint: int = 0
    prepared: int = 0


class Lockstep:
    """N joints' states and physics; :meth:`start` joints, :meth:`advance` a period.

    Parameters
    ----------
    size : int
        The number of joints N (each idle until started).
    jit : bool
        Advance on the compiled sweep (``Sweep(..., jit=True)``, numba: the same steps).

    Attributes
    ----------
    phi, vel : numpy arrays
        Each joint's state (rad, rad/s).
    effort : numpy array
        The torque each joint applied in the last step of its last period (N m), what its
        ``joint_states`` carries (0 after a start).
    limit : numpy array
        Each joint's ``max_effort`` (N m).
    configs : list
        Each joint's configuration (None while idle); its start state is the one given to
        :meth:`start`.
    stats : LockstepStats
        The periods taken each way.
    """

    def __init__(self, size: int, *, jit: bool = False) -> None:
        self.size = size
        self.jit = jit
        self.configs: list[JointConfig | None] = [None] * size
        self.phi = np.zeros(size)
        self.vel = np.zeros(size)
        self.effort = np.zeros(size)
        self.limit = np.zeros(size)
        self._om2 = np.zeros(size)
        self._gam = np.zeros(size)
        self._n = np.ones(size)
        self._fr = np.zeros(size)   # the Coulomb friction beside the law, f/I
        self._inv_i = np.ones(size)
        self._vmax = np.full(size, np.inf)
        self._reach = np.zeros(size)
        self._common: Common | None = None
        self._sweep: Any = None
        self._swept = np.empty(0, dtype=np.int64)
        self._joints: dict[int, SimulatedJoint] = {}   # joints taken by a SimulatedJoint
        self._periods = np.zeros(size, dtype=np.int64)   # periods since each joint's start
        self._pushed: set[int] = set()   # joints with a disturbance pulse
        # Each joint's disturbance torque now, and the period from which it may change (a
        # pulse's start or end): between them ``disturbance_at`` is not asked again.
        self._push_now = np.zeros(size)
        self._push_next = np.full(size, _NEVER, dtype=np.int64)
        self.stats = LockstepStats()

    @property
    def common(self) -> Common | None:
        """Return what the joints share (None before the first start)."""
        return self._common

    @property
    def period(self) -> float:
        """Return the control period in s."""
        assert self._common is not None
        h, k = self._common[0], self._common[1]
        return float(k * h)

    def start(self, ids: IntArray, config: JointConfig, phi0: FloatArray | None = None,
              dphi0: FloatArray | None = None) -> None:
        """Start the joints ``ids`` with ``config``, each at its state (``phi0``, ``dphi0``).

        The states default to the configuration's; ``config`` must pass
        :func:`batchable_config` and share :func:`common` with the joints that keep running.
        """
        why = batchable_config(config)
        if why:
            raise JointError(f'a lockstep steps the joints of the common path; this one '
                             f'cannot: {why}')
        mine = common(config)
        if self._common is not None and mine != self._common:
            starting = set(ids.tolist())
            if any(c is not None and j not in starting for j, c in enumerate(self.configs)):
                raise JointError(f'every joint of a lockstep steps with one h, control period, '
                                 f'integrator and guard; the joints started have '
                                 f'{common_text(mine)}, the others {common_text(self._common)}')
        self._common = mine
        p = config.params
        for j in ids.tolist():
            self.configs[j] = config
            self._joints.pop(j, None)
            if config.has_disturbance:
                self._pushed.add(j)
            else:
                self._pushed.discard(j)
        self._periods[ids] = 0
        self._push_now[ids] = 0.0
        self._push_next[ids] = 0 if config.has_disturbance else _NEVER
        self.phi[ids] = config.phi0 if phi0 is None else phi0
        self.vel[ids] = config.dphi0 if dphi0 is None else dphi0
        self.effort[ids] = 0.0
        self._om2[ids], self._gam[ids], self._n[ids] = p.omega0_sq, p.gamma, p.n
        self._fr[ids] = p.friction_accel   # f/I: the Stepper's float
        self._inv_i[ids] = 1.0 / p.inertia
        self.limit[ids] = config.max_effort
        self._vmax[ids] = speed_bound(config)
        # The most speed a period can add: gravity and the largest torque (damping and
        # friction only slow), so a joint further than this below its bound is not limited.
        self._reach[ids] = config.period_steps * config.h * (p.omega0_sq
                                                             + config.max_effort / p.inertia)
        self._sweep = None

    def stop(self, ids: IntArray) -> None:
        """Idle the joints ``ids`` until they are started again."""
        for j in ids.tolist():
            self.configs[j] = None
            self._joints.pop(j, None)
            self._pushed.discard(j)

    def advance(self, command: FloatArray, live: IntArray) -> dict[int, str]:
        """Take one control period of the joints ``live`` under ``command`` (N m, one each).

        Returns the joints that failed in it, with the joint's reason.
        """
        assert self._common is not None
        h, k, method, guard = self._common
        tau = np.minimum(np.maximum(command, -self.limit[live]), self.limit[live])
        risky = np.abs(self.vel[live]) + self._reach[live] >= self._vmax[live]
        alone = live[risky]
        swept = live[~risky]
        if swept.size:
            ain = (tau[~risky] + self._push(swept, k)) * self._inv_i[swept]
            try:
                if self._sweep is None or not np.array_equal(swept, self._swept):
                    self._sweep = Sweep(self._om2[swept], self._gam[swept], self._n[swept],
                                        self.phi[swept], self.vel[swept], h, method=method,
                                        torque=ain, guard=guard, friction=self._fr[swept],
                                        jit=self.jit)
                    self._swept = swept
                    self.stats.prepared += 1
                    res = self._sweep.advance(k * h)
                else:
                    res = self._sweep.advance(k * h, ain)
            except PendulumError:
                self._sweep = None
                alone = live
            else:
                fine = np.isfinite(res.phi) & np.isfinite(res.dphi)
                took = swept[fine]
                self.phi[took], self.vel[took] = res.phi[fine], res.dphi[fine]
                self.effort[took] = tau[~risky][fine]
                self.stats.swept += int(took.size)
                if self._joints:
                    for j in took.tolist():
                        self._joints.pop(j, None)   # its state moved on in the sweep
                if not fine.all():   # the joint says what became of them
                    self._sweep = None
                    alone = np.sort(np.concatenate([alone, swept[~fine]]))
        self._periods[live] += 1
        failed: dict[int, str] = {}
        if alone.size:
            self._sweep = None   # these states change outside the prepared sweep
            where = {j: n for n, j in enumerate(live.tolist())}
            for j in alone.tolist():
                reason = self._by_joint(j, float(command[where[j]]))
                if reason is not None:
                    failed[j] = reason
        return failed

    def _push(self, ids: IntArray, k: int) -> FloatArray | float:
        """Return the disturbance torque of the joints ``ids`` in their current period (N m).

        ``JointConfig.disturbance_at`` at the period's first step, asked again only in the
        period where one of the joint's pulses starts or ends (the torque is the same between).
        """
        if not self._pushed:
            return 0.0
        periods = self._periods[ids]
        for j in ids[self._push_next[ids] <= periods].tolist():
            c = self.configs[j]
            assert c is not None
            step = int(self._periods[j]) * k
            self._push_now[j] = c.disturbance_at(step)
            edges = [e for p in c.all_pulses for e in (p.start_step, p.start_step + p.steps)
                     if e > step]
            self._push_next[j] = -(-min(edges) // k) if edges else _NEVER
        return self._push_now[ids]

    def _by_joint(self, j: int, command: float) -> str | None:
        """Take joint ``j``'s period in a SimulatedJoint from its state; its failure or None.

        The joint starts at the state reached, its pulses moved back by the steps already
        taken (the SimulatedJoint counts its steps from its own start).
        """
        joint = self._joints.get(j)
        if joint is None:
            c = self.configs[j]
            assert c is not None
            taken = int(self._periods[j] - 1) * c.period_steps   # this period is counted
            try:
                joint = SimulatedJoint(dataclasses.replace(
                    c, phi0=float(self.phi[j]), dphi0=float(self.vel[j]),
                    disturbance_start_step=c.disturbance_start_step - taken,
                    pulses=tuple(p._replace(start_step=p.start_step - taken)
                                 for p in c.pulses)))
            except JointError as exc:
                return str(exc)
            self._joints[j] = joint
        joint.command(command)
        joint.advance(joint.config.period_steps)
        self.stats.by_joint += 1
        st = joint.stepper
        self.phi[j], self.vel[j], self.effort[j] = st.phi, st.dphi, joint.torque
        if joint.failed is not None:
            del self._joints[j]
        return joint.failed


__all__ = ['Common', 'Lockstep', 'LockstepStats', 'batchable_config', 'common',
           'common_text']
