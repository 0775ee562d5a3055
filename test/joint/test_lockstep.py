"""The batched lockstep of joints: each joint's periods as its own SimulatedJoint takes them."""
from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from pendulum_sim.core import PendulumParams
from pendulum_sim.core.model import MAX_SPEED, speed_limit
from pendulum_sim.joint.errors import JointError
from pendulum_sim.joint.joint import JointConfig, SimulatedJoint, speed_bound
from pendulum_sim.joint.lockstep import Lockstep, LockstepStats

H = 1e-3
K = 10   # steps a control period


def config(**changes: object) -> JointConfig:
    params = changes.pop('params', PendulumParams(m=0.2, l=1.0, inertia=0.2, g=9.8,
                                                  gamma=0.1, n=1.0))
    base: dict[str, object] = {'params': params, 'h': H, 'period_steps': K, 'phi0': 0.3,
                               'max_effort': 2.0}
    base.update(changes)
    return JointConfig(**base)  # type: ignore[arg-type]


def mixed() -> list[JointConfig]:
    """Joints of every damping law, with friction, and two whose speed bound binds."""
    out = []
    for k, (gamma, n, friction) in enumerate([(0.1, 1.0, 0.0), (0.3, 2.0, 0.0),
                                              (0.2, 0.0, 0.0), (0.05, 1.0, 0.02),
                                              (0.4, 2.0, 0.01), (0.1, 1.0, 0.0)]):
        p = PendulumParams(m=0.2, l=1.0, inertia=0.2, g=9.8, gamma=gamma, n=n,
                           friction=friction)
        out.append(config(params=p, phi0=0.4 * k - 1.0, dphi0=0.3 * k - 0.7,
                          max_velocity=1.5 if k in (2, 5) else float('inf')))
    return out


def test_a_lockstep_takes_each_joints_periods_as_its_own_joint_to_the_bit() -> None:
    configs = mixed()
    lock = Lockstep(len(configs))
    for j, c in enumerate(configs):
        lock.start(np.array([j]), c)
    alone = [SimulatedJoint(c) for c in configs]
    live = np.arange(len(configs))
    rng = np.random.default_rng(3)
    for _ in range(80):
        command = rng.uniform(-3.0, 3.0, len(configs))   # beyond max_effort: saturated
        assert lock.advance(command, live) == {}
        for j, joint in enumerate(alone):
            joint.command(float(command[j]))
            joint.advance(K)
        assert lock.phi.tobytes() == np.array([j.stepper.phi for j in alone]).tobytes()
        assert lock.vel.tobytes() == np.array([j.stepper.dphi for j in alone]).tobytes()
        assert lock.effort.tobytes() == np.array([j.torque for j in alone]).tobytes()
    # The two joints at max_velocity 1.5 rad/s took their periods near it as a joint: the
    # joint's torque limit acted there, and the sweep took everything else.
    assert sum(j.counters.limited for j in alone) > 0
    assert 0 < lock.stats.by_joint < 2 * 80
    assert lock.stats.swept + lock.stats.by_joint == 80 * len(configs)


def test_a_plain_lockstep_never_leaves_its_one_prepared_sweep() -> None:
    lock = Lockstep(8)
    lock.start(np.arange(8), config(), np.linspace(-2.0, 2.0, 8), np.zeros(8))
    live = np.arange(8)
    for _ in range(30):
        lock.advance(np.full(8, 0.5), live)
    assert lock.stats == LockstepStats(swept=240, by_joint=0, prepared=1)
    lock.start(np.array([3]), config(phi0=1.0))   # a start: the sweep is prepared again
    lock.advance(np.full(8, 0.5), live)
    lock.advance(np.full(5, 0.5), live[:5])       # another set of joints: again
    assert lock.stats == LockstepStats(swept=253, by_joint=0, prepared=3)
    assert lock.phi[3] != lock.phi[2]


def test_the_joints_speed_bound_is_the_lockstep_bound() -> None:
    """max_velocity 1e6 rad/s is allowed, but the joint's bound is the core's state bound."""
    fast = config(params=PendulumParams(m=0.2, l=1.0, inertia=0.2, g=9.8, gamma=0.0, n=1.0),
                  phi0=0.0, dphi0=MAX_SPEED, max_velocity=1e6, max_effort=1.0)
    assert speed_bound(fast) == speed_limit(0.0, 1.0) == MAX_SPEED
    assert speed_bound(dataclasses.replace(fast, max_velocity=2.0)) == 2.0
    lock = Lockstep(1)
    lock.start(np.array([0]), fast)
    joint = SimulatedJoint(fast)
    for _ in range(20):
        lock.advance(np.array([0.001]), np.array([0]))
        joint.command(0.001)
        joint.advance(K)
        assert (lock.phi[0], lock.vel[0], lock.effort[0]) == (
            joint.stepper.phi, joint.stepper.dphi, joint.torque)
    assert joint.counters.limited > 0          # pushing at the bound: the joint cut the torque
    assert lock.stats.by_joint == 20 and lock.stats.swept == 0


def test_a_lockstep_refuses_joints_it_cannot_step_with_the_reason() -> None:
    lock = Lockstep(2)
    with pytest.raises(JointError, match=re.escape(
            'a lockstep steps the joints of the common path; this one cannot: command_delay '
            'is not 0')):
        lock.start(np.array([0]), config(command_delay_steps=2))
    lock.start(np.array([0]), config())
    message = ('every joint of a lockstep steps with one h, control period, integrator and '
               'guard; the joints started have h = 0.002 s, 5 steps a period, rk4, guard True, '
               'the others h = 0.001 s, 10 steps a period, rk4, guard True')
    with pytest.raises(JointError, match=re.escape(message)):
        lock.start(np.array([1]), config(h=0.002, period_steps=5))
    lock.stop(np.array([0]))   # nothing else runs: the joints may take another step
    lock.start(np.array([1]), config(h=0.002, period_steps=5))
    assert lock.period == 0.01
