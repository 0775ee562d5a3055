"""Near-Coulomb damping (0 < n < 1) where it dominates near rest: the creep of ``coulomb.py``.

Where γ |φ'|^n holds the pendulum (|F| < γ at rest, F = τ/I − ω0² sin φ), the velocity settles
within v_c / (n |F|) onto the creep speed v_c = (|F|/γ)^(1/n) (eq 16 with φ'' = 0), far below a
step: the Stepper, the sweep and so the node take such steps on the reduced equation instead of
handing each one to the implicit fallback. Checked against an independent stiff solver (scipy's
Radau at rtol 1e-12), for the energy balance, and for Stepper/sweep parity.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from pendulum_sim.core import PendulumParams, Stepper
from pendulum_sim.core.coulomb import TINY, creep_rate, creep_speed, creep_state
from pendulum_sim.core.law import compile_laws
from pendulum_sim.core.problem import Problem
from pendulum_sim.core.sweep import sweep

W2 = 9.8


def radau(n: float, gamma: float, p0: float, v0: float, t_end: float,
          ain: float = 0.0) -> np.ndarray:
    def f(_t: float, y: np.ndarray) -> list[float]:
        return [y[1], ain - gamma * math.copysign(abs(y[1]) ** n, y[1]) - W2 * math.sin(y[0])]

    sol = solve_ivp(f, (0.0, t_end), [p0, v0], method='Radau', rtol=1e-12, atol=1e-14)
    assert sol.success
    return np.asarray(sol.y[:, -1])


@pytest.mark.parametrize(('n', 'gamma', 'p0', 'v0', 'ain'), [
    (0.3, 100.0, 0.3, 0.0, 0.0),   # creeps from rest
    (0.3, 3.0, 2.0, 0.0, 0.0),     # swings, reverses, then creeps
    (0.1, 4.0, 1.5, 0.0, 0.0),
    (0.5, 5.0, 1.0, 3.0, 1.0),     # with input
])
def test_stepper_matches_a_stiff_reference_without_fallbacks(n: float, gamma: float, p0: float,
                                                             v0: float, ain: float) -> None:
    st = Stepper(PendulumParams.from_omega0_sq(W2, gamma, n), p0, v0, 1e-3)
    st.advance(3000, ain)
    ref = radau(n, gamma, p0, v0, 3.0, ain)
    assert abs(st.phi - ref[0]) < 1e-11
    assert abs(st.dphi - ref[1]) < 1e-11
    assert st.stats.fallbacks == 0
    assert abs(st.residual) < 1e-11


@pytest.mark.parametrize('n', [0.001, 0.01, 0.3])
def test_creep_speed_is_the_force_balance(n: float) -> None:
    """From rest at 0.3 rad, γ = 100: after the first step φ' is the closed-form creep speed."""
    st = Stepper(PendulumParams.from_omega0_sq(W2, 100.0, n), 0.3, 0.0, 1e-3)
    st.advance(50)
    force = -W2 * math.sin(st.phi)
    vc = creep_speed(Problem(W2, 100.0, n), force)
    assert st.dphi == vc
    assert vc == -(abs(force) / 100.0) ** (1.0 / n) or vc == 0.0
    assert 0.0 <= 0.3 - st.phi <= 50e-3 * abs(vc) * 1.01 + 1e-15
    assert st.stats.fallbacks == 0


def test_sweep_creeps_as_the_stepper() -> None:
    n = np.array([0.001, 0.01, 0.3, 0.5, 0.3])
    gamma = np.array([100.0, 100.0, 100.0, 30.0, 3.0])
    phi0 = np.array([0.3, 0.3, 0.3, -0.8, 2.0])
    res = sweep(W2, gamma, n, phi0, 0.0, 2.0, 1e-3)
    for i in range(n.size):
        st = Stepper(PendulumParams.from_omega0_sq(W2, float(gamma[i]), float(n[i])),
                     float(phi0[i]), 0.0, 1e-3)
        st.advance(2000)
        assert res.phi[i] == pytest.approx(st.phi, abs=1e-13)
        assert res.dphi[i] == pytest.approx(st.dphi, abs=1e-13)
        assert res.fallbacks[i] == 0


