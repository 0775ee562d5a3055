"""The core API's second and third hardening passes: tolerances, work bounds, torque and flag
types, huge integers, a huge damping exponent, a step that must pass the speed bound. Each
input is refused with the core's own message naming the argument and its limit, or gives a
finite, energy-consistent result; work is asserted as counted steps, never as time."""
from __future__ import annotations

import importlib
import math
import re
import subprocess
import sys
from decimal import Decimal
from typing import Any

import numpy as np
import pytest

from pendulum_sim.core import (
    METHODS,
    GuardStats,
    IntegratorError,
    ModelError,
    PendulumParams,
    Stepper,
    simulate,
)
from pendulum_sim.core.embedded import MAX_TRIALS, BudgetSpent
from pendulum_sim.core.engine import AheadCheck
from pendulum_sim.core.implicit import fallback_refused
from pendulum_sim.core.model import (
    MAX_RUN_TRIALS,
    MAX_SPEED,
    MAX_TOLERANCE,
    check_speed_ahead,
    oscillation_trials,
    run_speed_limit,
)
from pendulum_sim.core.problem import Problem
from pendulum_sim.core.sweep import sweep

PAPER = PendulumParams()
simulate_module = importlib.import_module('pendulum_sim.core.simulate')  # the package's
# ``simulate`` attribute is the function
ADAPTIVE = ('dopri5', 'dop853', 'rodas4', 'extrap6', 'extrap8')


def loose(name: str, value: str) -> str:
    return f'{name} must be <= 0.001 (the error control cannot honour a looser tolerance), ' \
           f'got {value}'


# --------------------------------------------------------------------------- 11: tolerances


@pytest.mark.parametrize(('method', 'gamma', 'rtol', 'atol', 'message'), [
    ('dopri5', 1e4, 1.0, 1.0, loose('rtol', '1')),        # ran to 3e119 J
    ('dopri5', 1.0, 10.0, 1e-10, loose('rtol', '10')),    # ran to inf
    ('dop853', 1.0, 1e3, 1e-10, loose('rtol', '1000')),   # ran to inf
    ('rodas4', 1.0, 10.0, 1e-10, loose('rtol', '10')),    # energy 2.8 J -> 24 J
    ('dopri5', 1e4, 1e-8, 1.0, loose('atol', '1')),
])
def test_tolerances_that_cannot_be_honoured_are_refused_with_the_limit(
        method: str, gamma: float, rtol: float, atol: float, message: str) -> None:
    params = PAPER.with_changes(gamma=gamma)
    with pytest.raises(IntegratorError, match=f'^{re.escape(message)}$'):
        simulate(params, 2.0, 0.0, 1.0, 1e-3, method, rtol=rtol, atol=atol)
    with pytest.raises(IntegratorError, match=f'^{re.escape(message)}$'):
        Stepper(params, 2.0, 0.0, 1e-3, method, rtol=rtol, atol=atol)


@pytest.mark.parametrize('method', ADAPTIVE)
@pytest.mark.parametrize(('gamma', 'n'), [(0.0, 1.0), (1.0, 1.0), (1.0, 2.0), (1e4, 1.0),
                                          (1.0, 0.5), (1.0, 0.0)])
@pytest.mark.parametrize('h', [1e-3, 1e-1])
def test_the_loosest_tolerances_accepted_give_finite_energy_consistent_runs(
        method: str, gamma: float, n: float, h: float) -> None:
    tol = MAX_TOLERANCE['rtol']
    assert tol == MAX_TOLERANCE['atol'] == 1e-3
    run = simulate(PAPER.with_changes(gamma=gamma, n=n), 2.0, 0.0, 10.0, h, method,
                   rtol=tol, atol=tol)
    assert np.all(np.isfinite(run.state)) and np.all(np.isfinite(run.residual))
    # Unforced: the energy never rises above an earlier value by more than the tolerance
    # (measured: 6.6e-4 of E(0) at most, rodas4 without damping).
    e = run.energy
    assert np.max(e - np.minimum.accumulate(e)) <= tol * e[0]
    # The energy balance: within 5 % of E(0) for the γ = 1e4 creep, whose speeds (1e-3 rad/s)
    # are of atol's size (measured 5.0e-2, dopri5), within 1e-3 elsewhere (measured 4.8e-4).
    assert np.max(np.abs(run.residual)) <= (0.06 if gamma == 1e4 else tol) * e[0]


