"""The compiled sweep's driver: long runs of fast steps compiled, refused steps handed back.

With ``jit=True`` a :class:`~pendulum_sim.core.sweep.Sweep` advances each group of pendulums (one
exponent n) by its compiled run (``kernel.kernel_source``, compiled by ``jit.compile_kernel``
once per law text, the careful step it calls once, both kept on disk by ``jit_cache.py``): every
pendulum takes fast steps, its state in registers, in parallel over the pendulums, until a step is
refused or the piece of the run is done. A refused step is taken by the compiled careful path
(``careful.careful_step``: Coulomb friction at rest, the near-Coulomb creep, the guard's
substeps, the reversal split, the fallback, the stiff transient's error-controlled substeps, the
energy redo) where the group's ``use_careful`` is set; the steps it declines (the fallback's
refusal by its work bound, a result that is not finite, the fallback beside a Coulomb friction)
are handed back to the one careful path
(``engine.Engine.careful``, through the sweep's callback; counted as ``handed_back``), and the run
goes on from the next step. Each pendulum thus takes exactly the steps the numpy sweep and the
``Stepper`` take (parity tests: ``test_sweep_jit.py``), in another order across pendulums: they do
not interact.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

from .careful import COUNTERS
from .kernel import record_row

PARALLEL_MIN = 512
"""Pendulums below which a run is taken by the serial kernel (threads cost more to wake)."""
FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
CarefulFn = Callable[[Any, int, float, int], None]
"""``careful(group, j, h, done)``: take the step of h of the group's pendulum j, after ``done``
steps of the run, on the careful path, in place in the group's state arrays ``p``, ``v``,
``e``."""


def run_piece(groups: list[Any], h: float, count: int, base: int, total: int, every: int,
              records: list[tuple[FloatArray, FloatArray]], vmax: FloatArray, counts: IntArray,
              careful: CarefulFn, guard: FloatArray) -> tuple[list[tuple[int, int]], int]:
    """Advance every group's pendulums by ``count`` steps of ``h`` (steps ``base`` + 1 …).

    Each group's ``kernel`` is its (parallel, serial) pair of ``jit.compile_kernel``; the
    groups whose laws share one source text (hence one kernel) run in one call, their columns
    side by side (:func:`_run_together`). ``records[g]`` are the group's recording arrays (rows
    by :func:`record_row`; shape (0, m) when not recording), ``vmax`` the run's speed bound
    over the n-sorted pendulums, ``guard`` the guard's ``StabilityGuard.constants`` for the
    compiled careful step (a group takes it where its ``use_careful`` is set). What the
    compiled careful step did is added to ``counts`` (a row per n-sorted pendulum,
    ``careful.COUNTERS``). Returns ``(step, position)`` of every pendulum whose |φ'|
    went beyond its bound (it stops there; the caller refuses the run) and how many steps were
    handed back to ``careful``.
    """
    shared: dict[int, list[int]] = {}
    for g, grp in enumerate(groups):
        shared.setdefault(id(grp.kernel), []).append(g)
    beyond: list[tuple[int, int]] = []
    handed = 0
    for members in shared.values():
        stopped, took = _run_together([groups[g] for g in members],
                                      [records[g] for g in members], h, count, base, total,
                                      every, vmax, counts, careful, guard)
        beyond += stopped
        handed += took
    return beyond, handed


def _run_together(grps: list[Any], recs: list[tuple[FloatArray, FloatArray]], h: float,
                  count: int, base: int, total: int, every: int, vmax: FloatArray,
                  counts: IntArray, careful: CarefulFn,
                  guard: FloatArray) -> tuple[list[tuple[int, int]], int]:
    """Run groups that share one kernel in its calls, over their columns put side by side.

    The groups' state arrays ``p``, ``v``, ``e`` become views of the joint ones, so that the
    kernel and the careful path (``careful(group, j, h, done)``) write the same floats.
    """
    one = len(grps) == 1
    sizes = [grp.sl.stop - grp.sl.start for grp in grps]
    offs = np.cumsum([0, *sizes]).tolist()

    def joint(name: str) -> Any:
        if one:
            return getattr(grps[0], name)
        return np.concatenate([getattr(grp, name) for grp in grps])

    P, V, E = joint('p'), joint('v'), joint('e')
    if not one:
        for grp, a, b in zip(grps, offs[:-1], offs[1:], strict=True):
            grp.p, grp.v, grp.e = P[a:b], V[a:b], E[a:b]
    # The input: one row (1, N), or the stretch's schedule (steps, N), C-ordered either way.
    if grps[0].sched is None:
        ain = np.ascontiguousarray(joint('ain_col')).reshape(1, -1)
    else:
        ain = np.ascontiguousarray(grps[0].sched if one else
                                   np.concatenate([grp.sched for grp in grps], axis=1))
    cols = [ain, *(joint(name) for name in ('w2_col', 'gamma_col', 'cf'))]
    nn = np.concatenate([np.broadcast_to(grp.nn, (size,))
                         for grp, size in zip(grps, sizes, strict=True)])
    decide = [joint(name) for name in
              ('lo', 'hi', 'reach', 'v_acc', 'check', 'nonsmooth', 'coulomb')]
    vm = np.concatenate([vmax[grp.sl] for grp in grps])
    use = np.concatenate([np.full(size, grp.use_careful)
                          for grp, size in zip(grps, sizes, strict=True)])
    rp = recs[0][0] if one else np.concatenate([r[0] for r in recs], axis=1)
    rv = recs[0][1] if one else np.concatenate([r[1] for r in recs], axis=1)
    rows = rp.shape[0]
    owner = np.repeat(np.arange(len(grps)), sizes)
    size = offs[-1]
    # The kernel adds to its rows of the counters: a lone group's own rows, else a joint array.
    cnt = counts[grps[0].sl] if one else np.zeros((size, len(COUNTERS)), dtype=np.int64)
    tally = np.zeros((size, len(COUNTERS)), dtype=np.int64)  # a careful step's, until taken
    handed_back = 0
    k = np.zeros(size, dtype=np.int64)
    idx = np.arange(size, dtype=np.int64)
    kernel = grps[0].kernel
    beyond: list[tuple[int, int]] = []

    def where(j: int) -> tuple[Any, int]:
        g = int(owner[j])
        return grps[g], j - offs[g]

    whole = True  # the first call runs every pendulum: its checks need no gathers
    while idx.size:
        run = kernel[0] if idx.size >= PARALLEL_MIN else kernel[1]
        run(P, V, E, k, idx, h, count, *cols, nn, *decide, vm, base, every, total, rp, rv,
            cnt, tally, use, guard)
        if whole:
            fast = ~(np.abs(V) <= vm)
            stopped, handed = np.flatnonzero(fast), np.flatnonzero(~fast & (k < count))
            whole = False
        else:
            fast = ~(np.abs(V[idx]) <= vm[idx])
            stopped, handed = idx[fast], idx[~fast & (k[idx] < count)]
        for j in stopped.tolist():
            grp, jl = where(j)
            beyond.append((base + int(k[j]), grp.sl.start + jl))
        left = []
        for j in handed.tolist():
            grp, jl = where(j)
            careful(grp, jl, h, base + int(k[j]))
            handed_back += 1
            k[j] += 1
            done = base + int(k[j])
            r = record_row(done, every, total, rows)
            if r >= 0:
                rp[r, j], rv[r, j] = P[j], V[j]
            if abs(V[j]) <= vm[j]:
                left.append(j)
            else:
                beyond.append((done, grp.sl.start + jl))
        idx = np.array(left, dtype=np.int64)
    for grp, (grp_rp, grp_rv), a, b in zip(grps, recs, offs[:-1], offs[1:], strict=True):
        if not one:
            counts[grp.sl] += cnt[a:b]
            grp_rp[:], grp_rv[:] = rp[:, a:b], rv[:, a:b]
    return beyond, handed_back


__all__ = ['CarefulFn', 'run_piece']
