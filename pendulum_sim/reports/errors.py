"""Exceptions of the reports."""
from __future__ import annotations

from ..core.errors import PendulumError


class ReportError(PendulumError):
    """A report cannot be written (bad output folder, bad grid, ...)."""