# --------------------------------------------------------------------------- 12: work bounds


def speed_message(v: str, t: str, bound: str = '10000.012') -> str:
    return (f'dphi reached {v} rad/s at t = {t} s, beyond +-{bound} rad/s (the state bound '
            f'10000 rad/s raised by the most gravity adds, sqrt(bound**2 + 4*omega0**2)): the '
            f'run stops there')


def test_the_speed_bound_holds_along_a_run_under_the_largest_torque() -> None:
    # τ = 2e7 N m on I = 0.2 kg m² is 1e8 rad/s²: one step of 1 ms adds 1e5 rad/s. Before, the
    # run went on to 1e7 rad/s, each step costing more guard substeps than the last.
    params = PAPER.with_changes(gamma=0.0)
    # One step from rest: 1e8 rad/s² for 1 ms, less what gravity takes back: 99999.9992 rad/s.
    exact = f'^{re.escape(speed_message("99999.9992", "0.001"))}$'
    with pytest.raises(IntegratorError, match=exact):
        simulate(params, 0.0, 0.0, 0.002, 1e-3, torque=2e7)
    with pytest.raises(IntegratorError, match=exact):
        simulate(params, 0.0, 0.0, 0.002, 1e-3, torque=lambda t, p, v: 2e7)
    stepper = Stepper(params, 0.0, 0.0, 1e-3)
    with pytest.raises(IntegratorError, match=exact):
        stepper.step(2e7)
    # Nothing is lost: the state is the last one inside the bound, and stepping on works.
    assert (stepper.phi, stepper.dphi, stepper.steps) == (0.0, 0.0, 0)
    stepper.step(1e3)
    assert stepper.steps == 1 and 0.0 < stepper.dphi <= MAX_SPEED


def test_a_run_starting_at_the_state_bound_keeps_running_under_gravity() -> None:
    # Gravity alone moves |φ'| about the bound (E conserved): within sqrt(1e4² + 4 ω0²).
    s = Stepper(PAPER.with_changes(gamma=0.0), 2.0, MAX_SPEED, 1e-4)
    s.advance(100)
    assert s.steps == 100 and MAX_SPEED < s.dphi <= run_speed_limit(0.0, 1.0, 9.8)


def test_sweep_holds_the_speed_bound_and_names_the_pendulum() -> None:
    message = speed_message('99999.9999', '0.001', '10000.0102') + ' (index 1)'
    with pytest.raises(IntegratorError, match=f'^{re.escape(message)}$'):
        sweep(1.0, 0.0, 1.0, 0.0, 0.0, 0.002, 1e-3, torque=[0.0, 1e8])


@pytest.mark.parametrize('method', ADAPTIVE)
def test_the_adaptive_substeps_hold_the_speed_bound(method: str) -> None:
    # Inside a step the error-controlled substeps reject a trial beyond the bound (a loose
    # relative tolerance scales its error by that speed and would accept it); the fallback
    # takes the rest of the step and the run stops after it, with few trials spent.
    exact = f'^{re.escape(speed_message("99999.9992", "0.001"))}$'
    with pytest.raises(IntegratorError, match=exact):
        simulate(PAPER.with_changes(gamma=0.0), 0.0, 0.0, 0.01, 1e-3, method, torque=2e7)
    stepper = Stepper(PAPER.with_changes(gamma=0.0), 0.0, 0.0, 1e-3, method)
    with pytest.raises(IntegratorError, match=exact):
        stepper.step(2e7)
    assert stepper.stats.fallbacks == 1 and stepper.stats.substeps < 100  # measured 32-45
    assert (stepper.phi, stepper.dphi, stepper.steps) == (0.0, 0.0, 0)


