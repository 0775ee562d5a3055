"""Example laws for closed loops and campaigns: the example controller's PD law as a callable.

``pd`` is what ``pendulum_pd_controller`` answers with its default gains
(:func:`pendulum_sim.controller.pd_law.pd_torque`), towards its keyword ``target`` (default
0.5 rad, the controller's default), so a campaign can name it as
``pendulum_sim.testing.examples:pd`` and vary the target; ``pd_batch`` is the same law on
arrays (a target per episode), declared :func:`~pendulum_sim.testing.vectorised`.

The swing-up task's reference laws (:mod:`pendulum_sim.controller.swing_up_law`, on the
``swing_up`` scene's body with its torque limit, half of m g l), each vectorised and each
also a law of one state: ``energy_lqr`` (energy-shaping swing-up, LQR balance inside its
region-of-attraction ellipse), ``lqr_balance`` (the LQR balance alone) and ``saturated_pd``
(a PD towards upright, saturated: the contrast). ``energy_lqr`` and ``lqr_balance`` carry
the LQR ellipse's function as ``roa_estimate``.
"""
from __future__ import annotations

import dataclasses
import functools
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pendulum_sim.controller.pd_law import PDGains, pd_torque
from pendulum_sim.controller.swing_up_law import (
    Balance,
    Ellipse,
    SwingUpGains,
    balance,
    lqr_torque,
    pd_upright_torque,
    swing_up_torque,
)

from .vector import vectorised

GAINS = PDGains()


@functools.lru_cache(maxsize=64)
def gains_for(target: float) -> PDGains:
    """Return the default gains with the reference ``target`` (rad; built once per target)."""
    return dataclasses.replace(GAINS, target=target)


def pd(t: float, position: float, velocity: float, *, target: float = GAINS.target) -> float:
    """Return the example controller's torque for one state, towards ``target`` (rad)."""
    return pd_torque(gains_for(target), position, velocity)


@vectorised
def pd_batch(t: NDArray[np.float64], position: NDArray[np.float64],
             velocity: NDArray[np.float64], *,
             target: ArrayLike = GAINS.target) -> NDArray[np.float64]:
    """Return :func:`pd` for many states at once (same operations, element by element)."""
    g = GAINS
    error = np.remainder(np.asarray(target, dtype=float) - position + np.pi, 2 * np.pi) - np.pi
    tau = g.mgl * np.sin(position) + g.kp * error - g.kd * velocity
    return np.clip(tau, -g.max_effort, g.max_effort)


# ------------------------------------------------------------------ the swing-up task
SWING_UP = SwingUpGains()   # the swing_up scene's body, torque limit half of m g l


@functools.cache
def reference_balance() -> Balance:
    """Return the reference LQR balance of :data:`SWING_UP` (computed at first use: importing
    python-control takes a second or more, which a law's module need not pay at import)."""
    return balance(SWING_UP)


def reference_region() -> Ellipse:
    """Return the reference balance's region-of-attraction estimate (the LQR ellipse)."""
    return reference_balance().region


@vectorised
def energy_lqr(t: Any, position: Any, velocity: Any) -> Any:
    """Return the energy-shaping swing-up's torque, LQR's inside its ellipse (any shape)."""
    return swing_up_torque(SWING_UP, reference_balance(), position, velocity)


@vectorised
def lqr_balance(t: Any, position: Any, velocity: Any) -> Any:
    """Return the LQR balance's torque alone, saturated at the torque limit (any shape)."""
    return lqr_torque(SWING_UP, reference_balance().gain, position, velocity)


@vectorised
def saturated_pd(t: Any, position: Any, velocity: Any) -> Any:
    """Return the saturated PD's torque towards upright (any shape): the contrast."""
    return pd_upright_torque(SWING_UP, position, velocity)


# The linearised region-of-attraction estimate the benchmark draws over their maps (a
# function returning it: the benchmark calls it when it draws).
energy_lqr.roa_estimate = reference_region  # type: ignore[attr-defined]
lqr_balance.roa_estimate = reference_region  # type: ignore[attr-defined]
