"""Order for every real n through velocity reversals (issue 10's oracles).

The reference is independent of the core's stepping: scipy's DOP853 restarted at every
reversal (``reports.reference``), so each of its segments is smooth."""
from __future__ import annotations

import numpy as np
import pytest

from pendulum_sim.core import PendulumParams, simulate
from pendulum_sim.core.analysis import convergence_quotient

pytest.importorskip('scipy')
from pendulum_sim.reports.reference import reference

T_END = 6.0  # the paper's start reverses 5 times in 6 s for every n here


@pytest.mark.parametrize('n', [0.5, 1.5, 2.5, 3.5])
def test_rk4_keeps_order_four_through_reversals(n: float) -> None:
    # The paper's start: x0 = 2 rad, x1 = 0, ω0² = 9.8, γ = 1. The release from rest and each
    # reversal are t^n singularities of |φ'|^n; before the graded steps, RK4's fitted order
    # was 1.50 at n = 0.5, 2.51 at n = 1.5 and 3.60 at n = 2.5.
    params = PendulumParams(gamma=1.0, n=n)
    ref = reference(params, 2.0, 0.0, np.array([0.0, T_END]))
    hs = [0.02, 0.01, 0.005, 0.0025]
    errs = []
    for h in hs:
        r = simulate(params, 2.0, 0.0, T_END, h)
        assert r.stats.reversals == 5
        errs.append(float(np.hypot(r.phi[-1] - ref.phi[-1], r.dphi[-1] - ref.dphi[-1])))
    assert errs[-1] > 100.0 * ref.disagreement  # far above the reference's own error
    order = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert order >= 3.8, (order, errs)
    # Q(t) of eq 34 over the run: 16 for a 4th-order method.
    q = convergence_quotient(params, 2.0, 0.0, T_END, 1e-2).q[1:]
    assert 14.0 <= float(np.nanmedian(q)) <= 18.0


@pytest.mark.parametrize('method', ['dopri5', 'dop853'])
@pytest.mark.parametrize('n', [0.3, 0.5, 1.5])
def test_embedded_pairs_meet_their_tolerance_through_reversals(n: float, method: str) -> None:
    # Each accepted substep that crosses a reversal is cut there, so the pair's estimate stays
    # valid: the global error is within 10 × tol × state scale (it was ~900 × at n = 0.3).
    params = PendulumParams(gamma=1.0, n=n)
    t = np.linspace(0.0, T_END, 61)
    ref = reference(params, 2.0, 0.0, t)
    scale = float(np.max(np.hypot(ref.phi, ref.dphi)))
    for rtol in (1e-6, 1e-9):
        r = simulate(params, 2.0, 0.0, T_END, 0.1, method=method, rtol=rtol, atol=rtol * 1e-2)
        assert r.stats.reversals == 5
        err = float(np.max(np.hypot(r.phi - ref.phi, r.dphi - ref.dphi)))
        assert err <= 10.0 * rtol * scale, (n, rtol, err)


def test_dop853_step_is_of_order_eight() -> None:
    # The bare tableau in a fixed-step loop on a smooth case (n = 1): the error falls as h^8.
    # Its linear part: R(z) = Σ z^k / k! up to k = 8.
    from math import factorial

    from pendulum_sim.core.explicit import compile_step
    from pendulum_sim.core.tableaus import DOP853

    poly = DOP853.stability_poly
    for k in range(9):
        assert poly[k] == pytest.approx(1.0 / factorial(k), rel=1e-12)
    params = PendulumParams(gamma=1.0, n=1.0)
    step = compile_step(DOP853, 1.0)
    t_end = 4.0
    ref = reference(params, 1.0, 0.0, np.array([0.0, t_end]))
    hs, errs = [0.4, 0.2, 0.1], []
    for h in hs:
        p, v = 1.0, 0.0
        for _ in range(round(t_end / h)):
            p, v, _, _ = step(p, v, h, 0.0, params.omega0_sq, 1.0, 1.0)
        errs.append(float(np.hypot(p - ref.phi[-1], v - ref.dphi[-1])))
    assert min(errs) > 100.0 * ref.disagreement
    slope = float(np.polyfit(np.log(hs), np.log(errs), 1)[0])
    assert 7.5 <= slope <= 8.5, (errs, slope)


def test_a_split_that_finds_no_reversal_covers_the_whole_step() -> None:
    # n = 1.059, γ = 0.84 from (0.457 rad, 2.372 rad/s): the first reversal falls 12 µs after
    # the end of a step of 8 ms that starts within |φ'|/|φ''| <= h of it, so the step is split
    # but its branch step does not reach φ' = 0. Its graded substeps once covered only
    # |φ'|/|φ''| = 7.988 ms of the 8 ms (an error of 4.5e-5 where 4 ms gives 8e-11); they cover
    # h, and the error falls as h^4 through that step on every path.
    pytest.importorskip('numba')
    from pendulum_sim.core.sweep import sweep

    n, gamma = 1.0594493917784233, 0.8389507055602972
    p0, v0 = 0.45680574267181484, 2.3721725565586613
    params = PendulumParams.from_omega0_sq(9.8, gamma, n)
    t_end = 0.64
    ref = reference(params, p0, v0, np.array([0.0, t_end]))
    errs: dict[str, list[float]] = {'simulate': [], 'numpy': [], 'jit': []}
    for h in (0.008, 0.004):
        r = simulate(params, p0, v0, t_end, h)
        assert r.stats.reversals == 1
        ends = {'simulate': (r.phi[-1], r.dphi[-1])}
        for path, jit in (('numpy', False), ('jit', True)):
            s = sweep(9.8, gamma, n, p0, v0, t_end, h, jit=jit)
            ends[path] = (s.phi[0], s.dphi[0])
        for path, (p, v) in ends.items():
            errs[path].append(float(np.hypot(p - ref.phi[-1], v - ref.dphi[-1])))
    for path, (coarse, fine) in errs.items():
        assert fine > 100.0 * ref.disagreement
        assert coarse < 2.0 * 16.0 * fine, (path, coarse, fine)  # order 4: 16x, with margin
