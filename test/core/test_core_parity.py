"""One physics: the Stepper and the sweep take the same decisions and agree to round-off, and
every generated step is the plain reference ``rk_step`` of its tableau."""
from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from pendulum_sim.core import PendulumParams, Stepper
from pendulum_sim.core.explicit import compile_step
from pendulum_sim.core.rk import rk_step
from pendulum_sim.core.sweep import sweep
from pendulum_sim.core.tableaus import TABLEAUS

W2 = 9.8

# (γ, n, h, φ0, φ'0): smooth and non-smooth laws, Coulomb, stiff cells that need substeps and
# the fallback, a spinning start, coarse and fine steps.
GRID = list(itertools.product(
    [0.0, 1.0, 30.0, 1e4],  # γ
    [0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 5.0],  # n
    [1e-3, 2e-2],  # h
    [0.3, 2.0, 3.1],  # φ0
    [0.0, 8.0],  # φ'0
))


@pytest.mark.parametrize('h', [1e-3, 2e-2])
def test_stepper_and_sweep_take_the_same_decisions(h: float) -> None:
    cells = [c for c in GRID if c[2] == h]
    gam, nn, _, p0, v0 = (np.array(col) for col in zip(*cells, strict=True))
    steps = 40
    res = sweep(W2, gam, nn, p0, v0, steps * h, h)
    acted = 0
    for i, (g, n, _, x0, dx0) in enumerate(cells):
        s = Stepper(PendulumParams.from_omega0_sq(W2, g, n), x0, dx0, h)
        s.advance(steps)
        st = s.stats
        # The same decisions: every careful-path action counted alike.
        got = (res.substeps[i], res.fallbacks[i], res.reversals[i], res.sticks[i])
        assert got == (st.substeps, st.fallbacks, st.reversals, st.sticks), cells[i]
        acted += any(got)
        # The same numbers, to round-off (numpy's and math's sin may differ in the last ulp).
        scale = 1.0 + abs(s.phi) + abs(s.dphi)
        assert abs(res.phi[i] - s.phi) <= 1e-12 * scale, cells[i]
        assert abs(res.dphi[i] - s.dphi) <= 1e-12 * scale, cells[i]
    assert acted >= len(cells) // 6  # the grid exercises the careful path, not just plain steps


@pytest.mark.parametrize('name', ['euler', 'midpoint', 'rk4', 'dopri5', 'dop853'])
@pytest.mark.parametrize('n', [0.0, 0.5, 1.0, 2.0, 2.5, 3.0])
def test_generated_steps_are_the_reference_rk_step(name: str, n: float) -> None:
    tab = TABLEAUS[name]
    gamma, ain = 0.7, 0.3

    def f(y: np.ndarray) -> np.ndarray:
        v = y[1]
        d = 0.0 if v == 0.0 else gamma * math.copysign(abs(v) ** n, v)
        return np.array([v, ain - d - W2 * math.sin(y[0])])

    scalar = compile_step(tab, n)
    vector = compile_step(tab, n, vector=True)
    rng = np.random.default_rng(11)
    p = rng.uniform(-3.0, 3.0, 16)
    v = rng.uniform(-4.0, 4.0, 16)
    h = 0.05
    pv, vv, _, _ = vector(p, v, h, ain, W2, gamma, 1.0)
    for k in range(p.size):
        ref = rk_step(tab, f, np.array([p[k], v[k]]), h)
        p1, v1, _, _ = scalar(float(p[k]), float(v[k]), h, ain, W2, gamma, 1.0)
        for got in ((p1, v1), (pv[k], vv[k])):
            assert abs(got[0] - ref[0]) <= 1e-14 * (1.0 + abs(ref[0]))
            assert abs(got[1] - ref[1]) <= 1e-14 * (1.0 + abs(ref[1]))


def test_branch_step_is_the_smooth_continuation_of_one_side() -> None:
    # s γ |v|^n equals γ v|v|^(n−1) while v has the sign s, and continues it smoothly.
    tab = TABLEAUS['rk4']
    branch = compile_step(tab, 1.5, branch=True)
    plain = compile_step(tab, 1.5)
    assert branch(1.0, 2.0, 0.01, 0.0, W2, 0.5, 1.0) == plain(1.0, 2.0, 0.01, 0.0, W2, 0.5, 1.0)
    assert branch(1.0, -2.0, 0.01, 0.0, W2, 0.5, -1.0) == plain(1.0, -2.0, 0.01, 0.0, W2, 0.5,
                                                                 1.0)
