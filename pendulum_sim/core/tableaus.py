"""Butcher tableaus: every Runge-Kutta method of the core, as data.

An explicit method is ``A`` (strictly lower triangular), ``B``, ``C`` and its order; an embedded
pair adds ``E`` (the weights of the error estimate, B − B̂); a diagonally implicit method has a
lower triangular ``A`` with a non-zero diagonal. One generic step serves each kind
(``explicit.py``, ``embedded.py``, ``dirk.py``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Tableau:
    """A Runge-Kutta method's coefficients and declared order."""

    name: str
    order: int
    A: FloatArray
    B: FloatArray
    C: FloatArray
    E: FloatArray | None = None  # error weights of an embedded pair
    error_order: int = 0  # order of the embedded (lower) solution
    description: str = ''
    stability_poly: FloatArray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        for arr in (self.A, self.B, self.C):
            arr.setflags(write=False)
        object.__setattr__(self, 'stability_poly', _stability_polynomial(self.A, self.B))

    @property
    def stages(self) -> int:
        """Return the number of stages s."""
        return len(self.B)

    @property
    def explicit(self) -> bool:
        """Return True where A is strictly lower triangular."""
        return bool(np.all(np.triu(self.A) == 0.0))

    def stability_function(self, z: complex) -> complex:
        """Return R(z) = 1 + z bᵀ (I − z A)⁻¹ 1, the amplification of y' = λ y at z = h λ."""
        s = self.stages
        if self.explicit:
            return complex(np.polyval(self.stability_poly[::-1], z))
        m = np.eye(s) - z * self.A
        return complex(1.0 + z * (self.B @ np.linalg.solve(m, np.ones(s))))


def _stability_polynomial(A: FloatArray, B: FloatArray) -> FloatArray:
    """Return c_k of R(z) = Σ c_k z^k for an explicit method (c_k = bᵀ A^(k−1) 1)."""
    s = len(B)
    coeffs = [1.0]
    v = np.ones(s)
    for _ in range(s):
        coeffs.append(float(B @ v))
        v = A @ v
    return np.array(coeffs)


def _t(rows: object) -> FloatArray:
    return np.array(rows, dtype=float)


EULER = Tableau('euler', 1, _t([[0.0]]), _t([1.0]), _t([0.0]),
                description='explicit Euler')

MIDPOINT = Tableau('midpoint', 2, _t([[0.0, 0.0], [0.5, 0.0]]), _t([0.0, 1.0]), _t([0.0, 0.5]),
                   description='explicit midpoint (RK2)')

RK4 = Tableau(
    'rk4', 4,
    _t([[0.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0], [0.0, 0.5, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]]),
    _t([1 / 6, 1 / 3, 1 / 3, 1 / 6]),
    _t([0.0, 0.5, 0.5, 1.0]),
    description="classic Runge-Kutta, the paper's method",
)

# Dormand and Prince (1980), RK5(4)7M; the 7th stage is FSAL.
DOPRI5 = Tableau(
    'dopri5', 5,
    _t([
        [0, 0, 0, 0, 0, 0, 0],
        [1 / 5, 0, 0, 0, 0, 0, 0],
        [3 / 40, 9 / 40, 0, 0, 0, 0, 0],
        [44 / 45, -56 / 15, 32 / 9, 0, 0, 0, 0],
        [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0, 0, 0],
        [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0, 0],
        [35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0],
    ]),
    _t([35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0]),
    _t([0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1, 1]),
    E=_t([71 / 57600, 0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40]),
    error_order=4,
    description='Dormand-Prince 5(4), adaptive, for offline accuracy',
)

_G2 = 1.0 - math.sqrt(2.0) / 2.0
# Alexander (1977): 2-stage, order 2, L-stable, stiffly accurate SDIRK.
SDIRK2 = Tableau('sdirk2', 2, _t([[_G2, 0.0], [1.0 - _G2, _G2]]), _t([1.0 - _G2, _G2]),
                 _t([_G2, 1.0]), description='L-stable SDIRK, order 2 (Alexander 1977)')

_G3 = 0.43586652150845899941601945
_B1 = -(6 * _G3**2 - 16 * _G3 + 1) / 4
_B2 = (6 * _G3**2 - 20 * _G3 + 5) / 4
# Alexander (1977): 3-stage, order 3, L-stable, stiffly accurate SDIRK.
SDIRK3 = Tableau(
    'sdirk3', 3,
    _t([[_G3, 0.0, 0.0], [(1 - _G3) / 2, _G3, 0.0], [_B1, _B2, _G3]]),
    _t([_B1, _B2, _G3]),
    _t([_G3, (1 + _G3) / 2, 1.0]),
    description='L-stable SDIRK, order 3 (Alexander 1977), the stiff fallback',
)

# Backward Euler: order 1, L-stable, and monotone in the velocity (its one stage cannot flip the
# sign of φ' against the forces), the last resort of the guard's fallback.
BACKWARD_EULER = Tableau('backward_euler', 1, _t([[1.0]]), _t([1.0]), _t([1.0]),
                         description='backward Euler, the last resort of the fallback')

TABLEAUS: dict[str, Tableau] = {t.name: t for t in (EULER, MIDPOINT, RK4, DOPRI5, SDIRK2, SDIRK3)}
