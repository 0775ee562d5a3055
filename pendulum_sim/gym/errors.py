"""Exceptions of the Gymnasium environments."""
from __future__ import annotations


class GymError(ValueError):
    """An environment cannot be made or stepped as asked (bad keyword, action or call order)."""
