"""The two tasks: what a policy observes and how a period is rewarded, on arrays of episodes.

``DampedPendulum`` (swing-up and stabilise) observes ``[cos φ, sin φ, φ']`` as Gymnasium's
``Pendulum-v1`` does, with φ the joint's angle (0 hanging down, so upright is φ = π and
cos φ = −1), and is rewarded with Pendulum-v1's reward shape, on the state at the start of
the period and the torque applied over it::

    r = −(θ² + 0.1 φ'² + 0.001 τ²),   θ = φ − π wrapped into [−π, π)

(Pendulum-v1's θ is measured from upright already; its reward is at most 0 and 0 only at
rest upright without torque).

``StepResponse`` (track a target angle φ*) observes ``[cos φ, sin φ, φ', φ*]`` and is
rewarded with the test bench's integral of absolute error (``iae`` of
:func:`pendulum_sim.testing.metrics.step_metrics`: e = φ − φ*, the trapezoidal rule on the
samples at the period boundaries): a period from state ``a`` to state ``b`` earns

    r = −½ (|e_a| + |e_b|) T

so the return of an episode of K periods is −``iae`` of its K + 1 samples, the figure
``closed_loop(...).metrics(target).iae`` gives the same run.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
BIG = float(np.finfo(np.float64).max)
TAU_WEIGHT = 0.001
SPEED_WEIGHT = 0.1


def wrap(angle: FloatArray) -> FloatArray:
    """Return ``angle`` wrapped into [−π, π) (Pendulum-v1's ``angle_normalize``)."""
    return np.asarray(((angle + math.pi) % (2 * math.pi)) - math.pi)


def swing_up_observation(phi: FloatArray, vel: FloatArray, target: FloatArray) -> FloatArray:
    """Return ``[cos φ, sin φ, φ']`` per episode, shape (N, 3)."""
    return np.stack([np.cos(phi), np.sin(phi), vel], axis=-1)


def step_observation(phi: FloatArray, vel: FloatArray, target: FloatArray) -> FloatArray:
    """Return ``[cos φ, sin φ, φ', φ*]`` per episode, shape (N, 4)."""
    return np.stack([np.cos(phi), np.sin(phi), vel, target], axis=-1)


def swing_up_reward(phi: FloatArray, vel: FloatArray, phi1: FloatArray, vel1: FloatArray,
                    effort: FloatArray, target: FloatArray, period: float) -> FloatArray:
    """Return Pendulum-v1's reward of the periods from ``(phi, vel)`` under ``effort``."""
    theta = wrap(phi - math.pi)
    return np.asarray(-(theta * theta + SPEED_WEIGHT * vel * vel
                        + TAU_WEIGHT * effort * effort))


def step_reward(phi: FloatArray, vel: FloatArray, phi1: FloatArray, vel1: FloatArray,
                effort: FloatArray, target: FloatArray, period: float) -> FloatArray:
    """Return −(the iae of the periods from ``phi`` to ``phi1``) towards ``target``."""
    return np.asarray(-0.5 * (np.abs(phi - target) + np.abs(phi1 - target)) * period)


@dataclass(frozen=True)
class Task:
    """A task: its observation, reward, default scene and spaces, and episode length.

    ``goal`` is the angle a swing-up task's episodes are measured towards at their end
    (:func:`~pendulum_sim.testing.swing_up.metrics.swing_up_metrics`; rad), None for a task
    without one.
    """

    name: str
    observe: Any
    reward: Any
    size: int
    scene: str
    defaults: dict[str, Any]
    target: Any
    max_episode_steps: int
    goal: float | None = None

    def observation_bounds(self) -> tuple[FloatArray, FloatArray]:
        """Return the observation space's bounds (finite: the state bound lies within)."""
        high = np.array([1.0, 1.0, BIG, BIG][:self.size])
        return -high, high


SWING_UP = Task(
    'DampedPendulum', swing_up_observation, swing_up_reward, 3, 'controller_test',
    # Pendulum-v1's start: anywhere, slowly; 1 N m, less than m g l = 1.96 N m, so the
    # swing-up must pump energy.
    {'phi0': {'distribution': 'uniform', 'low': -math.pi, 'high': math.pi},
     'dphi0': {'distribution': 'uniform', 'low': -1.0, 'high': 1.0},
     'max_effort': 1.0},
    0.0, 1000, math.pi)
STEP = Task(
    'StepResponse', step_observation, step_reward, 4, 'controller_test',
    # From rest at 0 to a target that 1 N m can hold (m g l sin φ* ≤ 1 N m).
    {'phi0': 0.0, 'dphi0': 0.0, 'max_effort': 1.0},
    {'distribution': 'uniform', 'low': -0.5, 'high': 0.5}, 500)
TASKS = {t.name: t for t in (SWING_UP, STEP)}
