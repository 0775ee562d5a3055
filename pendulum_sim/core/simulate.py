"""``simulate``: one call from parameters and an initial state to sampled numpy arrays."""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .embedded import BudgetSpent, CoverFailed
from .guard import GuardStats
from .model import (
    MAX_RUN_TRIALS,
    MAX_STEPS,
    FloatArray,
    PendulumParams,
    check_count,
    check_run_length,
    check_speed,
    check_torque,
    energy,
    oscillation_trials,
    run_speed_limit,
    run_work_refusal,
)
from .stepper import Stepper

TorqueInput = float | Callable[[float, float, float], float] | None


@dataclass(frozen=True)
class Trajectory:
    """A sampled run: arrays over the output times ``t`` (s), from 0 to exactly ``t_end``."""

    t: FloatArray
    phi: FloatArray
    dphi: FloatArray
    energy: FloatArray
    dissipated_work: FloatArray
    input_work: FloatArray
    torque: FloatArray
    stats: GuardStats
    params: PendulumParams
    method: str
    h: float

    @property
    def residual(self) -> FloatArray:
        """Return the energy-balance residual E(t) − E(0) + ∫ dissipated − ∫ input, in J."""
        return np.asarray(self.energy - self.energy[0] + self.dissipated_work - self.input_work)

    @property
    def state(self) -> FloatArray:
        """Return the states as an array of shape (len(t), 2): columns φ, φ'."""
        return np.column_stack([self.phi, self.dphi])


def step_count(t_end: float, h: float) -> tuple[int, float]:
    """Return the number of full steps of ``h`` in ``t_end`` and the length of a last partial one.

    Rounds instead of truncating: 0.7 / 0.001 = 699.999… is 700 steps, not 699 (the seed code's
    bug). A remainder below 1e-9 h is round-off, not a step.
    """
    ratio = t_end / h
    k = round(ratio)
    if abs(ratio - k) <= 1e-9 * max(1.0, ratio):
        return k, 0.0
    k = math.floor(ratio)
    return k, t_end - k * h


def simulate(params: PendulumParams, phi0: float, dphi0: float, t_end: float, h: float,
             method: str = 'rk4', *, torque: TorqueInput = None, guard: bool = True,
             energy_check: bool = True, rtol: float = 1e-8, atol: float = 1e-10,
             record_every: int = 1, max_steps: int = MAX_STEPS,
             jit: bool = False) -> Trajectory:
    """Integrate the pendulum from ``(phi0, dphi0)`` over ``[0, t_end]`` with step ``h``.

    Parameters
    ----------
    params : PendulumParams
        Physical parameters.
    phi0, dphi0 : float
        Initial angle (rad) and angular velocity (rad/s).
    t_end : float
        Final time in s (> 0); the last sample lands exactly on it.
    h : float
        Step in s. For the adaptive methods it is the output spacing; the method chooses its own
        substeps to meet ``rtol``/``atol`` and lands one on every output, or, for methods of
        order ≤ 4 (``'rodas4'``) with a constant torque, runs them freely across the outputs,
        which are then interpolated (``embedded.dense_run``).
    method : str
        A name in ``METHODS`` (default ``'rk4'``, the paper's).
    torque : float or callable, optional
        External torque τ in N m: a constant, or ``torque(t, phi, dphi)`` evaluated at the start
        of each step and held over it (a zero-order hold, as a controller would apply it).
    guard, energy_check : bool
        See :class:`Stepper`.
    record_every : int
        Keep every k-th step (the last step is always kept).
    max_steps : int
        Refuse runs of more steps than this (default ``MAX_STEPS`` = 1e8), with the reason.
        An adaptive method's run also stops, with the reason, once it has spent
        ``MAX_RUN_TRIALS`` (1e6) trial substeps (refused at once where its swing alone is
        estimated to need more, ``model.oscillation_trials``): its work is bounded by both.
    jit : bool
        Run an adaptive method's steps compiled by numba (see :class:`Stepper`).

    Returns
    -------
    Trajectory
    """
    record_every = check_count('record_every', record_every)
    max_steps = check_count('max_steps', max_steps)
    stepper = Stepper(params, phi0, dphi0, h, method, guard=guard, energy_check=energy_check,
                      rtol=rtol, atol=atol, jit=jit)
    h = stepper.h
    t_end = check_run_length(t_end, h, max_steps)
    k_full, last = step_count(t_end, h)
    adaptive = not stepper.engine.method.fixed_step
    budget = MAX_RUN_TRIALS if adaptive else 0
    spent = 0  # trial substeps of a dense run that could not run through

    def refusal() -> Exception:
        return run_work_refusal(stepper.method, t_end, rtol, params.omega0_sq, budget)

    if callable(torque):
        tau_of: Callable[[float, float, float], float] = torque
    else:
        tau_const = 0.0 if torque is None else check_torque(torque, params)
        if adaptive and tau_const == 0.0 and oscillation_trials(
                stepper.method, stepper.engine.method.tableau.error_order, t_end,
                stepper.engine.rtol, stepper.engine.atol, params, stepper.phi,
                stepper.dphi) > budget:
            raise refusal()  # before any work: the swing alone needs more than the budget
        if stepper.engine.dense_capable:
            try:
                return _dense(stepper, t_end, k_full, last, record_every, tau_const, budget)
            except BudgetSpent:
                raise refusal() from None
            except CoverFailed:
                # The one cover could not run through: step by step below, where a step the
                # cover fails on is taken by the fallback (``embedded.Cover``).
                spent = stepper.stats.substeps
                stepper.stats = GuardStats()

        def tau_of(t: float, phi: float, dphi: float) -> float:
            return tau_const

    recorded = set(recorded_steps(k_full, last, record_every))
    ps, vs, wd, wi, taus = [stepper.phi], [stepper.dphi], [0.0], [0.0], []
    for k in range(1, k_full + 1):
        tau = tau_of(stepper.t, stepper.phi, stepper.dphi)
        stepper.step(tau)
        if spent + stepper.stats.substeps > budget > 0:
            raise refusal()
        if k in recorded:
            taus.append(tau)
            ps.append(stepper.phi)
            vs.append(stepper.dphi)
            wd.append(stepper.dissipated_work)
            wi.append(stepper.input_work)
    if last > 0.0:
        tau = tau_of(stepper.t, stepper.phi, stepper.dphi)
        stepper.step_by(last, tau)
        if spent + stepper.stats.substeps > budget > 0:
            raise refusal()
        taus.append(tau)
        ps.append(stepper.phi)
        vs.append(stepper.dphi)
        wd.append(stepper.dissipated_work)
        wi.append(stepper.input_work)
    taus.append(taus[-1] if taus else 0.0)
    phi = np.array(ps)
    dphi = np.array(vs)
    return Trajectory(
        t=output_times(t_end, h, k_full, last, record_every), phi=phi, dphi=dphi,
        energy=np.asarray(energy(params, phi, dphi)), dissipated_work=np.array(wd),
        input_work=np.array(wi), torque=np.array(taus), stats=stepper.stats, params=params,
        method=stepper.method, h=h)


