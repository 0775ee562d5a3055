"""Laws that misbehave in the episodes whose target is 0.4 (the campaign fault tests).

Every law answers the example PD torque in the other episodes, and in its own after
t = 0.1 s does what its name says. Imported by Dask workers by name (test/ on PYTHONPATH).
"""
from __future__ import annotations

import os
import sys
import time
from typing import Any

import numpy as np

from pendulum_sim.testing import vectorised
from pendulum_sim.testing.examples import pd, pd_batch

FAULTY = 0.4
HOARD: list[bytes] = []
SLOW_S = 0.3   # s a call of ``slow`` takes: its 40 slow calls in an episode of 50 take 12 s


def _faulty(t: float, target: float) -> bool:
    return target == FAULTY and t > 0.1


def overflow(t: float, position: float, velocity: float, *, target: float) -> object:
    """Return an int too large for a float."""
    return 10**400 if _faulty(t, target) else pd(t, position, velocity, target=target)


def exits(t: float, position: float, velocity: float, *, target: float) -> float:
    """Call sys.exit(3)."""
    if _faulty(t, target):
        sys.exit(3)
    return pd(t, position, velocity, target=target)


def hard_exit(t: float, position: float, velocity: float, *, target: float) -> float:
    """Call os._exit(4)."""
    if _faulty(t, target):
        os._exit(4)
    return pd(t, position, velocity, target=target)


def leaks(t: float, position: float, velocity: float, *, target: float) -> float:
    """Take memory, 10 MB at a time, and never give it back."""
    while _faulty(t, target):
        HOARD.append(b'x' * 10_000_000)
    return pd(t, position, velocity, target=target)


def hangs(t: float, position: float, velocity: float, *, target: float) -> float:
    """Never answer."""
    while _faulty(t, target):
        time.sleep(1.0)
    return pd(t, position, velocity, target=target)


def slow(t: float, position: float, velocity: float, *, target: float) -> float:
    """Answer every call, each after SLOW_S (well within the episode's limit)."""
    if _faulty(t, target):
        time.sleep(SLOW_S)
    return pd(t, position, velocity, target=target)


def text(t: float, position: float, velocity: float, *, target: float) -> object:
    """Return the torque as a string ('0.5' reads as a number, but a command is a number)."""
    return '0.5' if _faulty(t, target) else pd(t, position, velocity, target=target)


@vectorised
def batch_exit(t: float, position: Any, velocity: Any, *, target: Any) -> Any:
    """The example batched law, which calls os._exit(4) when one of its episodes is faulty."""
    if t > 0.1 and bool(np.any(np.asarray(target) == FAULTY)):
        os._exit(4)
    return pd_batch(t, position, velocity, target=target)