@pytest.mark.parametrize('g', [4e10, 1e11])
def test_adaptive_work_at_a_huge_gravity_is_bounded_by_the_trial_budget(g: float) -> None:
    # ω0 = 2e5-3e5 s⁻¹ from φ = 2 rad: every output interval costs at most MAX_TRIALS trial
    # substeps (before, at g = 1e11, the cover ran out of them and the fallback took 1e5
    # substeps a step, for minutes).
    run = simulate(PAPER.with_changes(g=g), 2.0, 0.0, 0.003, 1e-3, 'dopri5')
    assert run.stats.steps == 3
    assert 0 < run.stats.substeps <= MAX_TRIALS * run.stats.steps
    assert np.all(np.isfinite(run.residual))


def test_adaptive_work_is_bounded_by_the_trial_budget_per_output() -> None:
    # g = 1e11 at a small amplitude stays inside the speed bound: each output interval costs at
    # most MAX_TRIALS trial substeps, so the work is at most MAX_TRIALS t_end / h.
    run = simulate(PAPER.with_changes(g=1e11), 1e-3, 0.0, 0.01, 1e-3, 'dopri5')
    assert run.stats.steps == 10
    assert 0 < run.stats.substeps <= MAX_TRIALS * run.stats.steps
    assert np.all(np.isfinite(run.residual))


BUDGET_MESSAGE = (
    'dopri5 needs more than MAX_RUN_TRIALS = 5000 trial substeps for t_end = 0.01 s at rtol = '
    '1e-08 (omega0 = 316228 rad/s: 3.16e+03 rad of oscillation), beyond the work budget of one '
    'call: shorten t_end, loosen rtol or simulate the run in parts')


@pytest.mark.parametrize('torque', [0.0, 1e-12, lambda t, p, v: 0.0],
                         ids=['up front', 'dense', 'stepwise'])
def test_an_adaptive_run_stops_at_its_trial_budget_with_the_reason(
        monkeypatch: pytest.MonkeyPatch, torque: Any) -> None:
    # g = 1e11: 3.2e3 rad of oscillation in 0.01 s take dopri5 35 000 trial substeps at rtol
    # 1e-8 (3.5e6 for one second). Without input the swing's estimate (15 000) refuses it at
    # once; with a torque the run stops once it has spent the budget, both when it runs as one
    # cover (a constant) and output by output (a callable). A budget of 5000 stands for
    # MAX_RUN_TRIALS here, whose 1e6 trials take seconds.
    monkeypatch.setattr(simulate_module, 'MAX_RUN_TRIALS', 5000)
    with pytest.raises(IntegratorError, match=f'^{re.escape(BUDGET_MESSAGE)}$'):
        simulate(PAPER.with_changes(g=1e11), 1e-3, 0.0, 0.01, 1e-3, 'dopri5', torque=torque)


def test_a_swing_beyond_the_budget_is_refused_before_any_work() -> None:
    params = PAPER.with_changes(g=1e11)
    need = oscillation_trials('dopri5', 4, 1.0, 1e-8, 1e-10, params, 2.0, 0.0)
    assert need > MAX_RUN_TRIALS  # 1.5e6 estimated, 3.5e6 counted a second of this swing
    message = BUDGET_MESSAGE.replace('5000', '1000000').replace('0.01 s', '1 s').replace(
        '3.16e+03', '3.16e+05')
    with pytest.raises(IntegratorError, match=f'^{re.escape(message)}$'):
        simulate(params, 2.0, 0.0, 1.0, 1e-3, 'dopri5')


@pytest.mark.parametrize('method', ADAPTIVE)
@pytest.mark.parametrize(('phi0', 'gamma', 'rtol'), [(1e-3, 0.0, 1e-3), (2.0, 1.0, 1e-6)])
def test_the_swing_estimate_stays_below_the_trials_counted(
        method: str, phi0: float, gamma: float, rtol: float) -> None:
    # 300 rad of swing at g = 1e9 (omega0 = 3.2e4 s^-1), undamped and damped.
    params = PAPER.with_changes(g=1e9, gamma=gamma)
    t_end = 300.0 / math.sqrt(params.omega0_sq)
    run = simulate(params, phi0, 0.0, t_end, t_end / 10, method, rtol=rtol, atol=1e-10)
    need = oscillation_trials(method, METHODS[method].tableau.error_order, t_end, rtol, 1e-10,
                              params, phi0, 0.0)
    assert 0.0 < need < run.stats.steps + run.stats.substeps