def recorded_steps(k_full: int, last: float, record_every: int) -> list[int]:
    """Return the full steps of h after which a run keeps a sample.

    Every ``record_every``-th, and the last one where it ends the run (no partial step
    ``last`` follows; a partial step is always kept).
    """
    ks = list(range(record_every, k_full + 1, record_every))
    if last == 0.0 and k_full and (not ks or ks[-1] != k_full):
        ks.append(k_full)
    return ks


def output_times(t_end: float, h: float, k_full: int, last: float,
                 record_every: int) -> FloatArray:
    """Return the sample times of a run: 0, the :func:`recorded_steps` times k h, ``t_end``."""
    ks = recorded_steps(k_full, last, record_every)
    t = np.array([0, *ks], dtype=float) * h
    if last > 0.0:
        return np.append(t, t_end)
    if ks:
        t[-1] = t_end  # the last full step ends the run: exactly t_end
    return t


def _dense(stepper: Stepper, t_end: float, k_full: int, last: float, record_every: int,
           tau: float, budget: int) -> Trajectory:
    """Run an adaptive method over all outputs in one cover (``embedded.dense_run``)."""
    params = stepper.params
    t = output_times(t_end, stepper.h, k_full, last, record_every)
    p0, v0 = stepper.phi, stepper.dphi
    stepper.engine.check_ahead(v0, stepper.h, tau / params.inertia, 0.0)
    phi, dphi, w = stepper.engine.dense(p0, v0, t, tau / params.inertia, stepper.stats,
                                        budget)
    phi[0], dphi[0], w[0] = p0, v0, 0.0
    lim = run_speed_limit(params.gamma, params.n, params.omega0_sq)
    fast = np.flatnonzero(~(np.abs(dphi) <= lim))
    if fast.size:
        check_speed(float(dphi[fast[0]]), params.gamma, params.n, params.omega0_sq,
                    float(t[fast[0]]))
    stepper.stats.steps = k_full + (1 if last > 0.0 else 0)
    return Trajectory(
        t=t, phi=phi, dphi=dphi, energy=np.asarray(energy(params, phi, dphi)),
        dissipated_work=w * params.inertia, input_work=tau * (phi - p0),
        torque=np.full(len(t), tau), stats=stepper.stats, params=params,
        method=stepper.method, h=stepper.h)

