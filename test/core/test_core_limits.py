"""Extreme inputs: every input is refused with the core's own error naming the limit, or gives a
correct finite result; the validation is written once (``model.py``)."""
from __future__ import annotations

import itertools
import math

import pytest

from pendulum_sim.core import (
    IntegratorError,
    ModelError,
    PendulumError,
    PendulumParams,
    Stepper,
    simulate,
)
from pendulum_sim.core.model import MAX_SPEED, speed_limit, validate_state
from pendulum_sim.core.sweep import sweep

PAPER = PendulumParams()


def test_paper_body_is_a_point_mass_and_allowed() -> None:
    # m l² = 0.2 kg m² = I: the paper's pendulum sits exactly on the parallel-axis limit.
    assert PAPER.inertia == PAPER.m * PAPER.l**2
    PendulumParams(m=0.2, l=1.0, inertia=0.2 * (1.0 - 1e-13))  # round-off is allowed


def test_impossible_rigid_body_is_refused_with_the_limit() -> None:
    with pytest.raises(ModelError) as info:
        PendulumParams(m=0.2, l=1.0, inertia=0.1)
    assert str(info.value) == ('inertia must be >= m*l**2 = 0.2 kg m^2 for a rigid body '
                               '(parallel-axis theorem), got 0.1')
    with pytest.raises(ModelError, match=r'^inertia must be >= m\*l\*\*2 = 0.5 kg m\^2'):
        PAPER.with_changes(m=0.5)


@pytest.mark.parametrize(('phi0', 'dphi0', 'message'), [
    (0.0, 1e200, 'dphi0 must be within +-10000 rad/s (the state bound that keeps energy and '
                 'damping finite), got 1e+200'),
    (0.0, -1e100, 'dphi0 must be within +-10000 rad/s (the state bound that keeps energy and '
                  'damping finite), got -1e+100'),
    (math.nan, 0.0, 'phi0 must be finite, got nan'),
    (0.0, True, 'dphi0 must be a real number, got True'),
])
def test_state_bound_without_parameters(phi0: float, dphi0: float, message: str) -> None:
    # The node's parameter check calls validate_state without parameters.
    with pytest.raises(ModelError) as info:
        validate_state(phi0, dphi0)
    assert str(info.value) == message


def test_state_bound_from_the_damping_law() -> None:
    # n = 1000 at 5 rad/s: γ |φ'|^(n+1) = 5^1001 is beyond float64; the bound says where.
    p = PAPER.with_changes(n=1000.0)
    lim = speed_limit(1.0, 1000.0)
    assert 1.5 < lim < 2.0 and math.isfinite(lim ** 1001)
    with pytest.raises(ModelError) as info:
        Stepper(p, 2.0, 5.0, 1e-3)
    assert str(info.value) == (f'dphi0 must be within +-{lim:.6g} rad/s for gamma = 1 and '
                               'n = 1000 (keeps gamma*|dphi|**(n+1) below 1e+250), got 5')
    assert speed_limit(1.0, 2.0) == MAX_SPEED


@pytest.mark.parametrize(('call', 'error', 'message'), [
    (lambda: simulate(PAPER, 2.0, 0.0, 1e9, 1e-3), IntegratorError,
     't_end / h = 1e+12 steps exceeds max_steps = 100000000 (pass a larger max_steps to run '
     'it)'),
    (lambda: simulate(PAPER, 2.0, 0.0, 1.0, 1e-3, record_every=True), IntegratorError,
     'record_every must be an integer >= 1, got True'),
    (lambda: Stepper(PAPER, 2.0, 0.0, 1e-3, rtol='x'), IntegratorError,  # type: ignore
     "rtol must be a finite tolerance > 0, got 'x'"),
    (lambda: Stepper(PAPER, 2.0, 0.0, 1e3), IntegratorError,
     'h must be <= 100/omega0 = 31.9438 s for these parameters, got 1000'),
    (lambda: Stepper(PAPER, 2.0, 0.0, 1e-3).step(1e300), ModelError,
     'torque must be within +-2e+07 N m (|torque/I| <= 1e+08 rad/s^2), got 1e+300'),
    (lambda: Stepper(PAPER, 2.0, 0.0, 1e-3).step(math.nan), ModelError,
     'torque must be finite, got nan'),
])
def test_limits_are_refused_with_exact_messages(call: object, error: type[Exception],
                                                message: str) -> None:
    with pytest.raises(error) as info:
        call()  # type: ignore[operator]
    assert str(info.value) == message


# Exponents, damping and states from the paper's extremes to far beyond: n = 1000 and γ = 1e300
# overflow the damping law itself, h = 10 s is most of a period per step.
EXTREMES = [c for c in itertools.product(
    [0.0, 0.3, 1.0, 2.0, 6.0, 200.0, 1000.0],  # n
    [0.0, 1e-3, 1.0, 1e6, 1e300],  # γ
    [0.0, 5.0, 50.0, 1e4],  # φ'0
    [1e-3, 0.3],  # h
) if c[2] < 1e4 or c[3] < 0.3 or c[:2] == (2.0, 1.0)]