def test_the_swing_estimate_claims_nothing_where_damping_may_end_the_swing() -> None:
    # The paper's pendulum (gamma = 1 s^-1) over 100 s: the damping may bring the speed
    # scale below atol/rtol, where the error control no longer follows the swing.
    assert oscillation_trials('dopri5', 4, 100.0, 1e-8, 1e-10, PAPER, 2.0, 0.0) == 0.0
    assert oscillation_trials('dopri5', 4, 1.0, 1e-8, 1e-10, PAPER, 2.0, 0.0) > 0.0
    assert oscillation_trials('dopri5', 4, 1.0, 1e-8, 1e-10, PAPER, 0.0, 0.0) == 0.0  # at rest


def test_the_dense_run_spends_exactly_its_budget_before_it_stops() -> None:
    stepper = Stepper(PAPER.with_changes(g=1e11), 1e-3, 0.0, 1e-3, 'dopri5')
    stats = GuardStats()
    with pytest.raises(BudgetSpent):
        stepper.engine.dense(1e-3, 0.0, np.linspace(0.0, 0.01, 11), 0.0, stats, 5000)
    assert stats.substeps == 5001
    # Without a budget the same run takes what it needs (no stop, more trial substeps).
    free = GuardStats()
    stepper.engine.dense(1e-3, 0.0, np.linspace(0.0, 0.01, 11), 0.0, free)
    assert free.substeps > 5001


def test_the_trial_budget_leaves_fixed_step_methods_to_max_steps() -> None:
    # rk4 at g = 1e11 is refused by its step (h omega0 <= 100), not by a trial budget.
    run = simulate(PAPER.with_changes(g=1e11), 1e-3, 0.0, 0.01, 1e-5, 'rk4')
    assert run.stats.steps == 1000 and MAX_RUN_TRIALS == 1_000_000


def too_many_fallback_substeps(h: str) -> str:
    """Return the pattern of the whole refusal of a step of ``h`` s from phi = 2, dphi = 0
    that the fallback cannot cover in MAX_FALLBACK_SUBSTEPS = 100000 substeps."""
    message = (f'a step of {h} s from phi = 2 rad, dphi = 0 rad/s needs more than '
               'MAX_FALLBACK_SUBSTEPS = 100000 substeps of the fallback (each sweeps at most '
               '0.5 rad); use a smaller h')
    return f'^{re.escape(message)}$'


@pytest.mark.parametrize('method', ['rodas4', 'dopri5'])
def test_an_output_the_fallback_cannot_cover_in_bounded_substeps_is_refused(method: str) -> None:
    # One output at 1e20 s: where the error-controlled substeps give up, the fallback would
    # need 1e20 substeps of at most 0.5 rad (before: it ran unbounded).
    with pytest.raises(IntegratorError, match=too_many_fallback_substeps('1e+20')):
        simulate(PAPER, 2.0, 0.0, 1e20, 1e20, method)


# --------------------------------------------------------------------------- 13: h = 1e300


@pytest.mark.parametrize('method', ['dopri5', 'rodas4', 'extrap6'])
def test_a_huge_guarded_step_is_refused_for_what_it_is(method: str) -> None:
    # Before: "the unguarded ... step diverged; run with guard=True", with the guard on.
    with pytest.raises(IntegratorError, match=too_many_fallback_substeps('1e+300')):
        simulate(PAPER, 2.0, 0.0, 1e300, 1e300, method)
    with pytest.raises(IntegratorError, match=too_many_fallback_substeps('1e+300')):
        Stepper(PAPER, 2.0, 0.0, 1e300, method, guard=True).step()


# --------------------------------------------------------------------------- 14: torque types

BAD_TORQUES: list[tuple[Any, str]] = [
    (np.complex128(1), 'torque must be a real number, got np.complex128(1+0j)'),
    (1 + 0j, 'torque must be a real number, got (1+0j)'),
    (True, 'torque must be a real number, got True'),
    (np.bool_(True), 'torque must be a real number, got np.True_'),
    ('1', "torque must be a real number, got '1'"),
    (np.array([1.0]), 'torque must be a real number, got array([1.])'),
    (np.array([1.0, 2.0]), 'torque must be a real number, got array([1., 2.])'),
    (float('nan'), 'torque must be finite, got nan'),
]


