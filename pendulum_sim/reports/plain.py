"""Plain integrators for comparison: a fixed-step loop of a core tableau with nothing around it.

No stability guard, no reversal splitting, no energy check: what the paper's C++ code did (a
classic RK4 loop at fixed h). Used to show why the paper's Q(t) wandered for n = 2, to measure a
tableau's order by itself, and as the *plain vector field* handed to scipy's solvers.
"""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from ..core.explicit import compile_step
from ..core.law import compile_damping, damping_derivative
from ..core.model import PendulumParams
from ..core.tableaus import TABLEAUS

FloatArray = npt.NDArray[np.float64]


def plain_run(params: PendulumParams, phi0: float, dphi0: float, t_end: float, h: float,
              method: str = 'rk4', record_every: int = 1,
              torque: float = 0.0) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Integrate with the bare tableau step of ``method`` at fixed ``h``; return t, φ, φ'.

    ``t_end / h`` must be an integer (within round-off). The loop stops at the first
    non-finite state (overflow) and fills the rest with NaN, as a plain loop would produce.
    """
    steps = round(t_end / h)
    step = compile_step(TABLEAUS[method], params.n)
    w2, gamma = params.omega0_sq, params.gamma
    ain = torque / params.inertia
    p, v = float(phi0), float(dphi0)
    ts, ps, vs = [0.0], [p], [v]
    dead = False
    for k in range(1, steps + 1):
        if not dead:
            try:
                p, v, _, _ = step(p, v, h, ain, w2, gamma, 1.0)
            except (OverflowError, ValueError):
                p = v = math.nan
            if not (math.isfinite(p) and math.isfinite(v)):
                p = v = math.nan
                dead = True
        if k % record_every == 0 or k == steps:
            ts.append(k * h)
            ps.append(p)
            vs.append(v)
    return np.array(ts), np.array(ps), np.array(vs)


def vector_field(params: PendulumParams,
                 torque: float = 0.0) -> Callable[[float, FloatArray], list[float]]:
    """Return f(t, y) = [φ', −γ φ'|φ'|^(n−1) − ω0² sin φ + τ/I], the plain vector field (eq 20).

    The damping is the core's one law (``explicit.damping_expression``), compiled for n.
    """
    w2, g, ain = params.omega0_sq, params.gamma, torque / params.inertia
    law = compile_damping(params.n)

    def fun(t: float, y: FloatArray) -> list[float]:
        v = float(y[1])
        return [v, ain - law(v, g, 1.0) - w2 * math.sin(y[0])]
    return fun


def jacobian(params: PendulumParams) -> Callable[[float, FloatArray], FloatArray]:
    """Return the Jacobian [[0, 1], [−ω0² cos φ, −γ n |φ'|^(n−1)]] (eq 18-19 linearised) for scipy.

    The slope is the core's ``damping_derivative``; at rest, where it is unbounded for n < 1,
    0 is given to scipy (its Newton iteration needs a finite matrix).
    """
    w2, g, n = params.omega0_sq, params.gamma, params.n

    def jac(t: float, y: FloatArray) -> FloatArray:
        d = damping_derivative(g, n, float(y[1]))
        return np.array([[0.0, 1.0], [-w2 * math.cos(float(y[0])), -d if math.isfinite(d)
                                      else 0.0]])
    return jac
