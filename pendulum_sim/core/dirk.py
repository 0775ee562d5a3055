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

import math

from .law import DampingFn, damping_derivative
from .tableaus import Tableau

_EPS = 2.220446049250313e-16


def _solve_stage(P: float, W: float, alpha: float, w2: float, ain: float, gamma: float,
                 n: float, damping: DampingFn) -> float:
    """Return the stage velocity V with G(V) = 0 (see the module docstring)."""
    rest = W + alpha * ain
    hi_d = 0.0

    def g(v: float) -> float:
        try:
            d = damping(v)
        except OverflowError:  # |v|^n beyond float64: the damping saturates, G keeps its sign
            d = math.copysign(math.inf, v)
        return v - rest + alpha * d + alpha * w2 * math.sin(P + alpha * v)

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
    glo, ghi = g(lo), g(hi)
    if glo > 0.0 or ghi < 0.0:
        # Not monotone (α² ω0² ≥ 1): widen once, then bisect on whatever sign change is found.
        span = abs(hi - lo) + 1.0
        lo, hi = lo - span, hi + span
        glo, ghi = g(lo), g(hi)
    v = min(max(rest, lo), hi)
    for _ in range(200):
        gv = g(v)
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


def dirk_step(tableau: Tableau, p0: float, v0: float, h: float, ain: float, w2: float,
              gamma: float, n: float, damping: DampingFn) -> tuple[float, float, float, float]:
    """Advance ``(φ, φ')`` by ``h`` with the DIRK method ``tableau``.

    Returns ``(φ₁, φ'₁, w, a₀)`` like the explicit steps: ``w`` is the damping work per unit
    inertia by the same quadrature, ``a₀`` the acceleration of the first stage.
    """
    A, B = tableau.A.tolist(), tableau.B.tolist()  # plain floats: the state stays a float
    s = tableau.stages
    vs: list[float] = []
    acc: list[float] = []
    ds: list[float] = []
    for i in range(s):
        P = p0 + h * sum(A[i][j] * vs[j] for j in range(i))
        W = v0 + h * sum(A[i][j] * acc[j] for j in range(i))
        alpha = h * A[i][i]
        V = _solve_stage(P, W, alpha, w2, ain, gamma, n, damping)
        # The stage acceleration follows from the stage equation itself, (V − W)/α; this keeps
        # the set-valued Coulomb case exact when the stage sticks.
        a = (V - W) / alpha
        vs.append(V)
        acc.append(a)
        ds.append(ain - w2 * math.sin(P + alpha * V) - a)
    p1 = p0 + h * sum(B[i] * vs[i] for i in range(s))
    v1 = v0 + h * sum(B[i] * acc[i] for i in range(s))
    w = h * sum(B[i] * vs[i] * ds[i] for i in range(s))
    return p1, v1, w, acc[0]
