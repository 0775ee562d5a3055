"""Exceptions of the controller test bench."""
from __future__ import annotations

from typing import Any

from pendulum_sim.core.errors import PendulumError


class TestingError(PendulumError, ValueError):
    """A metric, a closed-loop run or a campaign cannot be computed as asked (says why)."""

    __test__ = False   # not a pytest test class, whatever its name


class ControllerFailed(TestingError):
    """The controller under test raised, returned a non-finite command or could not start.

    ``run`` is the in-process run up to the state the controller failed to answer (a
    :class:`~pendulum_sim.testing.ClosedLoopRun`), when there is one.
    """

    __test__ = False
    run: Any = None


class CampaignError(TestingError):
    """A campaign file is unusable (unknown parameter, impossible distribution, ...)."""

    __test__ = False


class BenchmarkError(CampaignError):
    """A benchmark cannot be run as asked (unknown criterion, a goal box or torque limit of
    zero, an output folder in use, ...)."""

    __test__ = False
