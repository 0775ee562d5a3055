"""The linearly implicit ``rodas4``: L-stable, order 4, accurate on long stiff runs.

Oracles: its stability function against exp(z) and at z → −∞; the textbook Rosenbrock step
(numpy solve) for the generated one; an independent reference (scipy restarted at every
reversal, ``reports.reference``) for the runs.
"""
from __future__ import annotations

import cmath
import math

import numpy as np
import pytest
from augmented_field import augmented

from pendulum_sim.core import METHODS, PendulumParams, Stepper, simulate
from pendulum_sim.core.engine import ENERGY_TOL
from pendulum_sim.core.rosenbrock import compile_rosenbrock, rosenbrock_step
from pendulum_sim.core.tableaus import RODAS4

W2 = 9.8


def test_rodas4_is_registered_as_an_adaptive_method() -> None:
    m = METHODS['rodas4']
    assert (m.kind, m.order, m.fixed_step, m.tableau.explicit) == ('adaptive', 4, False, False)


def test_stability_function_is_l_stable_and_of_order_four() -> None:
    r = RODAS4.stability_function
    assert abs(r(-1e8)) < 1e-6  # L-stable: R(−∞) = 0
    assert abs(r(-1e4)) < 1e-3
    ys = np.logspace(-3, 7, 300)
    assert max(abs(r(1j * y)) for y in ys) <= 1.0 + 1e-12  # A-stable on the imaginary axis
    # Local error R(z) − e^z = O(z^5): halving z divides it by 32.
    ratio = abs(r(0.1) - cmath.exp(0.1)) / abs(r(0.05) - cmath.exp(0.05))
    assert 28.0 < ratio < 36.0, ratio


@pytest.mark.parametrize('n', [0.5, 1.0, 2.0, 2.5, 3.0])
@pytest.mark.parametrize('branch', [False, True])
def test_generated_step_is_the_reference_rosenbrock_step(n: float, branch: bool) -> None:
    g, ain = 0.7, 0.3
    p0, v0, h = 1.1, -0.8, 0.05
    sign = -1.0  # the branch of the start's direction of motion

    law, f, jac = augmented(g, n, ain, branch, sign, p0, v0)
    y1, err = rosenbrock_step(RODAS4, f, jac, np.array([p0, v0, 0.0]), h)
    got = compile_rosenbrock(RODAS4, n, branch)(p0, v0, h, ain, W2, g, sign)
    np.testing.assert_allclose(got[:3], y1, rtol=0.0, atol=1e-15)
    np.testing.assert_allclose(got[4:], err[:2], rtol=0.0, atol=1e-15)
    assert got[3] == pytest.approx(ain - law(v0) - W2 * math.sin(p0), abs=1e-15)


def test_fixed_step_order_is_four() -> None:
    # The bare generated step in a fixed-step loop on the smooth n = 1 case: error ∝ h⁴.
    step = compile_rosenbrock(RODAS4, 1.0)
    ref = simulate(PendulumParams(gamma=1.0, n=1.0), 2.0, 0.0, 2.0, 2.0, 'dopri5',
                   rtol=1e-13, atol=1e-15)
    errs = []
    for h in (0.1, 0.05, 0.025):
        p, v = 2.0, 0.0
        for _ in range(round(2.0 / h)):
            p, v, _, _, _, _ = step(p, v, h, 0.0, W2, 1.0, 1.0)
        errs.append(math.hypot(p - ref.phi[-1], v - ref.dphi[-1]))
    slopes = [math.log2(errs[i] / errs[i + 1]) for i in range(2)]
    assert all(abs(s - 4.0) < 0.3 for s in slopes), slopes


def test_error_follows_the_tolerance() -> None:
    params = PendulumParams(gamma=1.0, n=1.0)
    ref = simulate(params, 2.0, 0.0, 5.0, 5.0, 'dopri5', rtol=1e-13, atol=1e-15)
    errs = []
    for rtol in (1e-6, 1e-8, 1e-10):
        r = simulate(params, 2.0, 0.0, 5.0, 5.0, 'rodas4', rtol=rtol, atol=rtol * 1e-2)
        errs.append(math.hypot(r.phi[-1] - ref.phi[-1], r.dphi[-1] - ref.dphi[-1]))
    assert errs[0] > errs[1] > errs[2]
    assert all(e < 50 * rtol for e, rtol in zip(errs, (1e-6, 1e-8, 1e-10), strict=True))
    # Tolerance proportionality of an order-4(3) pair: two decades of rtol, ≥ 1.5 of error.
    assert math.log10(errs[0] / errs[2]) >= 3.0, errs


