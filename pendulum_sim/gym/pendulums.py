"""N simulated joints stepped one control period at a time in one batched core call.

Each joint is one pendulum of the joint's common path (effort commands, an ideal sensor, no
delays, disturbance or effort offset, an explicit method;
:func:`pendulum_sim.testing.batch.batchable` says why a scene is not one). A period saturates
each command at the joint's ``max_effort`` as :meth:`SimulatedJoint.command` does and
advances the pendulums together through one prepared :class:`pendulum_sim.core.sweep.Sweep`
(the Stepper's numerics on arrays), prepared again only when an episode starts or the set of
pendulums it holds changes.

A joint whose speed could reach its speed bound within the period (where the joint would
limit the torque), and every joint of a period the sweep refuses, takes that period in a
:class:`~pendulum_sim.joint.joint.SimulatedJoint` started from its state, which decides for
it; a joint that fails there (its reason kept) ends its episode. A scalar environment is this
class with N = 1, so a vector environment's pendulum and a scalar environment's take the same
steps.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pendulum_sim.joint.errors import JointError
from pendulum_sim.joint.joint import JointConfig, SimulatedJoint

from .errors import GymError

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class Pendulums:
    """N joints' states and physics; :meth:`start` an episode, :meth:`advance` a period."""

    def __init__(self, size: int) -> None:
        self.size = size
        self.configs: list[Any] = [None] * size
        self.phi = np.zeros(size)
        self.vel = np.zeros(size)
        self.effort = np.zeros(size)   # the torque applied in the last period (N m)
        self._om2 = np.zeros(size)
        self._gam = np.zeros(size)
        self._n = np.ones(size)
        self._fr = np.zeros(size)   # the Coulomb friction beside the law, f/I
        self._inv_i = np.ones(size)
        self.limit = np.zeros(size)
        self._vmax = np.full(size, np.inf)
        self._reach = np.zeros(size)
        self._common: tuple[Any, ...] | None = None
        self._sweep: Any = None
        self._swept = np.empty(0, dtype=np.int64)

    def start(self, i: int, config: JointConfig) -> None:
        """Start joint ``i`` at rest at its configuration's initial state."""

        check(config)
        common = (config.h, config.period_steps, config.method, config.guard)
        if self._common is not None and common != self._common and any(
                c is not None for j, c in enumerate(self.configs) if j != i):
            raise GymError(f'every pendulum of a vector environment steps with one h, control '
                           f'period, integrator and guard; episode has {_common_text(common)}, '
                           f'the others {_common_text(self._common)}')
        self._common = common
        p = config.params
        self.configs[i] = config
        self.phi[i], self.vel[i], self.effort[i] = config.phi0, config.dphi0, 0.0
        self._om2[i], self._gam[i], self._n[i] = p.omega0_sq, p.gamma, p.n
        self._fr[i] = p.friction_accel   # f/I: the Stepper's float
        self._inv_i[i] = 1.0 / p.inertia
        self.limit[i] = config.max_effort
        self._vmax[i] = SimulatedJoint._speed_bound(config)
        # The most speed a period can add: gravity and the largest torque (damping only slows).
        self._reach[i] = config.period_steps * config.h * (p.omega0_sq
                                                            + config.max_effort / p.inertia)
        self._sweep = None

    @property
    def period(self) -> float:
        """Return the control period in s."""
        assert self._common is not None
        h, k = self._common[0], self._common[1]
        return float(k * h)

    def advance(self, command: FloatArray, live: IntArray) -> dict[int, str]:
        """Take one control period of the joints ``live`` under ``command`` (N m, one each).

        Returns the joints that failed in it, with the joint's reason.
        """
        from pendulum_sim.core.errors import PendulumError
        from pendulum_sim.core.sweep import Sweep

        assert self._common is not None
        h, k, method, guard = self._common
        tau = np.minimum(np.maximum(command, -self.limit[live]), self.limit[live])
        risky = np.abs(self.vel[live]) + self._reach[live] >= self._vmax[live]
        failed: dict[int, str] = {}
        alone = live[risky]
        swept = live[~risky]
        if swept.size:
            ain = tau[~risky] * self._inv_i[swept]
            try:
                if self._sweep is None or not np.array_equal(swept, self._swept):
                    self._sweep = Sweep(self._om2[swept], self._gam[swept], self._n[swept],
                                        self.phi[swept], self.vel[swept], h, method=method,
                                        torque=ain, guard=guard, friction=self._fr[swept])
                    self._swept = swept
                    res = self._sweep.advance(k * h)
                else:
                    res = self._sweep.advance(k * h, ain)
            except PendulumError:
                self._sweep = None
                alone = live
            else:
                self.phi[swept], self.vel[swept] = res.phi, res.dphi
                self.effort[swept] = tau[~risky]
                bad = swept[~(np.isfinite(res.phi) & np.isfinite(res.dphi))]
                for j in bad.tolist():
                    failed[j] = (f'non-finite state phi = {self.phi[j]}, dphi = '
                                 f'{self.vel[j]}')
        if alone.size:
            self._sweep = None   # these states change outside the prepared sweep
            where = {j: n for n, j in enumerate(live.tolist())}
            for j in alone.tolist():
                reason = self._by_joint(j, float(command[where[j]]))
                if reason is not None:
                    failed[j] = reason
        return failed

    def _by_joint(self, j: int, command: float) -> str | None:
        """Take joint ``j``'s period in a SimulatedJoint from its state; its failure or None."""

        c = self.configs[j]
        try:
            joint = SimulatedJoint(dataclasses.replace(c, phi0=float(self.phi[j]),
                                                       dphi0=float(self.vel[j])))
        except JointError as exc:
            return str(exc)
        joint.command(command)
        joint.advance(c.period_steps)
        st = joint.stepper
        self.phi[j], self.vel[j], self.effort[j] = st.phi, st.dphi, joint.torque
        return joint.failed


def check(config: JointConfig) -> None:
    """Refuse a joint configuration the environments cannot step (``batchable_config``'s why)."""
    from pendulum_sim.testing.batch import batchable_config

    why = batchable_config(config)
    if why:
        raise GymError(f'the environment steps the joint of effort commands with an ideal '
                       f'sensor and an explicit method; this scene cannot: {why}')


def _common_text(common: tuple[Any, ...]) -> str:
    h, k, method, guard = common
    return f'h = {h:g} s, {k} steps a period, {method}, guard {guard}'


def wrap(angle: FloatArray) -> FloatArray:
    """Return ``angle`` wrapped into [−π, π) (Pendulum-v1's ``angle_normalize``)."""
    return np.asarray(((angle + math.pi) % (2 * math.pi)) - math.pi)