@pytest.mark.parametrize(('torque', 'message'), BAD_TORQUES)
def test_every_entry_point_refuses_a_torque_that_is_not_one_real_number(
        torque: Any, message: str) -> None:
    exact = f'^{re.escape(message)}$'
    stepper = Stepper(PAPER, 1.0, 0.0, 1e-3)
    with pytest.raises(ModelError, match=exact):
        stepper.step(torque)
    with pytest.raises(ModelError, match=exact):
        stepper.advance(2, torque)
    with pytest.raises(ModelError, match=exact):
        stepper.step_by(5e-4, torque)
    with pytest.raises(ModelError, match=exact):
        stepper.local_error_estimate(torque)
    assert stepper.steps == 0 and isinstance(stepper.dphi, float)
    with pytest.raises(ModelError, match=exact):
        simulate(PAPER, 1.0, 0.0, 0.01, 1e-3, torque=torque)
    with pytest.raises(ModelError, match=exact):
        simulate(PAPER, 1.0, 0.0, 0.01, 1e-3, torque=lambda t, p, v: torque)
    with pytest.raises(ModelError, match=exact):
        simulate(PAPER, 1.0, 0.0, 0.01, 1e-3, 'dopri5', torque=torque)
    if np.ndim(torque) == 0:  # sweep takes an array of torques, one per pendulum
        with pytest.raises(ModelError, match=exact):
            sweep(9.8, 1.0, 1.0, 1.0, 0.0, 0.01, 1e-3, torque=torque)


def test_none_is_no_torque_in_simulate_and_refused_by_the_stepper() -> None:
    message = 'torque must be a real number, got None'
    with pytest.raises(ModelError, match=f'^{re.escape(message)}$'):
        Stepper(PAPER, 1.0, 0.0, 1e-3).step(None)  # type: ignore[arg-type]
    with pytest.raises(ModelError, match=f'^{re.escape(message)}$'):
        sweep(9.8, 1.0, 1.0, 1.0, 0.0, 0.01, 1e-3, torque=None)
    free = simulate(PAPER, 1.0, 0.0, 0.01, 1e-3, torque=None)
    assert np.all(free.torque == 0.0)


def test_a_decimal_torque_is_the_real_number_it_spells() -> None:
    a, b = Stepper(PAPER, 1.0, 0.0, 1e-3), Stepper(PAPER, 1.0, 0.0, 1e-3)
    a.step(Decimal('0.25'))  # type: ignore[arg-type]
    b.step(0.25)
    assert (a.phi, a.dphi) == (b.phi, b.dphi) and type(a.dphi) is float
    run = simulate(PAPER, 1.0, 0.0, 0.01, 1e-3, torque=Decimal('0.25'))  # type: ignore[arg-type]
    assert run.torque.dtype == np.float64 and np.all(run.torque == 0.25)


# --------------------------------------------------------------------------- 15: huge integers

HUGE = 10 ** 400
BITS = 'an integer of 1329 bits'


