"""A policy as a law of the test bench: ``closed_loop`` and ``pendulum_campaign`` unchanged.

:func:`policy_law` turns a policy, any callable from an observation to an action, into the
law ``(t, position, velocity) -> command`` the test bench runs: at each state the law builds
the observation the environment would give (the same function,
:mod:`pendulum_sim.gym.tasks`), calls the policy, and answers with the torque, checked as the
environment checks an action (shape (1,), finite). The joint saturates it at ``max_effort``
as the environment does. A ``StepResponse`` law takes the keyword ``target`` (the bench
binds it, a campaign draws it), so the same policy gets the same verdict, figure and
campaign table as a PD law::

    law = policy_law(policy, task='StepResponse')
    run = closed_loop(law, periods=500, overrides={'max_effort': 1.0, 'phi0': 0.0},
                      target=0.3)

For a campaign, make the law a module attribute (``mymodule:law``) and name it as the
campaign file's ``controller``.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from .errors import GymError
from .tasks import TASKS

Policy = Callable[[Any], Any]


def policy_law(policy: Policy, *, task: str = 'DampedPendulum') -> Callable[..., float]:
    """Return the law ``(t, position, velocity[, target=]) -> torque`` of ``policy``.

    Parameters
    ----------
    policy : callable
        Observation (a numpy array as the environment gives) to action (shape (1,)).
    task : str
        ``'DampedPendulum'`` (observation ``[cos φ, sin φ, φ']``) or ``'StepResponse'``
        (``[cos φ, sin φ, φ', φ*]``; the law then takes the keyword ``target``, rad).
    """
    if task not in TASKS:
        raise GymError(f'task must be one of {", ".join(TASKS)}, got {task!r}')
    if not callable(policy):
        raise GymError(f'policy must be a callable from an observation to an action, got '
                       f'{policy!r}')
    observe = TASKS[task].observe

    def answer(position: float, velocity: float, target: float) -> float:
        obs = observe(np.array([position]), np.array([velocity]), np.array([target]))[0]
        action = np.asarray(policy(obs), dtype=np.float64)
        if action.shape != (1,):
            raise GymError(f'action must have shape (1,) (torques in N m), got shape '
                           f'{action.shape}')
        if not np.isfinite(action[0]):
            raise GymError(f'action must be a finite torque, got {action[0]}')
        return float(action[0])

    if task == 'StepResponse':
        def tracking_law(t: float, position: float, velocity: float, *,
                         target: float = 0.0) -> float:
            """Answer with the policy's torque for the state and the target (rad)."""
            return answer(position, velocity, target)
        return tracking_law

    def law(t: float, position: float, velocity: float) -> float:
        """Answer with the policy's torque for the state."""
        return answer(position, velocity, 0.0)
    return law
