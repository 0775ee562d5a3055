"""Compile the compiled sweep's paths before the clock starts: the ``jit`` warm-up.

A process's first ``jit=True`` sweep compiles the careful path once and a run per spelling of
the damping law (``decisions.kernel_source``): tens of seconds on a small machine, paid inside
whatever the user times. :func:`warm_up` pays it up front: it takes one compiled step for one
pendulum per spelling asked for, so a following sweep of those laws (any ω0², γ, state, torque
and any exponent of those spellings) starts at once. The compiled paths are kept for the
process, not on disk: every new process (a campaign worker too) pays the compile again.
"""
from __future__ import annotations

import time
from collections.abc import Iterable

from .errors import IntegratorError
from .jit import INSTALL_HINT, available
from .law import power_source
from .sweep import SWEEP_METHODS, sweep

DEFAULT_EXPONENTS = (0.0, 0.5, 1.0, 1.5, 2.0, 3.0)
"""The spellings a warm-up compiles by default: Coulomb, 0.5, 1, 2, 3 and every other real n."""


def warm_up(exponents: Iterable[float] = DEFAULT_EXPONENTS, method: str = 'rk4',
            friction: bool = False) -> float:
    """Compile the compiled sweep for the damping laws of ``exponents``; return the seconds.

    One exponent stands for all that the law spells alike (``law.power_source``: 0, 0.5 and
    each whole n up to 8 their own, every other n one spelling), so ``(1.5,)`` serves every
    non-integer exponent. ``method`` is one of the sweep's methods. With ``friction`` the runs
    of those laws beside a Coulomb friction (their own texts: ``decisions.kernel_source``) are
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
        # A moving pendulum with damping: the run and the careful step it calls compile.
        sweep(9.8, 1.0, n, 1.0, 0.5, 1e-3, 1e-3, method=method, jit=True)
        if friction:
            sweep(9.8, 1.0, n, 1.0, 0.5, 1e-3, 1e-3, method=method, jit=True, friction=0.5)
    return time.perf_counter() - t0


__all__ = ['DEFAULT_EXPONENTS', 'warm_up']
