"""One generic diagonally implicit Runge-Kutta (DIRK) step, for stiff damping.

Each stage of a DIRK method solves ``Y = base + h aᵢᵢ f(Y)``. For the pendulum the angle of a
stage is linear in its velocity (Φ = P + α V, α = h aᵢᵢ), so the 2-D stage equation reduces to one
scalar equation in the stage velocity V:

    G(V) = V − W + α D(V) + α ω0² sin(P + α V) − α a_in = 0,

with D(V) = γ V|V|^(n−1) increasing. G is increasing while α² ω0² < 1, and its root lies in a
bracket known in advance, so a Newton iteration safeguarded by bisection always converges, for
every n ≥ 0 and γ up to any size, even where D is not differentiable (n < 1) or not even a
function (n = 0: Coulomb friction is the set-valued sign, and the stage sticks, V = 0, whenever
0 ∈ G(0)). This is the standard implicit treatment of dry friction, and it is why the implicit
method is also the fallback of the stability guard.
"""
from __future__ import annotations

import functools
import math
from collections.abc import Callable

from .codegen import define
from .law import SCALAR_ENV, SPECIAL_SLOPES, damping_derivative, damping_expression
from .tableaus import Tableau

_EPS = 2.220446049250313e-16

StageLaw = Callable[[float, float, float], float]
"""``law(v, gamma, n)``: the damping acceleration D(v) with the exponent an argument."""
Coefficients = tuple[tuple[tuple[float, ...], ...], tuple[float, ...]]
"""A DIRK tableau's (A, B) as tuples of floats (what :func:`dirk_step` reads)."""


@functools.lru_cache(maxsize=256)
def stage_law(n: float) -> StageLaw:
    """Return ``law(v, gamma, n)``: D(v) as ``law.damping_expression(n)`` spells it.

    The exponent is an argument (one text serves every exponent spelled alike), so the same
    law is the one a compiled caller reads for a run-time n (:data:`DAMPING_FORMULA_SOURCE`).
    """
    src = f'def law(v, gamma, n):\n    return {damping_expression(n)}\n'
    return define(src, 'law', dict(SCALAR_ENV), '<stage law>')  # type: ignore[no-any-return]


def _formula_source() -> str:
    """Return the source of :func:`damping_formula`: every spelling of :func:`stage_law`."""
    lines = ['def damping_formula(v, gamma, n):']
    for e in (0.0, *SPECIAL_SLOPES):
        lines += [f'    if n == {e!r}:', f'        return {damping_expression(e)}']
    lines.append(f'    return {damping_expression(math.pi)}')  # any exponent not spelled apart
    return '\n'.join(lines) + '\n'


DAMPING_FORMULA_SOURCE = _formula_source()

damping_formula: StageLaw = define(DAMPING_FORMULA_SOURCE, 'damping_formula', dict(SCALAR_ENV),
                                   '<damping formula>')
"""Return D(v) (``v, gamma, n``) for any n, each n spelled as :func:`stage_law` (n) spells it:
the stage law a compiled caller (the compiled sweep's fallback) reads for a run-time n."""


@functools.lru_cache(maxsize=64)
def coefficients(tableau: Tableau) -> Coefficients:
    """Return the tableau's (A, B) as tuples of floats, made once per tableau."""
    a = tuple(tuple(row) for row in tableau.A.tolist())
    return a, tuple(tableau.B.tolist())


def saturated(law: StageLaw, v: float, gamma: float, n: float) -> float:
    """Return ``law(v, gamma, n)``; beyond float64 ±inf: the damping saturates, G keeps its sign.

    Compiled (``jit.py``), :func:`saturated_formula`: there a power beyond float64 is inf.
    """
    try:
        return law(v, gamma, n)
    except OverflowError:
        return math.copysign(math.inf, v)


def saturated_formula(law: StageLaw, v: float, gamma: float, n: float) -> float:
    """Return ``law(v, gamma, n)``: :func:`saturated` without its ``except`` (compiled)."""
    return law(v, gamma, n)


