"""``extrap6``, ``extrap8``: linearly implicit Euler extrapolated to order 6 and 8.

Oracles: its stability function against exp(z) and at z → −∞; the textbook scheme (numpy
solves, ``extrapolation_step``) for the generated step; an independent reference (scipy
restarted at every reversal, ``reports.reference``) for the runs.
"""
from __future__ import annotations

import cmath
import math

import numpy as np
import pytest
from augmented_field import augmented

from pendulum_sim.core import METHODS, PendulumParams, simulate
from pendulum_sim.core.extrapolation import compile_extrapolation, extrapolation_step
from pendulum_sim.core.tableaus import EXTRAP6, EXTRAP8, Extrapolation

W2 = 9.8


@pytest.mark.parametrize(('name', 'order'), [('extrap6', 6), ('extrap8', 8)])
def test_is_registered_as_an_adaptive_method(name: str, order: int) -> None:
    m = METHODS[name]
    assert (m.kind, m.order, m.fixed_step, m.tableau.explicit) == ('adaptive', order, False, False)
    assert m.tableau.error_order == order - 1


@pytest.mark.parametrize('ext', [EXTRAP6, EXTRAP8], ids=['extrap6', 'extrap8'])
def test_stability_function_damps_the_stiff_limit(ext: Extrapolation) -> None:
    r = ext.stability_function
    assert abs(r(-1e8)) < 1e-6  # every row's (1 − z/n)^(−n) vanishes at z → −∞
    assert max(abs(r(complex(-x, 0.0))) for x in np.logspace(-2, 8, 200)) <= 1.0


def test_stability_function_is_order_six() -> None:
    r = EXTRAP6.stability_function
    # Local error R(z) − e^z = O(z^7): halving z divides it by 128.
    ratio = abs(r(0.1) - cmath.exp(0.1)) / abs(r(0.05) - cmath.exp(0.05))
    assert 110.0 < ratio < 150.0, ratio


@pytest.mark.parametrize(('ext', 'atol'), [(EXTRAP6, 3e-13), (EXTRAP8, 3e-12)],
                         ids=['extrap6', 'extrap8'])
@pytest.mark.parametrize('n', [0.5, 1.0, 2.0, 2.5, 3.0])
@pytest.mark.parametrize('branch', [False, True])
def test_generated_step_is_the_reference_extrapolation_step(n: float, branch: bool,
                                                            ext: Extrapolation,
                                                            atol: float) -> None:
    g, ain = 0.7, 0.3
    p0, v0, h = 1.1, -0.8, 0.05
    sign = -1.0

    law, f, jac = augmented(g, n, ain, branch, sign, p0, v0)
    y1, err = extrapolation_step(ext, f, jac, np.array([p0, v0, 0.0]), h)
    got = compile_extrapolation(ext, n, branch)(p0, v0, h, ain, W2, g, sign)
    # The extrapolation combines the rows with weights whose magnitudes sum to 302 (six rows)
    # or 3392 (eight), so the two orders of summation differ by that many ulp.
    np.testing.assert_allclose(got[:3], y1, rtol=0.0, atol=atol)
    np.testing.assert_allclose(got[4:], err[:2], rtol=0.0, atol=atol)
    assert got[3] == pytest.approx(ain - law(v0) - W2 * math.sin(p0), abs=1e-15)


@pytest.mark.parametrize('ext', [EXTRAP6, EXTRAP8], ids=['extrap6', 'extrap8'])
@pytest.mark.parametrize('turns', [16, 160, 1600])
def test_round_off_of_a_step_does_not_grow_with_the_weights(ext: Extrapolation,
                                                            turns: int) -> None:
    # The same step from φ₀ and from φ₀ + 2π k: the law is the same, so the increments differ
    # by round-off only. Summed apart from the state, the increments carry that of the state
    # (≈ eps |φ₀|) once; taken as (state − φ₀) they carried it times the extrapolation
    # weights (|weights| sum to 3392 for extrap8: 30–2000× eps |φ₀| measured).
    step = compile_extrapolation(ext, 2.0, branch=True)
    shift = 2.0 * math.pi * turns
    p0, v0 = 0.5, -0.1
    base = step(p0, v0, 0.1, 0.0, W2, 1000.0, -1.0)
    moved = step(p0 + shift, v0, 0.1, 0.0, W2, 1000.0, -1.0)
    scale = np.finfo(float).eps * (p0 + shift)
    assert abs((moved[0] - shift) - base[0]) <= 2.0 * scale
    assert abs(moved[1] - base[1]) <= 10.0 * scale


