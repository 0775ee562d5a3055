"""Fit each law to its best on a record: many starts, each carried over growing windows.

An output-error fit of an oscillator has many local minima: a simulation whose frequency is
off by more than half a cycle over the record matches the data a period late, and a
damping far off makes the decay of the whole record a poor guide to the first swings. Every
start of :func:`search` is therefore fitted first to the record's beginning, about two
periods (:data:`FIRST_TURNS` turning points), where those minima are far apart and the start
lies in the right one, and the window then doubles, each fit starting where the last ended,
until it holds the whole record (continuation in the length of the record: the standard
remedy for the phase ambiguity of output-error fits, e.g. Bock's multiple shooting for
parameter estimation, or the "growing horizon" of Ljung's *System Identification*, 2nd ed.,
sec. 10.5, on starting a nonlinear prediction-error search). All starts of all records run
in one lockstep per window (``solver.solve``: one compiled sweep per iteration).

The starts are the physically reasoned guesses of ``fit._starts`` (the exponents of
:data:`EXPONENTS` among them where n is free) and, within ``compare``, the optima of the laws
a law nests (:data:`NESTED`, :func:`seed`): the power law starts from the viscous, quadratic
and Coulomb fits, ``power+coulomb`` from those and the power law's, so a nesting law never
ends worse than a law it contains. What a law reaches is its best start's; the starts whose
end lies within :data:`REACHED` of it on the BIC scale are counted (``Fit.at_optimum``).
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from .record import Record
from .solver import MAX_ITERATIONS, Problem, solve

FIRST_TURNS = 4
"""Turning points the first window holds (two periods, counted from the first whole half
swing): enough to time the period and see the decay begin."""
GROWTH = 4.0
"""Each window is this many times as long as the last (the last is the whole record)."""
WINDOW_ITERATIONS = 20
"""Iterations a window's fit may take before the next, longer one (the whole record's may
take ``solver.MAX_ITERATIONS``): each window only has to bring its starts into the basin the
next one refines."""
SAME = 1e-4
"""Fits whose parameters agree within this fraction of their size (or of their typical size,
``Problem.scale``) ended at one point and go on as one."""
EXPONENTS = (0.5, 1.0, 2.0, 3.0)
"""The exponents a power-law fit starts from, beside the one the envelope suggests."""
FRICTION_EXPONENTS = (1.0, 2.0)
"""The exponents ``power+coulomb`` starts from beside it, each with four shares of friction
(``fit.friction_starts``); it starts from the fits of the laws it nests as well."""
REACHED = 2.0
"""A start reached the law's optimum where m ln(RSS / RSS_best) <= this: a BIC difference of
at most 2 between two fits of one law, "not worth more than a bare mention" (Kass and
Raftery, J. Am. Stat. Assoc. 90 (1995) 773), so that no start short of it could change the
ranking of the laws by BIC."""
NESTED: dict[str, tuple[str, ...]] = {
    'viscous': (), 'quadratic': (), 'coulomb': (),
    'power': ('viscous', 'quadratic', 'coulomb'),
    'power+coulomb': ('viscous', 'quadratic', 'coulomb', 'power'),
}
"""The laws each law nests: their optima are points of its parameter space (``power`` at
n = 1, 2 or 0; ``power+coulomb`` with its friction 0)."""

Starter = Callable[[Record, Mapping[str, float]], Problem]
"""Make the problem of one start on one record (``fit._problem`` of a law)."""


def windows(rec: Record) -> list[int]:
    """Return the sample counts of the growing windows of ``rec``, the last the whole record.

    The first ends at the :data:`FIRST_TURNS`-th turning point (``guess.turning_points``);
    each next one is :data:`GROWTH` times as long (in time from the first sample). A record
    of fewer turning points is one window.
    """
    size = int(rec.t.size)
    peaks = rec.guess.peaks_t
    if peaks.size <= FIRST_TURNS:
        return [size]
    end = float(peaks[FIRST_TURNS - 1])
    out: list[int] = []
    while True:
        k = int(np.searchsorted(rec.t, end, side='right'))
        if k >= size or rec.t[-1] - end < 0.25 * end:   # a last stretch joins the record
            out.append(size)
            return out
        out.append(k)
        end *= GROWTH


def part(rec: Record, k: int) -> Record:
    """Return the first ``k`` samples of ``rec`` (its guess kept: it sets the starts)."""
    if k >= rec.t.size:
        return rec
    return type(rec)(t0=rec.t0, t=rec.t[:k], y=rec.y[:k], guess=rec.guess)


@dataclass
class Run:
    """The fit of the whole record that one or more starts ended in (merged where they met)."""

    problem: Problem
    starts: int


def _merge(fits: list[tuple[Problem, int]]) -> list[tuple[Problem, int]]:
    """Return ``fits`` with those that ended at one point (within :data:`SAME`) merged."""
    out: list[tuple[Problem, int]] = []
    for p, count in sorted(fits, key=lambda f: f[0].cost):
        for j, (q, c) in enumerate(out):
            if p.jac is not None and q.jac is not None and np.all(
                    np.abs(p.theta - q.theta) <= SAME * np.maximum(np.abs(q.theta), q.scale)):
                out[j] = (q, c + count)
                break
        else:
            out.append((p, count))
    return out


def search(records: Sequence[Record], starts: Sequence[Sequence[Mapping[str, float]]],
           problem: Starter, *, jit: bool,
           seeds: Sequence[Sequence[Mapping[str, float]]] | None = None,
           progress: Callable[[int, int], None] | None = None) -> list[list[Run]]:
    """Fit every start of every record over its growing windows; return the whole-record fits.

    ``starts[i]`` are the starts of ``records[i]``, each fitted window after window; its
    ``seeds[i]``, fits of the whole record already (of the laws the law nests), join at the
    whole record. Starts that end a window at one point go on as one (``Run.starts`` counts
    them). All records and starts run in lockstep, window after window: a record of fewer
    windows waits until its windows are the last ones. A start that cannot be simulated ends
    with ``cost`` inf and ``jac`` None.
    """
    plans = [windows(rec) for rec in records]
    stages = max((len(p) for p in plans), default=0)
    current: list[list[tuple[Mapping[str, float], int]]] = [[(s, 1) for s in st]
                                                            for st in starts]
    finals: list[list[Run]] = [[] for _ in records]
    for stage in range(stages):
        last = stage == stages - 1
        batch: list[tuple[int, Problem, int]] = []
        for i, rec in enumerate(records):
            step = stage - (stages - len(plans[i]))
            if step < 0:
                continue
            window = part(rec, plans[i][step])
            todo = list(current[i])
            if last and seeds is not None:
                todo += [(s, 1) for s in seeds[i]]
            batch += [(i, problem(window, s), c) for s, c in todo]
        solve([p for _, p, _ in batch], jit=jit, progress=progress,
              max_iterations=MAX_ITERATIONS if last else WINDOW_ITERATIONS)
        for i in range(len(records)):
            mine = _merge([(p, c) for j, p, c in batch if j == i])
            if last:
                finals[i] = [Run(p, c) for p, c in mine]
            elif mine:
                # A start that cannot be simulated is tried again, and fails again.
                current[i] = [(p.full(p.theta), c) for p, c in mine]
    return finals


def reached(runs: Sequence[Run]) -> int:
    """Return how many starts of one record end within :data:`REACHED` of the best on BIC."""
    ok = [r for r in runs if r.problem.jac is not None and math.isfinite(r.problem.cost)]
    if not ok:
        return 0
    return count_reached([r.problem.cost for r in ok], [r.starts for r in ok],
                         ok[0].problem.y.size)


def count_reached(costs: Sequence[float], weights: Sequence[int], samples: int) -> int:
    """Return the weight of the finite ``costs`` within :data:`REACHED` of the best on BIC.

    A cost is a residual sum of squares over ``samples`` residuals; on the BIC scale two fits
    differ by ``samples`` log(cost / best). ``weights`` counts the starts each cost stands for.
    """
    ok = [(c, w) for c, w in zip(costs, weights, strict=True) if math.isfinite(c)]
    if not ok:
        return 0
    best = min(c for c, _ in ok)
    if best <= 0.0:
        return sum(w for c, w in ok if c <= best)
    return sum(w for c, w in ok if samples * math.log(c / best) <= REACHED)


def seed(params: Mapping[str, float | None]) -> dict[str, float] | None:
    """Return the fitted ``params`` of a nested law as a start of a law that nests it, or None.

    None where a value the start needs was not determined. No law that others nest fits a
    friction beside its law (the Coulomb law's friction is its γ, at n = 0), so the start's
    ``friction_accel`` is 0.
    """
    keys = ('omega0', 'gamma', 'n', 'phi_offset', 'phi0', 'dphi0')
    values = [params.get(k) for k in keys]
    if any(v is None for v in values):
        return None
    start = {k: float(v) for k, v in zip(keys, values, strict=True) if v is not None}
    start['friction_accel'] = 0.0
    return start


__all__ = ['EXPONENTS', 'FIRST_TURNS', 'FRICTION_EXPONENTS', 'GROWTH', 'NESTED', 'REACHED',
           'Run', 'count_reached', 'reached', 'search', 'seed', 'windows']
