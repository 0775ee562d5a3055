"""The law's clock: when the running episode and call of the law under test began, from outside.

An episode process (:mod:`~pendulum_sim.testing.campaign.sandbox`) writes the monotonic time
at which each episode's closed loop begins (the first call of its :func:`watched` law) and
ends (:func:`loop_done`), at which each call
of the law begins, 0 when they end, and the time the episode's law calls took, to 24 bytes of
memory it shares with the process that watches it; the watcher reads them to hold an episode
to its time limit (``episode_timeout``, however its law spends it: one call that never returns
or many that each take long), to tell whether the law took most of that time, and to tell a
law that exits or is killed during a call from the rest of the episode. Without a clock (an
episode run in the caller's process) :func:`watched` leaves the law as it is.
"""
from __future__ import annotations

import functools
import mmap
import struct
import time
from collections.abc import Callable
from typing import Any, TypeVar

F = TypeVar('F', bound=Callable[..., Any])
SIZE = 24
_CALL, _EPISODE, _SPENT = 0, 8, 16   # the offsets of the three times


class LawClock:
    """24 shared bytes: when the running law call and episode began (monotonic, 0.0: none),
    and the seconds the episode's finished law calls took."""

    def __init__(self, fd: int) -> None:
        self._memory = mmap.mmap(fd, SIZE)

    def enter(self) -> None:
        """Mark the start of a call of the law."""
        struct.pack_into('d', self._memory, _CALL, time.monotonic())

    def leave(self) -> None:
        """Mark that the law answered; add the call's time to the episode's law time."""
        began = self.since()
        if began > 0.0:
            spent: float = struct.unpack_from('d', self._memory, _SPENT)[0]
            struct.pack_into('d', self._memory, _SPENT, spent + time.monotonic() - began)
        struct.pack_into('d', self._memory, _CALL, 0.0)

    def since(self) -> float:
        """Return when the running call began (``time.monotonic``), 0.0 when none runs."""
        value: float = struct.unpack_from('d', self._memory, _CALL)[0]
        return value

    def begin_episode(self) -> None:
        """Mark the start of an episode's closed loop (or of a batch's); no law time yet."""
        struct.pack_into('d', self._memory, _SPENT, 0.0)
        struct.pack_into('d', self._memory, _EPISODE, time.monotonic())

    def end_episode(self) -> None:
        """Mark that the episode (or batch) ended: its row is made."""
        struct.pack_into('d', self._memory, _EPISODE, 0.0)

    def episode_since(self) -> float:
        """Return when the running episode began (``time.monotonic``), 0.0 when none runs."""
        value: float = struct.unpack_from('d', self._memory, _EPISODE)[0]
        return value

    def law_time(self, now: float) -> float:
        """Return the seconds the running episode's law calls took up to ``now`` (monotonic)."""
        spent: float = struct.unpack_from('d', self._memory, _SPENT)[0]
        began = self.since()
        return spent + (now - began if began > 0.0 else 0.0)

    def close(self) -> None:
        """Release the shared memory."""
        self._memory.close()


CLOCK: list[LawClock] = []   # the episode process's clock, when it has one


def watched(law: F) -> F:
    """Return ``law`` with each call marked on the process's clock (``law`` without one).

    Made once per episode (or batch): its first call marks the start of the episode's closed
    loop (the set-up before it, the same for every episode, is not timed), and
    :func:`loop_done` its end. The result has ``law``'s signature (:func:`functools.wraps`),
    so a keyword ``target`` and the ``vectorised`` declaration are seen through it.
    """
    if not CLOCK:
        return law
    clock = CLOCK[0]
    clock.end_episode()   # none runs until the first call

    @functools.wraps(law)
    def call(*args: Any, **kwargs: Any) -> Any:
        if clock.episode_since() == 0.0:
            clock.begin_episode()
        clock.enter()
        try:
            answer = law(*args, **kwargs)
        except Exception:   # the episode fails with it; an exit leaves the mark for the watcher
            clock.leave()
            raise
        clock.leave()
        return answer
    return call  # type: ignore[return-value]


def loop_done() -> None:
    """Mark that the running episode's closed loop ended (its time limit no longer runs)."""
    if CLOCK:
        CLOCK[0].end_episode()
