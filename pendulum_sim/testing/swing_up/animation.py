"""Animate a closed-loop run: the frames the Gymnasium environments render, as a GIF.

Each frame is :func:`pendulum_sim.frames.frame` (the rod at the measured angle, the torque
bar, the goal ray) of the sample nearest each frame's time, at ``fps`` frames per second of
simulated time, so the GIF plays the run in real time. Pillow (a dependency of matplotlib)
writes the file.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
from numpy.typing import NDArray

from pendulum_sim.frames import BACKGROUND, BOB, PIVOT, ROD, TARGET, TORQUE

from ..errors import TestingError
from ..run import ClosedLoopRun

FPS = 25
_COLOURS = sorted({BACKGROUND, ROD, BOB, PIVOT, TARGET, TORQUE},
                  key=lambda c: (c[0] << 16) | (c[1] << 8) | c[2])
_CODES = np.array([(c[0] << 16) | (c[1] << 8) | c[2] for c in _COLOURS], dtype=np.int32)
_PALETTE = [v for c in _COLOURS for v in c]


def frame_indices(t: np.ndarray, fps: float) -> np.ndarray:
    """Return the sample index shown at each frame: the last sample at or before its time."""
    if t.size == 0:
        raise TestingError('a run of 0 samples has nothing to animate')
    times = t[0] + np.arange(math.floor((t[-1] - t[0]) * fps + 1e-9) + 1) / fps
    index: np.ndarray = np.maximum(np.searchsorted(t, times + 1e-12, side='right') - 1, 0)
    return index


def _indexed(image: Any, rgb: NDArray[np.uint8]) -> Any:
    """Return the frame as a Pillow palette image of the frames' own colours (exact)."""
    codes = (rgb[..., 0].astype(np.int32) << 16) | (rgb[..., 1].astype(np.int32) << 8) | rgb[
        ..., 2]
    index = np.searchsorted(_CODES, codes).astype(np.uint8)
    out = image.fromarray(index, mode='P')
    out.putpalette(_PALETTE)
    return out


def write_gif(run: ClosedLoopRun, path: str | Path | BinaryIO, *,
              goal: float | None = None, fps: float = FPS, size: int = 200) -> Any:
    """Write ``run`` as an animated GIF to ``path`` (replaced); return the path.

    Parameters
    ----------
    run : ClosedLoopRun
        The run to draw.
    path : path or binary file
        Where the GIF goes (a file object is written to and returned as it is).
    goal : float, optional
        The angle drawn as the goal ray (rad); the run's target where None (none if it has
        none).
    fps : float
        Frames per second of simulated time (> 0).
    size : int
        The frames' width and height in pixels (>= 32).

    Raises
    ------
    TestingError
        If ``fps`` or ``size`` is out of range, the run has no samples, Pillow is missing or
        the file cannot be written.
    """
    from pendulum_sim.frames import frame

    if not (math.isfinite(fps) and fps > 0):
        raise TestingError(f'fps must be a finite number > 0, got {fps}')
    if size < 32:
        raise TestingError(f'size must be >= 32 pixels, got {size}')
    try:
        from PIL import Image
    except ImportError:
        raise TestingError("an animation needs Pillow: pip install 'pendulum_sim[plots]'") \
            from None
    ray = run.target if goal is None else goal
    limit = run.max_effort
    if not (math.isfinite(limit) and limit > 0):   # no limit: the largest torque fills the bar
        limit = float(np.max(np.abs(run.effort))) if run.effort.size else 0.0
    images = [_indexed(Image, frame(float(run.position[i]), float(run.effort[i]), limit,
                                    ray, size=size))
              for i in frame_indices(run.t, fps).tolist()]
    out = path if hasattr(path, 'write') else Path(path)
    try:
        images[0].save(out, format='GIF', save_all=True, append_images=images[1:],
                       duration=round(1000.0 / fps), loop=0, optimize=False)
    except OSError as exc:
        raise TestingError(f"cannot write '{out}': {exc}") from None
    return out
