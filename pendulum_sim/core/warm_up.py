"""Compile the compiled sweep's paths before the clock starts: the ``jit`` warm-up.

A ``jit=True`` sweep compiles the careful path once and a run per spelling of the damping law
(``kernel.kernel_source``), in a serial and a parallel form: 25–45 s on a 2-core machine
for the first spelling, 10–15 s for each further one. The compiled code is kept on disk
(``jit_cache.py``), so only the first process on a machine pays this; a later process loads it
(about 1 s for the first sweep, imports included). :func:`warm_up` takes one compiled step of
each form for each spelling asked for, so a following sweep of those laws (any ω0², γ, state,
torque, number of pendulums and any exponent of those spellings) starts at once: called before
the clock starts, it pays the compile (first process) or the load (later ones) there.
"""
from __future__ import annotations

import time
from collections.abc import Iterable

import numpy as np

from .compiled_sweep import PARALLEL_MIN
from .errors import IntegratorError
from .jit import INSTALL_HINT, available
from .law import power_source
from .sweep import SWEEP_METHODS, sweep

DEFAULT_EXPONENTS = (0.0, 0.5, 1.0, 1.5, 2.0, 3.0)
"""The spellings a warm-up compiles by default: Coulomb, 0.5, 1, 2, 3 and every other real n."""


def warm_up(exponents: Iterable[float] = DEFAULT_EXPONENTS, method: str = 'rk4',
            friction: bool = False) -> float:
    """Compile (or load from the disk cache) the compiled sweep for ``exponents``; return seconds.

    One exponent stands for all that the law spells alike (``law.power_source``: 0, 0.5 and
    each whole n up to 8 their own, every other n one spelling), so ``(1.5,)`` serves every
    non-integer exponent. ``method`` is one of the sweep's methods. With ``friction`` the runs
    of those laws beside a Coulomb friction (their own texts: ``kernel.kernel_source``) are
    compiled as well.

    Raises
    ------
    IntegratorError
        Where ``method`` is not a sweep method, or numba is not installed.
    """
    if not isinstance(method, str) or method not in SWEEP_METHODS:
        raise IntegratorError(f'warm_up supports the sweep methods {", ".join(SWEEP_METHODS)}, '
                              f'got {method!r}')
    if not available():
        raise IntegratorError(f'warm_up needs numba, which is not installed: {INSTALL_HINT}')
    spelled: dict[str, float] = {}
    for n in exponents:
        spelled.setdefault(power_source(float(n), 'n'), float(n))
    t0 = time.perf_counter()
    for n in spelled.values():
        # Moving pendulums with damping: the runs and the careful step they call compile, the
        # serial run for one pendulum, the parallel one for PARALLEL_MIN (compiled_sweep.py);
        # with ``friction`` the runs beside a Coulomb friction as well.
        for size in (1, PARALLEL_MIN):
            for fr in (0.0, 0.5) if friction else (0.0,):
                sweep(9.8, np.ones(size), n, 1.0, 0.5, 1e-3, 1e-3, method=method, jit=True,
                      friction=fr)
    return time.perf_counter() - t0


__all__ = ['DEFAULT_EXPONENTS', 'warm_up']