def _residual(v: float, rest: float, alpha: float, P: float, w2: float, gamma: float, n: float,
              law: StageLaw) -> float:
    """Return G(v) (see the module docstring)."""
    d = saturated(law, v, gamma, n)
    return v - rest + alpha * d + alpha * w2 * math.sin(P + alpha * v)


def _solve_stage(P: float, W: float, alpha: float, w2: float, ain: float, gamma: float,
                 n: float, law: StageLaw) -> float:
    """Return the stage velocity V with G(V) = 0 (see the module docstring)."""
    rest = W + alpha * ain
    hi_d = 0.0
    if n == 0.0 and gamma > 0.0:
        # Set-valued friction: stick if 0 lies in [G(0−), G(0+)].
        g0 = -rest + alpha * w2 * math.sin(P)
        hi_d = g0 + alpha * gamma
        if g0 - alpha * gamma <= 0.0 <= hi_d:
            return 0.0
    # Bracket: V + α D(V) = rest − α ω0² sin(·) ∈ [rest − α ω0², rest + α ω0²].
    lo = min(rest - alpha * abs(w2), 0.0)
    hi = max(rest + alpha * abs(w2), 0.0)
    if n == 0.0 and gamma > 0.0:
        if hi_d < 0.0:
            lo = max(lo, 0.0)
        else:
            hi = min(hi, 0.0)
    glo = _residual(lo, rest, alpha, P, w2, gamma, n, law)
    ghi = _residual(hi, rest, alpha, P, w2, gamma, n, law)
    if glo > 0.0 or ghi < 0.0:
        # Not monotone (α² ω0² ≥ 1): widen once, then bisect on whatever sign change is found.
        span = abs(hi - lo) + 1.0
        lo, hi = lo - span, hi + span
    v = min(max(rest, lo), hi)
    for _ in range(200):
        gv = _residual(v, rest, alpha, P, w2, gamma, n, law)
        if gv == 0.0:
            return v
        if gv < 0.0:
            lo = v
        else:
            hi = v
        dg = (1.0 + alpha * damping_derivative(gamma, n, v)
              + alpha * alpha * w2 * math.cos(P + alpha * v))
        nv = v - gv / dg if dg > 0.0 and math.isfinite(dg) else 0.5 * (lo + hi)
        if not lo < nv < hi:
            nv = 0.5 * (lo + hi)
        if abs(nv - v) <= 4.0 * _EPS * max(abs(nv), 1e-300) or hi - lo <= 4.0 * _EPS * abs(v):
            return nv
        v = nv
    return v


def dirk_step(coeffs: Coefficients, p0: float, v0: float, h: float, ain: float, w2: float,
              gamma: float, n: float, law: StageLaw) -> tuple[float, float, float, float]:
    """Advance ``(φ, φ')`` by ``h`` with the DIRK method of ``coeffs`` (:func:`coefficients`).

    Returns ``(φ₁, φ'₁, w, a₀)`` like the explicit steps: ``w`` is the damping work per unit
    inertia by the same quadrature, ``a₀`` the acceleration of the first stage. ``law`` is
    :func:`stage_law` (n) (compiled: :func:`damping_formula`). Written to compile: the compiled
    sweep's fallback runs this function.
    """
    A, B = coeffs
    s = len(B)
    vs = [0.0] * s
    acc = [0.0] * s
    ds = [0.0] * s
    for i in range(s):
        sp = 0.0
        sa = 0.0
        for j in range(i):
            sp += A[i][j] * vs[j]
            sa += A[i][j] * acc[j]
        P = p0 + h * sp
        W = v0 + h * sa
        alpha = h * A[i][i]
        V = _solve_stage(P, W, alpha, w2, ain, gamma, n, law)
        # The stage acceleration follows from the stage equation itself, (V − W)/α; this keeps
        # the set-valued Coulomb case exact when the stage sticks.
        a = (V - W) / alpha
        vs[i] = V
        acc[i] = a
        ds[i] = ain - w2 * math.sin(P + alpha * V) - a
    sp = 0.0
    sa = 0.0
    sw = 0.0
    for i in range(s):
        sp += B[i] * vs[i]
        sa += B[i] * acc[i]
        sw += B[i] * vs[i] * ds[i]
    return p0 + h * sp, v0 + h * sa, h * sw, acc[0]
