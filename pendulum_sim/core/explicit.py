"""Explicit Runge-Kutta steps generated from a tableau: the fast path of both drivers.

A method is data (``tableaus.py``); this module turns a tableau and a damping exponent into
Python source with the stages unrolled and zero coefficients dropped, and compiles that one
source twice: with ``math`` (a scalar step for :class:`~pendulum_sim.core.stepper.Stepper`,
fast enough for a 1 kHz real-time loop) and with ``numpy`` (the same step over arrays, for
:func:`~pendulum_sim.core.sweep.sweep`). The plain reference :func:`~pendulum_sim.core.rk.rk_step`
defines the semantics both are tested against.

A generated step is ``step(p0, v0, h, ain, w2, gamma, s)``: it advances ``(φ, φ')`` by ``h``
under ``φ'' = a_in − D(φ') − ω0² sin φ`` (Quiroga and Ospina-Henao 2017, eq 16 with input) and
returns ``(φ₁, φ'₁, w, a₀)``: the new state, the damping work per unit inertia
``w = h Σ bᵢ vᵢ Dᵢ`` (the same quadrature as the state, so the energy balance closes to the
method's own accuracy) and the acceleration at the start. ``s`` selects the damping branch of a
*branch* step, ``D(v) = s γ |v|^n`` (the smooth continuation of one direction of motion, used on
either side of a velocity reversal); the plain law ignores it.
"""
from __future__ import annotations

import functools
import re
from collections.abc import Callable
from typing import Any

from .codegen import define
from .law import SCALAR_ENV, VECTOR_ENV, damping_expression
from .tableaus import Tableau

StepFn = Callable[..., tuple[Any, Any, Any, Any]]
ErrStepFn = Callable[..., tuple[Any, Any, Any, Any, Any, Any]]


def _num(x: float) -> str:
    return repr(float(x))


def _weighted(terms: list[tuple[float, str]], hs: dict[float, str]) -> str:
    """Return Σ cᵢ xᵢ h as source, equal coefficients grouped: hc * (x + y) + …."""
    groups: dict[float, list[str]] = {}
    for c, x in terms:
        if c != 0.0:
            groups.setdefault(c, []).append(x)
    parts = []
    for c, xs in groups.items():
        name = hs.setdefault(c, f'h{len(hs)}')
        parts.append(f'{name} * ({" + ".join(xs)})' if len(xs) > 1 else f'{name} * {xs[0]}')
    return ' + '.join(parts) or '0.0'


