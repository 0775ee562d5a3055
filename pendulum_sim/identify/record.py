"""A record ready to fit: what ``fit`` prepares and every part of the fit reads."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from .guess import Guess

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Record:
    """A record ready to fit: times from its first sample, the unwrapped angle, the guess."""

    t0: float
    t: FloatArray
    y: FloatArray
    guess: Guess
