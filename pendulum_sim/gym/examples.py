"""Hand-written policies on the environments' observations (the tutorial's and the tests').

``energy_swing_up`` swings the default joint (``controller_test``: m g l = 1.96 N m,
I = 0.2002 kg m², 1 N m of torque) up by energy shaping and catches it upright with a PD law;
``tracking`` holds a target with a PD law and gravity compensation. ``tracking_law`` is
``tracking`` as a test bench law (:func:`~pendulum_sim.gym.bridge.policy_law`), to be named
in a campaign file as ``pendulum_sim.gym.examples:tracking_law``; ``tracking_batch`` is the
same law on a batch of observations (numpy's sin and arctan2: the same to round-off) and
``tracking_batch_law`` its ``@vectorised`` law, which a campaign runs N episodes at a time.
``energy_swing_up_batch`` is ``energy_swing_up`` on a batch (numpy's arctan2), and
``energy_swing_up_law`` / ``energy_swing_up_batch_law`` their laws, for ``pendulum_benchmark``
(``pendulum_sim.gym.examples:energy_swing_up_batch_law``).
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from .bridge import policy_law

FloatArray = NDArray[np.float64]
MGL = 0.2 * 9.8 * 1.0    # m g l of controller_test, N m
INERTIA = 0.2002         # kg m²
LIMIT = 1.0              # the environments' default max_effort, N m
CATCH = 0.35             # rad from upright where the PD law takes over
KP, KD = 8.0, 1.5        # the catching PD law, N m/rad and N m s/rad


def energy_swing_up(obs: FloatArray) -> FloatArray:
    """Return the torque that pumps energy to the upright's, or catches it near upright.

    Energy E = ½ I φ'² + m g l (1 − cos φ) (0 hanging at rest, 2 m g l upright at rest); its
    rate is τ φ', so the torque pushes along φ' while E is short and against it when over.
    """
    cos_phi, sin_phi, velocity = float(obs[0]), float(obs[1]), float(obs[2])
    theta = math.atan2(-sin_phi, -cos_phi)   # φ − π wrapped: 0 upright
    if abs(theta) < CATCH:
        tau = -KP * theta - KD * velocity
    else:
        energy = 0.5 * INERTIA * velocity * velocity + MGL * (1.0 - cos_phi)
        push = 1.0 if velocity >= 0.0 else -1.0
        tau = LIMIT * push * (1.0 if energy < 2.0 * MGL else -1.0)
    return np.array([min(max(tau, -LIMIT), LIMIT)])


def tracking(obs: FloatArray) -> FloatArray:
    """Return a PD torque towards the target ``obs[3]`` with gravity compensation."""
    sin_phi, velocity, target = float(obs[1]), float(obs[2]), float(obs[3])
    phi = math.atan2(sin_phi, float(obs[0]))
    tau = MGL * sin_phi + 3.0 * (target - phi) - 0.8 * velocity
    return np.array([min(max(tau, -LIMIT), LIMIT)])


tracking_law = policy_law(tracking, task='StepResponse')


def tracking_batch(obs: FloatArray) -> FloatArray:
    """Return :func:`tracking`'s torques for a batch of observations (N, 4) as (N, 1)."""
    sin_phi, velocity, target = obs[:, 1], obs[:, 2], obs[:, 3]
    phi = np.arctan2(sin_phi, obs[:, 0])
    tau = MGL * sin_phi + 3.0 * (target - phi) - 0.8 * velocity
    return np.clip(tau, -LIMIT, LIMIT)[:, None]


tracking_batch_law = policy_law(tracking_batch, task='StepResponse', batched=True)


def energy_swing_up_batch(obs: FloatArray) -> FloatArray:
    """Return :func:`energy_swing_up`'s torques for a batch of observations, shape (N, 1)."""
    cos_phi, sin_phi, velocity = obs[:, 0], obs[:, 1], obs[:, 2]
    theta = np.arctan2(-sin_phi, -cos_phi)
    energy = 0.5 * INERTIA * velocity * velocity + MGL * (1.0 - cos_phi)
    push = np.where(velocity >= 0.0, 1.0, -1.0)
    pump = LIMIT * push * np.where(energy < 2.0 * MGL, 1.0, -1.0)
    tau = np.where(np.abs(theta) < CATCH, -KP * theta - KD * velocity, pump)
    return np.clip(tau, -LIMIT, LIMIT)[:, np.newaxis]


energy_swing_up_law = policy_law(energy_swing_up)
energy_swing_up_batch_law = policy_law(energy_swing_up_batch, batched=True)