@pytest.mark.parametrize('v0', [0.01, -0.02])
def test_a_creep_speed_below_the_smallest_double_comes_to_rest_where_dop853_does(
        v0: float) -> None:
    # n = 0.001, γ = 100 at 0.3 rad: v_c = (|F|/γ)^(1/n) = 0.0296^1000 underflows to 0. A
    # pendulum arriving there with φ' ≠ 0 stops within the step, after the distance
    # ∫ φ' dt (it divided by v_c = 0 before); scipy's DOP853, stopped where φ' reaches 0, is
    # the oracle (up to there the flow is smooth; Radau's Newton fails on the |φ'|^(n−1) slope).
    n, gamma, p0 = 0.001, 100.0, 0.3
    assert creep_speed(Problem(W2, gamma, n), -W2 * math.sin(p0)) == 0.0

    def f(_t: float, y: np.ndarray) -> list[float]:
        return [y[1], -gamma * math.copysign(abs(y[1]) ** n, y[1]) - W2 * math.sin(y[0])]

    def stop(_t: float, y: np.ndarray) -> float:
        return float(y[1])

    stop.terminal = True  # type: ignore[attr-defined]
    sol = solve_ivp(f, (0.0, 1.0), [p0, v0], method='DOP853', rtol=1e-12, atol=1e-16,
                    events=stop)
    assert sol.status == 1  # it stopped, within the step below
    st = Stepper(PendulumParams.from_omega0_sq(W2, gamma, n), p0, v0, 1e-3)
    st.step()
    assert st.dphi == 0.0
    assert st.phi - p0 == pytest.approx(sol.y_events[0][0][0] - p0, rel=1e-8)


def test_a_creep_below_the_smallest_normal_double_does_no_work_and_stays() -> None:
    # n = 0.005, γ = 100 at 0.3 rad: v_c = 0.0296^200 ≈ 1e-308 is a normal double but h v_c is
    # not. The creep keeps φ and v_c and counts no work (coulomb.TINY), so the step does no
    # arithmetic on subnormal numbers; a creep speed with h v_c above TINY still counts its
    # work h v_c F.
    n, gamma, p0, h = 0.005, 100.0, 0.3, 1e-3
    laws = compile_laws(n)
    force = -W2 * math.sin(p0)
    vc = creep_rate(force, gamma, n)
    assert 0.0 < abs(vc) < TINY / h and abs(vc) >= TINY
    crept, p1, v1, w = creep_state(laws, n, gamma, W2, p0, vc, h, 0.0)
    assert (crept, p1, v1, w) == (True, p0, vc, 0.0)
    # At n = 0.02 the creep speed is far above: its work is the creep's h v_c F.
    n = 0.02
    vc = creep_rate(force, gamma, n)
    assert abs(vc) > TINY / h
    crept, p1, v1, w = creep_state(compile_laws(n), n, gamma, W2, p0, vc, h, 0.0)
    assert crept and p1 == p0 and v1 == vc and w == h * vc * force != 0.0


def branch_radau(n: float, gamma: float, cf: float, p0: float, v0: float,
                 t_end: float) -> np.ndarray:
    """Integrate the branch s = −1 (φ' <= 0 throughout) with the friction c_f beside the law."""
    def f(_t: float, y: np.ndarray) -> list[float]:
        return [y[1], gamma * abs(y[1]) ** n + cf - W2 * math.sin(y[0])]

    sol = solve_ivp(f, (0.0, t_end), [p0, v0], method='Radau', rtol=1e-12, atol=1e-14)
    assert sol.success
    assert (sol.y[1] <= 0.0).all()  # it never turned round: the branch is the flow
    return np.asarray(sol.y[:, -1])


@pytest.mark.parametrize(('n', 'gamma', 'p0', 'v0'), [
    (0.3, 100.0, 0.3, 0.0),    # breaks away from rest, then creeps
    (0.1, 30.0, 1.0, 0.0),
    (0.2, 100.0, 1.0, 0.0),
])
def test_a_creep_beside_a_friction_matches_a_stiff_reference_without_fallbacks(
        n: float, gamma: float, p0: float, v0: float) -> None:
    # A Coulomb friction c_f beside the law: moving in the direction s it is the input −s c_f,
    # and the pendulum creeps where γ |φ'|^n + c_f balances the force.
    cf = 0.25
    st = Stepper(PendulumParams.from_omega0_sq(W2, gamma, n, cf), p0, v0, 1e-3)
    st.advance(3000)
    ref = branch_radau(n, gamma, cf, p0, v0, 3.0)
    assert abs(st.phi - ref[0]) < 1e-11
    assert abs(st.dphi - ref[1]) < 1e-11
    assert st.stats.fallbacks == 0
    assert abs(st.residual) < 1e-11


