"""Linearly implicit Euler extrapolation: high order on stiff runs, for tight tolerances.

One step of H runs the linearly implicit Euler method (Hairer and Wanner, *Solving ODEs II*,
1996, IV.9, eq 9.25; the base of Deuflhard's extrapolation codes and of SEULEX)

    (I − δ J) (y_{m+1} − y_m) = δ f(y_m),    δ = H / n_j,

with nⱼ substeps for each number of the step sequence (1, 2, 3, …, k), and the Jacobian J at the
start of the step, then extrapolates the k results to δ → 0 with the Aitken-Neville scheme for
an error expansion in powers of δ (IV.9, eq 9.26):

    T_{j,l+1} = T_{j,l} + (T_{j,l} − T_{j−1,l}) / (nⱼ / n_{j−l} − 1).

T_kk has order k; T_kk − T_{k,k−1} estimates the error of the order-(k−1) value, so the step
behaves as an embedded pair of orders k(k−1) with an L-stable base, and the error-controlled cover
of ``embedded.py`` (with its cut at velocity reversals) drives it unchanged. As in
``rosenbrock.py``, J = [[0, 1], [−ω0² cos φ, −d]] with the damping slope d = γ n |φ'|^(n−1) of
``law.damping_derivative`` (eq 18-19), every solve is a 2×2 one written out by hand, and the
damping work w is a third, quadrature component (its row of J is [0, D + φ' D', 0]).

The generated step has the signature and results of the embedded steps,
``step(p0, v0, h, ain, w2, gamma, s)`` → ``(φ₁, φ'₁, w, a₀, e_φ, e_φ')``, and
:func:`extrapolation_step` is its plain numpy reference.
"""
from __future__ import annotations

import functools
import math
import re
from collections.abc import Callable
from typing import Any

import numpy as np

from .codegen import define
from .law import SCALAR_ENV, damping_derivative, damping_expression
from .tableaus import Extrapolation, FloatArray


def extrapolation_step(ext: Extrapolation, f: Callable[[FloatArray], FloatArray],
                       jac: FloatArray, y: FloatArray,
                       h: float) -> tuple[FloatArray, FloatArray]:
    """Return (T_kk, T_kk − T_{k,k−1}) of one step of ``ext`` with Jacobian ``jac`` (numpy).

    The textbook scheme (module docstring), solved with ``numpy.linalg.solve``: the semantics
    the generated step is tested against.
    """
    y = np.asarray(y, dtype=float)
    eye = np.eye(len(y))
    rows: list[list[FloatArray]] = []
    for j, nj in enumerate(ext.sequence):
        d = h / nj
        m = eye - d * np.asarray(jac, dtype=float)
        yj = y.copy()
        for _ in range(nj):
            yj = yj + np.linalg.solve(m, d * np.asarray(f(yj), dtype=float))
        row = [yj]
        for k in range(1, j + 1):
            ratio = nj / ext.sequence[j - k]
            row.append(row[k - 1] + (row[k - 1] - rows[j - 1][k - 1]) / (ratio - 1.0))
        rows.append(row)
    last = rows[-1]
    return last[-1], last[-1] - last[-2]


def step_source(ext: Extrapolation, damping: str) -> str:
    """Return the unrolled source of one extrapolation step with the damping law ``damping``.

    ``slope`` (the core's damping derivative), ``cos`` and ``n`` come from the compile
    environment. A slope that is unbounded (n < 1 at rest) is replaced by 0 for that step, as
    in the Rosenbrock step; the error control judges the result.
    """
    def law(v: str) -> str:
        return re.sub(r'\bv\b', v, damping)

    body = [
        'def step(p0, v0, h, ain, w2, gamma, s):',
        '    dd = slope(gamma, n, v0)',
        '    if not dd < INF:',
        '        dd = 0.0',
        '    kk = w2 * cos(p0)',
        f'    d0 = {law("v0")}',
        '    a0 = ain - d0 - w2 * sin(p0)',
        '    g0 = v0 * d0',
        '    jw = d0 + v0 * dd',
    ]
    seq = ext.sequence
    for j, nj in enumerate(seq):
        body += [
            f'    hs = h / {float(nj)!r}',
            '    m11 = 1.0 + hs * dd',
            '    hk = hs * kk',
            '    q = 1.0 / (m11 + hs * hk)',
            '    rp = hs * v0',
            '    rv = hs * a0',
            '    DV = q * (rv - hk * rp)',
            '    DP = q * (m11 * rp + hs * rv)',
            '    W = hs * (g0 + jw * DV)',
        ]
        for _ in range(nj - 1):
            body += [
                '    V = v0 + DV',
                f'    d = {law("V")}',
                '    rp = hs * V',
                '    rv = hs * (ain - d - w2 * sin(p0 + DP))',
                '    dv = q * (rv - hk * rp)',
                '    W += hs * (V * d + jw * dv)',
                '    DP += q * (m11 * rp + hs * rv)',
                '    DV += dv',
            ]
        # Extrapolate the increments, summed apart from the state: the weights (their
        # magnitudes sum to ~300 for six rows, 3392 for eight) then multiply the round-off of
        # the increments only, not that of the state they are added to.
        body.append(f'    p_{j}_0, v_{j}_0, w_{j}_0 = DP, DV, W')
        for k in range(1, j + 1):
            c = 1.0 / (nj / seq[j - k] - 1.0)
            for x in 'pvw':
                body.append(f'    {x}_{j}_{k} = {x}_{j}_{k - 1} + {c!r} * '
                            f'({x}_{j}_{k - 1} - {x}_{j - 1}_{k - 1})')
    last = len(seq) - 1
    body.append(f'    return (p0 + p_{last}_{last}, v0 + v_{last}_{last}, w_{last}_{last}, a0, '
                f'p_{last}_{last} - p_{last}_{last - 1}, v_{last}_{last} - v_{last}_{last - 1})')
    return '\n'.join(body) + '\n'


@functools.lru_cache(maxsize=256)
def compile_extrapolation(ext: Extrapolation, n: float, branch: bool = False) -> Any:
    """Compile one extrapolation step of ``ext`` for damping exponent ``n`` (scalar).

    ``branch`` uses the branch law s γ |φ'|^n (one side of a velocity reversal).
    """
    src = step_source(ext, damping_expression(n, branch, scalar=True))
    env: dict[str, object] = dict(SCALAR_ENV, n=n, cos=math.cos, slope=damping_derivative,
                                  INF=math.inf)
    return define(src, 'step', env, f'<{ext.name} step>')
