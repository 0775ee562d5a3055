"""The stateful fixed-step integrator: what the real-time node and ``simulate`` both drive.

One :class:`Stepper` owns a pendulum's state, its work accounting and the input torque, and
advances it by a fixed step ``h``. The numerics are those of ``engine.Engine``, the same ones
``sweep`` uses: a plain step on the fast path where the engine's decisions accept it, the
engine's careful path (guard, reversal split, Coulomb sticking, energy redo, fallback)
everywhere else.
"""
from __future__ import annotations

import math

from .coulomb import friction_work, moving_input
from .decisions import ENERGY_TOL, compile_fast_step
from .engine import Engine
from .errors import ModelError
from .guard import GuardStats
from .jit import check_jit
from .methods import Method, get_method
from .model import (
    MAX_INPUT_ACCEL,
    PendulumParams,
    check_flag,
    check_speed,
    check_step,
    check_tolerance,
    check_torque,
    run_speed_limit,
    validate_state,
)

__all__ = ['ENERGY_TOL', 'Stepper']


class Stepper:
    """Advance one pendulum by a fixed step ``h``, guarded, with its energy balance.

    Parameters
    ----------
    params : PendulumParams
        The physical parameters; replace them live with :meth:`set_params`.
    phi0, dphi0 : float
        Initial angle (rad) and angular velocity (rad/s); see ``model.validate_state``.
    h : float
        The fixed step in s (> 0, h ω0 <= 100).
    method : str
        A name of ``METHODS``: ``'rk4'`` (default, the paper's), ``'euler'``, ``'midpoint'``,
        ``'sdirk2'``, ``'sdirk3'``, or the adaptive ``'dopri5'``, ``'dop853'``, ``'rodas4'``
        (linearly implicit, for long stiff runs), ``'extrap6'`` and ``'extrap8'``,
        error-controlled inside each step of h.
    guard : bool
        Keep explicit steps inside their stability region (substeps or implicit fallback).
    energy_check : bool
        Redo an explicit step implicitly when energy rose without input (γ > 0).
    rtol, atol : float
        Tolerances of the adaptive method.
    jit : bool
        Run the adaptive method's steps compiled to machine code by numba (the ``jit`` extra;
        ``jit.py``): the same steps and decisions, 7.7–15.4× less time per step
        (``bench/bench_jit.py``), after a compile of 0.7–2.3 s per method and exponent (once
        per process).
    """

    def __init__(self, params: PendulumParams, phi0: float, dphi0: float, h: float,
                 method: str = 'rk4', *, guard: bool = True, energy_check: bool = True,
                 rtol: float = 1e-8, atol: float = 1e-10, jit: bool = False) -> None:
        if not isinstance(params, PendulumParams):
            raise ModelError(f'params must be PendulumParams, got {type(params).__name__}')
        self._method: Method = get_method(method)
        self._h = check_step(h, self._limited(params))
        self._rtol = check_tolerance('rtol', rtol)
        self._atol = check_tolerance('atol', atol)
        self._guard_on = check_flag('guard', guard)
        self._energy_check = check_flag('energy_check', energy_check)
        self._jit = check_jit(jit, self._method.name, self._method.family.error_controlled)
        self._initial = validate_state(phi0, dphi0, params)
        self.stats = GuardStats()
        self._configure(params)
        self.reset()

    # ------------------------------------------------------------------ configuration
    def _configure(self, params: PendulumParams) -> None:
        self._params = params
        eng = Engine(params.omega0_sq, params.gamma, params.n, self._method, self._guard_on,
                     self._energy_check, self._rtol, self._atol, self._jit,
                     params.friction_accel)
        self._engine = eng
        self._cf = eng.cf  # the friction beside the law, f/I: the fast step's input moves
        self._inv_inertia = 1.0 / params.inertia
        self._max_torque = MAX_INPUT_ACCEL * params.inertia
        # The state bound, held along a run; not on plain unguarded steps (their work does not
        # grow with the speed, and their divergence is the answer they were asked for).
        self._max_speed = math.inf if eng.unguarded else run_speed_limit(
            params.gamma, params.n, params.omega0_sq)
        self._fast = eng.fast  # the generated fast path exists
        # The method's Advance (everything the fast path refuses), with fresh memory: a new
        # pendulum or method starts its adaptive substeps afresh.
        self._slow = eng.fresh_advance()
        self._coulomb = eng.coulomb
        self._fast_fn = compile_fast_step(eng.plain_tableau, eng.n, eng.nonsmooth, eng.reach,
                                          eng.v_acc, eng.energy_check, eng.w2, eng.gamma)
        self._e = math.nan  # E/I of the current state where the fast path knows it
        self._range_ain = math.nan  # the a_in the cached fast range is for
        self._lo, self._hi = math.inf, -math.inf

    def set_params(self, params: PendulumParams) -> None:
        """Replace the physical parameters from the next step on; the state is kept.

        ``n`` and ``γ`` may change while running (the node's live parameters): the state
        (φ, φ') is continuous, only the vector field changes.
        """
        if not isinstance(params, PendulumParams):
            raise ModelError(f'params must be PendulumParams, got {type(params).__name__}')
        check_step(self._h, self._limited(params))
        self._configure(params)

    def _limited(self, params: PendulumParams) -> PendulumParams | None:
        """Return the parameters that bound h (none for the adaptive method: h is its output
        spacing and its substeps are error-controlled)."""
        return params if self._method.fixed_step else None

    def reset(self, phi0: float | None = None, dphi0: float | None = None) -> None:
        """Return to t = 0 and the initial state (or a new one), clearing work and counters."""
        if phi0 is not None or dphi0 is not None:
            self._initial = validate_state(self._initial[0] if phi0 is None else phi0,
                                           self._initial[1] if dphi0 is None else dphi0,
                                           self._params)
        self._p, self._v = self._initial
        self._e = math.nan
        self._steps = 0
        self._work_damping = 0.0  # per unit inertia, J / (kg m²)
        self._work_input = 0.0  # J
        self._e0 = self.energy()
        self._slow = self._engine.fresh_advance()  # no trial-step memory across a reset
        self.stats = GuardStats()

    # ------------------------------------------------------------------ state
    @property
    def params(self) -> PendulumParams:
        """Return the current physical parameters."""
        return self._params

    @property
    def method(self) -> str:
        """Return the method's name."""
        return self._method.name

    @property
    def engine(self) -> Engine:
        """Return the engine that takes the decisions for the current parameters and method."""
        return self._engine

    @property
    def h(self) -> float:
        """Return the fixed step in s."""
        return self._h

    @property
    def steps(self) -> int:
        """Return the number of steps of h taken since the last reset."""
        return self._steps

    @property
    def t(self) -> float:
        """Return the simulated time, ``steps · h`` (no accumulated round-off)."""
        return self._steps * self._h

    @property
    def phi(self) -> float:
        """Return the angle φ in rad."""
        return self._p

    @property
    def dphi(self) -> float:
        """Return the angular velocity φ' in rad/s."""
        return self._v

    def energy(self) -> float:
        """Return the mechanical energy E = ½ I φ'² + m g l (1 − cos φ) in J (eq 23)."""
        p = self._params
        s = math.sin(0.5 * self._p)
        return 0.5 * p.inertia * self._v * self._v + 2.0 * p.mgl * s * s

    @property
    def dissipated_work(self) -> float:
        """Return ∫ (γ I |φ'|^(n+1) + f |φ'|) dt since the reset, in J (eq 26, friction f)."""
        return self._work_damping * self._params.inertia

    @property
    def input_work(self) -> float:
        """Return ∫ τ φ' dt since the reset, in J."""
        return self._work_input

    @property
    def residual(self) -> float:
        """Return the energy-balance residual E(t) − E(0) + ∫ dissipated − ∫ input, in J."""
        return self.energy() - self._e0 + self.dissipated_work - self._work_input

    # ------------------------------------------------------------------ stepping
    def advance(self, k: int, torque: float = 0.0) -> None:
        """Take ``k`` steps of h with constant torque."""
        for _ in range(k):
            self._advance(self._h, torque, 1)

    def step(self, torque: float = 0.0) -> None:
        """Advance one step h under the constant input torque ``torque`` (N m)."""
        self._advance(self._h, torque, 1)

    def step_by(self, h: float, torque: float = 0.0) -> None:
        """Advance by a one-off step ``h`` (for landing on an end time); ``t`` is not moved."""
        self._range_ain = math.nan
        self._advance(check_step(h, self._limited(self._params)), torque, 0)
        self._range_ain = math.nan

    def _advance(self, h: float, torque: float, count: int) -> None:
        if type(torque) is not float or not abs(torque) <= self._max_torque:  # also NaN
            torque = check_torque(torque, self._params)
        ain = torque * self._inv_inertia
        p, v = self._p, self._v
        if self._fast:
            if ain != self._range_ain:
                self._lo, self._hi = self._engine.fast_range(h, ain)
                if self._coulomb:  # at rest, Coulomb friction decides: never the fast path
                    self._lo = max(self._lo, 5e-324)
                self._range_ain = ain
            r = None
            if self._lo <= abs(v) <= self._hi:
                cf = self._cf  # moving in the direction of v, the friction is an input
                try:
                    r = self._fast_fn(p, v, h, moving_input(ain, v, cf) if cf else ain, self._e)
                except (OverflowError, ValueError):
                    r = None
                if r is not None and cf:
                    r = (r[0], r[1], r[2] + friction_work(cf, v, p, r[0]), r[3])
            if r is None:
                self._engine.check_ahead(v, h, ain, self._steps * self._h)
                p1, v1, w = self._slow(p, v, h, ain, self.stats)
                self._e = math.nan
            else:
                p1, v1, w, self._e = r
        else:
            self._engine.check_ahead(v, h, ain, self._steps * self._h)
            p1, v1, w = self._slow(p, v, h, ain, self.stats)
        if not abs(v1) <= self._max_speed:
            params = self._params
            self._e = math.nan  # the state stays (p, v)
            check_speed(v1, params.gamma, params.n, params.omega0_sq, self._steps * self._h + h)
        self._work_damping += w
        self._work_input += torque * (p1 - p)
        self._p, self._v = p1, v1
        self.stats.steps += 1
        self._steps += count

    # ------------------------------------------------------------------ diagnostics
    def local_error_estimate(self, torque: float = 0.0) -> float:
        """Return a step-doubling estimate of the local error of the next step (state kept).

        One step h against two steps h/2 of the same method with the same safeguards, scaled
        by 1 / (2^p − 1): the 2-norm over (φ, φ') of the error the next step will make, in rad
        and rad/s.
        """
        if type(torque) is not float or not abs(torque) <= self._max_torque:
            torque = check_torque(torque, self._params)
        ain = torque * self._inv_inertia
        p, v, h = self._p, self._v, self._h
        scratch = GuardStats()
        eng = self._engine

        def take(pp: float, vv: float, hh: float) -> tuple[float, float]:
            r = eng.fresh_advance()(pp, vv, hh, ain, scratch)
            return r[0], r[1]

        pa, va = take(p, v, h)
        pb, vb = take(p, v, 0.5 * h)
        pb, vb = take(pb, vb, 0.5 * h)
        return math.hypot(pa - pb, va - vb) / (2.0 ** self._method.order - 1.0)
