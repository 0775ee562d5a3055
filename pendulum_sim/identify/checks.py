"""The checks every fit makes where its inputs enter: arrays of numbers, the jit switch."""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

from pendulum_sim.core.jit import available as jit_available

from .errors import IdentifyError

FloatArray = npt.NDArray[np.float64]

MIN_SAMPLES = 10
"""The fewest samples a record may have."""


def as_array(name: str, value: Any, size: int | None) -> FloatArray:
    """Return ``value`` as a 1-D float array of ``size`` finite numbers, or say what it is."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise IdentifyError(f'{name} must be a 1-D array of numbers, got {type(value).__name__}'
                            ) from None
    if arr.ndim != 1:
        raise IdentifyError(f'{name} must be a 1-D array, got shape {arr.shape}')
    if size is not None and arr.size != size:
        raise IdentifyError(f'{name} has {arr.size} samples but t has {size}')
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise IdentifyError(f'{name} has {bad.size} samples that are NaN or infinite (the first '
                            f'at index {bad[0]}); drop them before fitting')
    return arr


def jit_choice(jit: bool | None) -> bool:
    """Say whether the fit simulates on the compiled sweep (None: where numba is installed)."""
    if jit is None:
        return jit_available()
    if not isinstance(jit, bool):
        raise IdentifyError(f'jit must be True, False or None, got {jit!r}')
    return jit


Progress = Callable[[int, int], None]
"""``progress(iteration, starts_done)`` after each iteration of a fit."""


__all__ = ['MIN_SAMPLES', 'Progress', 'as_array', 'jit_choice']
