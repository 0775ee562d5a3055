"""The stiff transient's cover written to compile decides as the adaptive methods' cover.

``stiff.stiff_cover`` (which the careful step runs, in Python and compiled) and
``embedded.cover`` (the adaptive methods' trial loop) share their error control
(``error_control.py``). Oracle: ``embedded.cover`` itself, run with the same pair (``dop853``,
the exponent bound in), tolerance, first trial and trial limit: the two loops must give the same
floats and counts, and fail (``CoverFailed`` / ``TO_GUARD``) on the same steps.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from pendulum_sim.core import embedded, error_control, stiff
from pendulum_sim.core.decisions import (
    STIFF_MAX_TRIALS,
    STIFF_PAIR,
    STIFF_TOL,
    accuracy_speed,
    stiff_transient,
)
from pendulum_sim.core.guard import GuardStats
from pendulum_sim.core.law import damping_derivative, power_formula
from pendulum_sim.core.model import run_speed_limit
from pendulum_sim.core.problem import Problem


def _by_embedded_cover(prob: Problem, p: float, v: float, h: float,
                       ain: float) -> tuple[int, float, float, float, int, int]:
    """Return the step as ``embedded.cover`` takes it with the stiff path's settings."""
    tol = STIFF_TOL * (h * max(prob.omega0, 1.0)) ** 4
    d = damping_derivative(prob.gamma, prob.n, v)
    first = min(h, 1.0 / d) if d > 0.0 else h
    st = GuardStats()
    try:
        p1, v1, w, _ = embedded.cover(prob, STIFF_PAIR, embedded.pair_steps(STIFF_PAIR, prob.n),
                                      p, v, h, ain, tol, tol, first, st,
                                      STIFF_MAX_TRIALS)
    except embedded.CoverFailed:
        return stiff.TO_GUARD, p, v, 0.0, st.substeps, st.reversals
    return stiff.TAKEN, p1, v1, w, st.substeps, st.reversals


@pytest.mark.parametrize('n', [1.5, 2.0, 2.5, 4.0, 5.0, 6.0])
def test_the_stiff_cover_takes_the_adaptive_covers_substeps(n: float) -> None:
    rng = np.random.default_rng(int(10 * n))
    pair = stiff.stiff_pair(n)
    taken = subs = turns = 0
    for _ in range(150):
        gamma = float(rng.choice([0.5, 2.0, 10.0, 50.0]))
        w2 = float(rng.choice([0.0, 9.8, 40.0]))
        h = float(rng.choice([1e-3, 2e-2, 5e-2, 0.2]))
        ain = float(rng.choice([0.0, 1.7, -3.0]))
        p = float(rng.uniform(-3.0, 3.0))
        speed = min(accuracy_speed(gamma, n, math.sqrt(w2)) * float(rng.uniform(1.5, 30.0)),
                    0.5 * run_speed_limit(gamma, n, w2))
        v = speed if rng.uniform() < 0.5 else -speed
        prob = Problem(w2, gamma, n)
        if not stiff_transient(abs(v), ain - prob.damping(v) - w2 * math.sin(p), gamma,
                               power_formula(abs(v), n), prob.v_acc):
            continue  # the input and gravity balance the damping: not a stiff transient
        got = stiff.stiff_cover(*pair, p, v, h, ain, w2, gamma, n, prob.nonsmooth, False)
        want = _by_embedded_cover(prob, p, v, h, ain)
        assert got == want, (gamma, w2, h, ain, p, v)
        taken += got[0] == stiff.TAKEN
        subs += got[4]
        turns += got[5]
    assert taken > 100 and subs > 200
    assert turns > 0 if prob.nonsmooth else turns == 0  # reversals cut alike


def test_a_step_the_substeps_cannot_cover_fails_alike() -> None:
    # γ = 1e5, n = 1.5: the substeps chatter at rest and spend STIFF_MAX_TRIALS trials.
    n, gamma, w2, h = 1.5, 1e5, 1e4, 0.2
    prob = Problem(w2, gamma, n)
    for ain, p, v in [(1.7, -0.18886198245603225, 34.53516442633296),
                      (0.0, -2.808724818925504, 0.006014820267336139)]:
        got = stiff.stiff_cover(*stiff.stiff_pair(n), p, v, h, ain, w2, gamma, n,
                                prob.nonsmooth, False)
        want = _by_embedded_cover(prob, p, v, h, ain)
        assert got[0] == want[0] == stiff.TO_GUARD
        assert got[4:] == want[4:] and got[4] == STIFF_MAX_TRIALS


def test_an_overflowing_slope_is_reported_not_raised() -> None:
    # γ n |φ'|^(n−1) beyond float64: the code OVERFLOW (the careful step then has the fallback
    # take the step as Python, and declines it compiled).
    got = stiff.stiff_cover(*stiff.stiff_pair(2.5), 0.5, 1e200, 1e-3, 0.0, 9.8, 1e10, 2.5,
                            True, True)
    assert got == (stiff.OVERFLOW, 0.5, 1e200, 0.0, 0, 0)


def test_both_loops_call_the_one_error_control() -> None:
    shared = {'error_norm', 'accepted', 'step_factor'}
    assert shared <= set(embedded.cover.__code__.co_names)
    assert {'accepted', 'step_factor'} <= set(stiff.stiff_cover.__code__.co_names)
    assert 'error_norm' in stiff.trial.__code__.co_names
    # The factor's bounds: at most MAX_GROWTH after an accepted trial, at least MIN_SHRINK
    # after a rejected one (NaN and inf included), 0.9 err^(−q) between.
    q = stiff.STIFF_Q
    assert error_control.step_factor(0.0, q) == error_control.MAX_GROWTH
    assert error_control.step_factor(1e-30, q) == error_control.MAX_GROWTH
    assert error_control.step_factor(0.5, q) == 0.9 * 0.5 ** -q
    assert error_control.step_factor(2.0, q) == 0.9 * 2.0 ** -q
    assert error_control.step_factor(1e30, q) == error_control.MIN_SHRINK
    assert error_control.step_factor(math.nan, q) == error_control.MIN_SHRINK
    assert error_control.step_factor(math.inf, q) == error_control.MIN_SHRINK
    assert not error_control.accepted(math.nan)
    assert error_control.error_norm(0.0, 1.0, 0.0, 2.0, 0.0, 0.0, 1e-6, 1e-6, 1.5) == math.inf
