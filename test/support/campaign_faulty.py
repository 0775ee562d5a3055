"""Laws that misbehave in the episodes whose target is 0.4 (the campaign fault tests).

Every law answers the example PD torque in the other episodes, and in its own after
t = 0.1 s does what its name says. Imported by Dask workers by name (test/ on PYTHONPATH).
"""
from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from pendulum_sim.testing import vectorised
from pendulum_sim.testing.examples import pd, pd_batch

FAULTY = 0.4
HOARD: list[bytes] = []
SLOW_S = 0.3   # s a call of ``slow`` takes: its 40 slow calls in an episode of 50 take 12 s


def _faulty(t: float, target: float) -> bool:
    return target == FAULTY and t > 0.1


def misbehaving(fault: Callable[[], object]) -> Callable[..., object]:
    """Return the law that calls ``fault`` where it is faulty and answers with what ``fault``
    returns (when not None), and answers the example PD torque otherwise.

    The law keeps ``fault``'s name and docstring (a campaign names it ``campaign_faulty:<name>``)
    and has the signature of a law that takes the target.
    """
    def law(t: float, position: float, velocity: float, *, target: float) -> object:
        if _faulty(t, target):
            answer = fault()
            if answer is not None:
                return answer
        return pd(t, position, velocity, target=target)

    law.__name__ = law.__qualname__ = fault.__name__
    law.__doc__ = fault.__doc__
    return law


@misbehaving
def overflow() -> object:
    """Return an int too large for a float."""
    return 10**400


@misbehaving
def exits() -> None:
    """Call sys.exit(3)."""
    sys.exit(3)


@misbehaving
def hard_exit() -> None:
    """Call os._exit(4)."""
    os._exit(4)


@misbehaving
def leaks() -> None:
    """Take memory, 10 MB at a time, and never give it back."""
    while True:
        HOARD.append(b'x' * 10_000_000)


@misbehaving
def hangs() -> None:
    """Never answer."""
    while True:
        time.sleep(1.0)


@misbehaving
def slow() -> None:
    """Answer every call, each after SLOW_S (well within the episode's limit)."""
    time.sleep(SLOW_S)


@misbehaving
def text() -> object:
    """Return the torque as a string ('0.5' reads as a number, but a command is a number)."""
    return '0.5'


@vectorised
def batch_exit(t: float, position: Any, velocity: Any, *, target: Any) -> Any:
    """The example batched law, which calls os._exit(4) when one of its episodes is faulty."""
    if t > 0.1 and bool(np.any(np.asarray(target) == FAULTY)):
        os._exit(4)
    return pd_batch(t, position, velocity, target=target)
