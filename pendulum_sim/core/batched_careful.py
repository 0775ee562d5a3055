"""The careful path's graded steps next to a reversal, batched over the pendulums that take them.

For a non-integer 1 < n < 3 the careful path (``Engine.careful``) grades every step within the
window S of a velocity reversal (``reversal.graded_mesh``): a step that does not reach φ' = 0
is taken as branch substeps that shrink towards the reversal, so the method keeps its order. At
h = 1 ms and ω0 ≈ 3 s⁻¹ that is about half of all steps, and the numpy sweep took each of them
by one Python call. :func:`graded_steps` takes them over arrays, exactly as the scalar careful
path takes each one: the plain step with the exponent an argument and its reversal test
(``split.micro_step``), the graded mesh (:func:`graded_meshes`, the operations of
``graded_mesh`` in the same order on each element), the branch run (``reversal.branch_run``),
the energy test (``Engine.careful``) and the finiteness of the result (``Engine._settle``). Every
power is the C library's (``law.ExactExponent``: ``numpy.float_power``) and every sine the
C library's (``math.sin``), so each pendulum gets the scalar path's floats; a test compares the
two on random and edge states (``test_batched_careful.py``).

A pendulum it cannot take so is handed back to the scalar path, from the same state (nothing is
counted or changed for it): a step that crosses φ' = 0 (the reversal split), whose branch run
reaches φ' = 0 after all, whose energy rose, or whose result is not finite. The splits are taken
over arrays in turn by ``batched_split.py``, which reuses the parts here (:func:`graded_parts`,
:func:`graded_meshes`, :func:`branch_runs`, :func:`settled`). The sweep hands it only pendulums for
which ``Engine.careful`` surely starts with one plain step: not Coulomb, not near-Coulomb (n > 1),
below the stiff-transient speed, and where the guard's count (``guard.substep_count``) is surely
1 (``guard.one_substep``: inside its safe speed range shrunk by ``guard.RANGE_MARGIN``).
"""
from __future__ import annotations

import functools
from typing import Any

import numpy as np
import numpy.typing as npt

from .codegen import define
from .decisions import energy_rose, reversal_suspect, specific_energy
from .explicit import compile_step_with_n, step_source_with_n
from .law import VECTOR_ENV, ExactExponent, whole
from .tableaus import Tableau

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

def batchable_law(n: float) -> bool:
    """Return True where :func:`graded_steps` serves the exponent ``n``: 1 < n < 3, not whole.

    The laws graded at reversals (``reversal.graded_law``) that cannot creep (n < 1 may, in
    ``coulomb.creep_state``) and whose plain law the vector text spells as the scalar one.
    """
    return 1.0 < n < 3.0 and not whole(n)


def graded_meshes(x_a: FloatArray, x_b: FloatArray, h: float, n: Any, window: FloatArray
                  ) -> tuple[FloatArray, IntArray, IntArray]:
    """Return ``reversal.graded_mesh`` for arrays: (lengths, start, count).

    ``lengths[start[i]:start[i] + count[i]]`` is the mesh of
    ``graded_mesh(x_a[i], x_b[i], h, n[i], window[i])``, the same floats (powers by
    ``numpy.float_power``, the C library's pow, and the lengths summed in their order from 0),
    for exponents with ``reversal.graded_law`` true.
    """
    size = x_a.size
    length = x_b - x_a
    alpha = np.broadcast_to(1.0 - (n + 1.0) / 5.0, (size,))
    first = window * np.float_power(h / window, 1.0 / (1.0 - alpha))
    count = np.ones(size, dtype=np.int64)
    idx = np.flatnonzero((length > 0.0) & (x_a < window))
    count[idx] = 0
    looped = idx
    xa, xb, win, al, fi = x_a[idx], x_b[idx], window[idx], alpha[idx], first[idx]
    made: list[tuple[IntArray, FloatArray]] = []
    while idx.size:
        rem = xb - xa
        d = np.maximum(fi, h * np.float_power(xa / win, al))
        d[xa >= win] = h
        np.minimum(d, rem, out=d)
        snap = rem - d < 1e-3 * d
        d[snap] = rem[snap]
        made.append((idx, d))
        count[idx] += 1
        xa = xa + d
        go = xa < xb
        if not go.all():
            idx, xa, xb, win, al, fi = idx[go], xa[go], xb[go], win[go], al[go], fi[go]
    start = np.cumsum(count) - count
    flat = length[np.repeat(np.arange(size), count)]  # the columns of one length keep it
    total = np.zeros(size)
    for k, (at, d) in enumerate(made):
        flat[start[at] + k] = d
        total[at] += d
    # lens[-1] += length - sum(lens), where the loop made the mesh.
    flat[start[looped] + count[looped] - 1] += length[looped] - total[looped]
    return flat, start, count