@pytest.mark.parametrize(('method', 'energy_tol'), [
    ('rk4', 1e-9),     # the energy check redoes a step whose energy rose
    ('dopri5', 5e-7),  # error control at rtol 1e-8, no energy check: a few tolerances
    ('rodas4', 5e-7),
    ('extrap8', 5e-7),
])
def test_extreme_inputs_refuse_or_stay_finite(method: str, energy_tol: float) -> None:
    # Before: the adaptive methods ran for ever at n = 0.3, γ = 1e6 (10⁶ trial substeps a
    # step, chattering at rest), and rodas4 raised ZeroDivisionError at γ = 1e300.
    refused = 0
    for n, gamma, dphi0, h in EXTREMES:
        params = PendulumParams.from_omega0_sq(9.8, gamma, n)
        try:
            s = Stepper(params, 2.0, dphi0, h, method)
        except PendulumError:
            refused += 1
            continue
        s.advance(3)
        s.advance(2, 0.5)
        values = (s.phi, s.dphi, s.energy(), s.residual, s.local_error_estimate(0.5))
        assert all(math.isfinite(x) for x in values), (n, gamma, dphi0, h, values)
        # Damping never adds energy: E(t) <= E(0) + the work of the input torque.
        e0 = 0.5 * dphi0**2 + 9.8 * (1.0 - math.cos(2.0))
        assert s.energy() <= e0 + s.input_work + energy_tol * (e0 + 9.8), (n, gamma, dphi0, h)
    assert 0 < refused < len(EXTREMES) // 2


@pytest.mark.parametrize(('method', 'h'), [
    ('rk4', 1e-3), ('rk4', 3e-3), ('rk4', 1e-4), ('midpoint', 1e-3), ('dopri5', 1e-3),
    ('dop853', 3e-3), ('rodas4', 1e-3), ('extrap6', 3e-3), ('extrap8', 1e-4)])
def test_a_strong_sublinear_law_stops_where_the_closed_form_says(method: str, h: float) -> None:
    # n = 0.3, γ = 1e6 from 1e4 rad/s: φ'' = −γ φ'^n stops in finite time, after
    # t* = φ'0^(1−n) / ((1−n) γ) = 0.90 ms, at φ0 + φ'0^(2−n) / ((2−n) γ); gravity moves that by
    # less than ½ ω0² t*² = 4.0e-6 rad. Then the pendulum creeps at (|ω0² sin φ| / γ)^(1/n),
    # 2.6e-18 rad/s. Before: RK4 at h = 1 ms ended 2.2 rad away still turning at −420 rad/s (the
    # explicit branch run after the stop met a law whose rate at rest is beyond any step);
    # the adaptive methods never finished the first step.
    n, gamma, v0 = 0.3, 1e6, 1e4
    s = Stepper(PendulumParams.from_omega0_sq(9.8, gamma, n), 2.0, v0, h, method)
    s.advance(round(3e-3 / h))
    t_stop = v0 ** (1.0 - n) / ((1.0 - n) * gamma)
    assert t_stop < 1e-3
    assert s.phi == pytest.approx(2.0 + v0 ** (2.0 - n) / ((2.0 - n) * gamma),
                                  abs=0.5 * 9.8 * t_stop**2 + 2e-6)
    assert 0.0 <= s.dphi <= 1e-17


def test_a_step_of_most_of_a_period_still_lands_on_the_solution() -> None:
    # h = 10 s on a 2.67 s pendulum: the fallback obeys the angle limit in substeps, so the
    # run ends where a tight dopri5 does (it used to end 13 turns away).
    ref = simulate(PAPER, 2.0, 0.0, 20.0, 20.0, method='dopri5', rtol=1e-12, atol=1e-14)
    r = simulate(PAPER, 2.0, 0.0, 20.0, 10.0)
    assert abs(r.phi[-1] - ref.phi[-1]) < 1e-6 and abs(r.dphi[-1] - ref.dphi[-1]) < 1e-6


def test_sweep_uses_the_same_validation() -> None:
    with pytest.raises(ModelError, match=r'^dphi0 must be within \+-10000 rad/s'):
        sweep(9.8, 1.0, 1.0, 0.0, [0.0, 1e200], 1.0, 1e-3)
    with pytest.raises(IntegratorError, match=r'^t_end / h = 1e\+12 steps exceeds max_steps'):
        sweep(9.8, 1.0, 1.0, 0.0, 0.0, 1e9, 1e-3)


@pytest.mark.parametrize('method', ['rodas4', 'extrap8'])
def test_simulate_falls_back_to_steps_where_one_cover_cannot_run_through(method: str) -> None:
    # The same stop through simulate: its single cover over all outputs stalls at rest (more
    # than MAX_TRIALS trials an output interval), so the outputs are stepped one by one.
    n, gamma, v0 = 0.3, 1e6, 1e4
    r = simulate(PendulumParams.from_omega0_sq(9.8, gamma, n), 2.0, v0, 3e-3, 1e-3, method)
    stop = 2.0 + v0 ** (2.0 - n) / ((2.0 - n) * gamma)
    assert r.stats.fallbacks >= 1 and r.stats.steps == 3
    assert r.phi[1:] == pytest.approx([stop] * 3, abs=6e-6)
    assert list(r.t) == [0.0, 1e-3, 2e-3, 3e-3]
