"""The plain reference Runge-Kutta step: the semantics every fast step is tested against.

``rk_step(tableau, f, y, h)`` is the textbook definition (Butcher, *Numerical Methods for
Ordinary Differential Equations*, 2016, section 23): stages ``kᵢ = f(y + h Σⱼ aᵢⱼ kⱼ)`` and
``y₁ = y + h Σ bᵢ kᵢ``, with no specialisation at all. The generated steps of ``explicit.py``
(scalar and numpy) are checked against it to round-off for every explicit tableau.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from .tableaus import Tableau

FloatArray = npt.NDArray[np.float64]


def rk_step(tableau: Tableau, f: Callable[[FloatArray], FloatArray], y: FloatArray,
            h: float) -> FloatArray:
    """Return y advanced by one explicit Runge-Kutta step of ``tableau`` for y' = f(y)."""
    if not tableau.explicit:
        raise ValueError(f'{tableau.name} is not explicit; rk_step is the explicit reference')
    y = np.asarray(y, dtype=float)
    ks: list[FloatArray] = []
    for i in range(tableau.stages):
        yi = y + h * sum((tableau.A[i, j] * ks[j] for j in range(i)), np.zeros_like(y))
        ks.append(np.asarray(f(yi), dtype=float))
    return np.asarray(y + h * sum((tableau.B[i] * ks[i] for i in range(tableau.stages)),
                                  np.zeros_like(y)))
