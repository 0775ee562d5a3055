"""Optional machine-code steps: the generated steps of the adaptive methods compiled by numba.

The adaptive methods' steps are generated Python (``explicit.py``, ``rosenbrock.py``,
``extrapolation.py``): the interpreter spends 2–12 µs on one of them, and at tight tolerances
on stiff runs that is most of the run. With numba installed (the ``jit`` extra,
``pip install 'pendulum_sim[jit]'``) and ``jit=True`` (``Stepper``, ``simulate``),
:func:`compile_step` hands the very same function objects to ``numba.njit``: one source, two
executions, results equal to the last bit on the tested grid of states, steps and exponents
(``test_core_jit.py``), 0.3–0.8 µs a call from Python (``bench/bench_jit.py``). Everything
around the steps (error control, the cut at reversals, dense output) stays the one Python
implementation.

Two things keep the two executions equal. No fast-math: numba leaves IEEE arithmetic as
written (no fused multiply-add, no reassociation), but LLVM still rewrites a power with the
constant exponent 0.5, 2 or −1 (to sqrt, x·x, 1/x), which the C library's pow differs from in
the last bit for 7–8 in 10 000 random x; the generated damping law and ``model.slope_formula``
therefore spell those cases so themselves. And where Python raises OverflowError or
ValueError (a power beyond float64, the sine of inf), compiled code returns inf or NaN: the
cover rejects a trial step either way (its error norm is then not finite), so both take the
same decisions.

Compiling a method's two steps (plain and branch law) for one exponent costs 0.7–2.3 s, once per
process (the compiled steps are cached per method, exponent and law); at 2–11 µs saved per
trial step that pays for itself after some 2–5 × 10⁵ trial steps, over one run or many.
"""
from __future__ import annotations

import functools
import types
from typing import Any

from .errors import IntegratorError
from .model import damping_derivative, slope_formula

SIGNATURE = 'UniTuple(float64, 6)(float64, float64, float64, float64, float64, float64, float64)'
"""The embedded steps' signature: (φ₀, φ'₀, h, a_in, ω0², γ, s) → (φ₁, φ'₁, w, a₀, e_φ, e_φ')."""

INSTALL_HINT = "pip install 'pendulum_sim[jit]' (or numba)"


def available() -> bool:
    """Return True where numba can be imported."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def check_jit(jit: object, method: str, adaptive: bool) -> bool:
    """Validate the ``jit`` argument of ``Stepper``/``simulate`` for ``method``; return it."""
    if not isinstance(jit, bool):
        raise IntegratorError(f'jit must be True or False, got {jit!r}')
    if jit and not adaptive:
        raise IntegratorError(f'jit=True compiles the steps of the adaptive methods; {method} '
                              'is a fixed-step method')
    if jit and not available():
        raise IntegratorError(f'jit=True needs numba, which is not installed: {INSTALL_HINT}')
    return jit


@functools.cache
def _helper(fn: Any) -> Any:
    """Return the compiled form of a function a generated step calls (numba needs it compiled).

    The core's damping slope is compiled from its arithmetic alone (``slope_formula``): numba
    does not catch OverflowError, and overflows to inf, the value the Python wrapper returns.
    """
    import numba

    return numba.njit(slope_formula if fn is damping_derivative else fn)


@functools.lru_cache(maxsize=512)
def compile_step(fn: Any) -> Any:
    """Return the generated embedded step ``fn`` compiled to machine code by numba.

    The step's code object is rebound to a copy of its globals in which the Python functions it
    calls (the sign, the damping slope) are their compiled forms; math functions and constants
    are read by numba as they are. Compiled eagerly for :data:`SIGNATURE`.
    """
    if not available():
        raise IntegratorError(f'compiled steps need numba, which is not installed: '
                              f'{INSTALL_HINT}')
    import numba

    env = {name: _helper(value) if isinstance(value, types.FunctionType) else value
           for name, value in fn.__globals__.items()
           if name != '__builtins__' and value is not fn}
    env['__builtins__'] = fn.__globals__.get('__builtins__', __builtins__)
    twin = types.FunctionType(fn.__code__, env, fn.__name__)
    return numba.njit(SIGNATURE)(twin)
