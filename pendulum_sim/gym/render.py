"""Frames of the pendulum drawn with numpy: the rod, the bob, the pivot, the torque's sign."""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

SIZE = 256
BACKGROUND = (255, 255, 255)
ROD = (60, 60, 60)
BOB = (200, 70, 40)
PIVOT = (0, 0, 0)
TARGET = (40, 140, 60)
TORQUE = (40, 90, 200)


def frame(phi: float, effort: float, max_effort: float, target: float | None = None,
          size: int = SIZE) -> NDArray[np.uint8]:
    """Return an RGB frame (size × size × 3, uint8) of the pendulum at angle ``phi`` (rad).

    φ = 0 hangs straight down; the rod is drawn from the pivot at the centre. A target
    (rad) is drawn as a thin green ray; the applied torque as a blue bar at the top, to the
    right for positive torque, of length ``|effort| / max_effort`` of half the width.
    """
    img = np.empty((size, size, 3), dtype=np.uint8)
    img[:] = BACKGROUND
    y, x = np.mgrid[0:size, 0:size].astype(np.float64)
    c = (size - 1) / 2.0
    length = 0.4 * size

    def segment(angle: float, width: float, colour: tuple[int, int, int]) -> None:
        ex, ey = c + length * math.sin(angle), c + length * math.cos(angle)
        dx, dy = ex - c, ey - c
        s = np.clip(((x - c) * dx + (y - c) * dy) / (dx * dx + dy * dy), 0.0, 1.0)
        near = (x - c - s * dx) ** 2 + (y - c - s * dy) ** 2 <= width * width
        img[near] = colour

    if target is not None:
        segment(target, 0.006 * size, TARGET)
    segment(phi, 0.02 * size, ROD)
    bx, by = c + length * math.sin(phi), c + length * math.cos(phi)
    img[(x - bx) ** 2 + (y - by) ** 2 <= (0.06 * size) ** 2] = BOB
    img[(x - c) ** 2 + (y - c) ** 2 <= (0.02 * size) ** 2] = PIVOT
    share = min(abs(effort) / max_effort, 1.0) if max_effort > 0 else 0.0
    reach = share * (size / 2.0 - 4)
    lo, hi = (c, c + reach) if effort >= 0 else (c - reach, c)
    img[(y >= 4) & (y <= 4 + 0.03 * size) & (x >= lo) & (x <= hi)] = TORQUE
    return img
