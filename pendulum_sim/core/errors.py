"""Exceptions of the numerical core."""
from __future__ import annotations


class PendulumError(Exception):
    """Base class of every error raised by pendulum_sim."""


class ModelError(PendulumError, ValueError):
    """A physical parameter or initial state is outside its allowed range."""


class IntegratorError(PendulumError, ValueError):
    """An integrator was asked for something it cannot do (unknown name, bad step, ...)."""
