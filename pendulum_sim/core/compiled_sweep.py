"""The compiled sweep's driver: long runs of fast steps compiled, refused steps handed back.

With ``jit=True`` a :class:`~pendulum_sim.core.sweep.Sweep` advances each group of pendulums
(one exponent n) by its compiled run (``decisions.kernel_source``, compiled by
``jit.compile_kernel``): every pendulum takes fast steps, its state in registers, in parallel
over the pendulums, until a step is refused or the piece of the run is done. The refused
steps are handed to the one careful path (``engine.Engine.careful``, through the sweep's
callback), and the run goes on from the next step. Each pendulum thus takes exactly the steps
the numpy sweep and the ``Stepper`` take (parity tests: ``test_sweep_jit.py``), in another
order across pendulums: they do not interact.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

from .decisions import record_row

PARALLEL_MIN = 512
"""Pendulums below which a run is taken by the serial kernel (threads cost more to wake)."""
CarefulFn = Callable[[Any, int, float], None]
"""``careful(group, j, h)``: take the step of h of the group's pendulum j on the careful path,
in place in the group's state arrays ``p``, ``v``, ``e``."""


def run_piece(groups: list[Any], h: float, count: int, base: int, total: int, every: int,
              records: list[tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]],
              vmax: npt.NDArray[np.float64], turns: npt.NDArray[np.int64], careful: CarefulFn,
              guard: tuple[float, float, float]) -> list[tuple[int, int]]:
    """Advance every group's pendulums by ``count`` steps of ``h`` (steps ``base`` + 1 …).

    Each group's ``kernel`` is its (parallel, serial) pair of ``jit.compile_kernel``;
    ``records[g]`` are the group's recording arrays (rows by :func:`record_row`; shape (0, m)
    when not recording), ``vmax`` the run's speed bound over the n-sorted pendulums, ``guard``
    the guard's (disk, real, max_angle) for the compiled careful step (a group takes it where
    its ``use_careful`` is set). The reversals the compiled careful step splits are added to
    ``turns`` (over the n-sorted pendulums). Returns ``(step, position)`` of every pendulum
    whose |φ'| went beyond its bound (it stops there; the caller refuses the run).
    """
    beyond: list[tuple[int, int]] = []
    for grp, (rp, rv) in zip(groups, records, strict=True):
        sl = grp.sl
        size = sl.stop - sl.start
        vm = vmax[sl]
        k = np.zeros(size, dtype=np.int64)
        idx = np.arange(size, dtype=np.int64)
        rows = rp.shape[0]
        rev = turns[sl]
        while idx.size:
            run = grp.kernel[0] if idx.size >= PARALLEL_MIN else grp.kernel[1]
            run(grp.p, grp.v, grp.e, k, idx, h, count, grp.ain_col, grp.w2_col, grp.gamma_col,
                grp.n, grp.lo, grp.hi, grp.reach, grp.v_acc, grp.check, grp.nonsmooth,
                grp.coulomb, vm, base, every, total, rp, rv, rev, grp.use_careful, *guard)
            fast = ~(np.abs(grp.v[idx]) <= vm[idx])
            for j in idx[fast].tolist():
                beyond.append((base + int(k[j]), sl.start + j))
            left = []
            for j in idx[~fast & (k[idx] < count)].tolist():
                careful(grp, j, h)
                k[j] += 1
                done = base + int(k[j])
                r = record_row(done, every, total, rows)
                if r >= 0:
                    rp[r, j], rv[r, j] = grp.p[j], grp.v[j]
                if abs(grp.v[j]) <= vm[j]:
                    left.append(j)
                else:
                    beyond.append((done, sl.start + j))
            idx = np.array(left, dtype=np.int64)
    return beyond


__all__ = ['CarefulFn', 'run_piece']
