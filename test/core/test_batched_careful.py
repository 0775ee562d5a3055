"""The careful path batched over arrays takes the scalar careful path's floats, one by one.

``batched_careful.graded_steps`` serves the graded steps next to a reversal (non-integer
1 < n < 3) on the numpy sweep; each step it takes must be the very step ``Engine.careful``
takes from that state (the same floats, no counter moved), its mesh ``reversal.graded_mesh``'s,
and inside the shrunk guard range the guard's count must be one substep. A sweep of distinct
and non-integer n in one call agrees with the Stepper pendulum by pendulum.
"""
from __future__ import annotations

import math
import re

import numpy as np
import pytest

from pendulum_sim.core import METHODS, IntegratorError, PendulumParams, Stepper
from pendulum_sim.core.batched_careful import batchable_law, graded_meshes, graded_steps
from pendulum_sim.core.careful import NOT_TRIED, substep
from pendulum_sim.core.engine import Engine, guard_for
from pendulum_sim.core.explicit import compile_step_with_n
from pendulum_sim.core.guard import RANGE_MARGIN, GuardStats, safe_speed_range
from pendulum_sim.core.problem import Problem
from pendulum_sim.core.reversal import graded_mesh
from pendulum_sim.core.sweep import Sweep, sweep
from pendulum_sim.core.tableaus import RK4
from pendulum_sim.core.warm_up import warm_up


def test_batchable_laws_are_the_graded_ones_that_cannot_creep() -> None:
    assert [batchable_law(n) for n in (0.5, 1.0, 1.5, 2.0, 2.999, 3.0, 3.7)] == [
        False, False, True, False, True, False, False]


def test_meshes_are_the_scalar_meshes() -> None:
    rng = np.random.default_rng(3)
    size = 4000
    h = 1e-3
    window = rng.choice(np.array([0.05, 0.3, 1.0]), size)
    x = rng.uniform(0.0, 1.2, size) * window
    x[:200] = rng.uniform(0.0, 3.0 * h, 200)  # the steps next to the reversal: long meshes
    x[200:210] = 0.0
    back = rng.uniform(size=size) < 0.5
    x_a = np.where(back, np.maximum(x - h, 0.0), x)
    x_b = np.where(back, x, x + h)
    n = rng.uniform(1.0, 3.0, size)
    flat, start, count = graded_meshes(x_a, x_b, h, n, window)
    longest = 0
    for i in range(size):
        want = graded_mesh(float(x_a[i]), float(x_b[i]), h, float(n[i]), float(window[i]))
        got = flat[start[i]:start[i] + count[i]].tolist()
        assert got == want, i
        longest = max(longest, len(want))
    assert longest > 10  # the meshes next to a reversal were covered


@pytest.mark.parametrize('hint', [False, True])
@pytest.mark.parametrize('n', [1.5, 2.5, None])
def test_graded_steps_are_engine_careful(n: float | None, hint: bool) -> None:
    rng = np.random.default_rng(7)
    size = 3000
    h = 1e-3
    w2 = rng.choice(np.array([0.0, 9.8, 40.0]), size)
    gamma = rng.uniform(0.05, 3.0, size)
    nn = rng.uniform(1.01, 2.99, size) if n is None else np.full(size, n)
    p = rng.uniform(-3.0, 3.0, size)
    v = rng.uniform(-0.5, 0.5, size) * rng.choice(np.array([1e-4, 1e-2, 1.0]), size)
    ain = np.where(rng.uniform(size=size) < 0.3, rng.uniform(-5.0, 5.0, size), 0.0)
    reach = np.array([Problem(a, g, m).reach for a, g, m in zip(w2, gamma, nn, strict=True)])
    check = rng.uniform(size=size) < 0.8
    # With the hint, the fast path's φ'₁ (numpy's power, as the sweep passes it).
    fast = compile_step_with_n(RK4, 1.5, False, vector=True)(p, v, h, ain, w2, gamma, 1.0, nn)[1]
    done, p1, v1, _ = graded_steps(RK4, p, v, h, ain, w2, gamma, nn if n is None else n, reach,
                                   check, fast if hint else None)
    assert done.sum() > size // 2
    meth = METHODS['rk4']
    graded = 0
    for i in np.flatnonzero(done).tolist():
        eng = Engine(float(w2[i]), float(gamma[i]), float(nn[i]), meth, True, bool(check[i]))
        st = GuardStats()
        counts = [0] * 6
        want = substep(eng.steps, eng.pend, float(p[i]), float(v[i]), h, float(ain[i]), False,
                       NOT_TRIED, counts)[1:3]
        assert not any(counts), i
        # Engine.careful itself, where its guard's count is 1 (as the sweep hands it over).
        lo, hi = eng.fast_range(h, float(ain[i]))
        if lo * (1.0 + RANGE_MARGIN) <= abs(v[i]) <= hi * (1.0 - RANGE_MARGIN):
            want = eng.careful(float(p[i]), float(v[i]), h, float(ain[i]), st)[:2]
        assert (float(p1[i]), float(v1[i])) == want, i
        assert st == GuardStats(), i
        graded += abs(v[i]) < reach[i] * 1.0
    assert graded > size // 4


