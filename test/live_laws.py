"""A campaign law that waits for a Foxglove client before its first answer (test_foxglove)."""
from __future__ import annotations

import threading

from pendulum_sim.testing.examples import pd

GATE = threading.Event()


def gated_pd(t: float, position: float, velocity: float) -> float:
    """Answer as the example PD law, once GATE is set (at most 30 s later)."""
    GATE.wait(30.0)
    return pd(t, position, velocity)
