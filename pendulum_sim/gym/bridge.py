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
campaign file's ``controller``. With ``batched=True`` the policy takes a batch of
observations (shape (N, d)) and answers (N, 1); the law is then declared
:func:`~pendulum_sim.testing.vectorised`, so a campaign steps its episodes N at a time.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from .errors import GymError
from .runner import torques
from .tasks import TASKS

Policy = Callable[[Any], Any]


def policy_law(policy: Policy, *, task: str = 'DampedPendulum',
               batched: bool = False) -> Callable[..., Any]:
    """Return the law ``(t, position, velocity[, target=]) -> torque`` of ``policy``.

    Parameters
    ----------
    policy : callable
        Observation (a numpy array as the environment gives) to action (shape (1,)).
    task : str
        ``'DampedPendulum'`` (observation ``[cos φ, sin φ, φ']``) or ``'StepResponse'``
        (``[cos φ, sin φ, φ', φ*]``; the law then takes the keyword ``target``, rad).
    batched : bool
        The policy maps observations of shape (N, d) to actions (N, 1); the law answers
        arrays of states, ``@vectorised``.
    """
    if task not in TASKS:
        raise GymError(f'task must be one of {", ".join(TASKS)}, got {task!r}')
    if not callable(policy):
        raise GymError(f'policy must be a callable from an observation to an action, got '
                       f'{policy!r}')
    observe = TASKS[task].observe
    if batched:
        return _batched(policy, observe, task == 'StepResponse')

    def answer(position: float, velocity: float, target: float) -> float:
        obs = observe(np.array([position]), np.array([velocity]), np.array([target]))[0]
        return float(torques(policy(obs), (1,))[0])

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


def _batched(policy: Policy, observe: Any, tracking: bool) -> Callable[..., Any]:
    """Return the ``@vectorised`` law of a policy on batches of observations."""
    from pendulum_sim.testing.vector import vectorised

    def answer(position: Any, velocity: Any, target: Any) -> Any:
        p = np.asarray(position, dtype=np.float64)
        obs = observe(p, np.asarray(velocity, dtype=np.float64),
                      np.broadcast_to(np.asarray(target, dtype=np.float64), p.shape))
        return torques(policy(obs), (p.size, 1))

    if tracking:
        @vectorised
        def tracking_law(t: Any, position: Any, velocity: Any, *, target: Any = 0.0) -> Any:
            """Answer each state with the policy's torque towards its target (rad)."""
            return answer(position, velocity, target)
        return tracking_law

    @vectorised
    def law(t: Any, position: Any, velocity: Any) -> Any:
        """Answer each state with the policy's torque."""
        return answer(position, velocity, 0.0)
    return law
