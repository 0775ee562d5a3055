"""Output error over windows re-anchored on the measurement (multiple shooting).

A closed loop near an unstable equilibrium (balancing upright, the top of a swing-up) makes a
simulation from the first sample drift away from the record within a few 1/ω0 whatever the
parameters: the record cannot be fitted by one simulation of the whole of it. It is cut into
windows of a chosen length instead; each window is simulated from its own initial state under
the recorded effort, and the residual is the measured angle minus each window's simulation.
The joint's parameters are shared by every window (and every record); each window's initial
state (φ, φ') is a parameter of its own, started from the measurement (the angle and its
local slope, or the measured velocity) and fitted with the rest. That is multiple shooting
without continuity constraints (Bock, "Recent advances in parameter identification techniques
for O.D.E.", 1983), the prediction error of a model re-started from the measured state: a
window short against the loop's divergence keeps the cost smooth in the parameters (Ribeiro,
Tiels, Umenberger, Schön and Aguirre, "On the smoothness of nonlinear system identification",
Automatica 121, 2020), and one window of the whole record is the plain output-error fit.

Levenberg–Marquardt, each iteration one compiled or numpy :class:`~pendulum_sim.core.sweep.Sweep`
for every window of every start still going: its candidate, the candidate moved along each
shared parameter, and along each of the window's two states (a forward-difference Jacobian).
The normal equations have the arrow shape of multiple shooting (the shared parameters couple
every window, the states only their own), solved by the Schur complement of the 2×2 blocks;
the covariance of the shared parameters is s² times the inverse of that complement.
"""
from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from pendulum_sim.core.errors import PendulumError
from pendulum_sim.core.model import MAX_INPUT_ACCEL
from pendulum_sim.core.sweep import Sweep

from .effort import Effort
from .solver import LAMBDA_MAX, TOLERANCE, stiffened, verdict

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

RELATIVE_STEP = 1e-6
"""Forward-difference step of the Jacobian, relative to the parameter's size."""
MAX_ITERATIONS = 60
LAMBDA_TRIES = 12
"""Times λ grows within one iteration while the step is predicted to raise the cost."""
STATE_BOUNDS = ((-1e3, 1e3), (-100.0, 100.0))
"""Where a window's initial angle (rad) and velocity (rad/s) are searched."""


@dataclass(frozen=True)
class Series:
    """One record ready for the windowed fit (times from its first sample)."""

    t: FloatArray
    y: FloatArray
    effort: Effort | None
    anchor: FloatArray   # the measured (or locally fitted) velocity at each sample, rad/s


@dataclass(frozen=True)
class Windows:
    """The cut of the records into windows and the grid every window is simulated on.

    ``record``, ``start`` and ``stop`` give each window's record and sample range (stop
    excluded); ``t0`` its first sample's time. The samples of all windows in order are the
    fit's rows: ``row_window`` says whose each is, ``bounds`` where each window's rows begin
    (and the total at the end), and ``k``, ``w`` the grid interval and the four cubic Hermite
    weights of each row (the angle at the sample from the grid's states around it).
    """

    record: IntArray
    start: IntArray
    stop: IntArray
    t0: FloatArray
    h: float
    steps: int
    row_window: IntArray
    bounds: IntArray
    k: IntArray
    w: FloatArray
    y: FloatArray

    @property
    def count(self) -> int:
        """Return the number of windows."""
        return int(self.start.size)