def _reference(params: PendulumParams, t: np.ndarray) -> object:
    pytest.importorskip('scipy')
    from pendulum_sim.reports.reference import reference

    ref = reference(params, 2.0, 0.0, t)
    assert ref is not None
    return ref


@pytest.mark.parametrize(('gamma', 'n', 'rtol'), [
    (1000.0, 1.0, 1e-8), (1000.0, 2.0, 1e-8), (1000.0, 3.0, 1e-8), (1e4, 1.0, 1e-6),
])
def test_stiff_runs_are_accurate_with_few_steps(gamma: float, n: float, rtol: float) -> None:
    # The paper's start on the stiff cases of the work-precision study: the fast mode decays in
    # 1/(γ n |φ'|^(n−1)), then a slow creep; an L-stable method steps the creep at its own scale.
    params = PendulumParams(gamma=gamma, n=n)
    t = np.linspace(0.0, 5.0, 51)
    ref = _reference(params, t)
    r = simulate(params, 2.0, 0.0, 5.0, 0.1, 'rodas4', rtol=rtol, atol=rtol * 1e-2)
    err = float(np.max(ref.error(r.phi, r.dphi)))  # type: ignore[attr-defined]
    floor = 10.0 * ref.disagreement  # type: ignore[attr-defined]
    assert err <= max(50.0 * rtol, floor), err
    # Few substeps where the explicit pair is held at its stability limit (~3e4 at γ = 1e4).
    assert r.stats.substeps < 1000, r.stats
    if gamma == 1e4:
        rd = simulate(params, 2.0, 0.0, 1.0, 0.1, 'dopri5', rtol=rtol, atol=rtol * 1e-2)
        rr = simulate(params, 2.0, 0.0, 1.0, 0.1, 'rodas4', rtol=rtol, atol=rtol * 1e-2)
        assert rr.stats.substeps * 20 < rd.stats.substeps


@pytest.mark.parametrize('n', [0.3, 0.5, 1.5, 2.5])
def test_reversals_are_cut_by_the_shared_treatment(n: float) -> None:
    # Non-smooth laws: the same cut at φ' = 0 as dopri5 (embedded.cover), so the same
    # reversals as dopri5 and as the reference's restarts, and the error within 10× tol.
    params = PendulumParams(gamma=1.0, n=n)
    t = np.linspace(0.0, 10.0, 101)
    ref = _reference(params, t)
    tol = 1e-8
    r = simulate(params, 2.0, 0.0, 10.0, 0.1, 'rodas4', rtol=tol, atol=tol * 1e-2)
    rd = simulate(params, 2.0, 0.0, 10.0, 0.1, 'dopri5', rtol=tol, atol=tol * 1e-2)
    assert r.stats.reversals == rd.stats.reversals == ref.segments > 0  # type: ignore[attr-defined]
    scale = 2.0 + math.sqrt(W2)
    assert float(np.max(ref.error(r.phi, r.dphi))) <= 10.0 * tol * scale  # type: ignore[attr-defined]


@pytest.mark.parametrize('gamma', [1.0, 1000.0])
@pytest.mark.parametrize('n', [0.5, 1.0, 2.0, 3.0])
def test_energy_never_rises_without_input(gamma: float, n: float) -> None:
    params = PendulumParams(gamma=gamma, n=n)
    r = simulate(params, 2.0, 0.0, 5.0, 0.01, 'rodas4', rtol=1e-5, atol=1e-7)
    e = r.energy / params.inertia
    assert float(np.max(np.diff(e))) <= ENERGY_TOL * (e[0] + W2)
    # The damping work is integrated with the state: the balance closes to the tolerance at
    # every output (also those interpolated between free substeps).
    assert float(np.max(np.abs(r.residual))) <= 1e-5 * r.energy[0]


