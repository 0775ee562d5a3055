"""One generic linearly implicit (Rosenbrock) step, for long stiff runs.

A Rosenbrock method replaces the Newton iterations of an implicit Runge-Kutta method by one
linear solve per stage with the Jacobian J at the start of the step. In the transformed
variables of Hairer and Wanner (*Solving ODEs II*, 1996, IV.7, eq 7.25), for y' = f(y):

    (1/(h γ) I − J) kᵢ = f(y₀ + Σⱼ aᵢⱼ kⱼ) + Σⱼ (cᵢⱼ / h) kⱼ,    y₁ = y₀ + Σ bᵢ kᵢ,

and the embedded solution differs by Σ eᵢ kᵢ. For the pendulum y = (φ, φ') and
J = [[0, 1], [−ω0² cos φ, −d]] with the damping slope d = γ n |φ'|^(n−1) (eq 18-19), so every
stage is a 2×2 solve written out by hand with one determinant per step. The damping work
w = ∫ φ' D(φ') dt is a third, quadrature component of the same system (its row of J is
[0, D + φ' D', 0]), so the energy balance closes to the method's own order.

:func:`rosenbrock_step` is the plain reference (numpy, any dimension, a given J);
:func:`step_source` generates the unrolled step from the tableau, with the same signature and
results as an embedded explicit step of ``explicit.py`` — ``(φ₁, φ'₁, w, a₀, e_φ, e_φ')`` — so
the error-controlled cover of ``embedded.py`` (with its cut at velocity reversals) drives it
unchanged. The damping law is the core's one expression (``explicit.damping_expression``) and
its slope the core's one ``law.damping_derivative``.
"""
from __future__ import annotations

import functools
import math
import re
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

from .codegen import define
from .law import SCALAR_ENV, damping_derivative, damping_expression
from .tableaus import Tableau

FloatArray = npt.NDArray[np.float64]


def rosenbrock_step(tableau: Tableau, f: Callable[[FloatArray], FloatArray], jac: FloatArray,
                    y: FloatArray, h: float) -> tuple[FloatArray, FloatArray]:
    """Return (y₁, error estimate) of one Rosenbrock step of ``tableau`` with Jacobian ``jac``.

    The textbook transformed form (module docstring), solved with ``numpy.linalg.solve``: the
    semantics the generated step is tested against.
    """
    if tableau.G is None:
        raise ValueError(f'{tableau.name} is not a Rosenbrock method')
    y = np.asarray(y, dtype=float)
    m = np.eye(len(y)) / (h * tableau.gamma) - np.asarray(jac, dtype=float)
    ks: list[FloatArray] = []
    zero = np.zeros_like(y)
    for i in range(tableau.stages):
        yi = y + sum((tableau.A[i, j] * ks[j] for j in range(i)), zero)
        rhs = np.asarray(f(yi), dtype=float) + sum(
            (tableau.G[i, j] / h * ks[j] for j in range(i)), zero)
        ks.append(np.linalg.solve(m, rhs))
    y1 = y + sum((tableau.B[i] * ks[i] for i in range(tableau.stages)), zero)
    assert tableau.E is not None
    err = sum((tableau.E[i] * ks[i] for i in range(tableau.stages)), zero)
    return np.asarray(y1), np.asarray(err)


def _lin(terms: list[tuple[float, str]]) -> str:
    parts = [f'{c!r} * {x}' if c != 1.0 else x for c, x in terms if c != 0.0]
    return ' + '.join(parts)


def _extends(row: FloatArray, prev: FloatArray) -> bool:
    """Return True where ``row`` is ``prev`` (padded with 0) plus 1 in its last place."""
    k = len(row) - 1
    return bool(k >= 1 and row[k] == 1.0 and np.array_equal(row[:k], prev[:k])
                and not np.any(prev[k:]))


