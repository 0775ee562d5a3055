"""Campaign laws that wait for a Foxglove client before they answer (test_foxglove)."""
from __future__ import annotations

import os
import threading
import time

from pendulum_sim.testing.examples import pd

GATE = threading.Event()


def gated_pd(t: float, position: float, velocity: float) -> float:
    """Answer as the example PD law, once GATE is set (at most 30 s later)."""
    GATE.wait(30.0)
    return pd(t, position, velocity)


def file_gated_pd(t: float, position: float, velocity: float) -> float:
    """Answer as the example PD law once the file named by PENDULUM_LIVE_GATE exists (at most
    30 s later): the gate of a law in another process, an episode process of a campaign."""
    deadline = time.monotonic() + 30.0
    while not os.path.exists(os.environ['PENDULUM_LIVE_GATE']) and time.monotonic() < deadline:
        time.sleep(0.005)
    return pd(t, position, velocity)
