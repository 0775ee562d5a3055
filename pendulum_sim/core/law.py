"""The damping law of the generalized pendulum, written once (Quiroga and Ospina-Henao 2017).

Per unit inertia the law and the quantities derived from it are

    D(φ') = γ φ'|φ'|^(n−1)          the damping acceleration (eq 15; D(0) = 0 for every n),
    s γ |φ'|^n                      its branch for one direction of motion s = ±1,
    ∂D/∂φ' = γ n |φ'|^(n−1)         its slope, the Jacobian entry of eq 18-19,
    φ' D(φ') = γ |φ'|^(n+1)         the power it takes out of the motion (eq 26).

Each is generated here as Python source from one rule for a power of the speed,
:func:`power_source`: an integer exponent up to 8 is written as multiplications (a power call
costs as much as a whole stage of a step), 0.5 as ``sqrt`` (a compiler rewrites pow(x, 0.5)
so, and the C library's pow differs from sqrt in the last bit for 7-8 in 10 000 random x),
and every other exponent as a power of a name read from the namespace, so that all exponents
that are not special share one source text (``codegen.define`` compiles it once). The signed
forms write |φ'|^k as products of φ' and one |φ'|: rounding to nearest is symmetric in the
sign, so these are the same floats as sgn(φ') times the product of |φ'| (``test_core_law.py``).

The steps (``explicit.py``, ``rosenbrock.py``, ``extrapolation.py``), the fast-path decisions,
the reversal location, the creep, the guard, :class:`~pendulum_sim.core.model.PendulumParams`
and ``model.dissipated_power`` evaluate what this module generates, and the stiff-transient
test of ``decisions.py`` compares with half of γ |φ'|^n spelled by :func:`power_source`
(:func:`power_formula` is the same rule for an exponent known only at run time). The
creep speed (|F|/γ)^(1/n) of ``coulomb.py`` is not the law itself but its inverse.
"""
from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from .codegen import define

DampingFn = Callable[[float], float]

WHOLE_MAX = 8
"""The largest integer exponent written as multiplications (beyond it a power call is as fast)."""

SPECIAL_SLOPES = (0.5, *(float(k) for k in range(1, WHOLE_MAX + 1)))
"""The exponents n − 1 whose slope |φ'|^(n−1) :func:`power_source` spells specially."""


def _sign(x: float) -> float:
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


SCALAR_ENV: dict[str, object] = {'sin': math.sin, 'copysign': math.copysign, 'sign': _sign,
                                 'abs': abs, 'sqrt': math.sqrt}
"""The names generated scalar source reads (``math``: one pendulum, a real-time loop)."""

VECTOR_ENV: dict[str, object] = {'sin': np.sin, 'copysign': np.copysign, 'sign': np.sign,
                                 'abs': np.abs, 'sqrt': np.sqrt}
"""The same names over arrays (``numpy``: the sweep and the dense output)."""


def whole(e: float) -> bool:
    """Return True where the exponent ``e`` is written as multiplications (1, 2, ..., 8)."""
    return e == int(e) and 1.0 <= e <= WHOLE_MAX


def power_source(e: float, exponent: str, base: str = 'abs(v)') -> str:
    """Return source for ``base`` ** e (base >= 0) specialised for the exponent value ``e``.

    The one rule of the module: 0 is ``1.0``, 1-8 multiplications, 0.5 ``sqrt(base)``, and any
    other exponent ``base ** exponent``, where ``exponent`` is the source that computes it from
    the namespace (``'n'``, ``'(n - 1.0)'``), so that one text serves every such exponent.
    """
    if e == 0.0:
        return '1.0'
    if whole(e):
        return ' * '.join([base] * int(e))
    if e == 0.5:
        return f'sqrt({base})'
    return f'{base} ** {exponent}'


