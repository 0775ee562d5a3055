"""Laws written with numpy for many episodes at once: the ``vectorised`` declaration."""
from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

F = TypeVar('F', bound=Callable[..., Any])


def vectorised(law: F) -> F:
    """Declare ``law`` batched: ``(t, position[], velocity[]) -> command[]`` (sets ``vectorised``).

    A campaign then steps its episodes together, N at a time, instead of one by one.
    """
    law.vectorised = True  # type: ignore[attr-defined]
    return law


def is_vectorised(law: object) -> bool:
    """Return True when ``law`` was declared batched with :func:`vectorised`."""
    return getattr(law, 'vectorised', False) is True