def test_inside_the_shrunk_range_the_guard_takes_one_substep() -> None:
    rng = np.random.default_rng(11)
    guard = guard_for(RK4)
    for _ in range(3000):
        w2 = float(rng.choice([0.0, 9.8, 40.0]))
        gamma = float(10.0 ** rng.uniform(-2.0, 3.0))
        n = float(rng.uniform(1.01, 2.99))
        h = float(rng.choice([1e-3, 1e-2, 5e-2]))
        ain = float(rng.choice([0.0, rng.uniform(-20.0, 20.0)]))
        lo, hi = safe_speed_range(guard, w2, gamma, n, h, abs(ain))
        if not lo <= hi:
            continue
        for v in (lo * (1.0 + RANGE_MARGIN), hi * (1.0 - RANGE_MARGIN),
                  float(rng.uniform(lo, hi))):
            phi = float(rng.uniform(-3.2, 3.2))
            m = guard.substeps(h, w2, gamma, n, phi, v, abs(ain) + w2,
                               abs(ain - w2 * math.sin(phi)))
            assert m == 1, (w2, gamma, n, h, ain, v)


def test_distinct_and_non_integer_n_in_one_sweep_agree_with_the_stepper() -> None:
    rng = np.random.default_rng(5)
    size = 60
    n = np.concatenate([rng.uniform(1.0, 3.0, 30), [1.5] * 10, [2.0] * 5, [0.5] * 5,
                        rng.uniform(0.2, 0.9, 5), [3.7] * 5])
    gamma = rng.uniform(0.1, 2.0, size)
    p0 = rng.uniform(-2.0, 2.0, size)
    v0 = rng.uniform(-3.0, 3.0, size)
    h, steps = 1e-3, 400
    res = sweep(9.8, gamma, n, p0, v0, steps * h, h)
    assert res.batched > 0  # the batched careful path took steps
    for i in range(size):
        s = Stepper(PendulumParams.from_omega0_sq(9.8, float(gamma[i]), float(n[i])),
                    float(p0[i]), float(v0[i]), h)
        s.advance(steps)
        st = s.stats
        got = (res.substeps[i], res.fallbacks[i], res.reversals[i], res.sticks[i])
        assert got == (st.substeps, st.fallbacks, st.reversals, st.sticks), i
        scale = 1.0 + abs(s.phi) + abs(s.dphi)
        assert abs(res.phi[i] - s.phi) <= 1e-12 * scale, i
        assert abs(res.dphi[i] - s.dphi) <= 1e-12 * scale, i


def test_distinct_exponents_of_one_text_are_one_group_on_numpy() -> None:
    rng = np.random.default_rng(9)
    n = np.concatenate([rng.uniform(1.0, 3.0, 50), [2.0] * 5, [0.5] * 3, [1.0] * 2])
    prepared = Sweep(9.8, 0.5, n, 1.0, 0.0, 1e-3)
    # n = 0.5, 1 and 2 each their own group; the 50 distinct others one, n a column of it.
    assert [grp.sl.stop - grp.sl.start for grp in prepared._groups] == [3, 2, 5, 50]
    merged = prepared._groups[-1]
    assert isinstance(merged.nn, np.ndarray)
    assert np.array_equal(np.sort(merged.nn), np.sort(n[:50]))


def test_warm_up_refuses_a_method_the_sweep_has_not() -> None:
    msg = "warm_up supports the sweep methods euler, midpoint, rk4, got 'dopri5'"
    with pytest.raises(IntegratorError, match=re.escape(msg)):
        warm_up(method='dopri5')
