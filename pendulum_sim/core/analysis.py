"""Analysis: exact solutions, the convergence quotient Q(t), periods and decay laws.

Everything here is an oracle the numerics are checked against (the paper, eq 27-34), or a
measurement made on a computed trajectory.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from .errors import ModelError
from .model import FloatArray, PendulumParams
from .simulate import simulate


@dataclass(frozen=True)
class LinearSolution:
    """Exact solution of the linearised equation x'' + γ x' + ω0² x = 0 (eq 27-33).

    Underdamped (γ² < 4 ω0²): ``x = A e^(−γt/2) cos(ω t + α)`` with ``ω = sqrt(ω0² − γ²/4)``
    and ``tan α = −γ/(2ω) − x'(0)/(x(0) ω)``. Overdamped: ``x = c1 e^(r1 t) + c2 e^(r2 t)`` with
    ``r1,2 = −γ/2 ± sqrt(γ²/4 − ω0²)``. Critical: ``x = (c1 + c2 t) e^(−γt/2)``.
    """

    gamma: float
    omega0_sq: float
    x0: float
    v0: float

    @property
    def regime(self) -> str:
        """Return 'underdamped', 'critical' or 'overdamped'."""
        disc = self.gamma**2 / 4.0 - self.omega0_sq
        if disc < 0.0:
            return 'underdamped'
        return 'critical' if disc == 0.0 else 'overdamped'

    @property
    def omega(self) -> float:
        """Return the damped frequency ω = sqrt(ω0² − γ²/4) (eq 30; 0 unless underdamped)."""
        return math.sqrt(max(self.omega0_sq - self.gamma**2 / 4.0, 0.0))

    @property
    def alpha(self) -> float:
        """Return the phase α of the underdamped solution (eq 31)."""
        return math.atan2(-(self.v0 + 0.5 * self.gamma * self.x0) / self.omega, self.x0)

    @property
    def amplitude(self) -> float:
        """Return the amplitude A of the underdamped solution (eq 32)."""
        return math.hypot(self.x0, (self.v0 + 0.5 * self.gamma * self.x0) / self.omega)

    @property
    def rates(self) -> tuple[float, float]:
        """Return r1, r2 = −γ/2 ± sqrt(γ²/4 − ω0²) (overdamped and critical cases)."""
        s = math.sqrt(max(self.gamma**2 / 4.0 - self.omega0_sq, 0.0))
        return -0.5 * self.gamma + s, -0.5 * self.gamma - s

    def __call__(self, t: FloatArray | float) -> FloatArray:
        """Return x(t)."""
        return self.evaluate(t)[0]

    def evaluate(self, t: FloatArray | float) -> tuple[FloatArray, FloatArray]:
        """Return x(t) and x'(t)."""
        t = np.asarray(t, dtype=float)
        g2 = 0.5 * self.gamma
        if self.regime == 'underdamped':
            w, a, amp = self.omega, self.alpha, self.amplitude
            env = amp * np.exp(-g2 * t)
            x = env * np.cos(w * t + a)
            v = -g2 * x - env * w * np.sin(w * t + a)
            return x, v
        if self.regime == 'critical':
            c1, c2 = self.x0, self.v0 + g2 * self.x0
            e = np.exp(-g2 * t)
            return (c1 + c2 * t) * e, (c2 - g2 * (c1 + c2 * t)) * e
        r1, r2 = self.rates
        c1 = (self.v0 - r2 * self.x0) / (r1 - r2)
        c2 = (r1 * self.x0 - self.v0) / (r1 - r2)
        e1, e2 = np.exp(r1 * t), np.exp(r2 * t)
        return c1 * e1 + c2 * e2, c1 * r1 * e1 + c2 * r2 * e2


def linear_exact_solution(gamma: float, omega0_sq: float, x0: float,
                          v0: float = 0.0) -> LinearSolution:
    """Return the exact solution of x'' + γ x' + ω0² x = 0 from x(0) = x0, x'(0) = v0."""
    if not (math.isfinite(gamma) and gamma >= 0.0):
        raise ModelError(f'gamma must be >= 0 s^-1, got {gamma}')
    if not (math.isfinite(omega0_sq) and omega0_sq > 0.0):
        raise ModelError(f'omega0_sq must be > 0 s^-2, got {omega0_sq}')
    return LinearSolution(float(gamma), float(omega0_sq), float(x0), float(v0))


def ellipk(m: float) -> float:
    """Return the complete elliptic integral of the first kind K(m), parameter m = k² < 1.

    By the arithmetic-geometric mean: K(m) = π / (2 AGM(1, sqrt(1 − m))).
    """
    if not m < 1.0:
        raise ModelError(f'm must be < 1, got {m}')
    a, b = 1.0, math.sqrt(1.0 - m)
    for _ in range(60):
        if abs(a - b) <= 1e-16 * a:
            break
        a, b = 0.5 * (a + b), math.sqrt(a * b)
    return math.pi / (2.0 * a)


def undamped_period(omega0_sq: float, x0: float) -> float:
    """Return the period 4 K(sin²(x0/2)) / ω0 of the undamped pendulum released at rest from x0."""
    if not 0.0 < abs(x0) < math.pi:
        raise ModelError(f'x0 must be in (0, pi) in magnitude for an oscillation, got {x0}')
    return 4.0 * ellipk(math.sin(0.5 * x0) ** 2) / math.sqrt(omega0_sq)


def decay_coefficient(n: float) -> float:
    """Return c_n = Γ((n+2)/2) / (sqrt(π) Γ((n+3)/2)), the cycle average of |sin|^(n+1)·(2/π)."""
    return math.gamma((n + 2.0) / 2.0) / (math.sqrt(math.pi) * math.gamma((n + 3.0) / 2.0))