def test_fixed_step_order_is_six() -> None:
    # The bare generated step in a fixed-step loop on the conservative pendulum (γ = 0, where
    # the asymptotic range starts early): error ∝ h⁶. With damping the slopes wander between
    # 5.4 and 6.6 over the same h (error constants of changing sign), the runs below check it.
    step = compile_extrapolation(EXTRAP6, 1.0)
    ref = simulate(PendulumParams(gamma=0.0, n=1.0), 1.0, 0.0, 2.0, 2.0, 'dop853',
                   rtol=1e-14, atol=1e-16)
    errs = []
    for h in (0.1, 0.05, 0.025, 0.0125):
        p, v = 1.0, 0.0
        for _ in range(round(2.0 / h)):
            p, v, _, _, _, _ = step(p, v, h, 0.0, W2, 0.0, 1.0)
        errs.append(math.hypot(p - ref.phi[-1], v - ref.dphi[-1]))
    slopes = [math.log2(errs[i] / errs[i + 1]) for i in range(3)]
    assert all(abs(s - 6.0) < 0.5 for s in slopes), (errs, slopes)


def test_fixed_step_order_of_extrap8() -> None:
    # The order-8 step on the conservative pendulum: least-squares slope of log error over
    # h = 0.4 … 0.05 (below that the weights' round-off, ~1e-12 after 40 steps, takes over;
    # the successive slopes there are 9.1, 6.2, 7.6: pre-asymptotic, of changing sign).
    step = compile_extrapolation(EXTRAP8, 1.0)
    ref = simulate(PendulumParams(gamma=0.0, n=1.0), 1.0, 0.0, 2.0, 2.0, 'dop853',
                   rtol=1e-14, atol=1e-16)
    hs, errs = (0.4, 0.2, 0.1, 0.05), []
    for h in hs:
        p, v = 1.0, 0.0
        for _ in range(round(2.0 / h)):
            p, v, _, _, _, _ = step(p, v, h, 0.0, W2, 0.0, 1.0)
        errs.append(math.hypot(p - ref.phi[-1], v - ref.dphi[-1]))
    slope = float(np.polyfit(np.log(hs), np.log(errs), 1)[0])
    assert 7.3 <= slope <= 8.7, (errs, slope)


@pytest.mark.parametrize('method', ['extrap6', 'extrap8'])
@pytest.mark.parametrize(('gamma', 'n', 'rtol'), [
    (1.0, 0.5, 1e-8), (1.0, 1.5, 1e-8), (1000.0, 2.0, 1e-9), (1e4, 1.0, 1e-9),
])
def test_runs_meet_the_reference(gamma: float, n: float, rtol: float, method: str) -> None:
    # Through reversals (cut by the shared treatment of embedded.cover) and on stiff creeps.
    pytest.importorskip('scipy')
    from pendulum_sim.reports.reference import reference

    params = PendulumParams(gamma=gamma, n=n)
    t = np.linspace(0.0, 5.0, 51)
    ref = reference(params, 2.0, 0.0, t)
    assert ref is not None
    r = simulate(params, 2.0, 0.0, 5.0, 0.1, method, rtol=rtol, atol=rtol * 1e-2)
    err = float(np.max(ref.error(r.phi, r.dphi)))
    assert err <= max(20.0 * rtol * (2.0 + math.sqrt(W2)), 10.0 * ref.disagreement), err
    if n in (0.5, 1.5):
        assert r.stats.reversals == ref.segments > 0