def cut(series: Sequence[Series], window: float | None, h: float) -> Windows:
    """Return the windows of ``window`` seconds (None: one per record) on a grid of ``h``.

    Each record is cut into whole windows of at least ``window`` s (the last one taking the
    rest); every window is simulated for the longest one's steps.
    """
    rec, start, stop = [], [], []
    for r, s in enumerate(series):
        m = s.t.size
        if window is None or window >= float(s.t[-1]):
            edges = [0, m]
        else:
            count = max(1, int(float(s.t[-1]) // window))
            edges = sorted({int(np.searchsorted(s.t, j * window)) for j in range(count)} | {m})
            if len(edges) > 2 and edges[-1] - edges[-2] < 3:
                edges.pop(-2)   # too short a last window joins the one before
        for a, b in itertools.pairwise(edges):
            rec.append(r)
            start.append(a)
            stop.append(b)
    record = np.asarray(rec, dtype=np.int64)
    first = np.asarray(start, dtype=np.int64)
    last = np.asarray(stop, dtype=np.int64)
    t0 = np.array([series[r].t[a] for r, a in zip(rec, start, strict=True)])
    spans = np.array([series[r].t[b - 1] - series[r].t[a]
                      for r, a, b in zip(rec, start, stop, strict=True)])
    steps = max(1, math.ceil(float(np.max(spans)) / h - 1e-9))
    grid = np.arange(steps + 1) * h
    rows_k, rows_w, rows_y, owner = [], [], [], []
    for i, (r, a, b) in enumerate(zip(rec, start, stop, strict=True)):
        tt = series[r].t[a:b] - t0[i]
        k = np.clip(np.searchsorted(grid, tt, side='right') - 1, 0, steps - 1)
        s = (tt - grid[k]) / h
        rows_k.append(k)
        rows_w.append(np.stack([2 * s**3 - 3 * s**2 + 1, (s**3 - 2 * s**2 + s) * h,
                                -2 * s**3 + 3 * s**2, (s**3 - s**2) * h]))
        rows_y.append(series[r].y[a:b])
        owner.append(np.full(b - a, i, dtype=np.int64))
    sizes = last - first
    return Windows(record=record, start=first, stop=last, t0=t0, h=h, steps=steps,
                   row_window=np.concatenate(owner),
                   bounds=np.concatenate(([0], np.cumsum(sizes))).astype(np.int64),
                   k=np.concatenate(rows_k), w=np.concatenate(rows_w, axis=1),
                   y=np.concatenate(rows_y))


Inputs = tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray | None, FloatArray]
"""What a sweep takes per pendulum: ω0², γ, n, f/I, the input schedule (steps, N) or None,
and the sensor's zero offset added to the angle."""
Mapping_ = Callable[[dict[str, FloatArray], IntArray, int], Inputs]
"""``inputs(columns, window_of_each_pendulum, steps)``: the model's sweep inputs from its
parameters, its schedule for ``steps`` steps."""


@dataclass
class Problem:
    """One start: the shared parameters (free and fixed), the windows' states, the solver's state.

    ``theta`` holds the free shared parameters (``free`` order), ``states`` each window's
    (φ, φ') at its first sample; ``scale`` and ``state_scale`` their typical sizes (the
    Jacobian's steps); ``bounds`` the search range of each free parameter; ``win`` the
    windows of its records and ``inputs`` its model's map to the sweep's inputs. Problems
    of different records run in one sweep where their grids have one step.
    """

    free: tuple[str, ...]
    fixed: dict[str, float]
    theta: FloatArray
    states: FloatArray
    scale: FloatArray
    state_scale: FloatArray
    bounds: tuple[FloatArray, FloatArray]
    win: Windows
    inputs: Mapping_
    ratio: FloatArray | None = None   # a step keeps θ within [θ / r, θ r] where r > 0
    cost: float = math.inf
    residual: FloatArray | None = None
    jac: FloatArray | None = None        # (rows, p): along the shared parameters
    jac_states: FloatArray | None = None  # (rows, 2): along each row's window's state
    lam: float = 1e-3
    iterations: int = 0
    done: bool = False
    candidate: tuple[FloatArray, FloatArray] | None = field(default=None, repr=False)

    def full(self, theta: FloatArray) -> dict[str, float]:
        """Return every shared parameter for the free values ``theta``."""
        values = dict(self.fixed)
        values.update(zip(self.free, (float(v) for v in theta), strict=True))
        return values

    def clip(self, theta: FloatArray, states: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Return ``theta`` and ``states`` inside their search bounds."""
        lo, hi = self.bounds
        st = np.column_stack([np.clip(states[:, j], *STATE_BOUNDS[j]) for j in range(2)])
        return np.clip(theta, lo, hi), st


def schedule(effort: Effort, t0: FloatArray, h: float, steps: int, delay: FloatArray
             ) -> FloatArray:
    """Return the mean of the delayed effort u(t − d) over each grid step, shape (steps, N).

    ``t0`` and ``delay`` are each pendulum's window start and dead time (s).
    """
    grid = np.arange(steps + 1) * h
    times = t0[None, :] + grid[:, None] - delay[None, :]
    impulse = np.diff(effort.integral(times), axis=0)
    return np.asarray(impulse / h, dtype=np.float64)


def simulate(problems: Sequence[Problem], rows: Sequence[tuple[FloatArray, FloatArray]], *,
             jit: bool) -> list[FloatArray | None]:
    """Return the angle at every row of each problem for its parameter sets.

    ``rows[i]`` = (thetas (c, p), states (c, W, 2)): c candidates of problem i, each a set of
    shared parameters with a state per window. The result of problem i has shape (rows, c), or
    None where the core cannot simulate its candidates. Problems on one grid step run as one
    sweep (for the longest window's steps); a batch the core refuses is retried problem by
    problem.
    """
    out: list[FloatArray | None] = [None] * len(problems)
    groups: dict[float, list[int]] = {}
    for i, p in enumerate(problems):
        groups.setdefault(p.win.h, []).append(i)
    for members in groups.values():
        try:
            results = _run(problems, rows, members, jit)
        except (PendulumError, FloatingPointError, OverflowError):
            results = {}
            for i in members:
                try:
                    results.update(_run(problems, rows, [i], jit))
                except (PendulumError, FloatingPointError, OverflowError):
                    results[i] = None
        for i, r in results.items():
            out[i] = r
    return out


def _columns(p: Problem, thetas: FloatArray, states: FloatArray, steps: int
             ) -> tuple[Inputs, FloatArray, FloatArray] | None:
    """Return problem ``p``'s sweep inputs for its candidates (pendulum a W + v: candidate a,
    window v) over ``steps`` steps, and the initial states; None where the core would refuse
    an input."""
    count = p.win.count
    values = [p.full(theta) for theta in thetas]
    col = {k: np.repeat(np.array([v[k] for v in values]), count) for k in values[0]}
    wins = np.tile(np.arange(count), len(values))
    om2, gam, nn, fr, sched, offset = p.inputs(col, wins, steps)
    h = p.win.h
    ok = bool(np.all(np.isfinite(om2)) and np.all(np.isfinite(gam)) and np.all(np.isfinite(fr)))
    # A model the grid cannot resolve is no candidate (its simulation would only crawl through
    # the guard's fallback): ω0 h <= 1, and the input alone turns the joint by less than π
    # in a step.
    ok = ok and bool(np.all(om2 * h * h <= 1.0))
    if sched is not None:
        most = np.max(np.abs(sched), axis=0)
        ok = ok and bool(np.all(most <= MAX_INPUT_ACCEL) and np.all(0.5 * most * h * h <= math.pi))
    if not ok:
        return None
    return (om2, gam, nn, fr, sched, offset), states[:, :, 0].ravel(), states[:, :, 1].ravel()


def _run(problems: Sequence[Problem], rows: Sequence[tuple[FloatArray, FloatArray]],
         members: list[int], jit: bool) -> dict[int, FloatArray | None]:
    out: dict[int, FloatArray | None] = {}
    steps = max(problems[i].win.steps for i in members)
    h = problems[members[0]].win.h
    parts = []
    for i in members:
        made = _columns(problems[i], rows[i][0], rows[i][1], steps)
        if made is None:   # a candidate the core would refuse: its problem gets None
            out[i] = None
        else:
            parts.append((i, made))
    if not parts:
        return out
    def joined(j: int) -> FloatArray:
        return np.concatenate([made[0][j] for _, made in parts])
    om2, gam, nn, fr = (joined(j) for j in range(4))
    scheds = [made[0][4] for _, made in parts]
    size = om2.size
    if all(sc is None for sc in scheds):
        sched = None
    else:
        sched = np.concatenate([np.zeros((steps, made[1].size)) if sc is None else sc
                                for sc, (_, made) in zip(scheds, parts, strict=True)], axis=1)
    offset = joined(5)
    prepared = Sweep(om2, gam, nn, np.concatenate([made[1] for _, made in parts]),
                     np.concatenate([made[2] for _, made in parts]), h, jit=jit, friction=fr,
                     torque=0.0 if sched is None else sched[0])
    result = prepared.advance(steps * h, sched, record_every=1)
    assert result.phi_record is not None and result.dphi_record is not None
    phi, dphi = result.phi_record, result.dphi_record
    at = 0
    for i, made in parts:
        win = problems[i].win
        c = rows[i][0].shape[0]
        k, w = win.k[:, None], win.w
        # Pendulum (candidate a, window v) of this problem is column at + a W + v.
        idx = at + np.arange(c)[None, :] * win.count + win.row_window[:, None]
        pred = (w[0][:, None] * phi[k, idx] + w[1][:, None] * dphi[k, idx]
                + w[2][:, None] * phi[k + 1, idx] + w[3][:, None] * dphi[k + 1, idx]
                ) + offset[idx]
        out[i] = pred if np.all(np.isfinite(pred)) else None
        at += made[1].size
    assert at == size
    return out


def _with_steps(p: Problem, theta: FloatArray, states: FloatArray
                ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Return the candidate and its shifts (thetas (p+3, p), states (p+3, W, 2)) and steps."""
    nfree = theta.size
    steps = RELATIVE_STEP * np.maximum(np.abs(theta), p.scale)
    steps = np.where(theta + steps > p.bounds[1], -steps, steps)
    sst = RELATIVE_STEP * np.maximum(np.abs(states), p.state_scale)
    thetas = np.repeat(theta[None, :], nfree + 3, axis=0)
    thetas[1:nfree + 1] += np.diag(steps)
    st = np.repeat(states[None, :, :], nfree + 3, axis=0)
    st[nfree + 1, :, 0] += sst[:, 0]
    st[nfree + 2, :, 1] += sst[:, 1]
    return thetas, st, steps, sst


def _blocks(jac: FloatArray, jst: FloatArray, res: FloatArray, bounds: IntArray
            ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Return A = JgᵀJg, B_w = Jgᵀ Js_w, C_w = Js_wᵀ Js_w, Jgᵀ r and Js_wᵀ r."""
    starts = bounds[:-1]
    a = jac.T @ jac
    b = np.add.reduceat(jac[:, :, None] * jst[:, None, :], starts, axis=0)
    c = np.add.reduceat(jst[:, :, None] * jst[:, None, :], starts, axis=0)
    gg = jac.T @ res
    gs = np.add.reduceat(jst * res[:, None], starts, axis=0)
    return a, b, c, gg, gs


def _inv2(c: FloatArray) -> FloatArray:
    """Return the inverses of 2×2 matrices (W, 2, 2); a singular one gives its pseudo-inverse."""
    det = c[:, 0, 0] * c[:, 1, 1] - c[:, 0, 1] * c[:, 1, 0]
    inv = np.empty_like(c)
    inv[:, 0, 0], inv[:, 1, 1] = c[:, 1, 1], c[:, 0, 0]
    inv[:, 0, 1], inv[:, 1, 0] = -c[:, 0, 1], -c[:, 1, 0]
    good = np.abs(det) > 1e-300
    inv[good] /= det[good][:, None, None]
    if not good.all():
        inv[~good] = np.linalg.pinv(c[~good])
    return inv


def _schur(a: FloatArray, b: FloatArray, cinv: FloatArray) -> FloatArray:
    """Return A − Σ_w B_w C_w⁻¹ B_wᵀ: the normal matrix of the shared parameters alone."""
    return np.asarray(a - np.einsum('wpi,wij,wqj->pq', b, cinv, b), dtype=np.float64)


def _lm_step(p: Problem, bounds: IntArray, row_window: IntArray
             ) -> tuple[FloatArray, FloatArray, float]:
    """Return the Levenberg–Marquardt candidate (θ, states) and its predicted decrease.

    A projected step: a shared parameter moves at most by its own size (or its typical size)
    per step, one with a ratio r > 0 stays within [θ / r, θ r] (a scale such as the inertia,
    whose collapse would make the model stiff), and each stops at the bounds of its range;
    one at a bound that the descent pushes out of the range is held there for the step (the
    active set), so that a parameter whose true
    value is at a bound (no friction, no dead time) sits on it while the others take their
    own best step. Where the step so cut is predicted to raise the cost, λ grows and the
    step is made again.
    """
    assert p.jac is not None and p.jac_states is not None and p.residual is not None
    dg = np.linalg.norm(p.jac, axis=0)
    dg = np.where(dg > 0, dg, 1.0)
    ds = np.sqrt(np.add.reduceat(p.jac_states ** 2, bounds[:-1], axis=0))
    ds = np.where(ds > 0, ds, 1.0)
    jg = p.jac / dg
    js = p.jac_states / ds[row_window]
    a, b, c, gg, gs = _blocks(jg, js, p.residual, bounds)
    eye2 = np.eye(2)[None, :, :]
    lo, hi = p.bounds
    # A parameter at a bound that the descent pushes out of its range is held for this step
    # (the active set of a projected step): the others then take their own best step.
    held = ((p.theta <= lo) & (gg > 0.0)) | ((p.theta >= hi) & (gg < 0.0))
    if held.any():
        a, b, gg = a.copy(), b.copy(), gg.copy()
        a[held, :], a[:, held], b[:, held, :], gg[held] = 0.0, 0.0, 0.0, 0.0
        a[held, held] = 1.0
    cap = np.maximum(np.abs(p.theta), p.scale)
    low, high = p.theta - cap, p.theta + cap
    if p.ratio is not None:
        r = p.ratio > 0.0
        low = np.where(r, np.maximum(low, p.theta / np.where(r, p.ratio, 1.0)), low)
        high = np.where(r, np.minimum(high, p.theta * np.where(r, p.ratio, 1.0)), high)
    theta, states, predicted = p.theta, p.states, 0.0
    for _ in range(LAMBDA_TRIES):
        cinv = _inv2(c + p.lam * eye2)
        s = _schur(a + p.lam * np.eye(a.shape[0]), b, cinv)
        rhs = -gg + np.einsum('wpi,wij,wj->p', b, cinv, gs)
        try:
            dgs = np.linalg.solve(s, rhs)
        except np.linalg.LinAlgError:
            dgs = np.linalg.lstsq(s, rhs, rcond=None)[0]
        dss = np.einsum('wij,wj->wi', cinv, -gs - np.einsum('wpi,p->wi', b, dgs))
        theta, states = p.clip(np.clip(p.theta + dgs / dg, low, high), p.states + dss / ds)
        step_g, step_s = theta - p.theta, states - p.states
        jd = p.jac @ step_g + np.sum(p.jac_states * step_s[row_window], axis=1)
        predicted = -float(p.residual @ jd) - 0.5 * float(jd @ jd)
        if predicted > 0.0 or p.lam > LAMBDA_MAX:
            break
        p.lam = stiffened(p.lam)
    return theta, states, predicted


def solve(problems: Sequence[Problem], *, jit: bool,
          progress: Callable[[int, int], None] | None = None,
          max_iterations: int = MAX_ITERATIONS) -> None:
    """Fit every problem in lockstep (each problem's state is updated in place)."""
    cands = [p.clip(p.theta, p.states) for p in problems]
    for it in range(max_iterations + 1):
        active = [i for i, p in enumerate(problems) if not p.done]
        if not active:
            break
        batch = [problems[i] for i in active]
        shifted = [_with_steps(p, *cands[i]) for i, p in zip(active, batch, strict=True)]
        preds = simulate(batch, [(th, st) for th, st, _, _ in shifted], jit=jit)
        for i, p, (_, _, steps, sst), pred in zip(active, batch, shifted, preds, strict=True):
            p.iterations = it
            cost = math.inf
            win = p.win
            if pred is not None:
                res = pred[:, 0] - win.y
                cost = 0.5 * float(res @ res)
            nfree = p.theta.size
            if verdict(p, cost):
                assert pred is not None
                p.theta, p.states = cands[i]
                p.cost, p.residual = cost, res
                p.jac = (pred[:, 1:nfree + 1] - pred[:, :1]) / steps[None, :]
                per_row = sst[win.row_window]
                p.jac_states = (pred[:, nfree + 1:nfree + 3] - pred[:, :1]) / per_row
            if not p.done:
                theta, states, predicted = _lm_step(p, win.bounds, win.row_window)
                cands[i] = (theta, states)
                if (np.array_equal(theta, p.theta) and np.array_equal(states, p.states)) or (
                        predicted < TOLERANCE * p.cost):
                    p.done = True
        if progress is not None:
            progress(it + 1, sum(p.done for p in problems))


@dataclass(frozen=True)
class Covariance:
    """The shared parameters' covariance and the first window's state's, at the optimum."""

    shared: FloatArray      # (p, p)
    first_state: FloatArray  # (2, 2)
    s2: float
    dof: int


def covariance(p: Problem) -> Covariance:
    """Return s² times the shared block of (JᵀJ)⁻¹ (Schur complement) and the first state's.

    s² is the residual variance with every fitted value counted: m − p − 2 W degrees of
    freedom. A parameter the residual does not depend on at all (its Jacobian column zero,
    e.g. n where γ = 0) gets NaN and is left out of the others' covariance.
    """
    assert p.jac is not None and p.jac_states is not None and p.residual is not None
    win = p.win
    m = p.residual.size
    dof = max(m - p.theta.size - 2 * win.count, 1)
    s2 = float(p.residual @ p.residual) / dof
    dg = np.linalg.norm(p.jac, axis=0)
    use = np.flatnonzero(dg > 0)
    ds = np.sqrt(np.add.reduceat(p.jac_states ** 2, win.bounds[:-1], axis=0))
    ds = np.where(ds > 0, ds, 1.0)
    a, b, c, _, _ = _blocks(p.jac[:, use] / dg[use], p.jac_states / ds[win.row_window],
                            p.residual, win.bounds)
    cinv = _inv2(c)
    try:
        sinv = np.linalg.inv(_schur(a, b, cinv))
    except np.linalg.LinAlgError:
        sinv = np.full(a.shape, np.nan)
    shared = np.full((dg.size, dg.size), np.nan)
    shared[np.ix_(use, use)] = s2 * sinv / np.outer(dg[use], dg[use])
    # The first window's state: C⁻¹ + C⁻¹ Bᵀ S⁻¹ B C⁻¹ of its block.
    c0, b0 = cinv[0], b[0]
    first = s2 * (c0 + c0 @ b0.T @ sinv @ b0 @ c0) / np.outer(ds[0], ds[0])
    return Covariance(shared=shared, first_state=first, s2=s2, dof=dof)


__all__ = ['Covariance', 'Problem', 'Series', 'Windows', 'covariance', 'cut', 'schedule',
           'simulate', 'solve']
