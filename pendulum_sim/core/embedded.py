"""Embedded adaptive pairs: error-controlled substeps that cover one step of h.

The pair's two solutions differ by ``E`` (``tableaus.py``); a trial substep is accepted when
the scaled error norm is at most 1 and the next trial is ``0.9 err^(−1/(p̂+1))`` times the last,
within [0.2, 10] (Hairer, Nørsett and Wanner, *Solving ODEs I*, II.4; the norm, the acceptance
and the factor are ``error_control.py``'s, which the stiff transient's cover shares). Where the
damping is not smooth at φ' = 0 (n even, non-integer, or 0) an accepted substep that crosses a
reversal is cut at it: the reversal is located on the branch continuation of the start
(Hermite guess, Newton on the substep's own φ'), so no substep straddles the kink and the
pair's estimate stays valid.
The pair is an explicit one (``explicit.py``), a Rosenbrock one (``rosenbrock.py``) or an
extrapolated linearly implicit Euler step (``extrapolation.py``): all have the same signature
and results, and this one cover serves them. The first trial comes from the scale of the
solution and its derivatives (:func:`initial_step`). :func:`dense_run` lets the substeps run
free across many output times and interpolates them (dense output, order ≤ 4 methods).
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
import numpy.typing as npt

from .coulomb import friction_work, moving_input, rest_direction, stuck
from .error_control import accepted, error_norm, min_step, step_factor
from .errors import IntegratorError
from .explicit import ErrStepFn, compile_step
from .extrapolation import compile_extrapolation
from .guard import GuardStats
from .jit import compile_step as jit_step
from .law import compile_damping, damping_derivative
from .model import FloatArray, run_speed_limit
from .problem import Problem
from .reversal import CUT_ITERATIONS, CUT_TOL, branch_accel, locate_reversal
from .rosenbrock import compile_rosenbrock
from .tableaus import Extrapolation, Tableau

IntArray = npt.NDArray[np.intp]

StepResult = tuple[float, float, float]
Fallback = Callable[[float, float, float, float], StepResult]
"""The step a cover could not take: ``(φ, φ', h, a_in) → (φ₁, φ'₁, w)`` (the implicit one)."""


def pair_steps(tab: Tableau | Extrapolation, n: float,
               jit: bool = False) -> tuple[ErrStepFn, ErrStepFn]:
    """Return the embedded pair's (plain law, branch law) steps with error estimate.

    Generated Python; with ``jit``, the same steps compiled to machine code (``jit.py``).
    """
    if isinstance(tab, Extrapolation):
        steps = compile_extrapolation(tab, n), compile_extrapolation(tab, n, branch=True)
    elif tab.rosenbrock:
        steps = compile_rosenbrock(tab, n), compile_rosenbrock(tab, n, branch=True)
    else:
        steps = (compile_step(tab, n, with_error=True),
                 compile_step(tab, n, branch=True, with_error=True))
    if jit:
        return jit_step(steps[0]), jit_step(steps[1])
    return steps


MAX_TRIALS = 20_000
"""Trial substeps an adaptive method may spend on one step of h (in :func:`dense_run`: per
output interval covered) before the step goes to the fallback. Far above what a tolerance
needs where the solution's time scale can be resolved (Hairer's DOP853 allows 100 000 per
call); reached where the cover cannot progress: a strong n < 1 law chattering at rest (10⁶
trials a step of 1 ms at n = 0.3, γ = 1e6, measured), a γ beyond any time step."""


def initial_step(prob: Problem, p: float, v: float, h: float, ain: float, rtol: float,
                 atol: float, order: int) -> float:
    """Return a first trial substep from the scale of y and its first two derivatives.

    The starting-step rule of Hairer, Nørsett and Wanner (*Solving ODEs I*, II.4): h₀ =
    0.01 ‖y‖/‖f‖, then h₁ = (0.01 / max(‖f‖, ‖f'‖ h₀-estimate))^(1/(p+1)), p the ``order`` of
    the error estimate (the embedded solution's: 4 for dopri5, as in scipy's RK45; the
    propagated order 5 makes the first step of a fast transient too long for its estimate to
    see its error), the smaller of 100 h₀ and h₁, at most h, and at most 1/ρ with
    ρ = d + ω0 √|cos φ| a bound on the Jacobian's spectral radius (d the damping slope,
    eq 18-19): the first step resolves the fastest rate
    at the start (a stiff transient from rest) instead of stepping over it.
    """
    w2, damp = prob.w2, prob.damping

    def rms(x: float, y: float, sp: float, sv: float) -> float:
        return math.sqrt(0.5 * ((x / sp) ** 2 + (y / sv) ** 2))

    try:
        a0 = ain - damp(v) - w2 * math.sin(p)
        sp, sv = atol + rtol * abs(p), atol + rtol * abs(v)
        d0, d1 = rms(p, v, sp, sv), rms(v, a0, sp, sv)
        h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
        h0 = min(h0, h)
        p1, v1 = p + h0 * v, v + h0 * a0
        a1 = ain - damp(v1) - w2 * math.sin(p1)
        d2 = rms(v1 - v, a1 - a0, sp, sv) / h0
        big = max(d1, d2)
        h1 = max(1e-6, h0 * 1e-3) if big <= 1e-15 else (0.01 / big) ** (1.0 / (order + 1))
        rho = damping_derivative(prob.gamma, prob.n, v) + math.sqrt(w2 * abs(math.cos(p)))
    except (OverflowError, ValueError, ZeroDivisionError):
        return h * 1e-3
    first = min(100.0 * h0, h1, h)
    # An unbounded slope (n < 1 at rest) is the kink itself, not a rate to resolve.
    first = min(first, 1.0 / rho) if 0.0 < rho < math.inf else first
    # A rate beyond float64 (γ = 1e300) makes the estimate 0: start at the smallest substep.
    return max(first, min_step(h)) if first > 0.0 else min_step(h)


class CoverFailed(IntegratorError):
    """Raised by :func:`cover` when its error-controlled substeps cannot cover the step.

    ``reached`` is (time covered, φ, φ', w) after the last accepted substep: what was done
    before the cover stalled is accurate, and the fallback takes the rest from there.
    """

    def __init__(self, message: str, reached: tuple[float, float, float, float]) -> None:
        super().__init__(message)
        self.reached = reached


class BudgetSpent(IntegratorError):
    """Raised by :func:`cover` once the run's trial substeps exceed its ``budget``."""


class TooManySubsteps(CoverFailed):
    """Raised by :func:`cover` when ``max_trials`` trial substeps did not cover the step."""


class StepTooSmall(CoverFailed):
    """Raised by :func:`cover` when the error control asks for a substep below ``min_step``."""


def cover(prob: Problem, tab: Tableau | Extrapolation, steps: tuple[ErrStepFn, ErrStepFn],
          p: float, v: float, h: float, ain: float, rtol: float, atol: float,
          h_try: float, stats: GuardStats, max_trials: int = 0,
          trace: list[float] | None = None,
          stops: Sequence[float] = (), per: float = 0.0,
          budget: int = 0) -> tuple[float, float, float, float]:
    """Advance (φ, φ') by h with error-controlled substeps; return (φ₁, φ'₁, w, next trial).

    ``tab`` is the embedded pair and ``steps`` its compiled steps (:func:`pair_steps`); every
    trial after the first counts as a substep in ``stats``; with ``max_trials`` > 0,
    :class:`TooManySubsteps` is raised once that many trials did not cover h (with ``per`` > 0:
    once they exceed ``max_trials`` for every ``per`` of time covered, and one more);
    :class:`StepTooSmall` where the error control asks for less than :func:`min_step`. At rest
    under Coulomb friction the rest rule (``coulomb.rest_direction``) decides: the pendulum
    sticks for the rest of h, or breaks away with the force on that branch (a trial that turns
    back within itself is halved). Moving in the direction s, the friction beside the law is
    the input ``coulomb.moving_input`` and its work ``coulomb.friction_work`` is counted.
    ``trace``, if given, receives ``t, φ, φ', w`` after every accepted substep (t from the
    start of h): the mesh of :func:`dense_run`. ``stops`` (increasing, inside (0, h)) are
    times a substep must land on, as if h were covered by one call per stretch between them,
    the trial-step memory carried.
    With ``budget`` > 0, :class:`BudgetSpent` is raised once ``stats`` counts more substeps
    (the run's work bound, ``model.MAX_RUN_TRIALS``).
    """
    trials = 0
    plain, branch = steps
    w2, g, n, cf = prob.w2, prob.gamma, prob.n, prob.friction
    coulomb, nonsmooth = prob.coulomb, prob.nonsmooth
    q = 1.0 / (tab.error_order + 1)
    # Beyond the speed a run may reach (``model.run_speed_limit``) a trial is rejected like one
    # that overflows: a loose tolerance scales its error by that speed and would accept it.
    vmax = run_speed_limit(g, n, w2)
    done, w_total = 0.0, 0.0
    hh = h_try if h_try > 0.0 else initial_step(prob, p, v, h, ain, rtol, atol, tab.error_order)
    ahead = iter(stops)
    target = next(ahead, h)
    while done < h:
        while done >= target:
            target = next(ahead, h)
        if coulomb and v == 0.0:
            # At rest the rest rule decides: stick for the rest of h, or break away with the
            # force, the trials then on the branch of that direction.
            sign = rest_direction(p, ain, w2, g, n, cf)
            if sign == 0.0:
                break
        else:
            sign = 1.0 if v > 0.0 else -1.0
        trials += 1
        if trials > 1:
            stats.substeps += 1
            if stats.substeps > budget > 0:
                raise BudgetSpent(f'more than {budget} trial substeps')
        if 0 < max_trials < trials and (not per or trials > max_trials * (1 + done // per)):
            raise TooManySubsteps(f'{trials - 1} trial substeps did not cover h = {h:g} s',
                                  (done, p, v, w_total))
        last = hh >= target - done
        step_h = target - done if last else hh
        fn = branch if (nonsmooth and (v != 0.0 or coulomb)) else plain
        a = moving_input(ain, sign, cf)  # moving in the direction s (a_in itself where c_f = 0)
        try:
            p1, v1, w, a0, ep, ev = fn(p, v, step_h, a, w2, g, sign)
            err = error_norm(p, v, p1, v1, ep, ev, rtol, atol, vmax)
        except (OverflowError, ValueError):
            err = math.inf  # a trial step that overflows is rejected like any other
        if accepted(err) and coulomb and v == 0.0 and v1 * sign < 0.0:
            # A break-away that turned back within the trial: a shorter trial resolves it.
            hh = 0.5 * step_h
            if hh < min_step(h):
                raise StepTooSmall(f'adaptive step fell below {hh:.3g} s',
                                   (done, p, v, w_total))
        elif accepted(err):
            if nonsmooth and v1 * v < 0.0:
                # Cut at the reversal: the branch continuation's φ'(θ step_h) = 0.
                def accel(pp: float, vv: float, sg: float = sign, a: float = a) -> float:
                    return branch_accel(pp, vv, a, sg, g, n, w2)

                def at(hh: float, p0: float = p, v0: float = v, sg: float = sign,
                       fn: ErrStepFn = fn, a: float = a) -> tuple[float, float, float]:
                    pa, va, wa, _, _, _ = fn(p0, v0, hh, a, w2, g, sg)
                    return pa, va, wa

                th, pm, _, wm = locate_reversal(at, accel, v, v1, a0, accel(p1, v1), step_h,
                                                CUT_TOL, CUT_ITERATIONS)
                if cf != 0.0:
                    wm += friction_work(cf, sign, p, pm)
                stats.reversals += 1
                p, v = pm, 0.0
                w_total += wm
                done += th * step_h
                if trace is not None:
                    trace += (done, p, v, w_total)
                hh = max(th * step_h, 1e-6 * h)
                # Leave rest on the side the forces push to (a kink: the pair restarts small;
                # with Coulomb friction the rest rule decides sticking first).
                continue
            if cf != 0.0:
                w += friction_work(cf, sign, p, p1)
            done = target if last else done + step_h
            p, v = p1, v1
            w_total += w
            if trace is not None:
                trace += (done, p, v, w_total)
            factor = step_factor(err, q)
            hh = step_h * factor if not last else max(hh, step_h * factor)
        else:
            hh = step_h * step_factor(err, q)
            if hh < min_step(h):
                raise StepTooSmall(f'adaptive step fell below {hh:.3g} s',
                                   (done, p, v, w_total))
    return p, v, w_total, hh


class Cover:
    """The embedded adaptive method as an ``Advance``: :func:`cover` with its trial-step memory.

    Parameters
    ----------
    prob : Problem
        The pendulum.
    tab, steps :
        The embedded pair (e.g. ``dopri5``) and its compiled steps (:func:`pair_steps`).
    rtol, atol : float
        Tolerances of the error control.
    fallback : callable
        The step that takes what the cover could not.
    """

    def __init__(self, prob: Problem, tab: Tableau | Extrapolation,
                 steps: tuple[ErrStepFn, ErrStepFn], rtol: float, atol: float,
                 fallback: Fallback) -> None:
        self.prob, self.tab, self.steps = prob, tab, steps
        self.rtol, self.atol = rtol, atol
        self.fallback = fallback
        self.h_try = 0.0  # the next trial substep, carried from step to step

    def __call__(self, p: float, v: float, h: float, ain: float,
                 stats: GuardStats) -> tuple[float, float, float]:
        """Cover one step of h; the fallback takes what the cover could not (or not finitely)."""
        try:
            p1, v1, w, self.h_try = cover(self.prob, self.tab, self.steps, p, v, h,
                                          ain, self.rtol, self.atol, self.h_try, stats,
                                          max_trials=MAX_TRIALS)
        except CoverFailed as failed:
            done, p1, v1, w = failed.reached
            self.h_try = 0.0  # the next step starts afresh
            stats.fallbacks += 1
            p2, v2, w2 = self.fallback(p1, v1, h - done, ain)
            return p2, v2, w + w2
        if not (math.isfinite(p1) and math.isfinite(v1)):
            stats.fallbacks += 1
            return self.fallback(p, v, h, ain)
        if stuck(self.prob.coulomb, v, v1):
            stats.sticks += 1
        return p1, v1, w


DENSE_NODES = {4: 3}
"""Mesh points per interpolant, by the largest order of the methods it serves: the Hermite
polynomial through φ and φ' at m consecutive mesh points has degree 2m − 1, error O(δ^2m) in φ
and, by its derivative, O(δ^(2m−1)) in φ', so three points serve methods of order up to 4
(``rodas4``). Higher orders stop at every output: their steps are long enough that an
interpolant of their own order joins points too far apart (measured: four points for
``extrap6`` on the γ = 1000 creep were 500× less accurate than stopping at the outputs)."""

DENSE_MAX_ORDER = max(DENSE_NODES)


def dense_nodes(order: int) -> int:
    """Return the mesh points the interpolant of a method of ``order`` uses (0: none)."""
    return min((m for o, m in DENSE_NODES.items() if order <= o), default=0)


def dense_capable(error_controlled: bool, coulomb: bool) -> bool:
    """Return True where :func:`dense_run` may serve a method (of an error-controlled family).

    Every adaptive method but under Coulomb friction (n = 0: sticking at rest is decided per
    output interval by the cover, and the interval's end matters).
    """
    return error_controlled and not coulomb


def dense_run(prob: Problem, tab: Tableau | Extrapolation, steps: tuple[ErrStepFn, ErrStepFn],
              p: float, v: float, t_out: FloatArray, ain: float, rtol: float,
              atol: float, stats: GuardStats,
              budget: int = 0) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Integrate over [0, t_out[-1]] in one cover; return φ, φ', w at ``t_out``.

    The error-controlled substeps of :func:`cover` run over the whole span in one call (cut at
    velocity reversals, so no step straddles a kink). A method of order above
    :data:`DENSE_MAX_ORDER` lands a substep on every output (the ``stops`` of :func:`cover`: the
    decisions of one cover per output interval, without a call per output). For the others the
    substeps run free across the outputs and land on the last one; every other output is
    interpolated: φ and the damping work w by the Hermite polynomial through their values and
    rates (φ' and φ' D(φ')) at the m mesh points (:data:`DENSE_NODES`) around the step that
    contains the output, φ' by the derivative of φ's. The interpolant uses the states only,
    never the vector field: on a stiff creep the states carry errors of the tolerance's size
    across the fast mode, which f = φ'' would multiply by the fast rate (through φ'' at the ends
    of a 2 s step on the γ = 1000, n = 2 creep the interpolant was 80× less accurate than the
    states it joined). A stencil never reaches across a kink of the law (a mesh point at rest
    where the damping is not smooth); where fewer than m points lie between kinks it uses those
    (at least the step's two ends). ``t_out`` is increasing from 0; ``a_in`` is constant over
    the run. Raises :class:`CoverFailed` where the substeps cannot cover the run (more than
    :data:`MAX_TRIALS` trials per output interval, or a substep below :func:`min_step`), and
    :class:`BudgetSpent` beyond ``budget`` trial substeps in all (see :func:`cover`).
    """
    m = dense_nodes(tab.order)
    trace: list[float] = [0.0, p, v, 0.0]
    stops = () if m else t_out[1:-1].tolist()
    span = float(t_out[-1])
    cover(prob, tab, steps, p, v, span, ain, rtol, atol, 0.0, stats,
          max_trials=MAX_TRIALS, trace=trace, stops=stops, per=span / (len(t_out) - 1),
          budget=budget)
    # Counted as one cover per output interval would count them: the first trial of each
    # stretch after a landing is a step, not a substep.
    stats.substeps -= len(stops)
    ts, ps, vs, ws = np.asarray(trace).reshape(-1, 4).T
    last = len(ts) - 1
    if not m:  # every output is a mesh point
        at = np.minimum(np.searchsorted(ts, t_out), last)
        if not np.array_equal(ts[at], t_out):
            raise IntegratorError('the substeps did not land on every output time')
        return ps[at], vs[at], ws[at]
    k = np.searchsorted(ts, t_out, side='right') - 1
    np.minimum(k, last - 1, out=k)  # t_out[-1] = ts[-1] belongs to the last step
    # m mesh points around the step, within the stretch between kinks that holds it.
    kinks = np.flatnonzero(vs[1:-1] == 0.0) + 1 if prob.nonsmooth else ()
    if len(kinks):
        ends = np.concatenate(([0], kinks, [last]))
        seg = np.searchsorted(ends, k, side='right') - 1
        lo, hi = ends[seg], ends[seg + 1]
        nodes = np.minimum(hi - lo + 1, m)
        start = np.minimum(np.maximum(k - (m - 1) // 2, lo), hi - nodes + 1)
        idx = start + np.arange(m)[:, None]  # (node, output)
        top: IntArray | int = start + nodes - 1
        extra = idx > top  # beyond the stretch: placeholders, their terms are dropped
        short = bool(extra.any())
        terms: IntArray | None = 2 * nodes
    else:  # one stretch: the whole mesh
        size = min(last + 1, m)
        start = np.minimum(np.maximum(k - (m - 1) // 2, 0), last + 1 - size)
        idx = start + np.arange(m)[:, None]
        top = last
        short = size < m
        extra = idx > last
        terms = np.full_like(k, 2 * size)
    if short:
        idx = np.minimum(idx, top)
    x = ts[idx] + extra if short else ts[idx]  # distinct placeholder abscissae: finite
    rate = vs * compile_damping(prob.n, vector=True)(vs, prob.gamma, 1.0)  # dw/dt = φ' D(φ')
    # (node, [φ, w, φ', dw/dt], output), contiguous per node
    data = np.ascontiguousarray(np.array((ps, ws, vs, rate)).T[idx].transpose(0, 2, 1))
    val, der = hermite_eval(x, data[:, :2], data[:, 2:], terms if short else None, t_out)
    return val[0], der[0], val[1]


def hermite_eval(x: FloatArray, y: FloatArray, dy: FloatArray, terms: IntArray | None,
                 t: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Return the Hermite interpolant through (y, y') at nodes x and its derivative, at t.

    ``x`` is (m, P) and ``y``, ``dy`` (m, c, P): per point of ``t`` (P of them) m nodes with
    the values and slopes of c components. Newton's form on the doubled nodes x₀ x₀ x₁ x₁ …
    (confluent divided differences; Hermite interpolation, e.g. Stoer and Bulirsch,
    *Introduction to Numerical Analysis*, 2.1.5), of which the first ``terms`` (per point;
    None: all) are kept: 2j terms interpolate the first j nodes. Evaluated with its derivative
    by the nested product rule. (Every operand is made a contiguous (c, P) block first: numpy's
    small-array passes cost 2-5× more when strided or broadcast.)
    """
    m, c = y.shape[0], y.shape[1]
    xs = np.repeat(x[:, None, :], c, axis=1)  # (m, c, P)
    # The divided differences' denominators, z_{i+r} − z_i on z = x₀ x₀ x₁ x₁ …: x_b − x_a.
    gaps = {(a, b): xs[b] - xs[a] for a in range(m) for b in range(a + 1, m)}
    # First differences: the slope at a doubled node, the chord between neighbours.
    level = [dy[0]]
    for j in range(1, m):
        level.append((y[j] - y[j - 1]) / gaps[j - 1, j])
        level.append(dy[j])
    coef = [y[0], level[0]]
    for order in range(2, 2 * m):
        level = [(level[i + 1] - level[i]) / gaps[i // 2, (i + order) // 2]
                 for i in range(len(level) - 1)]
        coef.append(level[0] if terms is None else np.where(terms > order, level[0], 0.0))
    tc = np.repeat(t[None, :], c, axis=0)
    steps = [tc - xs[j] for j in range(m)]
    val = coef[-1] * steps[m - 1] + coef[-2]
    der = coef[-1].copy()
    for j in range(2 * m - 3, -1, -1):
        step = steps[j // 2]
        der *= step
        der += val
        val *= step
        val += coef[j]
    return val, der