@pytest.mark.parametrize(('call', 'error', 'message'), [
    (lambda: PendulumParams(m=HUGE), ModelError, f'm must be finite, got {BITS} (beyond float64)'),
    (lambda: PendulumParams(g=HUGE), ModelError, f'g must be finite, got {BITS} (beyond float64)'),
    (lambda: PendulumParams(n=HUGE), ModelError, f'n must be finite, got {BITS} (beyond float64)'),
    (lambda: simulate(PAPER, HUGE, 0.0, 1.0, 1e-3), ModelError,
     f'phi0 must be finite, got {BITS} (beyond float64)'),
    (lambda: simulate(PAPER, 1.0, HUGE, 1.0, 1e-3), ModelError,
     f'dphi0 must be finite, got {BITS} (beyond float64)'),
    (lambda: simulate(PAPER, 1.0, 0.0, HUGE, 1e-3), ModelError,
     f't_end must be finite, got {BITS} (beyond float64)'),
    (lambda: simulate(PAPER, 1.0, 0.0, 1.0, HUGE), IntegratorError,
     f'h must be a finite step > 0 s, got {BITS}'),
    (lambda: simulate(PAPER, 1.0, 0.0, 1.0, 1e-3, 'dopri5', rtol=HUGE), IntegratorError,
     f'rtol must be a finite tolerance > 0, got {BITS}'),
    (lambda: simulate(PAPER, 1.0, 0.0, 1.0, 1e-3, torque=HUGE), ModelError,
     f'torque must be finite, got {BITS} (beyond float64)'),
    (lambda: sweep(9.8, 1.0, 1.0, 1.0, 0.0, HUGE, 1e-3), ModelError,
     f't_end must be finite, got {BITS} (beyond float64)'),
    (lambda: sweep(HUGE, 1.0, 1.0, 1.0, 0.0, 1.0, 1e-3), ModelError,
     f'omega0_sq must be finite, got {BITS} (beyond float64)'),
    (lambda: sweep(9.8, 1.0, 1.0, 1.0, 0.0, 1.0, HUGE), IntegratorError,
     f'h must be a finite step > 0 s, got {BITS}'),
])
def test_integers_beyond_float64_are_refused_naming_the_argument(
        call: Any, error: type[Exception], message: str) -> None:
    with pytest.raises(error, match=f'^{re.escape(message)}$'):
        call()


# --------------------------------------------------------------------------- 16: flags


@pytest.mark.parametrize(('flag', 'value', 'shown'), [
    ('energy_check', 'no', "'no'"),
    ('energy_check', None, 'None'),
    ('energy_check', np.array([True, False]), 'array([ True, False])'),
    ('guard', np.array([True, False]), 'array([ True, False])'),
    ('guard', 1, '1'),
])
def test_flags_are_true_or_false_in_sweep_simulate_and_the_stepper(
        flag: str, value: Any, shown: str) -> None:
    exact = f'^{re.escape(f"{flag} must be True or False, got {shown}")}$'
    with pytest.raises(IntegratorError, match=exact):
        sweep([9.8, 9.8], 1.0, 1.0, 1.0, 0.0, 0.01, 1e-3, **{flag: value})
    with pytest.raises(IntegratorError, match=exact):
        simulate(PAPER, 1.0, 0.0, 0.01, 1e-3, **{flag: value})
    with pytest.raises(IntegratorError, match=exact):
        Stepper(PAPER, 1.0, 0.0, 1e-3, **{flag: value})


def test_numpy_booleans_are_flags() -> None:
    yes: Any = np.True_
    no: Any = np.False_
    a = sweep(9.8, 1.0, 1.0, 1.0, 0.0, 0.01, 1e-3, guard=yes, energy_check=no)
    b = sweep(9.8, 1.0, 1.0, 1.0, 0.0, 0.01, 1e-3, guard=True, energy_check=False)
    assert a.phi[0] == b.phi[0] and a.dphi[0] == b.dphi[0]


# --------------------------------------------------------------------------- 17: a huge n


def capped_swing(t: float) -> float:
    """Return φ(t) from 2 rad at rest for n -> inf, γ = 1, ω0² = 9.8: the damping γ |φ'|^n is
    0 below 1 rad/s and unbounded above, a speed cap. The undamped fall until |φ'| = 1, where
    ½ φ'² = ω0² (cos φ − cos 2), takes t1 = ∫ dφ / sqrt(2 ω0² (cos φ − cos 2)) (eq 23); then
    gravity still pulls (sin φ > 0) and the cap holds |φ'| = 1."""
    from scipy.integrate import quad

    w2, c2 = PAPER.omega0_sq, math.cos(2.0)
    phi1 = math.acos(c2 + 1.0 / (2.0 * w2))
    # φ = 2 − u²: the integrand's square-root singularity at φ = 2 is gone.
    t1, _ = quad(lambda u: 2.0 * u / math.sqrt(2.0 * w2 * (math.cos(2.0 - u * u) - c2)), 0.0,
                 math.sqrt(2.0 - phi1), epsabs=1e-14, epsrel=1e-13)
    assert t < t1 + (phi1 - 0.2)  # still on the cap
    return phi1 - (t - t1)


