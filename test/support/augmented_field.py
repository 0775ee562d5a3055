"""The pendulum with its damping work as a third component: the oracle of the linear solves.

The Rosenbrock and extrapolation steps integrate y = (φ, φ', w) with w' = φ' D(φ') and the
Jacobian J = [[0, 1, 0], [−ω0² cos φ, −d, 0], [0, D + φ' d, 0]] at the start of the step (d the
damping slope, eq 18-19 of Quiroga and Ospina-Henao 2017); their plain numpy references take
``f`` and ``J`` from here, written out independently of the generated code.
"""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from pendulum_sim.core.law import damping_derivative

W2 = 9.8


def augmented(gamma: float, n: float, ain: float, branch: bool, sign: float, p0: float,
              v0: float) -> tuple[Callable[[float], float],
                                  Callable[[np.ndarray], np.ndarray], np.ndarray]:
    """Return the damping law, the field f(y) and J at (p0, v0) (``branch``: s γ |φ'|^n)."""
    def law(v: float) -> float:
        if branch:
            return float(sign * gamma * abs(v) ** n)
        return 0.0 if v == 0.0 else gamma * math.copysign(abs(v) ** n, v)

    def f(y: np.ndarray) -> np.ndarray:
        d = law(float(y[1]))
        return np.array([y[1], ain - d - W2 * math.sin(y[0]), y[1] * d])

    d = damping_derivative(gamma, n, v0)
    jac = np.array([[0.0, 1.0, 0.0], [-W2 * math.cos(p0), -d, 0.0],
                    [0.0, law(v0) + v0 * d, 0.0]])
    return law, f, jac
