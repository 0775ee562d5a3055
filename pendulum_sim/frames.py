"""Frames of the pendulum drawn with numpy: the rod, the bob, the pivot, the torque's sign.

The Gymnasium environments' ``rgb_array`` render (:mod:`pendulum_sim.gym.render`) and the
animations of a closed-loop run (``swing_up.gif``, ``pendulum_report animate``) draw these
frames; numpy only, so neither Gymnasium nor a plotting library is needed for them.
"""
from __future__ import annotations

import functools
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


@functools.lru_cache(maxsize=8)
def _grid(size: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return the pixel rows and columns of a frame (made once per size, read-only)."""
    y, x = np.mgrid[0:size, 0:size].astype(np.float64)
    y.flags.writeable = False
    x.flags.writeable = False
    return y, x


def _window(lo: float, hi: float, size: int) -> slice:
    """Return the pixel indices from ``floor(lo)`` to ``ceil(hi)``, within the frame."""
    return slice(max(0, math.floor(lo)), min(size, math.ceil(hi) + 1))


def frame(phi: float, effort: float, max_effort: float, target: float | None = None,
          size: int = SIZE) -> NDArray[np.uint8]:
    """Return an RGB frame (size × size × 3, uint8) of the pendulum at angle ``phi`` (rad).

    φ = 0 hangs straight down; the rod is drawn from the pivot at the centre. A target
    (rad) is drawn as a thin green ray; the applied torque as a blue bar at the top, to the
    right for positive torque, of length ``|effort| / max_effort`` of half the width. Each
    shape's test runs on the pixels of its bounding box only (no pixel outside it passes).
    """
    img = np.empty((size, size, 3), dtype=np.uint8)
    img[:] = BACKGROUND
    y_all, x_all = _grid(size)
    c = (size - 1) / 2.0
    length = 0.4 * size

    def paint(rows: slice, cols: slice, near: NDArray[np.bool_],
              colour: tuple[int, int, int]) -> None:
        img[rows, cols][near] = colour

    def segment(angle: float, width: float, colour: tuple[int, int, int]) -> None:
        ex, ey = c + length * math.sin(angle), c + length * math.cos(angle)
        rows = _window(min(c, ey) - width, max(c, ey) + width, size)
        cols = _window(min(c, ex) - width, max(c, ex) + width, size)
        x, y = x_all[rows, cols], y_all[rows, cols]
        dx, dy = ex - c, ey - c
        s = np.clip(((x - c) * dx + (y - c) * dy) / (dx * dx + dy * dy), 0.0, 1.0)
        paint(rows, cols, (x - c - s * dx) ** 2 + (y - c - s * dy) ** 2 <= width * width,
              colour)

    def disc(cx: float, cy: float, radius: float, colour: tuple[int, int, int]) -> None:
        rows = _window(cy - radius, cy + radius, size)
        cols = _window(cx - radius, cx + radius, size)
        x, y = x_all[rows, cols], y_all[rows, cols]
        paint(rows, cols, (x - cx) ** 2 + (y - cy) ** 2 <= radius ** 2, colour)

    if target is not None:
        segment(target, 0.006 * size, TARGET)
    segment(phi, 0.02 * size, ROD)
    disc(c + length * math.sin(phi), c + length * math.cos(phi), 0.06 * size, BOB)
    disc(c, c, 0.02 * size, PIVOT)
    share = min(abs(effort) / max_effort, 1.0) if max_effort > 0 else 0.0
    reach = share * (size / 2.0 - 4)
    lo, hi = (c, c + reach) if effort >= 0 else (c - reach, c)
    rows, cols = _window(4, 4 + 0.03 * size, size), _window(lo, hi, size)
    x, y = x_all[rows, cols], y_all[rows, cols]
    paint(rows, cols, (y >= 4) & (y <= 4 + 0.03 * size) & (x >= lo) & (x <= hi), TORQUE)
    return img