@pytest.mark.parametrize('method', METHODS)
def test_a_huge_damping_exponent_gives_the_speed_capped_swing(method: str) -> None:
    # v ** (n − 1) overflowed in the work estimate of the adaptive methods (OverflowError).
    run = simulate(PendulumParams(n=1e300), 2.0, 0.0, 1.0, 1e-3, method)
    assert np.isfinite(run.phi).all() and np.isfinite(run.energy).all()
    # Adaptive methods to 1e-8 rad; the fixed steps meet the cap within a step of h = 1 ms
    # (measured 4.5e-7 rad for RK4).
    tol = 1e-8 if method in ADAPTIVE else 1e-6
    assert abs(run.phi[-1] - capped_swing(1.0)) < tol
    assert np.abs(run.dphi).max() <= 1.0 + 1e-12


def test_the_swing_estimate_takes_a_huge_exponent() -> None:
    # A lower estimate: the damping may end the swing at once, so no work is claimed.
    assert oscillation_trials('rodas4', 3, 1.0, 1e-8, 1e-10, PendulumParams(n=1e300),
                              2.0, 0.0) == 0.0


# --------------------------------------------------------------------------- 18: a step that
# cannot end inside the speed bound


def ahead_message(h: str, t: str, ain: str, c: str, v: str, least: str,
                  bound: str = '10000.012') -> str:
    return (f'dphi would pass +-{bound} rad/s within the step of h = {h} s from t = {t} s: '
            f'torque/I = {ain} rad/s^2 outweighs gravity and damping below that bound by {c} '
            f'rad/s^2, so from dphi = {v} rad/s it reaches at least {least} rad/s: the run '
            f'stops there, before the step')


@pytest.mark.parametrize('method', METHODS)
def test_a_step_too_long_to_work_through_that_must_pass_the_speed_bound_is_refused_first(
        method: str) -> None:
    # τ/I = 1e8 rad/s² for h = 0.3 s adds 3e7 rad/s: RK4 took 1.8e7 guard substeps (81 s)
    # before the speed bound refused the step; now nothing is stepped.
    params = PAPER.with_changes(gamma=0.0)
    exact = f'^{re.escape(ahead_message("0.3", "0", "1e+08", "1e+08", "0", "3e+07"))}$'
    with pytest.raises(IntegratorError, match=exact):
        simulate(params, 0.0, 0.0, 10.0, 0.3, method, torque=2e7)
    stepper = Stepper(params, 0.0, 0.0, 0.3, method)
    stepper.step(1.0)
    p, v, before = stepper.phi, stepper.dphi, stepper.stats.as_dict()
    c = 1e8 - params.omega0_sq   # no damping: only gravity holds the torque back
    later = ahead_message('0.3', '0.3', '1e+08', '1e+08', f'{v:g}', f'{v + c * 0.3:.6g}')
    with pytest.raises(IntegratorError, match=f'^{re.escape(later)}$'):
        stepper.step(2e7)
    assert (stepper.phi, stepper.dphi, stepper.steps) == (p, v, 1)
    assert stepper.stats.as_dict() == before    # no work spent on it
    stepper.step(1.0)   # the run goes on from the state it kept
    assert stepper.steps == 2


# The case on the sweep: ω0² = 9.8 s⁻², no damping, τ/I = 1e8 rad/s² for h = 0.3 s.
SWEEP_AHEAD = (9.8, 0.0, 1.0, 0.0, 0.0, 10.0, 0.3)
SWEEP_AHEAD_MESSAGE = ahead_message('0.3', '0', '1e+08', '1e+08', '0', '3e+07')


