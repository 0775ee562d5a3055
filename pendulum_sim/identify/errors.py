"""The identification's own exception class."""
from __future__ import annotations

from pendulum_sim.core.errors import PendulumError


class IdentifyError(PendulumError, ValueError):
    """A record or an option the identification cannot use; the message says what to pass."""
