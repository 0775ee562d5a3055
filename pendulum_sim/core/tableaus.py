"""Butcher tableaus: every Runge-Kutta method of the core, as data.

An explicit method is ``A`` (strictly lower triangular), ``B``, ``C`` and its order; an embedded
pair adds ``E`` (the weights of the error estimate, B − B̂; DOP853 a second one, ``E3``); a
diagonally implicit method has a lower triangular ``A`` with a non-zero diagonal; a linearly
implicit (Rosenbrock) method adds the coupling coefficients ``G`` (cᵢⱼ) and the diagonal
``gamma`` (γ) of its transformed form.
One generic step serves each kind (``explicit.py``, ``embedded.py``, ``dirk.py``,
``rosenbrock.py``).
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
    G: FloatArray | None = None  # Rosenbrock: cᵢⱼ of the transformed stages (Hairer-Wanner IV.7)
    gamma: float = 0.0  # Rosenbrock: the diagonal γ
    E3: FloatArray | None = None  # a second, lower-order error estimate (DOP853's order 3)
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
        """Return True where A is strictly lower triangular and the method is not Rosenbrock."""
        return self.G is None and bool(np.all(np.triu(self.A) == 0.0))

    @property
    def rosenbrock(self) -> bool:
        """Return True for a linearly implicit (Rosenbrock) method."""
        return self.G is not None

    def stability_function(self, z: complex) -> complex:
        """Return R(z) = 1 + z bᵀ (I − z A)⁻¹ 1, the amplification of y' = λ y at z = h λ."""
        s = self.stages
        if self.G is not None:
            # The transformed stages on y' = λ y with the exact Jacobian (z = h λ):
            # (1/γ − z) kᵢ = z (1 + Σ aᵢⱼ kⱼ) + Σ cᵢⱼ kⱼ, and R = 1 + Σ bᵢ kᵢ.
            ks: list[complex] = []
            for i in range(s):
                arg = 1.0 + sum(self.A[i, j] * ks[j] for j in range(i))
                cpl = sum(self.G[i, j] * ks[j] for j in range(i))
                ks.append((z * arg + cpl) / (1.0 / self.gamma - z))
            return complex(1.0 + sum(self.B[i] * ks[i] for i in range(s)))
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

