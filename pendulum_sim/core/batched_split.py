"""The careful path's reversal split, batched over the pendulums whose step crosses φ' = 0.

For a non-integer 1 < n < 3 a step that crosses a velocity reversal is split there
(``split.split_step``): the reversal is located on the branch step's own φ'(θh) = 0
(``reversal.locate_on_branch``: a Hermite guess, ``reversal.hermite_root``, then Newton), the
graded run up to it is moved onto φ' = 0 (``reversal.graded_landing``) and the rest of the step is
a graded branch run from rest on the side of the force (``reversal.branch_run`` over
``reversal.graded_mesh``). :func:`split_steps` takes those splits over arrays, each pendulum by
exactly its scalar operations: the loops whose exits depend on the data (the Hermite root's Newton
and bisection, the two Newton runs) are masked loops in which each pendulum does its own iterations
and leaves where its scalar loop leaves (below :data:`SCALAR_BELOW` pendulums the Hermite roots and
the meshes are the scalar functions' own, one call each); the steps are the generated vector texts
with the exponent an argument (``explicit.compile_step_with_n``), the meshes and runs
``batched_careful.graded_meshes`` and ``branch_runs``, the landing's work the law's text
(``law.compile_laws``); every power is the C library's (``law.ExactExponent``) and the sines are
numpy's, as in ``batched_careful.py``. A test compares it with ``Engine.careful`` on random and
edge states (``test_batched_split.py``).

:func:`careful_steps` is the batched careful path on the numpy sweep: the plain and graded
steps (``batched_careful.graded_parts``), these splits, and the finiteness and energy tests
(``batched_careful.settled``). A split it cannot take exactly is handed back to the scalar path
from the same state (nothing counted or changed for it): where the run from rest breaks its
bounds (the fallback), the force at rest is zero (``split_step``'s plain step), a value is not
finite, or a Newton step would divide by a zero that Python refuses. Each split it takes counts
one reversal (``GuardStats.reversals``, as ``careful.substep`` counts it) where the branch
step reached φ' = 0, none where it did not.
"""
from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from .batched_careful import branch_runs, graded_meshes, graded_parts, settled
from .explicit import compile_step_with_n
from .law import ExactExponent, compile_laws
from .reversal import (
    GRADED_ITERATIONS,
    GRADED_TOL,
    HERMITE_ITERATIONS,
    NEWTON_ITERATIONS,
    NEWTON_TOL,
    graded_mesh,
    hermite_root,
)
from .tableaus import Tableau

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

SCALAR_BELOW = 32
"""Below this many pendulums the Hermite roots and the graded meshes are taken by the scalar
functions themselves (``reversal.hermite_root``, ``reversal.graded_mesh``), one call each:
their loops run up to 60 iterations, and a numpy pass over a few elements costs as much as a
few dozen scalar ones."""

SPLIT_MIN = 48
"""Splits of one batch below which :func:`careful_steps` hands them all to the scalar path.

A batch of splits takes some 40 numpy passes of a branch step per graded run, four runs deep,
whatever its width: about 2.5 ms, the time of some 20 scalar splits (~0.12 ms each). Measured
on crossing states like ``bench/bench_real_n.py``'s (rk4, n = 1.5, ω0² = 9.8, γ in [0.1, 2],
h = 1 ms), a batch is as fast as the scalar splits at about 50 of them and 3x faster at 256."""


def _at(n: Any, rows: IntArray) -> Any:
    """Return the exponent of the pendulums ``rows``: ``n`` itself or its rows."""
    return n[rows] if isinstance(n, np.ndarray) else n


def meshes(x_a: FloatArray, x_b: FloatArray, h: float, n: Any, window: FloatArray
           ) -> tuple[FloatArray, IntArray, IntArray]:
    """Return ``batched_careful.graded_meshes``: below SCALAR_BELOW, ``graded_mesh`` on each."""
    if x_a.size >= SCALAR_BELOW:
        return graded_meshes(x_a, x_b, h, n, window)
    nn = np.broadcast_to(n, x_a.shape).tolist()
    lists = [graded_mesh(*x) for x in zip(x_a.tolist(), x_b.tolist(), [h] * x_a.size, nn,
                                          window.tolist(), strict=True)]
    count = np.array([len(x) for x in lists], dtype=np.int64)
    flat = np.array([d for x in lists for d in x])
    return flat, np.cumsum(count) - count, count