@functools.lru_cache(maxsize=256)
def step_source(tableau: Tableau, damping: str, with_error: bool = False) -> str:
    """Return the unrolled source of one explicit step of ``tableau`` with the law ``damping``.

    Products h aᵢⱼ and h bᵢ are formed once per step and equal weights share one product; the
    damping expression is written on each stage's own velocity. The result equals the plain
    reference ``rk.rk_step`` to round-off (tested).
    """
    s = tableau.stages
    A, B = tableau.A, tableau.B
    hs: dict[float, str] = {}
    body: list[str] = []
    for i in range(s):
        if i > 0:
            dp = _weighted([(float(A[i, j]), f'v_{j}') for j in range(i)], hs)
            dv = _weighted([(float(A[i, j]), f'a_{j}') for j in range(i)], hs)
            body.append(f'    p_{i} = p0 + {dp}')
            body.append(f'    v_{i} = v0 + {dv}')
        used = B[i] != 0.0 or i == 0 or any(A[k, i] != 0.0 for k in range(i + 1, s))
        used = used or (with_error and tableau.E is not None and tableau.E[i] != 0.0)
        used = used or (with_error and tableau.E3 is not None and tableau.E3[i] != 0.0)
        if not used:
            continue
        pi, vi = ('p0', 'v0') if i == 0 else (f'p_{i}', f'v_{i}')
        law = re.sub(r'\bv\b', vi, damping)
        body.append(f'    d_{i} = {law}')
        body.append(f'    a_{i} = ain - d_{i} - w2 * sin({pi})')
        if i == 0:
            body.append('    v_0 = v0')
    nz = [i for i in range(s) if B[i] != 0.0]
    body.append('    p1 = p0 + ' + _weighted([(float(B[i]), f'v_{i}') for i in nz], hs))
    body.append('    v1 = v0 + ' + _weighted([(float(B[i]), f'a_{i}') for i in nz], hs))
    body.append('    w = ' + _weighted([(float(B[i]), f'v_{i} * d_{i}') for i in nz], hs))
    if with_error:
        assert tableau.E is not None
        ne = [i for i in range(s) if tableau.E[i] != 0.0]
        ep = _weighted([(float(tableau.E[i]), f'v_{i}') for i in ne], hs)
        ev = _weighted([(float(tableau.E[i]), f'a_{i}') for i in ne], hs)
        if tableau.E3 is not None:
            # Two estimates (DOP853): e₅ |e₅| / hypot(e₅, 0.1 e₃) per component, the
            # combination of Hairer's code (an estimate of order h^8, homogeneous in scale).
            n3 = [i for i in range(s) if tableau.E3[i] != 0.0]
            body.append(f'    e5p = {ep}')
            body.append(f'    e5v = {ev}')
            e3 = tableau.E3
            body.append('    e3p = ' + _weighted([(float(e3[i]), f'v_{i}') for i in n3], hs))
            body.append('    e3v = ' + _weighted([(float(e3[i]), f'a_{i}') for i in n3], hs))
            ep = 'e5p * abs(e5p) / sqrt(e5p * e5p + 0.01 * e3p * e3p + 1e-300)'
            ev = 'e5v * abs(e5v) / sqrt(e5v * e5v + 0.01 * e3v * e3v + 1e-300)'
        body.append(f'    return p1, v1, w, a_0, {ep}, {ev}')
    else:
        body.append('    return p1, v1, w, a_0')
    head = ['def step(p0, v0, h, ain, w2, gamma, s):']
    head += [f'    {name} = {_num(c)} * h' if c != 1.0 else f'    {name} = h'
             for c, name in hs.items()]
    return '\n'.join(head + body) + '\n'


@functools.lru_cache(maxsize=512)
def compile_step(tableau: Tableau, n: float, branch: bool = False, vector: bool = False,
                 with_error: bool = False) -> Any:
    """Compile one explicit step of ``tableau`` for damping exponent ``n``.

    ``vector`` compiles the same source with numpy (arrays of pendulums); ``with_error`` adds
    the embedded pair's error estimate ``(e_φ, e_φ')`` to the result.
    """
    if not tableau.explicit:
        raise ValueError(f'{tableau.name} is not an explicit method')
    if with_error and tableau.E is None:
        raise ValueError(f'{tableau.name} has no embedded error estimate')
    src = step_source(tableau, damping_expression(n, branch, scalar=not vector), with_error)
    env: dict[str, object] = dict(VECTOR_ENV if vector else SCALAR_ENV, n=n)
    return define(src, 'step', env, f'<{tableau.name} step>')


def step_source_with_n(tableau: Tableau, n: float, branch: bool, name: str,
                       with_error: bool = False) -> str:
    """Return the scalar step of :func:`step_source` as ``name``, the exponent an argument.

    ``name(p0, v0, h, ain, w2, gamma, s, n)``: the same text with ``n`` a parameter, so one
    compiled function serves every exponent the law spells alike (the compiled sweep's
    ``plain`` and ``branch``, with ``with_error`` its ``pair_plain`` and ``pair_branch``, and
    the careful path's shared functions in Python).
    """
    lines = step_source(tableau, damping_expression(n, branch, scalar=True),
                        with_error).splitlines()
    return '\n'.join([f'def {name}(p0, v0, h, ain, w2, gamma, s, n):', *lines[1:]]) + '\n'


@functools.lru_cache(maxsize=512)
def compile_step_with_n(tableau: Tableau, n: float, branch: bool = False,
                        with_error: bool = False, vector: bool = False) -> Any:
    """Return :func:`step_source_with_n`'s step for ``n`` (scalar, ``math``).

    ``vector`` defines the same text with numpy (numpy's power: the numpy sweep's plain step for
    a group of exponents one text serves, the exponent a column).
    """
    src = step_source_with_n(tableau, n, branch, 'step', with_error)
    env: dict[str, object] = dict(VECTOR_ENV if vector else SCALAR_ENV)
    return define(src, 'step', env, f'<{tableau.name} step n>')