@pytest.mark.parametrize('jit', [False, True])
def test_the_sweep_refuses_ahead_what_simulate_and_the_stepper_refuse_ahead(jit: bool) -> None:
    # Before, the numpy sweep worked through the guard's substeps for more than 30 s and the
    # compiled one for 4 s, each refusing only after the step ('dphi reached 3e+07 rad/s').
    if jit:
        pytest.importorskip('numba')
    params = PendulumParams.from_omega0_sq(9.8, 0.0, 1.0)
    exact = f'^{re.escape(SWEEP_AHEAD_MESSAGE)}$'
    with pytest.raises(IntegratorError, match=exact):
        simulate(params, 0.0, 0.0, 10.0, 0.3, torque=1e8 * params.inertia)
    with pytest.raises(IntegratorError, match=exact):
        Stepper(params, 0.0, 0.0, 0.3).step(1e8 * params.inertia)
    with pytest.raises(IntegratorError, match=exact):
        sweep(*SWEEP_AHEAD, torque=1e8, jit=jit)
    # Among pendulums that go on, the one refused ahead is refused alike.
    with pytest.raises(IntegratorError, match=exact):
        sweep(9.8, 0.0, 1.0, [0.5, 0.0, 1.0], 0.0, 10.0, 0.3, torque=[1.0, 1e8, -1.0],
              jit=jit)


@pytest.mark.parametrize(('gamma', 'n'), [(0.0, 1.0), (0.5, 0.0), (100.0, 0.01), (0.1, 2.0)])
def test_the_check_ahead_decided_once_per_step_and_torque_is_the_full_check(gamma: float,
                                                                           n: float) -> None:
    # AheadCheck skips the test below the run's speed bound where a step from the bound is not
    # too long to work through: it must refuse exactly what the full rule refuses, in any order
    # of (h, torque) and state, beyond the bound too.
    params = PAPER.with_changes(gamma=gamma, n=n)
    prob = Problem(params.omega0_sq, gamma, n)
    check = AheadCheck(prob, False)
    lim = run_speed_limit(gamma, n, params.omega0_sq)
    refused = 0
    for h in (1e-3, 0.3, 1e-3):
        for ain in (0.0, 1e5, -1e8, 1e8, 1e5):
            for v in (0.0, -0.5 * lim, lim, -2.0 * lim, 3.0 * lim, 0.9 * lim):
                try:
                    if fallback_refused(v, h, ain, prob.w2, prob.omega0):
                        check_speed_ahead(v, ain, h, gamma, n, prob.w2, 0.0)
                    full = ''
                except IntegratorError as exc:
                    full = str(exc)
                    refused += 1
                try:
                    check(v, h, ain, 0.0)
                    got = ''
                except IntegratorError as exc:
                    got = str(exc)
                assert got == full, (h, ain, v)
    assert refused > 0


def test_the_numpy_sweep_refuses_the_step_ahead_in_bounded_time() -> None:
    # The timeout guard: the sweep runs in a process of its own (before: more than 40 s).
    code = ('from pendulum_sim.core.sweep import sweep\n'
            'from pendulum_sim.core import IntegratorError\n'
            'try:\n'
            f'    sweep(*{SWEEP_AHEAD!r}, torque=1e8)\n'
            'except IntegratorError as exc:\n'
            '    print(exc)\n')
    r = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                       timeout=60)
    assert (r.returncode, r.stdout, r.stderr) == (0, SWEEP_AHEAD_MESSAGE + '\n', '')


@pytest.mark.parametrize(('gamma', 'n'), [(0.0, 1.0), (0.5, 0.0), (1e-4, 1.0), (0.1, 2.0),
                                          (1e-9, 2.5)])
def test_a_step_refused_ahead_is_one_the_speed_bound_refuses_after_it(gamma: float,
                                                                      n: float) -> None:
    # The decision ahead is sound: at h = 1 ms the step is cheap to take, and every state
    # and torque it refuses ahead is refused by the check after the step too (the same ones
    # at h = 0.3 s were too long to take). At γ = 0.1, n = 2 the damping below the bound
    # (1e7 rad/s²) outweighs the smaller torques: those are not decided ahead.
    params = PAPER.with_changes(gamma=gamma, n=n)
    refused_ahead = 0
    for v0 in (-9000.0, -1000.0, 0.0, 5000.0, 9990.0):
        for torque in (-2e7, -1e7, -2e6, 2e5, 2e6, 1e7, 2e7):
            try:
                check_speed_ahead(v0, torque / params.inertia, 1e-3, gamma, n,
                                  params.omega0_sq, 0.0)
            except IntegratorError:
                refused_ahead += 1
                with pytest.raises(IntegratorError, match=r'^dphi reached '):
                    Stepper(params, 0.3, v0, 1e-3).step(torque)
    assert refused_ahead >= 10