def _finite(*xs: FloatArray) -> BoolArray:
    """Return where every one of ``xs`` is finite.

    A value the scalar path would not have made finite (``**`` beyond float64 raises there,
    ``math.sin`` of an infinity too) hands the pendulum back, so that the scalar path decides.
    """
    out: BoolArray = np.isfinite(xs[0])
    for x in xs[1:]:
        out &= np.isfinite(x)
    return out


def _max(a: Any, b: Any) -> FloatArray:
    """Return Python's ``max(a, b)`` element-wise: ``b`` only where ``b > a``."""
    out: FloatArray = np.where(b > a, b, a)
    return out


def _min(a: Any, b: Any) -> FloatArray:
    """Return Python's ``min(a, b)`` element-wise: ``b`` only where ``b < a``."""
    out: FloatArray = np.where(b < a, b, a)
    return out


def hermite_roots(v0: FloatArray, v1: FloatArray, dv0: FloatArray,
                  dv1: FloatArray) -> FloatArray:
    """Return ``reversal.hermite_root`` for arrays: each element by its scalar iterations.

    The same operations in the same order; an element leaves the loop where the scalar one
    returns (f = 0, or a Newton or bisection move of at most 1e-15). Below SCALAR_BELOW
    elements, ``hermite_root`` itself on each.
    """
    if v0.size < SCALAR_BELOW:
        return np.array([hermite_root(*x) for x in zip(v0.tolist(), v1.tolist(), dv0.tolist(),
                                                        dv1.tolist(), strict=True)])
    th = v0 / (v0 - v1)
    out = th.copy()
    idx = np.arange(v0.size)
    lo, hi = np.zeros(v0.size), np.ones(v0.size)
    neg = v0 < 0.0  # (flo < 0.0), flo = v0
    for _ in range(HERMITE_ITERATIONS):
        if not idx.size:
            break
        t2 = th * th
        t3 = t2 * th
        f = ((2 * t3 - 3 * t2 + 1) * v0 + (t3 - 2 * t2 + th) * dv0
             + (-2 * t3 + 3 * t2) * v1 + (t3 - t2) * dv1)
        hit = f == 0.0  # returns th
        below = (f < 0.0) == neg
        lo = np.where(below, th, lo)
        hi = np.where(below, hi, th)
        df = ((6 * t2 - 6 * th) * v0 + (3 * t2 - 4 * th + 1) * dv0
              + (-6 * t2 + 6 * th) * v1 + (3 * t2 - 2 * th) * dv1)
        mid = 0.5 * (lo + hi)
        nt = np.where(df != 0.0, th - f / np.where(df != 0.0, df, 1.0), mid)
        nt = np.where((lo < nt) & (nt < hi), nt, mid)
        out[idx] = np.where(hit, th, nt)
        go = ~hit & ~(np.abs(nt - th) <= 1e-15)
        idx, th, lo, hi, neg = idx[go], nt[go], lo[go], hi[go], neg[go]
        v0, v1, dv0, dv1 = v0[go], v1[go], dv0[go], dv1[go]
    return out


def locate_on_branches(branch: Any, p: FloatArray, v: FloatArray, v1: FloatArray,
                       a0: FloatArray, a1: FloatArray, h: float, ain: FloatArray,
                       w2: FloatArray, gamma: FloatArray, sign: FloatArray, n: Any
                       ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, BoolArray]:
    """Return ``reversal.locate_on_branch`` for arrays, and where each is exact.

    (θ, φ, φ', w, exact) of :data:`reversal.LOCATE_SRC` with NEWTON_TOL and NEWTON_ITERATIONS,
    its Newton iterations masked; ``exact`` is False where the scalar Newton step would divide
    by a zero (φ'' h underflowing to 0 with φ'' not 0: Python raises) or a value is not finite.
    """
    th = hermite_roots(v, v1, h * a0, h * a1)
    pm, vm, wm = branch(p, v, th * h, ain, w2, gamma, sign, ExactExponent(n))[:3]
    exact = _finite(th, pm, vm, wm)
    idx = np.arange(p.size)
    for _ in range(NEWTON_ITERATIONS):
        idx = idx[~(np.abs(vm[idx]) <= NEWTON_TOL * np.abs(v[idx]))]
        if not idx.size:
            break
        nk = _at(n, idx)
        acc = branch(pm[idx], vm[idx], 0.0, ain[idx], w2[idx], gamma[idx], sign[idx],
                     ExactExponent(nk))[3]
        step = acc * h
        exact[idx] &= ~((acc != 0.0) & (step == 0.0)) & np.isfinite(acc)
        go = (acc != 0.0) & (step != 0.0)
        nth = th[idx] - vm[idx] / np.where(go, step, 1.0)
        go &= (0.0 < nth) & (nth < 1.0)
        idx, nth = idx[go], nth[go]
        if not idx.size:
            break
        th[idx] = nth
        pi, vi, wi = branch(p[idx], v[idx], nth * h, ain[idx], w2[idx], gamma[idx], sign[idx],
                            ExactExponent(_at(n, idx)))[:3]
        pm[idx], vm[idx], wm[idx] = pi, vi, wi
        exact[idx] &= _finite(pi, vi, wi)
    return th, pm, vm, wm, exact


