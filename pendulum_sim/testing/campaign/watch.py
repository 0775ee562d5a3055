"""The law's clock: when the running call of the law under test began, seen from outside.

An episode process (:mod:`~pendulum_sim.testing.campaign.sandbox`) writes the monotonic time
at which each call of the law begins, and 0 when it returns, to 8 bytes of memory it shares
with the process that watches it; the watcher reads them to tell a law that does not answer
(or that exits, or is killed, during a call) from the rest of the episode. Without a clock
(an episode run in the caller's process) :func:`watched` leaves the law as it is.
"""
from __future__ import annotations

import functools
import mmap
import struct
import time
from collections.abc import Callable
from typing import Any, TypeVar

F = TypeVar('F', bound=Callable[..., Any])
SIZE = 8


class LawClock:
    """8 shared bytes: the monotonic time the running law call began, 0.0 between calls."""

    def __init__(self, fd: int) -> None:
        self._memory = mmap.mmap(fd, SIZE)

    def enter(self) -> None:
        """Mark the start of a call of the law."""
        struct.pack_into('d', self._memory, 0, time.monotonic())

    def leave(self) -> None:
        """Mark that the law answered."""
        struct.pack_into('d', self._memory, 0, 0.0)

    def since(self) -> float:
        """Return when the running call began (``time.monotonic``), 0.0 when none runs."""
        value: float = struct.unpack_from('d', self._memory, 0)[0]
        return value

    def close(self) -> None:
        """Release the shared memory."""
        self._memory.close()


CLOCK: list[LawClock] = []   # the episode process's clock, when it has one


def watched(law: F) -> F:
    """Return ``law`` with each call marked on the process's clock (``law`` without one).

    The result has ``law``'s signature (:func:`functools.wraps`), so a keyword ``target`` and
    the ``vectorised`` declaration are seen through it.
    """
    if not CLOCK:
        return law
    clock = CLOCK[0]

    @functools.wraps(law)
    def call(*args: Any, **kwargs: Any) -> Any:
        clock.enter()
        try:
            answer = law(*args, **kwargs)
        except Exception:   # the episode fails with it; an exit leaves the mark for the watcher
            clock.leave()
            raise
        clock.leave()
        return answer
    return call  # type: ignore[return-value]