def decay_law_amplitude(n: float, gamma: float, omega0_sq: float, a0: float,
                        t: FloatArray | float) -> FloatArray:
    """Return the averaged amplitude A(t) of small oscillations for n > 1 (energy averaging).

    ``dA/dt = −γ c_n ω0^(n−1) A^n`` gives ``A^(1−n) = A0^(1−n) + (n−1) γ c_n ω0^(n−1) t``: an
    algebraic decay ∝ t^(−1/(n−1)) instead of the exponential one of n = 1.
    """
    if not n > 1.0:
        raise ModelError(f'n must be > 1 for the algebraic decay law, got {n}')
    t = np.asarray(t, dtype=float)
    k = (n - 1.0) * gamma * decay_coefficient(n) * math.sqrt(omega0_sq) ** (n - 1.0)
    return np.asarray((a0 ** (1.0 - n) + k * t) ** (-1.0 / (n - 1.0)))


def turning_points(t: FloatArray, phi: FloatArray, dphi: FloatArray) -> tuple[FloatArray,
                                                                              FloatArray]:
    """Return the times and angles |φ| where φ' changes sign (linear interpolation in a step)."""
    s = np.signbit(dphi)
    idx = np.nonzero(s[1:] != s[:-1])[0]
    idx = idx[dphi[idx] != dphi[idx + 1]]
    w = dphi[idx] / (dphi[idx] - dphi[idx + 1])
    tt = t[idx] + w * (t[idx + 1] - t[idx])
    # The angle is stationary there, so the larger of the two neighbours is within O(h²).
    amp = np.maximum(np.abs(phi[idx]), np.abs(phi[idx + 1]))
    return tt, amp


@dataclass(frozen=True)
class ConvergenceQuotient:
    """The convergence quotient Q(t) = |y_h − y_{h/2}| / |y_{h/2} − y_{h/4}| (eq 34)."""

    t: FloatArray
    q: FloatArray
    diff_h: FloatArray  # |y_h − y_{h/2}|
    diff_h2: FloatArray  # |y_{h/2} − y_{h/4}|


def convergence_quotient(params: PendulumParams, phi0: float, dphi0: float, t_end: float,
                         h: float, method: str = 'rk4', **kwargs: object) -> ConvergenceQuotient:
    """Compute Q(t) on the grid of h from runs at h, h/2 and h/4 (2-norm over φ, φ').

    For a method of order p, Q → 2^p while the errors are above round-off (16 for RK4).
    Extra keyword arguments go to :func:`simulate`.
    """
    runs = [simulate(params, phi0, dphi0, t_end, h / 2**k, method, **kwargs)  # type: ignore
            for k in range(3)]
    ys = [np.column_stack([r.phi[:: 2**k], r.dphi[:: 2**k]]) for k, r in enumerate(runs)]
    d1 = np.linalg.norm(ys[0] - ys[1], axis=1)
    d2 = np.linalg.norm(ys[1] - ys[2], axis=1)
    with np.errstate(divide='ignore', invalid='ignore'):
        q = np.where(d2 > 0.0, d1 / d2, np.nan)
    return ConvergenceQuotient(runs[0].t, q, d1, d2)


def fit_percent(measured: FloatArray, predicted: FloatArray) -> float:
    """Return how well ``predicted`` reproduces ``measured``, in %: MATLAB ``compare``'s fit.

    ``100 (1 − ‖y − ŷ‖ / ‖y − mean(y)‖)`` with the 2-norm over the samples (the normalised
    root-mean-square error, MathWorks, System Identification Toolbox, ``compare``): 100 for a
    perfect prediction, 0 for one no better than the measurement's mean, negative for worse.
    NaN when the measurement is constant (its spread is zero: no scale to judge by).

    Raises
    ------
    ModelError
        If the two are not 1-D arrays of one length, at least one sample, all finite.
    """
    y = np.asarray(measured, dtype=np.float64)
    y_hat = np.asarray(predicted, dtype=np.float64)
    if y.ndim != 1 or y.shape != y_hat.shape or y.size == 0:
        raise ModelError(f'measured and predicted must be 1-D arrays of one length (at least '
                         f'one sample), got shapes {y.shape} and {y_hat.shape}')
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(y_hat))):
        raise ModelError('measured and predicted must be finite')
    spread = float(np.linalg.norm(y - y.mean()))
    if spread == 0.0:
        return math.nan
    return 100.0 * (1.0 - float(np.linalg.norm(y - y_hat)) / spread)


SETTLING_THRESHOLD = 0.02
"""The settling band of a step response: 2 % of the step around the target (python-control's
``step_info`` default)."""


def outside_settling_band(change: FloatArray, step: FloatArray) -> npt.NDArray[np.bool_]:
    """Return where a response is outside its settling band (python-control's ``step_info``).

    ``change`` is the response's change from its initial value and ``step`` the target's
    (``target − initial``, broadcast against ``change``): a sample is outside when
    ``|change / step − 1| >= SETTLING_THRESHOLD``, i.e. not within 2 % of the step around the
    target. The settling time is the time of the sample after the last one outside. The one
    statement of the rule: the metrics and the example controller's log
    (:class:`pendulum_sim.controller.pd_law.StepSettling`) both apply it, from here.
    """
    band = change / step
    band -= 1.0
    np.abs(band, out=band)
    outside: npt.NDArray[np.bool_] = band >= SETTLING_THRESHOLD
    return outside