def graded_landings(branch: Any, laws: Any, p: FloatArray, v: FloatArray, th: FloatArray,
                    pm: FloatArray, vm: FloatArray, wm: FloatArray, h: float, ain: FloatArray,
                    w2: FloatArray, gamma: FloatArray, sign: FloatArray, n: Any,
                    reach: FloatArray
                    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, BoolArray]:
    """Return ``reversal.graded_landing`` for arrays, and where each is exact.

    (θ, φ, φ', w, exact): the Newton runs on each graded run's own φ'(θh) = 0 masked (each
    element's run of GRADED_ITERATIONS at most, its exits its own), then the last Newton step
    in time onto φ' = 0. ``exact`` as :func:`locate_on_branches`.
    """
    th, pm, vm, wm = th.copy(), pm.copy(), vm.copy(), wm.copy()
    size = p.size
    exact = np.ones(size, dtype=bool)
    zero = np.zeros(size)
    flat, start, count = meshes(zero, th * h, h, n, reach)
    idx = np.flatnonzero(count > 1)  # len(lens) > 1: the first side is graded
    landed = idx
    acc = np.zeros(size)
    for it in range(GRADED_ITERATIONS):
        if not idx.size:
            break
        nk = _at(n, idx)
        if it:
            flat, start, count = meshes(zero[idx], th[idx] * h, h, nk, reach[idx])
        else:
            start, count = start[idx], count[idx]
        back = np.ones(idx.size, dtype=bool)
        pi, vi, wi = branch_runs(branch, p[idx], v[idx], flat, start, count, back, ain[idx],
                                 w2[idx], gamma[idx], sign[idx], nk)
        ai = branch(pi, vi, 0.0, ain[idx], w2[idx], gamma[idx], sign[idx], ExactExponent(nk))[3]
        pm[idx], vm[idx], wm[idx], acc[idx] = pi, vi, wi, ai
        go = ~((ai == 0.0) | (np.abs(vi) <= GRADED_TOL * np.abs(v[idx])))
        step = ai * h
        exact[idx] &= ~(go & (step == 0.0)) & _finite(pi, vi, wi, ai)
        go &= step != 0.0
        nth = th[idx] - vi / np.where(go, step, 1.0)
        go &= (0.0 < nth) & (nth < 1.0)
        idx = idx[go]
        th[idx] = nth[go]
    j = landed[acc[landed] != 0.0]
    if j.size:
        tj, aj, vj = th[j], acc[j], vm[j]
        dt = _min(_max(-vj / aj, -tj * h), (1.0 - tj) * h)
        pm[j] += dt * (vj + 0.5 * dt * aj)
        wm[j] += dt * vj * laws(vj, gamma[j], sign[j], ExactExponent(_at(n, j)))[1]
        vm[j] = 0.0
        th[j] = tj + dt / h
    return th, pm, vm, wm, exact