def _signed(k: int, odd_abs: bool) -> str:
    """Return v^k as multiplications; v^(k−1)|v| (= |v|^k) where ``odd_abs`` and k is odd."""
    if k % 2 == 1 and odd_abs:
        return ' * '.join(['v'] * (k - 1) + ['abs(v)'])
    return ' * '.join(['v'] * k)


def damping_expression(n: float, branch: bool = False, scalar: bool = False) -> str:
    """Return source for the damping law D(v) specialised for the exponent ``n`` (eq 15).

    The plain law is γ v|v|^(n−1) (D(0) = 0 for every n, also n = 0: sticking is decided by the
    caller); the branch law is s γ |v|^n. Both are sgn · γ · :func:`power_source` (n), with the
    sign carried by the factors v where n is whole (the same floats, one ``abs`` call fewer).
    Names read: ``v``, ``gamma``, ``n``, ``s``. ``scalar`` spells even whole n as ±γ v^n by the
    sign of v (the same floats without an ``abs`` call per stage), which arrays cannot.
    """
    if branch:
        if n == 0.0:
            return 's * gamma'
        if whole(n):
            return f's * gamma * {_signed(int(n), odd_abs=True)}'
        return f's * gamma * {power_source(n, "n")}'
    if n == 0.0:
        return 'gamma * sign(v)'
    if whole(n):
        k = int(n)
        # v|v|^(k−1): v^k for odd k, v^(k−1)|v| for even k.
        if k % 2:
            return f'gamma * {_signed(k, False)}'
        if scalar:
            return f'(gamma * {_signed(k, False)} if v > 0.0 else -(gamma * {_signed(k, False)}))'
        return f'gamma * {_signed(k - 1, False)} * abs(v)'
    return f'copysign(gamma * {power_source(n, "n")}, v)'


def power_expression(n: float) -> str:
    """Return source for the damping power per unit inertia φ' D(φ') = γ |v|^(n+1) (eq 26)."""
    return f'gamma * {power_source(n + 1.0, "(n + 1.0)")}'


def slope_expression(n: float) -> str:
    """Return source for the slope γ n |a|^(n−1) at a speed ``a`` > 0 (eq 18-19).

    At a = 0 the slope is 0 for n > 1 and unbounded for n < 1: :func:`slope_formula` decides
    that before it evaluates this.
    """
    if n == 1.0:
        return 'gamma'
    if n == 0.0:
        return '0.0'
    return f'gamma * n * ({power_source(n - 1.0, "(n - 1.0)", "a")})'


def _slope_source() -> str:
    """Return the source of :func:`slope_formula`: one branch per specially spelled exponent."""
    lines = ['def slope_formula(gamma, n, dphi):',
             '    if n == 1.0:',
             f'        return {slope_expression(1.0)}',
             '    if n == 0.0 or gamma == 0.0:',
             '        return 0.0',
             '    a = abs(dphi)',
             '    if a == 0.0:',
             '        return inf if n < 1.0 else 0.0']
    for e in SPECIAL_SLOPES:
        law = slope_expression(e + 1.0)
        lines += [f'    if n == {e + 1.0!r}:', f'        return float({law})']
    lines.append(f'    return float({slope_expression(math.pi)})')  # any non-special n
    return '\n'.join(lines) + '\n'


SLOPE_SOURCE = _slope_source()

slope_formula: Callable[[float, float, float], float] = define(
    SLOPE_SOURCE, 'slope_formula', {'abs': abs, 'sqrt': math.sqrt, 'inf': math.inf}, '<slope>')
"""Return d = γ n |φ'|^(n−1) (``gamma, n, dphi``; inf for n < 1 at rest), generated.

Free of exception handling so that numba can compile it for the compiled steps (``jit.py``);
in Python a power beyond float64 raises OverflowError, where compiled code gives inf."""


