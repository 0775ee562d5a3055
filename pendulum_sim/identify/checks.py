"""The checks every fit makes where its inputs enter: arrays of numbers, the jit switch."""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
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


def increasing(t: FloatArray) -> None:
    """Refuse sample times that do not increase strictly, naming the first pair."""
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        i = int(bad[0])
        raise IdentifyError(f't must increase strictly: t[{i + 1}] = {float(t[i + 1])!r} s '
                            f'follows t[{i}] = {float(t[i])!r} s; sort the samples and drop '
                            'repeated stamps')


def known_values(known: Mapping[str, float] | None, allowed: Sequence[str], prefix: str,
                 limit: Callable[[str, float], str | None]) -> dict[str, float]:
    """Return ``known`` (parameters a fit holds) as floats, or refuse it.

    Each key must be one of ``allowed`` (the message starts with ``prefix``), each value a
    finite number that ``limit(key, value)`` accepts (it returns what the value must be, or
    None).
    """
    if known is None:
        return {}
    if not isinstance(known, Mapping):
        raise IdentifyError(f'known must be a dict of parameter values, got {known!r}')
    out = {}
    for key, value in known.items():
        if key not in allowed:
            raise IdentifyError(f'{prefix}known may fix {", ".join(allowed)}; got {key!r}')
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(
                value):
            raise IdentifyError(f'known[{key!r}] must be a finite number, got {value!r}')
        must = limit(key, value)
        if must is not None:
            raise IdentifyError(f'known[{key!r}] must be {must}, got {value!r}')
        out[key] = float(value)
    return out


Progress = Callable[[int, int], None]
"""``progress(iteration, starts_done)`` after each iteration of a fit."""


__all__ = ['MIN_SAMPLES', 'Progress', 'as_array', 'increasing', 'jit_choice', 'known_values']