def split_steps(tableau: Tableau, p: FloatArray, v: FloatArray, h: float, ain: FloatArray,
                w2: FloatArray, gamma: FloatArray, n: Any, a0: FloatArray, reach: FloatArray
                ) -> tuple[BoolArray, FloatArray, FloatArray, FloatArray, IntArray]:
    """Take ``split.split_step`` for each pendulum (no Coulomb, no friction beside the law).

    Returns (done, φ₁, φ'₁, w, reversals): where ``done`` the scalar split's result and its
    reversal count (1 where the branch step reached φ' = 0, else 0: a graded run back from the
    distance to the reversal); elsewhere nothing, the scalar path takes it. ``a0`` is the plain
    step's φ''₀ (C library's powers), ``n`` a float or one per pendulum
    (``batched_careful.batchable_law`` true for each), ``reach`` the grading window S.
    """
    key = float(n) if np.ndim(n) == 0 else 1.5  # a non-special exponent: one text for all
    branch = compile_step_with_n(tableau, key, True, vector=True)
    laws = compile_laws(key, vector=True)
    size = p.size
    sign = np.where(v > 0.0, 1.0, -1.0)
    p1, v1, w, _ = branch(p, v, h, ain, w2, gamma, sign, ExactExponent(n))
    done = _finite(p1, v1, w)
    turns = np.zeros(size, dtype=np.int64)
    kink = ~(v1 * v > 0.0)
    # The branch step does not reach φ' = 0: no kink inside (graded if it is near).
    g = np.flatnonzero(~kink & (reach > 0.0) & (a0 != 0.0))
    if g.size:
        x = np.abs(v[g]) / np.abs(a0[g])
        ng = _at(n, g)
        flat, start, count = meshes(_max(x - h, 0.0), x, h, ng, reach[g])
        p1[g], v1[g], w[g] = branch_runs(branch, p[g], v[g], flat, start, count,
                                         np.ones(g.size, dtype=bool), ain[g], w2[g],
                                         gamma[g], sign[g], ng)
    k = np.flatnonzero(kink)
    if not k.size:
        return done, p1, v1, w, turns
    pk, vk, ak, w2k, gk, sk, nk = p[k], v[k], ain[k], w2[k], gamma[k], sign[k], _at(n, k)
    a1 = branch(p1[k], v1[k], 0.0, ak, w2k, gk, sk, ExactExponent(nk))[3]
    th, pm, vm, wm, ok = locate_on_branches(branch, pk, vk, v1[k], a0[k], a1, h, ak, w2k, gk,
                                            sk, nk)
    ok &= done[k] & np.isfinite(a1)
    th, pm, vm, wm, landed = graded_landings(branch, laws, pk, vk, th, pm, vm, wm, h, ak, w2k,
                                             gk, sk, nk, reach[k])
    ok &= landed
    rest = (1.0 - th) * h
    after = ak - w2k * np.sin(pm)
    side = np.where(after > 0.0, 1.0, -1.0)
    flat, start, count = meshes(np.zeros(k.size), rest, h, nk, reach[k])
    p2, v2, w2_ = branch_runs(branch, pm, vm, flat, start, count, np.zeros(k.size, dtype=bool),
                              ak, w2k, gk, side, nk)
    # After == 0: split_step's plain step from rest; beyond the bounds: the fallback (scalar).
    ok &= after != 0.0
    ok &= (v2 * side >= 0.0) & (np.abs(v2) <= rest * (np.abs(ak) + w2k) * (1.0 + 1e-9))
    ok &= _finite(th, pm, vm, wm, rest, after)
    done[k] = ok
    p1[k], v1[k], w[k] = p2, v2, wm + w2_
    turns[k] = 1
    return done, p1, v1, w, turns


def careful_steps(tableau: Tableau, p: FloatArray, v: FloatArray, h: float, ain: FloatArray,
                  w2: FloatArray, gamma: FloatArray, n: Any, reach: FloatArray,
                  check: BoolArray, v1_fast: FloatArray | None = None, split_min: int = SPLIT_MIN
                  ) -> tuple[BoolArray, FloatArray, FloatArray, FloatArray, IntArray]:
    """Take the careful path's step of h where it is a plain, graded or split step.

    ``batched_careful.graded_steps`` with the splits (:func:`split_steps`) taken as well where
    at least ``split_min`` steps split. Returns (done, φ₁, φ'₁, E₁/I, reversals): where
    ``done`` the scalar careful path's result and reversal count for that pendulum
    (``Engine.careful`` with the guard's count 1), elsewhere nothing (the scalar path takes it).
    """
    done, split, a0, p1, v1, w = graded_parts(tableau, p, v, h, ain, w2, gamma, n, reach,
                                              v1_fast)
    turns = np.zeros(p.size, dtype=np.int64)
    rows = np.flatnonzero(split)
    if rows.size and rows.size >= split_min:
        ok, ps, vs, ws, ts = split_steps(tableau, p[rows], v[rows], h, ain[rows], w2[rows],
                                         gamma[rows], _at(n, rows), a0[rows], reach[rows])
        done[rows] = ok
        p1[rows], v1[rows], w[rows], turns[rows] = ps, vs, ws, ts
    done, e1 = settled(done, p, v, p1, v1, w, ain, w2, check)
    return done, p1, v1, e1, turns


__all__ = ['SCALAR_BELOW', 'SPLIT_MIN', 'careful_steps',
           'graded_landings', 'hermite_roots', 'locate_on_branches', 'meshes', 'split_steps']
