"""Stiff and extreme cases: the stability guard keeps every run finite and energy-honest."""
from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from pendulum_sim.core import PendulumParams, Stepper, simulate
from pendulum_sim.core.guard import StabilityGuard
from pendulum_sim.core.stepper import ENERGY_TOL
from pendulum_sim.core.tableaus import RK4

PAPER = PendulumParams()


def test_plain_rk4_blows_up_where_its_stability_region_says_and_the_guard_does_not() -> None:
    # n = 1, γ = 1000: the fast eigenvalue is about −γ, RK4 needs h < 2.785 ms; 60 Hz is not.
    params = PAPER.with_changes(gamma=1000.0, n=1.0)
    with np.errstate(all='ignore'):
        plain = simulate(params, 2.0, 0.0, 1.0, 1 / 60, guard=False, energy_check=False)
    assert not np.all(np.isfinite(plain.phi)) or np.max(np.abs(plain.phi)) > 1e6
    guarded = simulate(params, 2.0, 0.0, 1.0, 1 / 60)
    assert np.all(np.isfinite(guarded.phi))
    assert guarded.stats.substeps + guarded.stats.fallbacks > 0
    assert np.max(np.diff(guarded.energy)) <= ENERGY_TOL * guarded.energy[0]
    # The overdamped creep is right: compare with a fine plain-RK4 run inside the region.
    fine = simulate(params, 2.0, 0.0, 1.0, 1e-4, guard=False)
    assert abs(guarded.phi[-1] - fine.phi[-1]) < 1e-4


def test_guard_criterion_matches_the_stability_function() -> None:
    guard = StabilityGuard(RK4)
    for gamma in (10.0, 100.0, 1000.0, 1e4):
        for h in (1e-4, 1e-3, 1e-2):
            m = guard.substeps(h, 9.8, gamma, 1.0, 0.0, 0.0, 9.8)
            lam = PAPER.with_changes(gamma=gamma).jacobian_eigenvalues(0.0, 0.0)
            if m == 1:
                assert all(abs(RK4.stability_function(h * z)) <= 1.0 for z in lam)
            elif m > 1:
                assert all(abs(RK4.stability_function(h * z / m)) <= 1.0 for z in lam)
                assert any(abs(RK4.stability_function(h * z / (m - 1))) > 1.0 * guard.safety
                           or h / (m - 1) * abs(z) > guard.real for z in lam)


CASES = list(itertools.product(
    [0.0, 1e-3, 1.0, 1e3, 1e6],  # γ
    [0.0, 0.5, 1.0, 2.0, 2.5, 5.0, 10.0],  # n
    [1e-3, 0.1],  # h
    [(3.1, 0.0), (4.0, 100.0)],  # near the top; over the top at 100 rad/s
))


@pytest.mark.parametrize(('gamma', 'n', 'h', 'x'), CASES)
def test_extreme_cases_stay_finite_and_never_gain_energy(gamma: float, n: float, h: float,
                                                        x: tuple[float, float]) -> None:
    params = PAPER.with_changes(gamma=gamma, n=n)
    r = simulate(params, x[0], x[1], 1.0, h)
    assert np.all(np.isfinite(r.phi)) and np.all(np.isfinite(r.dphi))
    if gamma > 0.0:
        assert np.max(np.diff(r.energy)) <= ENERGY_TOL * max(r.energy[0], params.mgl)


@pytest.mark.parametrize(('gamma', 'n'), [(1.0, 10.0), (1e3, 2.5), (1e3, 5.0), (1e6, 1.0)])
def test_large_torque_is_finite_and_the_balance_holds(gamma: float, n: float) -> None:
    params = PAPER.with_changes(gamma=gamma, n=n)
    r = simulate(params, 3.1, 0.0, 1.0, 1 / 60, torque=50.0)
    assert np.all(np.isfinite(r.phi)) and np.all(np.isfinite(r.dphi))
    # Work in minus work out equals the energy change, to the accuracy of the steps taken.
    assert abs(r.residual[-1]) < 1e-3 * (r.input_work[-1] + r.energy[0])


def test_guard_actions_are_counted() -> None:
    s = Stepper(PAPER.with_changes(gamma=1e6, n=1.0), 2.0, 0.0, 0.01)
    s.advance(10)
    assert s.stats.fallbacks == 10 and math.isfinite(s.phi)
    s = Stepper(PAPER.with_changes(gamma=500.0, n=1.0), 2.0, 0.0, 0.01)
    s.advance(10)
    assert s.stats.substeps > 0 and s.stats.fallbacks == 0
