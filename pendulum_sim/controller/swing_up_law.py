"""Swing-up by energy shaping, balance by LQR, and a saturated PD: the reference laws; no ROS.

The joint is ``I φ'' = −m g l sin φ − γ I φ' + τ`` (Quiroga & Ospina-Henao, Eur. J. Phys. 38
(2017) 065005, eq 11 with an input torque and viscous damping), its energy
``E = ½ I φ'² + m g l (1 − cos φ)`` (eq 23) and ``dE/dt = −γ I φ'² + τ φ'`` (eq 26).

- **Energy shaping** (Åström & Furuta, "Swinging up a pendulum by energy control",
  Automatica 36 (2000) 287-295): upright at rest has ``E_up = 2 m g l``; the torque
  ``τ = sat(k_E (E_up − E) sgn φ' + γ I φ')`` makes ``dE/dt = k_E |φ'| (E_up − E)`` where it
  does not saturate (the damping term cancels the loss), so the energy climbs to ``E_up``
  swing after swing under any torque limit; ``sgn 0 = +1`` kicks the pendulum out of rest.
- **LQR balance**: the joint linearised at upright, ``x = wrap(φ − π)``,
  ``A = [[0, 1], [m g l / I, −γ]]``, ``B = [[0], [1 / I]]``, and the gain ``K`` of
  ``u = −K x`` minimising ``∫ xᵀQx + uᵀRu dt`` (python-control's ``lqr``; SciPy's
  ``solve_continuous_are`` where python-control is not installed: the same Riccati equation,
  ``K = R⁻¹ Bᵀ S``). Its region-of-attraction estimate is the ellipse ``xᵀ S x < ρ`` with
  ``ρ = τ_max² / (K S⁻¹ Kᵀ)``, the largest level set of the Lyapunov function ``xᵀ S x`` on
  which ``|K x| ≤ τ_max`` (the torque does not saturate, so the linearised loop is the
  closed loop there).
- **Energy shaping + LQR**: LQR inside the ellipse, energy shaping outside.
- **Saturated PD** towards upright, ``τ = sat(Kp wrap(π − φ) − Kd φ')``: it balances near
  upright but cannot lift the pendulum once ``τ_max < m g l`` (gravity's torque at the
  horizontal is larger), the contrast to energy shaping.

Every function takes numpy arrays or floats (a campaign's batch or one state).
"""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pendulum_sim.core import PendulumParams
from pendulum_sim.core.jit_cache import cache_root, write_atomic
from pendulum_sim.core.model import energy, wrap_pi

from .errors import ControllerError

FloatArray = NDArray[np.float64]