def _power_source() -> str:
    """Return the source of :func:`power_formula`: one branch per specially spelled exponent."""
    lines = ['def power_formula(a, n):']
    for e in (0.0, 0.5, *(float(k) for k in range(1, WHOLE_MAX + 1))):
        lines += [f'    if n == {e!r}:', f'        return {power_source(e, "n", "a")}']
    lines.append(f'    return {power_source(math.pi, "n", "a")}')  # any non-special n
    return '\n'.join(lines) + '\n'


POWER_SOURCE = _power_source()

power_formula: Callable[[float, float], float] = define(
    POWER_SOURCE, 'power_formula', {'sqrt': math.sqrt}, '<power>')
"""Return a ** n for a speed ``a`` >= 0 and an exponent known only at run time, generated.

The value :func:`power_source` spells for that exponent (one branch per special exponent), for
code compiled once for every exponent (``careful.py``)."""


def damping_derivative(gamma: float, n: float, dphi: float) -> float:
    """Return d = ∂(γ φ'|φ'|^(n−1))/∂φ' = γ n |φ'|^(n−1) (inf for n < 1 at rest, eq 18-19)."""
    try:
        return slope_formula(gamma, n, dphi)
    except OverflowError:   # beyond float64: as steep as it gets
        return math.inf


@functools.lru_cache(maxsize=256)
def compile_damping(n: float, branch: bool = False, vector: bool = False) -> Any:
    """Return the damping law ``D(v, gamma, s)`` for exponent ``n`` (numpy with ``vector``)."""
    src = f'def damping(v, gamma, s):\n    return {damping_expression(n, branch)}\n'
    env: dict[str, object] = dict(VECTOR_ENV if vector else SCALAR_ENV, n=n)
    return define(src, 'damping', env, '<damping>')


def laws_source(n: float, name: str = 'laws') -> str:
    """Return source for ``name(v, gamma, s, n)`` → (plain law, branch law) at ``v``.

    The two texts of :func:`damping_expression` for the exponent ``n``, with the exponent an
    argument (not a name of the namespace), so that one compiled function serves every
    exponent its text serves: the form the careful path's shared functions call
    (``coulomb.creep_state``, ``reversal.graded_landing``), in Python and compiled.
    """
    return (f'def {name}(v, gamma, s, n):\n'
            f'    return {damping_expression(n)}, {damping_expression(n, True)}\n')


@functools.lru_cache(maxsize=256)
def compile_laws(n: float) -> Any:
    """Return :func:`laws_source`'s function for the exponent ``n`` (scalar, ``math``)."""
    return define(laws_source(n), 'laws', dict(SCALAR_ENV), '<laws>')


@functools.lru_cache(maxsize=256)
def compile_speed_power(n: float) -> Any:
    """Return ``power(a, n)`` = a ** n over numpy arrays, as :func:`power_source` spells n.

    The damping's |φ'|^n of the stiff-transient test on the numpy sweep (``n`` a float or one
    per pendulum of a text that spells them alike); numpy's power, not the C library's.
    """
    src = f'def power(a, n):\n    return {power_source(n, "n", "a")}\n'
    return define(src, 'power', dict(VECTOR_ENV), '<speed power>')


@functools.lru_cache(maxsize=256)
def compile_power(n: float) -> Any:
    """Return the damping power ``P(v, gamma)`` = γ |v|^(n+1) for exponent ``n`` (numpy)."""
    src = f'def power(v, gamma):\n    return {power_expression(n)}\n'
    return define(src, 'power', dict(VECTOR_ENV, n=n), '<damping power>')


__all__ = [
    'POWER_SOURCE',
    'SCALAR_ENV',
    'SLOPE_SOURCE',
    'VECTOR_ENV',
    'WHOLE_MAX',
    'DampingFn',
    'compile_damping',
    'compile_laws',
    'compile_power',
    'compile_speed_power',
    'damping_derivative',
    'damping_expression',
    'laws_source',
    'power_expression',
    'power_formula',
    'power_source',
    'slope_expression',
    'slope_formula',
    'whole',
]