def test_coulomb_sticks_and_stepper_matches_simulate() -> None:
    # n = 0: the shared Coulomb treatment (stick at rest while |ω0² sin φ| ≤ γ).
    params = PendulumParams(gamma=2.0, n=0.0)
    r = simulate(params, 1.0, 0.0, 5.0, 0.05, 'rodas4', rtol=1e-8, atol=1e-10)
    assert r.dphi[-1] == 0.0 and abs(W2 * math.sin(r.phi[-1])) <= 2.0
    assert r.stats.sticks + r.stats.reversals > 0
    s = Stepper(params, 1.0, 0.0, 0.05, 'rodas4', rtol=1e-8, atol=1e-10)
    s.advance(100)
    assert (s.phi, s.dphi) == (r.phi[-1], r.dphi[-1])


@pytest.mark.parametrize('nodes', [2, 3, 4])
def test_dense_interpolant_reproduces_polynomials_and_their_derivative(nodes: int) -> None:
    # The continuous extension of embedded.dense_run: Hermite through (y, y') at m nodes of
    # any spacing is exact for every polynomial of degree ≤ 2m − 1, and so is its derivative;
    # keeping the first 2j terms interpolates the first j nodes (the stencil cut at a kink).
    from pendulum_sim.core.embedded import hermite_eval

    rng = np.random.default_rng(nodes)
    size = 40
    x = np.cumsum(rng.uniform(0.05, 1.0, (4, size)), axis=0)  # spacings vary 20-fold
    t = rng.uniform(x[0], x[nodes - 1])
    polys = [np.polynomial.Polynomial(rng.normal(size=2 * nodes)) for _ in range(2)]
    y = np.array([[q(x[i]) for q in polys] for i in range(4)])  # (node, component, point)
    dy = np.array([[q.deriv()(x[i]) for q in polys] for i in range(4)])
    terms = None if nodes == 4 else np.full(size, 2 * nodes)
    val, der = hermite_eval(x, y, dy, terms, t)
    for c, q in enumerate(polys):
        np.testing.assert_allclose(val[c], q(t), rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(der[c], q.deriv()(t), rtol=1e-8, atol=1e-8)


@pytest.mark.parametrize('rtol', [1e-3, 1e-6])
def test_free_steps_resolve_a_stiff_start_and_cross_outputs(rtol: float) -> None:
    # γ = 1e4 from rest: φ' reaches the creep in ~1e-4 s. The first substep comes from the
    # scale of y, f and f' (embedded.initial_step), so the transient is resolved even at a loose
    # tolerance (a first trial of 1 s stepped over it: error 0.58 rad/s); on the creep the
    # substeps span many outputs, which are interpolated.
    params = PendulumParams(gamma=1e4, n=1.0)
    t = np.linspace(0.0, 5.0, 51)
    ref = _reference(params, t)
    r = simulate(params, 2.0, 0.0, 5.0, 0.1, 'rodas4', rtol=rtol, atol=rtol * 1e-2)
    err = float(np.max(ref.error(r.phi, r.dphi)))  # type: ignore[attr-defined]
    assert err <= 50.0 * rtol, err
    assert r.stats.substeps + 1 < len(t) - 1, r.stats  # fewer substeps than outputs


@pytest.mark.parametrize(('gamma', 'n'), [(1.0, 1.0), (1.0, 2.5), (1000.0, 2.0)])
def test_dense_run_agrees_with_stopping_at_every_output(gamma: float, n: float) -> None:
    # simulate (free substeps, interpolated outputs) and the Stepper (a cover per output) are
    # two routes to the same solution: both within the tolerance of each other.
    params = PendulumParams(gamma=gamma, n=n)
    rtol = 1e-8
    r = simulate(params, 2.0, 0.0, 5.0, 0.1, 'rodas4', rtol=rtol, atol=rtol * 1e-2)
    s = Stepper(params, 2.0, 0.0, 0.1, 'rodas4', rtol=rtol, atol=rtol * 1e-2)
    ps, vs = [s.phi], [s.dphi]
    for _ in range(50):
        s.step()
        ps.append(s.phi)
        vs.append(s.dphi)
    diff = np.hypot(r.phi - np.array(ps), r.dphi - np.array(vs))
    assert float(np.max(diff)) <= 20.0 * rtol * (2.0 + math.sqrt(W2)), float(np.max(diff))