def lqr(a: FloatArray, b: FloatArray, q: FloatArray,
        r: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Return ``(K, S)`` of the continuous LQR problem (python-control's ``lqr``).

    Without python-control, SciPy's ``solve_continuous_are`` solves the same algebraic
    Riccati equation and ``K = R⁻¹ Bᵀ S``. The answer is kept on disk (:func:`lqr_cache_file`)
    and read back by later processes: importing python-control costs some 2 s of CPU (it
    imports SciPy's signal and stats packages and Matplotlib), which every process of a
    campaign would pay for the same gain.
    """
    path = lqr_cache_file(a, b, q, r)
    kept = _read_lqr(path, a.shape[0], b.shape[1]) if path is not None else None
    if kept is not None:
        return kept
    k, s = _solve_lqr(a, b, q, r)
    if path is not None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            write_atomic(path, json.dumps({'gain': [float.hex(x) for x in k.reshape(-1)],
                                           'riccati': [float.hex(x) for x in s.reshape(-1)]}))
        except OSError:   # an unwritable cache: the next process solves it again
            pass
    return k, s


def lqr_cache_file(a: FloatArray, b: FloatArray, q: FloatArray,
                   r: FloatArray) -> Path | None:
    """Return the file that keeps the LQR answer of ``(a, b, q, r)``, or None.

    Under the package's cache directory (``core.jit_cache.cache_root``: deleting it is always
    safe), named by a digest of the four matrices' exact floats, this module's source and the
    versions of what solves them (python-control, slycot, which python-control prefers where
    it is installed, SciPy and numpy), so another solver, another way of calling it or other
    matrices never read an answer not theirs. None where a matrix is not finite (such a
    problem is solved, and refused, every time).
    """
    arrays = [np.asarray(x, dtype=float) for x in (a, b, q, r)]
    if not all(np.isfinite(x).all() for x in arrays):
        return None
    sha = hashlib.sha256(Path(__file__).read_bytes())
    for x in arrays:
        sha.update(repr(x.shape).encode() + b':' +
                   ','.join(float.hex(v) for v in x.reshape(-1).tolist()).encode() + b';')
    for name in ('control', 'slycot', 'scipy', 'numpy'):
        try:
            version = metadata.version(name)
        except metadata.PackageNotFoundError:
            version = 'none'
        sha.update(f'{name} {version};'.encode())
    return cache_root() / 'lqr' / f'{sha.hexdigest()[:32]}.json'


def _read_lqr(path: Path, states: int, inputs: int) -> tuple[FloatArray, FloatArray] | None:
    """Return the ``(K, S)`` kept in ``path``, or None where it is missing or unreadable."""
    try:
        data = json.loads(path.read_text(encoding='utf-8'))
        k = np.array([float.fromhex(x) for x in data['gain']]).reshape(inputs, states)
        s = np.array([float.fromhex(x) for x in data['riccati']]).reshape(states, states)
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if not (np.isfinite(k).all() and np.isfinite(s).all()):
        return None
    return k, s


def _solve_lqr(a: FloatArray, b: FloatArray, q: FloatArray,
               r: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Return ``(K, S)`` solved now: python-control's ``lqr``, else SciPy's Riccati solver."""
    try:
        import control  # type: ignore[import-untyped]
    except ImportError:
        from scipy.linalg import solve_continuous_are  # type: ignore[import-untyped]

        s = solve_continuous_are(a, b, q, r)
        return np.linalg.solve(r, b.T @ s), s
    k, s, _ = control.lqr(a, b, q, r)
    return np.asarray(k, dtype=float), np.asarray(s, dtype=float)


@dataclass(frozen=True)
class Ellipse:
    """A region-of-attraction estimate around a state: ``(x − c)ᵀ S (x − c) < level``.

    ``center`` is (φ, φ') in rad and rad/s; the angle difference is wrapped
    (:func:`~pendulum_sim.core.model.wrap_pi`).
    """

    center: tuple[float, float]
    matrix: FloatArray
    level: float

    def contains(self, phi: Any, rate: Any) -> Any:
        """Return True where the state (φ, φ') lies inside the ellipse."""
        x = wrap_pi(np.subtract(phi, self.center[0]))
        v = np.subtract(rate, self.center[1])
        s = self.matrix
        return s[0, 0] * x * x + 2.0 * s[0, 1] * x * v + s[1, 1] * v * v < self.level

    def area(self) -> float:
        """Return the ellipse's area, ``π level / sqrt(det S)`` (rad²/s)."""
        return float(math.pi * self.level / math.sqrt(np.linalg.det(self.matrix)))


def _positive(name: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0.0):
        raise ControllerError(f'{name} must be a finite number > 0, got {value!r}')


@dataclass(frozen=True)
class SwingUpGains:
    """The model the laws assume, their torque limit and weights; validated when built.

    Parameters
    ----------
    m, l, inertia, g : float
        Mass (kg), pivot to centre of mass (m), inertia about the pivot (kg m²), gravity
        (m/s²): the ``swing_up`` scene's body by default.
    gamma : float
        Viscous damping (1/s) the laws assume (``n = 1``).
    max_effort : float
        The torque limit (N m, > 0); half of m g l by default.
    q : (float, float)
        LQR state weights on the angle (1/rad²) and rate (s²/rad²) from upright.
    r : float
        LQR torque weight (1/(N m)²).
    k_energy : float
        Energy-shaping gain (N m per J): the torque per joule of missing energy.
    kp, kd : float
        The saturated PD's gains (N m/rad, N m s/rad).
    """

    m: float = 0.2
    l: float = 1.0   # noqa: E741 (the paper's symbol)
    inertia: float = 0.2002
    g: float = 9.8
    gamma: float = 0.1
    max_effort: float = 0.5 * 0.2 * 9.8 * 1.0
    q: tuple[float, float] = (10.0, 1.0)
    r: float = 1.0
    k_energy: float = 5.0
    kp: float = 4.0
    kd: float = 1.0
    params: PendulumParams = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name in ('max_effort', 'r', 'k_energy'):
            _positive(name, getattr(self, name))
        for name, value in (('q[0]', self.q[0]), ('q[1]', self.q[1]), ('kp', self.kp),
                            ('kd', self.kd)):
            if not (math.isfinite(value) and value >= 0.0):
                raise ControllerError(f'{name} must be a finite number >= 0, got {value!r}')
        try:
            params = PendulumParams(m=self.m, l=self.l, inertia=self.inertia, g=self.g,
                                    gamma=self.gamma, n=1.0)
        except Exception as exc:   # the core's ModelError, said as the controller's
            raise ControllerError(str(exc)) from None
        object.__setattr__(self, 'params', params)

    @property
    def mgl(self) -> float:
        """Return m g l (N m), gravity's torque at the horizontal."""
        return self.params.mgl

    def linearised(self) -> tuple[FloatArray, FloatArray]:
        """Return ``(A, B)`` of the joint linearised at upright (x = wrap(φ − π), φ')."""
        a = np.array([[0.0, 1.0], [self.mgl / self.inertia, -self.gamma]])
        b = np.array([[0.0], [1.0 / self.inertia]])
        return a, b


@dataclass(frozen=True)
class Balance:
    """The LQR gain of :class:`SwingUpGains` and its region-of-attraction ellipse."""

    gain: FloatArray
    riccati: FloatArray
    region: Ellipse


def balance(gains: SwingUpGains) -> Balance:
    """Return the LQR gain at upright and its ellipse (see the module)."""
    a, b = gains.linearised()
    k, s = lqr(a, b, np.diag(gains.q), np.array([[gains.r]]))
    spread = float((k @ np.linalg.solve(s, k.T))[0, 0])
    level = gains.max_effort ** 2 / spread
    return Balance(k.reshape(-1), s, Ellipse((math.pi, 0.0), s, level))


def lqr_torque(gains: SwingUpGains, gain: FloatArray, phi: Any, rate: Any) -> Any:
    """Return ``sat(−K x)`` with ``x = (wrap(φ − π), φ')``."""
    tau = -(gain[0] * wrap_pi(np.subtract(phi, math.pi)) + gain[1] * np.asarray(rate))
    return np.clip(tau, -gains.max_effort, gains.max_effort)


def energy_torque(gains: SwingUpGains, phi: Any, rate: Any) -> Any:
    """Return the energy-shaping torque ``sat(k_E (E_up − E) sgn φ' + γ I φ')``."""
    p = gains.params
    missing = 2.0 * p.mgl - energy(p, phi, rate)
    direction = np.where(np.asarray(rate) >= 0.0, 1.0, -1.0)
    tau = gains.k_energy * missing * direction + p.gamma * p.inertia * np.asarray(rate)
    return np.clip(tau, -gains.max_effort, gains.max_effort)


def swing_up_torque(gains: SwingUpGains, law: Balance, phi: Any, rate: Any) -> Any:
    """Return LQR's torque inside its ellipse, energy shaping's outside."""
    near = law.region.contains(phi, rate)
    return np.where(near, lqr_torque(gains, law.gain, phi, rate),
                    energy_torque(gains, phi, rate))


def pd_upright_torque(gains: SwingUpGains, phi: Any, rate: Any) -> Any:
    """Return the saturated PD's torque towards upright, ``sat(Kp wrap(π − φ) − Kd φ')``."""
    tau = gains.kp * wrap_pi(np.subtract(math.pi, phi)) - gains.kd * np.asarray(rate)
    return np.clip(tau, -gains.max_effort, gains.max_effort)