def step_source(tableau: Tableau, damping: str) -> str:
    """Return the unrolled source of one Rosenbrock step of ``tableau`` with the law ``damping``.

    ``step(p0, v0, h, ain, w2, gamma, s)`` → ``(φ₁, φ'₁, w, a₀, e_φ, e_φ')``; ``slope`` (the
    core's damping derivative) and ``n`` are taken from the compile environment. A slope that
    is unbounded (n < 1 at rest) is replaced by 0 for that step; the error control judges it.
    """
    if tableau.G is None or tableau.E is None:
        raise ValueError(f'{tableau.name} is not an embedded Rosenbrock method')
    s = tableau.stages
    A, G, B, E = tableau.A, tableau.G, tableau.B, tableau.E
    body = [
        'def step(p0, v0, h, ain, w2, gamma, s):',
        f'    hg = {tableau.gamma!r} * h',
        '    c = 1.0 / hg',
        '    ih = 1.0 / h',
        '    dd = slope(gamma, n, v0)',
        '    if not dd < INF:',
        '        dd = 0.0',
        '    kk = w2 * cos(p0)',
        '    cd = c + dd',
        '    q = 1.0 / (c * cd + kk)',
        '    qcd = q * cd',
        '    qc = q * c',
        '    qk = q * kk',
    ]
    for i in range(s):
        pi, vi = ('p0', 'v0')
        dp = _lin([(float(A[i, j]), f'kp_{j}') for j in range(i)])
        if dp and _extends(A[i, :i], A[i - 1, :i]):
            # This stage's sum is the previous stage's plus its own k (stiffly accurate rows).
            body.append(f'    P_{i} = P_{i - 1} + kp_{i - 1}')
            body.append(f'    V_{i} = V_{i - 1} + kv_{i - 1}')
            pi, vi = f'P_{i}', f'V_{i}'
        elif dp:
            dv = _lin([(float(A[i, j]), f'kv_{j}') for j in range(i)])
            body.append(f'    P_{i} = p0 + {dp}')
            body.append(f'    V_{i} = v0 + {dv}')
            pi, vi = f'P_{i}', f'V_{i}'
        if i == 0 or dp:
            law = re.sub(r'\bv\b', vi, damping)
            body.append(f'    d_{i} = {law}')
            body.append(f'    f_{i} = ain - d_{i} - w2 * sin({pi})')
            body.append(f'    g_{i} = {vi} * d_{i}')
        else:  # the stage is y₀ itself: reuse the first evaluation
            body += [f'    d_{i} = d_0', f'    f_{i} = f_0', f'    g_{i} = g_0']
        if i == 0:
            body.append('    jw = d_0 + v0 * dd')
        cp = _lin([(float(G[i, j]), f'kp_{j}') for j in range(i)])
        cv = _lin([(float(G[i, j]), f'kv_{j}') for j in range(i)])
        cw = _lin([(float(G[i, j]), f'kw_{j}') for j in range(i)])
        rp = f'{vi} + ih * ({cp})' if cp else vi
        rv = f'f_{i} + ih * ({cv})' if cv else f'f_{i}'
        rw = f'g_{i} + ih * ({cw})' if cw else f'g_{i}'
        body.append(f'    rp = {rp}')
        body.append(f'    rv = {rv}')
        body.append(f'    kp_{i} = qcd * rp + q * rv')
        body.append(f'    kv_{i} = qc * rv - qk * rp')
        body.append(f'    kw_{i} = hg * ({rw} + jw * kv_{i})')
    if _extends(B, A[s - 1]) and any(A[s - 1, :s - 1]):
        body.append(f'    p1 = P_{s - 1} + kp_{s - 1}')
        body.append(f'    v1 = V_{s - 1} + kv_{s - 1}')
    else:
        body.append(f'    p1 = p0 + {_lin([(float(B[i]), f"kp_{i}") for i in range(s)])}')
        body.append(f'    v1 = v0 + {_lin([(float(B[i]), f"kv_{i}") for i in range(s)])}')
    body.append(f'    w = {_lin([(float(B[i]), f"kw_{i}") for i in range(s)])}')
    ep = _lin([(float(E[i]), f'kp_{i}') for i in range(s)]) or '0.0'
    ev = _lin([(float(E[i]), f'kv_{i}') for i in range(s)]) or '0.0'
    body.append(f'    return p1, v1, w, f_0, {ep}, {ev}')
    return '\n'.join(body) + '\n'


@functools.lru_cache(maxsize=256)
def compile_rosenbrock(tableau: Tableau, n: float, branch: bool = False) -> Any:
    """Compile one Rosenbrock step of ``tableau`` for damping exponent ``n`` (scalar).

    ``branch`` uses the branch law s γ |φ'|^n (one side of a velocity reversal), as for the
    explicit steps.
    """
    src = step_source(tableau, damping_expression(n, branch, scalar=True))
    env: dict[str, object] = dict(SCALAR_ENV, n=n, cos=math.cos, slope=damping_derivative,
                                  INF=math.inf)
    return define(src, 'step', env, f'<{tableau.name} step>')