def branch_runs(branch: Any, p: FloatArray, v: FloatArray, flat: FloatArray, start: IntArray,
                count: IntArray, back: BoolArray, ain: FloatArray, w2: FloatArray,
                gamma: FloatArray, side: FloatArray, n: Any
                ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Return ``reversal.branch_run`` for arrays: (φ, φ', w) after each column's branch steps.

    Column i runs the ``count[i]`` lengths ``flat[start[i]:start[i] + count[i]]``
    (:func:`graded_meshes`; in reverse where ``back[i]``). ``branch`` is the vector branch step
    with the exponent an argument; ``n`` a float or an array. The columns are taken longest
    run first, so that the pendulums still running are a prefix of the arrays.
    """
    order = np.argsort(-count, kind='stable')
    cnt, first, rev = count[order], start[order], back[order]
    # The k-th length run: start + k, or start + count − 1 − k where back.
    base = np.where(rev, first + cnt - 1, first)
    step = np.where(rev, -1, 1)
    pp, vv, aa, ww2, gg, ss = (x[order] for x in (p, v, ain, w2, gamma, side))
    nn = n[order] if isinstance(n, np.ndarray) else n
    w = np.zeros(p.size)
    ends = np.searchsorted(-cnt, -np.arange(1, int(cnt[0]) + 1), side='right')
    for k, m in enumerate(ends.tolist()):
        dt = flat[base[:m] + k * step[:m]]
        nk = nn[:m] if isinstance(nn, np.ndarray) else nn
        p1, v1, wi, _ = branch(pp[:m], vv[:m], dt, aa[:m], ww2[:m], gg[:m], ss[:m],
                               ExactExponent(nk))
        pp[:m], vv[:m] = p1, v1
        w[:m] += wi
    out_p, out_v, out_w = np.empty_like(p), np.empty_like(v), np.empty_like(w)
    out_p[order], out_v[order], out_w[order] = pp, vv, w
    return out_p, out_v, out_w


SIGN_MARGIN = 1e-9
"""Where a plain step's φ'₁ by numpy's power (the fast path's) is above this relative size of
the step's speed scale, its sign is the C library's step's: the two differ by the last bits of
a few powers (some 1e-15 relative), far below it; so the reversal test needs no second step."""


@functools.lru_cache(maxsize=64)
def first_stage(tableau: Tableau, n: float) -> Any:
    """Return the plain step's φ''₀ alone: its text's first-stage lines, over arrays.

    ``a0(p0, v0, h, ain, w2, gamma, s, n)`` (``n`` a ``law.ExactExponent``) is the very float
    the step's ``a_0`` is, without the step's other stages.
    """
    lines = step_source_with_n(tableau, n, False, 'a0').splitlines()
    body = [x for x in lines[1:] if x.startswith(('    d_0 =', '    a_0 ='))]
    return define('\n'.join([lines[0], *body, '    return a_0']) + '\n', 'a0',
                  dict(VECTOR_ENV), f'<{tableau.name} first stage>')


def graded_parts(tableau: Tableau, p: FloatArray, v: FloatArray, h: float, ain: FloatArray,
                 w2: FloatArray, gamma: FloatArray, n: Any, reach: FloatArray,
                 v1_fast: FloatArray | None = None
                 ) -> tuple[BoolArray, BoolArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Take the plain and graded steps of :func:`graded_steps`; find the steps to split.

    Returns (done, split, φ''₀, φ₁, φ'₁, w): where ``done`` the micro step's result
    (``split.micro_step``: the plain step or the graded branch run), before the finiteness and
    energy tests (:func:`settled`); where ``split`` the micro step splits at the reversal
    (``split.split_step`` from the same state and φ''₀: the step crosses φ' = 0, or its graded
    branch run reached φ' = 0 after all). Elsewhere nothing (a plain step that is not finite).
    """
    key = float(n) if np.ndim(n) == 0 else 1.5  # a non-special exponent: one text for all
    plain = compile_step_with_n(tableau, key, False, vector=True)
    branch = compile_step_with_n(tableau, key, True, vector=True)
    nx = ExactExponent(n)
    size = p.size
    p1, v1, w = np.empty(size), np.empty(size), np.empty(size)
    stepped = np.zeros(size, dtype=bool)  # where p1, v1, w are the plain step's

    def step_at(rows: IntArray) -> None:
        rows = rows[~stepped[rows]]
        if rows.size:
            out = plain(p[rows], v[rows], h, ain[rows], w2[rows], gamma[rows], 1.0,
                        ExactExponent(n[rows] if isinstance(n, np.ndarray) else n))
            p1[rows], v1[rows], w[rows] = out[0], out[1], out[2]
            stepped[rows] = True

    if v1_fast is None:
        p1, v1, w, a0 = plain(p, v, h, ain, w2, gamma, 1.0, nx)
        stepped[:] = True
        v1s = v1
    else:
        a0 = first_stage(tableau, key)(p, v, h, ain, w2, gamma, 1.0, nx)
        scale = np.abs(v) + 2.0 * h * (np.abs(a0) + np.abs(ain) + w2)
        sure = np.abs(v1_fast) > SIGN_MARGIN * scale
        step_at(np.flatnonzero(~sure))
        v1s = np.where(sure, v1_fast, v1)  # its sign is the C library's step's
    done = np.isfinite(a0) & np.isfinite(v1s)
    sus = reversal_suspect(v, v1s, a0, h, reach)
    cross = (v1s * v < 0.0) | ((a0 * v < 0.0) & (np.abs(v) <= h * np.abs(a0)))
    split = done & sus & cross
    done &= ~split
    graded = done & sus & (reach > 0.0) & (a0 != 0.0)
    step_at(np.flatnonzero(done & ~graded))  # the plain step is the result
    near = np.flatnonzero(graded)
    if near.size:
        vn, an = v[near], a0[near]
        side = np.where((vn > 0.0) | ((vn == 0.0) & (an > 0.0)), 1.0, -1.0)
        x = np.abs(vn) / np.abs(an)
        back = an * vn < 0.0
        x_a = np.where(back, np.maximum(x - h, 0.0), x)
        x_b = np.where(back, x, x + h)
        nn = n[near] if isinstance(n, np.ndarray) else n
        flat, start, count = graded_meshes(x_a, x_b, h, nn, reach[near])
        pg, vg, wg = branch_runs(branch, p[near], vn, flat, start, count, back, ain[near],
                                 w2[near], gamma[near], side, nn)
        p1[near], v1[near], w[near] = pg, vg, wg
        reached = vg * vn < 0.0  # reached φ' = 0 after all: the split
        done[near] &= ~reached
        split[near] |= reached
    return done, split, a0, p1, v1, w


def settled(done: BoolArray, p: FloatArray, v: FloatArray, p1: FloatArray, v1: FloatArray,
            w: FloatArray, ain: FloatArray, w2: FloatArray, check: BoolArray
            ) -> tuple[BoolArray, FloatArray]:
    """Return (done, E₁/I): ``done`` kept where the careful path would keep the step's result.

    Where the result is not finite (``Engine._settle`` takes the fallback's) or its energy rose
    without input where ``check`` (``Engine.careful`` redoes it), ``done`` is cleared: the
    scalar path takes the step.
    """
    with np.errstate(invalid='ignore'):
        done = done & np.isfinite(p1) & np.isfinite(v1) & np.isfinite(w)
    e1 = specific_energy(v1, np.sin(0.5 * p1), w2)
    rows = np.flatnonzero(done & check & (ain == 0.0))
    if rows.size:
        e0 = specific_energy(v[rows], np.sin(0.5 * p[rows]), w2[rows])
        done[rows] &= ~energy_rose(e0, e1[rows], w2[rows])  # the energy redo (scalar)
    return done, e1


def graded_steps(tableau: Tableau, p: FloatArray, v: FloatArray, h: float, ain: FloatArray,
                 w2: FloatArray, gamma: FloatArray, n: Any, reach: FloatArray,
                 check: BoolArray, v1_fast: FloatArray | None = None
                 ) -> tuple[BoolArray, FloatArray, FloatArray, FloatArray]:
    """Take the careful path's step of h for each pendulum where it is one plain or graded step.

    Returns (done, φ₁, φ'₁, E₁/I): where ``done`` the scalar careful path's result for that
    pendulum (``Engine.careful`` with the guard's count 1), elsewhere nothing (the scalar path
    takes it, or the batched split, ``batched_split.careful_steps``).
    ``n`` is the exponent, a float or one per pendulum (:func:`batchable_law` true for each),
    ``reach`` the grading window S (``Problem.reach``), ``check`` where the energy test applies.
    ``v1_fast``, the fast path's φ'₁ of the same plain step (numpy's power), spares the C
    library's plain step where its sign decides the reversal test (:data:`SIGN_MARGIN`) and
    the step is graded (its result is then the branch run's).
    """
    done, _, _, p1, v1, w = graded_parts(tableau, p, v, h, ain, w2, gamma, n, reach, v1_fast)
    done, e1 = settled(done, p, v, p1, v1, w, ain, w2, check)
    return done, p1, v1, e1


__all__ = ['SIGN_MARGIN', 'batchable_law', 'branch_runs', 'first_stage',
           'graded_meshes', 'graded_parts', 'graded_steps', 'settled']
