"""Exceptions of the controller test bench."""
from __future__ import annotations


class TestingError(ValueError):
    """A metric, a closed-loop run or a campaign cannot be computed as asked (says why)."""

    __test__ = False   # not a pytest test class, whatever its name


class ControllerFailed(TestingError):
    """The controller under test raised, returned a non-finite command or could not start."""

    __test__ = False


class CampaignError(TestingError):
    """A campaign file is unusable (unknown parameter, impossible distribution, ...)."""

    __test__ = False
