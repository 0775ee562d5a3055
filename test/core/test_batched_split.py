"""The reversal split batched over arrays takes the scalar split's floats and counts, one by one.

``batched_split.split_steps`` serves the steps that cross a velocity reversal (non-integer
1 < n < 3) on the numpy sweep; each split it takes must be ``split.split_step``'s from that
state to the bit (and, inside the guard's shrunk range, ``Engine.careful``'s with its reversal
count), and each it cannot take exactly (the run from rest beyond its bounds, no force at rest,
a value not finite) must be handed back. A sweep with the splits batched takes the floats and
counts of one with the splits taken one by one.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import pendulum_sim.core.sweep as sweep_module
from pendulum_sim.core import METHODS
from pendulum_sim.core.batched_split import (
    SCALAR_BELOW,
    careful_steps,
    hermite_roots,
    split_steps,
)
from pendulum_sim.core.engine import Engine
from pendulum_sim.core.explicit import compile_step_with_n
from pendulum_sim.core.guard import RANGE_MARGIN, GuardStats
from pendulum_sim.core.law import compile_laws
from pendulum_sim.core.problem import Problem
from pendulum_sim.core.reversal import hermite_root
from pendulum_sim.core.split import split_step
from pendulum_sim.core.sweep import sweep
from pendulum_sim.core.tableaus import RK4

FIELDS = ('phi', 'dphi', 'energy', 'substeps', 'fallbacks', 'reversals', 'sticks',
          'energy_rejections', 'projections')


@pytest.mark.parametrize('size', [SCALAR_BELOW - 1, 4000])
def test_hermite_roots_are_the_scalar_roots(size: int) -> None:
    rng = np.random.default_rng(2)
    v0 = rng.uniform(0.01, 1.0, size) * rng.choice(np.array([-1.0, 1.0]), size)
    v1 = -np.sign(v0) * rng.uniform(0.0, 1.0, size)
    dv0 = (v1 - v0) * rng.uniform(0.2, 3.0, size)
    dv1 = dv0 * rng.uniform(0.5, 1.5, size)
    v1[:5] = 0.0
    dv1[5:10] = 0.0
    want = [hermite_root(*x) for x in zip(v0.tolist(), v1.tolist(), dv0.tolist(), dv1.tolist(),
                                          strict=True)]
    assert hermite_roots(v0, v1, dv0, dv1).tolist() == want


def crossing_states(rng: np.random.Generator, size: int, n: float | None, h: float
                    ) -> tuple[np.ndarray, ...]:
    """Return (φ, φ', a_in, ω0², γ, n, reach) of steps of h that mostly cross φ' = 0."""
    w2 = rng.choice(np.array([0.0, 9.8, 40.0]), size)
    gamma = 10.0 ** rng.uniform(-1.5, 0.7, size)
    nn = rng.uniform(1.01, 2.99, size) if n is None else np.full(size, n)
    p = rng.uniform(-3.0, 3.0, size)
    ain = np.where(rng.uniform(size=size) < 0.4, rng.uniform(-8.0, 8.0, size), 0.0)
    ain[w2 == 0.0] = rng.uniform(-5.0, 5.0, int(np.count_nonzero(w2 == 0.0)))
    force = ain - w2 * np.sin(p)
    # Against the force, stopping within about the step (some beyond it: graded, no crossing).
    v = -force * h * rng.uniform(0.01, 1.6, size)
    v[:20] *= 1e-6  # next to rest
    reach = np.array([Problem(a, g, m).reach for a, g, m in zip(w2, gamma, nn, strict=True)])
    return p, v, ain, w2, gamma, nn, reach


def plain_a0(p: np.ndarray, v: np.ndarray, h: float, ain: np.ndarray, w2: np.ndarray,
             gamma: np.ndarray, nn: np.ndarray) -> np.ndarray:
    """Return the scalar plain step's φ''₀ of each state (the C library's powers)."""
    plain = compile_step_with_n(RK4, 1.5)
    return np.array([plain(*x, 1.0, m)[3] for *x, m in zip(
        p.tolist(), v.tolist(), [h] * p.size, ain.tolist(), w2.tolist(), gamma.tolist(),
        nn.tolist(), strict=True)])


@pytest.mark.parametrize('h', [1e-3, 1e-2])
@pytest.mark.parametrize('size', [SCALAR_BELOW - 2, 3000])
@pytest.mark.parametrize('n', [1.5, None])
def test_split_steps_are_split_step(n: float | None, size: int, h: float) -> None:
    rng = np.random.default_rng(17 + size)
    p, v, ain, w2, gamma, nn, reach = crossing_states(rng, size, n, h)
    if size > 100:  # no force at rest (ω0² = 0, no input): a step too stiff overshoots rest
        w2[-30:], ain[-30:], gamma[-30:] = 0.0, 0.0, 3.0 / h
        v[-30:] = rng.uniform(0.5, 3.0, 30) * rng.choice(np.array([-1.0, 1.0]), 30)
    a0 = plain_a0(p, v, h, ain, w2, gamma, nn)
    with np.errstate(all='ignore'):
        done, p1, v1, w, turns = split_steps(RK4, p, v, h, ain, w2, gamma,
                                             1.5 if n is not None else nn, a0, reach)
    plain = compile_step_with_n(RK4, 1.5)
    branch = compile_step_with_n(RK4, 1.5, branch=True)
    laws = compile_laws(1.5)
    turned = handed = 0
    for i in range(size):
        try:
            res = split_step(plain, branch, laws, float(p[i]), float(v[i]), h, float(ain[i]),
                             float(w2[i]), float(gamma[i]), float(nn[i]), float(a0[i]),
                             float(reach[i]), False)
        except OverflowError:  # |φ'|^n beyond float64 (Engine.careful: the fallback)
            assert not done[i], i
            handed += 1
            continue
        ok, q1, u1, wi, ti, pm = res[:6]
        after = float(ain[i]) - float(w2[i]) * math.sin(pm)
        exact = ok and (ti == 0 or after != 0.0) and all(map(math.isfinite, (q1, u1, wi)))
        assert bool(done[i]) == exact, i
        if exact:
            assert (float(p1[i]), float(v1[i]), float(w[i]), int(turns[i])) == (q1, u1, wi, ti)
            turned += ti
        else:
            handed += 1
    assert turned > size // 2  # most crossed φ' = 0
    if size > 100:
        assert handed >= 20  # most states with no force at rest went back


@pytest.mark.parametrize('n', [1.5, None])
def test_careful_steps_are_engine_careful(n: float | None) -> None:
    rng = np.random.default_rng(23)
    h = 1e-3
    meth = METHODS['rk4']
    p, v, ain, w2, gamma, nn, reach = crossing_states(rng, 6000, n, h)
    inside = []
    for i in range(p.size):  # the guard's count 1 (as the sweep hands them over)
        eng = Engine(float(w2[i]), float(gamma[i]), float(nn[i]), meth)
        lo, hi = eng.fast_range(h, float(ain[i]))
        if lo * (1.0 + RANGE_MARGIN) <= abs(v[i]) <= hi * (1.0 - RANGE_MARGIN):
            inside.append(i)
    rows = np.array(inside)
    p, v, ain, w2, gamma, nn, reach = (x[rows] for x in (p, v, ain, w2, gamma, nn, reach))
    check = rng.uniform(size=rows.size) < 0.8
    with np.errstate(all='ignore'):
        done, p1, v1, _, turns = careful_steps(RK4, p, v, h, ain, w2, gamma,
                                               1.5 if n is not None else nn, reach, check,
                                               split_min=1)
    taken = 0
    for i in range(rows.size):
        eng = Engine(float(w2[i]), float(gamma[i]), float(nn[i]), meth, True, bool(check[i]))
        st = GuardStats()
        want = eng.careful(float(p[i]), float(v[i]), h, float(ain[i]), st)[:2]
        if st.fallbacks or st.energy_rejections:
            assert not done[i], i
        if done[i]:
            assert (float(p1[i]), float(v1[i])) == want, i
            assert st == GuardStats(reversals=int(turns[i])), i
            taken += int(turns[i])
    assert taken > rows.size // 2


@pytest.mark.parametrize('torque', [0.0, 1.5])
@pytest.mark.parametrize('case', ['n = 1.5', 'distinct n'])
def test_a_sweep_with_the_splits_batched_is_the_sweep_one_by_one(
        case: str, torque: float, monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(29)
    size = 300
    n = np.full(size, 1.5) if case == 'n = 1.5' else rng.uniform(1.0, 3.0, size)
    gamma = rng.uniform(0.1, 2.0, size)
    p0 = rng.uniform(-2.0, 2.0, size)
    v0 = rng.uniform(-3.0, 3.0, size)
    tau = np.where(rng.uniform(size=size) < 0.5, torque, 0.0)
    runs = {}
    for split_min in (1, 10 ** 9):
        monkeypatch.setattr(sweep_module, 'SPLIT_MIN', split_min)
        runs[split_min] = sweep(9.8, gamma, n, p0, v0, 0.4, 1e-3, torque=tau)
    batched, one_by_one = runs[1], runs[10 ** 9]
    for field in FIELDS:
        assert np.array_equal(getattr(batched, field), getattr(one_by_one, field)), field
    assert one_by_one.reversals.sum() > 50
    assert batched.handed_back < one_by_one.handed_back // 10
    moved = one_by_one.handed_back - batched.handed_back
    assert batched.batched + batched.handed_back == one_by_one.batched + one_by_one.handed_back
    assert moved > 50
