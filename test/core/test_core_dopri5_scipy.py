"""dopri5 against scipy's RK45 (the same Dormand-Prince 5(4) pair) at the same tolerances.

On each case and tolerance (atol = rtol and atol = rtol/100) where RK45 succeeds, the largest
error of ``simulate(..., 'dopri5')`` over the outputs is within 3x of RK45's, both measured
against scipy's DOP853 at rtol 1e-13, and it falls in proportion to rtol (the error control is
honoured, not merely bounded by the output spacing).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from pendulum_sim.core import PendulumParams, simulate

W2 = 9.8
CASES = [
    (5.23, 0.00264, 0.55, 6.0),   # a fast damped transient at the start (non-integer n)
    (2.0, 1.0, 2.0, 0.0),          # the paper's n = 2 from 2 rad
    (1.5, 0.3, 1.0, 2.0),
    (3.0, 0.05, 0.5, 4.0),
]
RTOLS = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8)
T_END, OUTPUTS = 5.0, 50


def errors(n: float, gamma: float, p0: float, v0: float,
           atol_scale: float) -> list[tuple[float, float, float]]:
    def f(_t: float, y: np.ndarray) -> list[float]:
        return [y[1], -gamma * math.copysign(abs(y[1]) ** n, y[1]) - W2 * math.sin(y[0])]

    ts = np.linspace(0.0, T_END, OUTPUTS + 1)
    ref = solve_ivp(f, (0.0, T_END), [p0, v0], method='DOP853', rtol=1e-13, atol=1e-13,
                    t_eval=ts).y
    out = []
    for rtol in RTOLS:
        atol = atol_scale * rtol
        rk45 = solve_ivp(f, (0.0, T_END), [p0, v0], method='RK45', rtol=rtol, atol=atol,
                         t_eval=ts)
        theirs = float(np.max(np.abs(rk45.y - ref))) if rk45.success else math.nan
        run = simulate(PendulumParams.from_omega0_sq(W2, gamma, n), p0, v0, T_END,
                       T_END / OUTPUTS, 'dopri5', rtol=rtol, atol=atol)
        ours = max(float(np.max(np.abs(run.phi - ref[0]))),
                   float(np.max(np.abs(run.dphi - ref[1]))))
        out.append((rtol, ours, theirs))
    return out


@pytest.mark.parametrize('atol_scale', [1.0, 1e-2])
@pytest.mark.parametrize(('n', 'gamma', 'p0', 'v0'), CASES)
def test_dopri5_error_within_3x_of_rk45_and_proportional_to_rtol(
        n: float, gamma: float, p0: float, v0: float, atol_scale: float) -> None:
    rows = errors(n, gamma, p0, v0, atol_scale)
    for rtol, ours, theirs in rows:
        if math.isfinite(theirs):
            assert ours <= 3.0 * theirs, (rtol, ours, theirs)
    # Three decades of rtol: at least two decades less error.
    by_rtol = {rtol: ours for rtol, ours, _ in rows}
    assert by_rtol[1e-8] <= 1e-2 * by_rtol[1e-5]
