"""Integrators: tableau consistency, measured orders, the paper's oracles, Q(t) → 16."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pendulum_sim.core import METHODS, IntegratorError, PendulumParams, Stepper, simulate
from pendulum_sim.core.analysis import (
    convergence_quotient,
    linear_exact_solution,
    undamped_period,
)
from pendulum_sim.core.simulate import step_count
from pendulum_sim.core.stepper import ENERGY_TOL
from pendulum_sim.core.tableaus import TABLEAUS

PAPER = PendulumParams()  # m = 0.2, l = 1, I = 0.2, g = 9.8: ω0² = 9.8


@pytest.mark.parametrize('name', sorted(TABLEAUS))
def test_tableau_is_consistent(name: str) -> None:
    t = TABLEAUS[name]
    assert t.B.sum() == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_allclose(t.A.sum(axis=1), t.C, atol=1e-15)
    if t.E is not None:
        assert t.E.sum() == pytest.approx(0.0, abs=1e-15)


def test_rk4_stability_region_meets_the_axes_at_the_known_bounds() -> None:
    rk4 = TABLEAUS['rk4']
    assert abs(rk4.stability_function(-2.785293563405)) == pytest.approx(1.0, abs=1e-11)
    assert abs(rk4.stability_function(2j * math.sqrt(2))) == pytest.approx(1.0, abs=1e-12)


def _final_error(method: str, h: float, ref: tuple[float, float], params: PendulumParams,
                 t_end: float) -> float:
    r = simulate(params, 2.0, 0.0, t_end, h, method, guard=False, energy_check=False)
    return math.hypot(r.phi[-1] - ref[0], r.dphi[-1] - ref[1])


def _reference(params: PendulumParams, t_end: float) -> tuple[float, float]:
    # Independent route: the adaptive Dormand-Prince pair at a tight tolerance.
    r = simulate(params, 2.0, 0.0, t_end, t_end, 'dopri5', rtol=1e-13, atol=1e-14)
    return r.phi[-1], r.dphi[-1]


@pytest.mark.parametrize(('method', 'hs'), [
    ('euler', (4e-3, 2e-3, 1e-3)),
    ('midpoint', (2e-2, 1e-2, 5e-3)),
    ('rk4', (4e-2, 2e-2, 1e-2)),
    ('sdirk2', (2e-2, 1e-2, 5e-3)),
    ('sdirk3', (2e-2, 1e-2, 5e-3)),
])
def test_measured_order_matches_the_declared_one(method: str, hs: tuple[float, ...]) -> None:
    params = PAPER.with_changes(gamma=1.0, n=1.0)
    ref = _reference(params, 2.0)
    errs = [_final_error(method, h, ref, params, 2.0) for h in hs]
    slopes = [math.log2(errs[i] / errs[i + 1]) for i in range(len(errs) - 1)]
    order = METHODS[method].order
    assert all(abs(s - order) < 0.15 for s in slopes), (method, slopes)


def test_dopri5_error_follows_its_tolerance() -> None:
    params = PAPER.with_changes(gamma=1.0, n=1.0)
    ref = _reference(params, 5.0)
    errs = []
    for rtol in (1e-6, 1e-8, 1e-10):
        r = simulate(params, 2.0, 0.0, 5.0, 5.0, 'dopri5', rtol=rtol, atol=rtol * 1e-2)
        errs.append(math.hypot(r.phi[-1] - ref[0], r.dphi[-1] - ref[1]))
    assert errs[0] > errs[1] > errs[2]
    assert all(e < 50 * rtol for e, rtol in zip(errs, (1e-6, 1e-8, 1e-10), strict=True))


def test_paper_constants_eq_30_to_32() -> None:
    sol = linear_exact_solution(gamma=0.1, omega0_sq=9.8, x0=0.1, v0=0.0)
    assert sol.omega == pytest.approx(3.130095845, abs=5e-10)
    assert sol.alpha == pytest.approx(-0.01597259328, abs=5e-12)
    assert sol.amplitude == pytest.approx(0.1000127575, abs=5e-11)


def test_numerical_solution_matches_the_exact_linear_one_fig_8() -> None:
    # sin φ ≈ φ to O(φ³): at x0 = 1e-4 the nonlinearity is ~1e-9 of the amplitude over 20 s,
    # so what is left is the integrator's error.
    x0 = 1e-4
    params = PAPER.with_changes(gamma=0.1, n=1.0)
    r = simulate(params, x0, 0.0, 20.0, 1e-3)
    exact = linear_exact_solution(0.1, 9.8, x0)(r.t)
    assert np.max(np.abs(r.phi - exact)) < 1e-8 * x0 * 20
    # At the paper's x0 = 0.1 the pendulum is slower than the linear one by x0²/16 (the first
    # term of 4K(sin²(x0/2))/(2π)): the curves of Fig 8 agree to a few percent of the amplitude.
    r = simulate(params, 0.1, 0.0, 20.0, 1e-3)
    exact = linear_exact_solution(0.1, 9.8, 0.1)(r.t)
    assert np.max(np.abs(r.phi - exact)) < 0.05 * 0.1


@pytest.mark.parametrize('n', [1, 2, 3, 4, 5])
def test_convergence_quotient_tends_to_16_for_every_n(n: int) -> None:
    params = PAPER.with_changes(gamma=1.0, n=float(n))
    worst = []
    for h in (1e-2, 5e-3):
        q = convergence_quotient(params, 2.0, 0.0, 20.0, h).q[1:]
        assert np.all(np.isfinite(q))
        assert np.median(q) == pytest.approx(16.0, abs=0.3)
        worst.append(np.max(np.abs(q - 16.0)))
    # Q → 16: the largest departure shrinks as h halves, and is below 1 at h = 5 ms.
    assert worst[1] < worst[0] and worst[1] < 1.0, worst


def test_without_reversal_location_q_wanders_for_n_2() -> None:
    # The paper's Fig 9 remark: plain RK4 loses its order at velocity reversals for n = 2.
    from pendulum_sim.core.explicit import compile_step
    from pendulum_sim.core.tableaus import RK4

    def plain(h: float) -> np.ndarray:
        step = compile_step(RK4, 2.0)
        k = round(20.0 / h)
        out = np.empty((k + 1, 2))
        p, v = 2.0, 0.0
        out[0] = p, v
        for i in range(k):
            p, v, _, _ = step(p, v, h, 0.0, 9.8, 1.0, 1.0)
            out[i + 1] = p, v
        return out

    ys = [plain(1e-2 / 2**k)[:: 2**k] for k in range(3)]
    q = np.linalg.norm(ys[0] - ys[1], axis=1)[1:] / np.linalg.norm(ys[1] - ys[2], axis=1)[1:]
    assert np.max(np.abs(q - 16.0)) > 3.0


def test_fig_3_facts() -> None:
    from pendulum_sim.core.analysis import turning_points

    amps = {}
    for n in (1, 2, 3, 4, 5):
        r = simulate(PAPER.with_changes(gamma=1.0, n=float(n)), 2.0, 0.0, 20.0, 1e-3)
        _, a = turning_points(r.t, r.phi, r.dphi)
        amps[n] = a[1:]  # a[0] is the release at rest
    first = [amps[n][0] for n in (1, 2, 3, 4, 5)]
    last = [amps[n][-1] for n in (1, 2, 3, 4, 5)]
    # Short times (|φ'| > 1): friction bites harder for higher n, so the first swing is
    # largest for n = 1; long times (|φ'| < 1): the order reverses (the paper, figs 3 and 5).
    assert first == sorted(first, reverse=True)
    assert last == sorted(last)
    # At γ = 1, n = 1 decays fastest.
    assert last[0] < 1e-3 < min(last[1:])
    # At γ = 10: n = 1 is overdamped (no zero crossing) while n ≥ 2 keep oscillating.
    for n in (1, 2, 3, 4, 5):
        phi = simulate(PAPER.with_changes(gamma=10.0, n=float(n)), 2.0, 0.0, 20.0, 1e-3).phi
        assert np.all(phi > 0.0) == (n == 1), n


def test_undamped_period_is_4K_over_omega0() -> None:
    assert undamped_period(9.8, 2.0) == pytest.approx(2.6672307342739, abs=1e-12)
    r = simulate(PAPER.with_changes(gamma=0.0), 2.0, 0.0, 6.0, 1e-3)
    # Downward zero crossings of φ' ... times of the turning points, interpolated.
    from pendulum_sim.core.analysis import turning_points
    tt, _ = turning_points(r.t, r.phi, r.dphi)
    period = tt[2] - tt[0]
    assert period == pytest.approx(2.6672307342739, abs=2e-6)


@pytest.mark.parametrize('n', [0.0, 0.5, 1.0, 2.0, 3.5])
def test_energy_never_increases_and_the_balance_closes(n: float) -> None:
    for gamma in (0.05, 1.0, 10.0):
        r = simulate(PAPER.with_changes(gamma=gamma, n=n), 2.0, 0.0, 10.0, 1e-3)
        scale = r.energy[0]
        assert np.max(np.diff(r.energy)) <= ENERGY_TOL * scale, (n, gamma)
        # The residual is the method's own truncation error: O(h⁴) for n > 0; for Coulomb
        # friction (n = 0) the sticking events leave O(h²) (README: known limits).
        bound = 1e-7 if n == 0.0 else 1e-9
        assert np.max(np.abs(r.residual)) < bound * scale, (n, gamma)


def test_energy_balance_residual_is_fourth_order() -> None:
    params = PAPER.with_changes(gamma=1.0, n=3.0)
    res = [np.max(np.abs(simulate(params, 2.0, 0.0, 10.0, h).residual)) for h in (4e-2, 2e-2)]
    assert math.log2(res[0] / res[1]) == pytest.approx(4.0, abs=0.3)


def test_rk4_matches_an_independent_reference() -> None:
    # Two independent routes: dopri5 at a tight tolerance, and Richardson extrapolation of RK4.
    params = PAPER.with_changes(gamma=1.0, n=2.0)
    ref = _reference(params, 5.0)
    a = simulate(params, 2.0, 0.0, 5.0, 2e-3)
    b = simulate(params, 2.0, 0.0, 5.0, 1e-3)
    rich = (16 * b.phi[-1] - a.phi[-1]) / 15
    assert abs(rich - ref[0]) < 1e-11
    assert abs(b.phi[-1] - ref[0]) < 5e-11


def test_simulate_lands_exactly_on_t_end_with_rounded_step_counts() -> None:
    assert step_count(0.7, 0.001) == (700, 0.0)
    r = simulate(PAPER, 2.0, 0.0, 0.7, 0.001)
    assert len(r.t) == 701 and r.t[0] == 0.0 and r.t[-1] == 0.7
    r = simulate(PAPER, 2.0, 0.0, 0.705, 0.01)
    assert r.t[-1] == 0.705 and r.t[-2] == pytest.approx(0.70)


def test_coulomb_friction_sticks_instead_of_chattering() -> None:
    params = PAPER.with_changes(gamma=1.0, n=0.0)
    r = simulate(params, 2.0, 0.0, 20.0, 1e-3)
    stop = int(np.argmax((r.dphi == 0.0) & (np.arange(len(r.t)) > 0)))
    assert stop > 0 and r.stats.sticks == 1
    assert np.all(r.dphi[stop:] == 0.0) and np.all(r.phi[stop:] == r.phi[stop])
    # Static friction holds where it stopped, and it could not have held a turn earlier.
    assert abs(params.omega0_sq * math.sin(r.phi[stop])) <= params.gamma
    # Released inside the static band it never moves.
    held = simulate(params.with_changes(gamma=10.0), 2.0, 0.0, 1.0, 1e-3)
    assert np.all(held.phi == 2.0) and np.all(held.dphi == 0.0)


def test_stepper_takes_live_parameter_changes_without_a_jump() -> None:
    s = Stepper(PAPER, 2.0, 0.0, 1e-3)
    s.advance(500)
    phi, dphi = s.phi, s.dphi
    s.set_params(s.params.with_changes(n=2.0, gamma=5.0))
    assert (s.phi, s.dphi) == (phi, dphi)
    s.step()
    ref = Stepper(PAPER.with_changes(n=2.0, gamma=5.0), phi, dphi, 1e-3)
    ref.step()
    assert (s.phi, s.dphi) == (ref.phi, ref.dphi)
    assert s.t == pytest.approx(0.501, abs=1e-15)


@pytest.mark.parametrize(('kwargs', 'message'), [
    ({'h': 0.0}, 'h must be a finite step > 0 s, got 0.0'),
    ({'h': math.nan}, 'h must be a finite step > 0 s, got nan'),
    ({'method': 'rk45'},
     "unknown method 'rk45'; known methods: dop853, dopri5, euler, extrap6, extrap8, midpoint, "
     'rk4, rodas4, sdirk2, sdirk3'),
    ({'t_end': -1.0}, 't_end must be > 0 s, got -1.0'),
])
def test_bad_integrator_arguments_raise_exact_messages(kwargs: dict[str, object],
                                                       message: str) -> None:
    args: dict[str, object] = {'t_end': 1.0, 'h': 1e-3, 'method': 'rk4'}
    args.update(kwargs)
    with pytest.raises(IntegratorError) as info:
        simulate(PAPER, 2.0, 0.0, **args)  # type: ignore[arg-type]
    assert str(info.value) == message


@pytest.mark.parametrize('method', ['dopri5', 'dop853', 'extrap6'])
@pytest.mark.parametrize(('gamma', 'n'), [(1.0, 1.0), (1.0, 2.5), (1000.0, 2.0)])
def test_one_cover_lands_on_every_output_like_a_cover_per_output(method: str, gamma: float,
                                                                 n: float) -> None:
    # simulate runs an adaptive method of order > 4 in one cover with a landing at every output
    # (embedded.dense_run); the Stepper covers one output interval per call. Same decisions:
    # the same reversals and substeps, states equal to round-off (the interval's remaining
    # length is computed from global instead of local times).
    params = PendulumParams(gamma=gamma, n=n)
    r = simulate(params, 2.0, 0.0, 5.0, 0.1, method, rtol=1e-8, atol=1e-10)
    s = Stepper(params, 2.0, 0.0, 0.1, method, rtol=1e-8, atol=1e-10)
    ps, vs = [s.phi], [s.dphi]
    for _ in range(50):
        s.step()
        ps.append(s.phi)
        vs.append(s.dphi)
    assert r.stats.reversals == s.stats.reversals
    assert abs(r.stats.substeps - s.stats.substeps) <= 2
    assert float(np.max(np.abs(r.phi - np.array(ps)))) <= 1e-10
    assert float(np.max(np.abs(r.dphi - np.array(vs)))) <= 1e-10