def test_a_pendulum_arriving_at_its_creep_beside_a_friction_creeps_on() -> None:
    # Moving with the force at -0.5 rad/s, n = 0.3, γ = 100, c_f = 0.25: it slows onto the
    # creep speed -5.4e-6 rad/s within 10 ms and creeps on. The arrival step is taken split at
    # the apparent reversal the plain step overshoots to, as without friction, and leaves
    # 4e-9 rad in φ and 8e-10 J in the energy balance (without friction: 1e-9 rad, 1.2e-9 J).
    # From there the creep adds nothing: its velocity is the reference's to round-off, and the
    # angle's error and the balance stay. Before, it stopped dead each step (φ' = 0) and
    # drifted 5e-9 rad a step from the reference.
    n, gamma, cf, p0, v0 = 0.3, 100.0, 0.25, 0.3, -0.5
    st = Stepper(PendulumParams.from_omega0_sq(W2, gamma, n, cf), p0, v0, 1e-3)
    st.advance(20)
    arrived = st.phi - branch_radau(n, gamma, cf, p0, v0, 0.02)[0]
    balance = st.residual
    st.advance(2980)
    ref = branch_radau(n, gamma, cf, p0, v0, 3.0)
    assert abs(st.dphi - ref[1]) < 1e-11 and st.dphi < 0.0
    assert abs(st.phi - ref[0] - arrived) < 1e-11
    assert abs(st.residual - balance) < 1e-12
    assert st.stats.fallbacks == 0


@pytest.mark.parametrize('n', [0.001, 0.05, 0.3])
def test_creep_speed_beside_a_friction_is_the_force_balance(n: float) -> None:
    """From rest at 0.3 rad, γ = 100, c_f = 0.25: φ' is the speed where γ |φ'|^n + c_f = |F|."""
    cf = 0.25
    st = Stepper(PendulumParams.from_omega0_sq(W2, 100.0, n, cf), 0.3, 0.0, 1e-3)
    st.advance(50)
    force = -W2 * math.sin(st.phi)
    assert st.dphi == creep_rate(force + cf, 100.0, n)
    assert st.dphi == -((abs(force) - cf) / 100.0) ** (1.0 / n) or st.dphi == 0.0
    assert st.stats.fallbacks == 0


def test_friction_at_the_coulomb_level_holds_a_near_coulomb_law_still() -> None:
    # |F| <= c_f at rest: the rest rule holds it, nothing creeps.
    cf = 0.25
    p0 = math.asin(0.2 / W2)
    st = Stepper(PendulumParams.from_omega0_sq(W2, 100.0, 0.3, cf), p0, 0.0, 1e-3)
    st.advance(100)
    assert (st.phi, st.dphi) == (p0, 0.0)


def test_sweep_creeps_beside_a_friction_as_the_stepper() -> None:
    n = np.array([0.001, 0.01, 0.3, 0.5, 0.3])
    gamma = np.array([100.0, 100.0, 100.0, 30.0, 3.0])
    phi0 = np.array([0.3, 0.3, 0.3, -0.8, 2.0])
    fr = np.full(n.size, 0.25)
    res = sweep(W2, gamma, n, phi0, 0.0, 2.0, 1e-3, friction=fr)
    for i in range(n.size):
        st = Stepper(PendulumParams.from_omega0_sq(W2, float(gamma[i]), float(n[i]), 0.25),
                     float(phi0[i]), 0.0, 1e-3)
        st.advance(2000)
        assert res.phi[i] == pytest.approx(st.phi, abs=1e-13)
        assert res.dphi[i] == pytest.approx(st.dphi, abs=1e-13)
        assert res.fallbacks[i] == st.stats.fallbacks == 0
