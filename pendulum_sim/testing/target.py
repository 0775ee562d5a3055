"""How a controller receives its target: a keyword ``target`` or a ``{target}`` placeholder.

A Python law receives the target when its signature names a parameter ``target`` (keyword-only
or positional-or-keyword), e.g. ``law(t, position, velocity, *, target)``: :func:`bind_target`
then returns the law with the target bound once (``functools.partial``), so each control period
is a plain call. A :func:`~pendulum_sim.testing.vectorised` law gets an array, one target per
episode of the batch. A command line receives it through the placeholder ``{target}`` in any
of its arguments, e.g. ``['pendulum_pd_controller', '--ros-args', '-p', 'target:={target}']``:
:func:`substitute_target` writes the number there, as the shortest decimal that reads back as
the same float (``repr``), so the controller's target is the campaign's bit for bit.
"""
from __future__ import annotations

import functools
import inspect
from collections.abc import Callable, Sequence
from typing import Any

from .errors import TestingError

PLACEHOLDER = '{target}'
_TAKES = (inspect.Parameter.KEYWORD_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)


def takes_target(law: Callable[..., Any]) -> bool:
    """Return True when ``law``'s signature has a parameter ``target`` it takes by keyword."""
    try:
        parameters = inspect.signature(law).parameters
    except (TypeError, ValueError):   # no signature to read (some builtins): no keyword
        return False
    found = parameters.get('target')
    return found is not None and found.kind in _TAKES


def bind_target(law: Callable[..., Any], target: Any) -> Callable[..., Any]:
    """Return ``law`` with ``target=target`` bound (the law itself when it takes no target)."""
    return functools.partial(law, target=target) if takes_target(law) else law


def has_placeholder(command: Sequence[str]) -> bool:
    """Return True when an argument of the command line holds :data:`PLACEHOLDER`."""
    return any(PLACEHOLDER in arg for arg in command)


def substitute_target(command: Sequence[str], target: float | None) -> list[str]:
    """Return the command line with :data:`PLACEHOLDER` replaced by ``repr(float(target))``.

    Raises
    ------
    TestingError
        If the command line has the placeholder and ``target`` is None.
    """
    if not has_placeholder(command):
        return list(command)
    if target is None:
        raise TestingError(f'the controller command line has a {PLACEHOLDER} placeholder but '
                           'no target was given (closed_loop(..., target=...))')
    text = repr(float(target))
    return [arg.replace(PLACEHOLDER, text) for arg in command]