# Dormand and Prince's RK8(5,3) (Hairer, Nørsett and Wanner, *Solving ODEs I*, 2nd ed. 1993,
# II.10, their code DOP853; the values as in scipy's ``dop853_coefficients``): 12 stages of
# order 8 with two embedded estimates, E (order 5) and E3 (order 3), combined per component as
# e₅ |e₅| / hypot(e₅, 0.1 e₃), which behaves as h^8 (``explicit.step_source``).
_D8 = {
    1: {0: 0.05260015195876773},
    2: {0: 0.0197250569845379, 1: 0.0591751709536137},
    3: {0: 0.02958758547680685, 2: 0.08876275643042054},
    4: {0: 0.2413651341592667, 2: -0.8845494793282861, 3: 0.924834003261792},
    5: {0: 0.037037037037037035, 3: 0.17082860872947386, 4: 0.12546768756682242},
    6: {0: 0.037109375, 3: 0.17025221101954405, 4: 0.06021653898045596, 5: -0.017578125},
    7: {0: 0.03709200011850479, 3: 0.17038392571223998, 4: 0.10726203044637328,
         5: -0.015319437748624402, 6: 0.008273789163814023},
    8: {0: 0.6241109587160757, 3: -3.3608926294469414, 4: -0.868219346841726, 5: 27.59209969944671,
         6: 20.154067550477894, 7: -43.48988418106996},
    9: {0: 0.47766253643826434, 3: -2.4881146199716677, 4: -0.590290826836843,
         5: 21.230051448181193, 6: 15.279233632882423, 7: -33.28821096898486,
         8: -0.020331201708508627},
    10: {0: -0.9371424300859873, 3: 5.186372428844064, 4: 1.0914373489967295,
         5: -8.149787010746927, 6: -18.52006565999696, 7: 22.739487099350505,
         8: 2.4936055526796523, 9: -3.0467644718982196},
    11: {0: 2.273310147516538, 3: -10.53449546673725, 4: -2.0008720582248625, 5: -17.9589318631188,
         6: 27.94888452941996, 7: -2.8589982771350235, 8: -8.87285693353063, 9: 12.360567175794303,
         10: 0.6433927460157636},
}
DOP853 = Tableau(
    'dop853', 8,
    _t([[_D8.get(i, {}).get(j, 0.0) for j in range(12)] for i in range(12)]),
    _t([0.054293734116568765, 0.0, 0.0, 0.0, 0.0, 4.450312892752409, 1.8915178993145003,
        -5.801203960010585, 0.3111643669578199, -0.1521609496625161, 0.20136540080403034,
        0.04471061572777259]),
    _t([0.0, 0.05260015195876773, 0.0789002279381516, 0.1183503419072274, 0.2816496580927726,
        0.3333333333333333, 0.25, 0.3076923076923077, 0.6512820512820513, 0.6, 0.8571428571428571,
        1.0]),
    E=_t([0.01312004499419488, 0.0, 0.0, 0.0, 0.0, -1.2251564463762044, -0.4957589496572502,
        1.6643771824549864, -0.35032884874997366, 0.3341791187130175, 0.08192320648511571,
        -0.022355307863886294]),
    E3=_t([-0.18980075407240762, 0.0, 0.0, 0.0, 0.0, 4.450312892752409, 1.8915178993145003,
        -5.801203960010585, -0.4226823213237919, -0.1521609496625161, 0.20136540080403034,
        0.02265179219836082]),
    error_order=7,
    description='Dormand-Prince 8(5,3), adaptive, for tight tolerances',
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

# Hairer and Wanner, *Solving ODEs II* (1996), IV.7, Table 7.2: RODAS, the stiffly accurate,
# L-stable Rosenbrock method of order 4 with an embedded order-3 solution, 6 stages (the last
# two evaluate f at the embedded and the final solution), in the transformed variables of
# eq (7.25): A = aᵢⱼ, G = cᵢⱼ, B = mᵢ, E = mᵢ − m̂ᵢ, C = αᵢ (stage times).
_R51, _R52, _R53, _R54 = (1.221224509226641, 6.019134481288629, 12.53708332932087,
                          -0.6878860361058950)
RODAS4 = Tableau(
    'rodas4', 4,
    _t([
        [0, 0, 0, 0, 0, 0],
        [1.544, 0, 0, 0, 0, 0],
        [0.9466785280815826, 0.2557011698983284, 0, 0, 0, 0],
        [3.314825187068521, 2.896124015972201, 0.9986419139977817, 0, 0, 0],
        [_R51, _R52, _R53, _R54, 0, 0],
        [_R51, _R52, _R53, _R54, 1.0, 0],
    ]),
    _t([_R51, _R52, _R53, _R54, 1.0, 1.0]),
    _t([0.0, 0.386, 0.21, 0.63, 1.0, 1.0]),
    E=_t([0, 0, 0, 0, 0, 1.0]),
    error_order=3,
    description='RODAS4: L-stable Rosenbrock 4(3), adaptive, for long stiff runs',
    G=_t([
        [0, 0, 0, 0, 0, 0],
        [-5.6688, 0, 0, 0, 0, 0],
        [-2.430093356833875, -0.2063599157091915, 0, 0, 0, 0],
        [-0.1073529058151375, -9.594562251023355, -20.47028614809616, 0, 0, 0],
        [7.496443313967647, -10.24680431464352, -33.99990352819905, 11.70890893206160, 0, 0],
        [8.083246795921522, -7.981132988064893, -31.52159432874371, 16.31930543123136,
         -6.058818238834054, 0],
    ]),
    gamma=0.25,
)

@dataclass(frozen=True, eq=False)
class Extrapolation:
    """An extrapolation method as data: its base step is linearly implicit Euler (L-stable).

    ``sequence`` is the step-number sequence n₁ < n₂ < … < n_k; the extrapolated value T_kk has
    order k and T_kk − T_{k,k−1} is its error estimate, of order k − 1 (``extrapolation.py``).
    It answers the questions a tableau answers (order, kind, stability function), so the
    methods table and the embedded cover take either.
    """

    name: str
    sequence: tuple[int, ...]
    description: str = ''

    @property
    def order(self) -> int:
        """Return the order k of T_kk."""
        return len(self.sequence)

    @property
    def error_order(self) -> int:
        """Return the order of the estimated value T_{k,k−1}."""
        return len(self.sequence) - 1

    @property
    def explicit(self) -> bool:
        """Return False: the base step solves a linear system."""
        return False

    @property
    def rosenbrock(self) -> bool:
        """Return False: not a Rosenbrock tableau (its own generated step)."""
        return False

    def stability_function(self, z: complex) -> complex:
        """Return R(z) of T_kk on y' = λ y at z = h λ (exact Jacobian)."""
        rows: list[list[complex]] = []
        for j, nj in enumerate(self.sequence):
            row = [complex((1.0 - z / nj) ** -nj)]
            for k in range(1, j + 1):
                ratio = nj / self.sequence[j - k]
                row.append(row[k - 1] + (row[k - 1] - rows[j - 1][k - 1]) / (ratio - 1.0))
            rows.append(row)
        return rows[-1][-1]


# The harmonic sequence 1, 2, …, 6 (Deuflhard's choice for linearly implicit Euler; Hairer and
# Wanner, *Solving ODEs II*, IV.9): order 6, 16 evaluations of f and 21 2×2 solves per step.
EXTRAP6 = Extrapolation('extrap6', (1, 2, 3, 4, 5, 6),
                        'linearly implicit Euler extrapolated to order 6, adaptive, for tight '
                        'tolerances on stiff runs')
# Two more rows (1, …, 8): order 8 for 29 evaluations of f and 36 solves; its weights' magnitudes
# sum to 3392 (302 for six rows), so round-off sets a floor near 1e-12 on long runs.
EXTRAP8 = Extrapolation('extrap8', (1, 2, 3, 4, 5, 6, 7, 8),
                        'linearly implicit Euler extrapolated to order 8, adaptive, for the '
                        'tightest tolerances on stiff runs')

TABLEAUS: dict[str, Tableau] = {t.name: t for t in (EULER, MIDPOINT, RK4, DOPRI5, DOP853, SDIRK2,
                                                    SDIRK3)}
