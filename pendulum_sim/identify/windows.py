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

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from pendulum_sim.core.errors import PendulumError
from pendulum_sim.core.model import MAX_INPUT_ACCEL
from pendulum_sim.core.sweep import Sweep

from .effort import Effort

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

RELATIVE_STEP = 1e-6
"""Forward-difference step of the Jacobian, relative to the parameter's size."""
MAX_ITERATIONS = 60
TOLERANCE = 1e-8
"""Stop when an accepted step lowers the sum of squares by less than this fraction, or the next
step is predicted to."""
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
        for a, b in zip(edges[:-1], edges[1:], strict=True):
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
Mapping_ = Callable[[dict[str, FloatArray], IntArray], Inputs]
"""``inputs(columns, window_of_each_pendulum)``: the model's sweep inputs from its parameters."""


@dataclass
class Problem:
    """One start: the shared parameters (free and fixed), the windows' states, the solver's state.

    ``theta`` holds the free shared parameters (``free`` order), ``states`` each window's
    (φ, φ') at its first sample; ``scale`` and ``state_scale`` their typical sizes (the
    Jacobian's steps); ``bounds`` the search range of each free parameter.
    """

    free: tuple[str, ...]
    fixed: dict[str, float]
    theta: FloatArray
    states: FloatArray
    scale: FloatArray
    state_scale: FloatArray
    bounds: tuple[FloatArray, FloatArray]
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


def simulate(problems: Sequence[Problem], rows: Sequence[tuple[FloatArray, FloatArray]],
             win: Windows, inputs: Mapping_, jit: bool) -> list[FloatArray | None]:
    """Return the angle at every row for each problem's parameter sets.

    ``rows[i]`` = (thetas (c, p), states (c, W, 2)): c candidates of problem i, each a set of
    shared parameters with a state per window. The result of problem i has shape (rows, c), or
    None where the core cannot simulate its candidates. All problems run as one sweep; a
    batch the core refuses is retried problem by problem.
    """
    out: list[FloatArray | None] = [None] * len(problems)
    try:
        results = _run(problems, rows, list(range(len(problems))), win, inputs, jit)
    except (PendulumError, FloatingPointError, OverflowError):
        results = {}
        for i in range(len(problems)):
            try:
                results.update(_run(problems, rows, [i], win, inputs, jit))
            except (PendulumError, FloatingPointError, OverflowError):
                results[i] = None
    for i, r in results.items():
        out[i] = r
    return out


def _run(problems: Sequence[Problem], rows: Sequence[tuple[FloatArray, FloatArray]],
         members: list[int], win: Windows, inputs: Mapping_, jit: bool
         ) -> dict[int, FloatArray | None]:
    names = list(problems[members[0]].full(rows[members[0]][0][0]))
    cols: dict[str, list[FloatArray]] = {k: [] for k in names}
    phi0, dphi0, window = [], [], []
    count = win.count
    for i in members:
        thetas, states = rows[i]
        for theta, st in zip(thetas, states, strict=True):
            values = problems[i].full(theta)
            for k in names:
                cols[k].append(np.full(count, values[k]))
            phi0.append(st[:, 0])
            dphi0.append(st[:, 1])
            window.append(np.arange(count))
    col = {k: np.concatenate(v) for k, v in cols.items()}
    wins = np.concatenate(window)
    om2, gam, nn, fr, sched, offset = inputs(col, wins)
    ok = np.isfinite(om2) & np.isfinite(gam) & np.isfinite(fr)
    if sched is not None:
        ok &= np.all(np.abs(sched) <= MAX_INPUT_ACCEL, axis=0)
    sizes = [rows[i][0].shape[0] * count for i in members]
    owner = np.repeat(np.arange(len(members)), sizes)
    bad = {int(j) for j in np.unique(owner[~ok])}
    if bad:   # a candidate the core would refuse: its problem gets None, the others run
        keep = [j for j in range(len(members)) if j not in bad]
        out: dict[int, FloatArray | None] = {members[j]: None for j in bad}
        if keep:
            out.update(_run(problems, rows, [members[j] for j in keep], win, inputs, jit))
        return out
    prepared = Sweep(om2, gam, nn, np.concatenate(phi0), np.concatenate(dphi0), win.h,
                     jit=jit, friction=fr,
                     torque=0.0 if sched is None else sched[0])
    result = prepared.advance(win.steps * win.h, sched, record_every=1)
    assert result.phi_record is not None and result.dphi_record is not None
    phi, dphi = result.phi_record, result.dphi_record
    out = {}
    at = 0
    k, w = win.k, win.w
    for j, i in enumerate(members):
        c = rows[i][0].shape[0]
        # Pendulum (candidate a, window v) is column at + a * count + v.
        idx = at + np.arange(c)[None, :] * count + win.row_window[:, None]
        pred = (w[0][:, None] * phi[k[:, None], idx] + w[1][:, None] * dphi[k[:, None], idx]
                + w[2][:, None] * phi[k[:, None] + 1, idx]
                + w[3][:, None] * dphi[k[:, None] + 1, idx]) + offset[idx]
        out[i] = pred if np.all(np.isfinite(pred)) else None
        at += sizes[j]
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
    """Return the Levenberg–Marquardt candidate (θ, states) and its predicted decrease."""
    assert p.jac is not None and p.jac_states is not None and p.residual is not None
    dg = np.linalg.norm(p.jac, axis=0)
    dg = np.where(dg > 0, dg, 1.0)
    ds = np.sqrt(np.add.reduceat(p.jac_states ** 2, bounds[:-1], axis=0))
    ds = np.where(ds > 0, ds, 1.0)
    jg = p.jac / dg
    js = p.jac_states / ds[row_window]
    a, b, c, gg, gs = _blocks(jg, js, p.residual, bounds)
    eye2 = np.eye(2)[None, :, :]
    cinv = _inv2(c + p.lam * eye2)
    s = _schur(a + p.lam * np.eye(a.shape[0]), b, cinv)
    rhs = -gg + np.einsum('wpi,wij,wj->p', b, cinv, gs)
    try:
        dgs = np.linalg.solve(s, rhs)
    except np.linalg.LinAlgError:
        dgs = np.linalg.lstsq(s, rhs, rcond=None)[0]
    dss = np.einsum('wij,wj->wi', cinv, -gs - np.einsum('wpi,p->wi', b, dgs))
    theta, states = p.clip(p.theta + dgs / dg, p.states + dss / ds)
    step_g, step_s = theta - p.theta, states - p.states
    jd = p.jac @ step_g + np.sum(p.jac_states * step_s[row_window], axis=1)
    predicted = -float(p.residual @ jd) - 0.5 * float(jd @ jd)
    return theta, states, predicted


def solve(problems: Sequence[Problem], win: Windows, inputs: Mapping_, *, jit: bool,
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
        preds = simulate(batch, [(th, st) for th, st, _, _ in shifted], win, inputs, jit)
        for i, p, (_, _, steps, sst), pred in zip(active, batch, shifted, preds, strict=True):
            p.iterations = it
            cost = math.inf
            if pred is not None:
                res = pred[:, 0] - win.y
                cost = 0.5 * float(res @ res)
            nfree = p.theta.size
            if cost < p.cost:
                gain = (p.cost - cost) / cost if math.isfinite(p.cost) and cost > 0 else math.inf
                assert pred is not None
                p.theta, p.states = cands[i]
                p.cost, p.residual = cost, res
                p.jac = (pred[:, 1:nfree + 1] - pred[:, :1]) / steps[None, :]
                per_row = sst[win.row_window]
                p.jac_states = (pred[:, nfree + 1:nfree + 3] - pred[:, :1]) / per_row
                p.lam = max(p.lam / 3.0, 1e-12)
                if gain < TOLERANCE:
                    p.done = True
            elif p.jac is None:
                p.done = True           # the start itself cannot be simulated
            else:
                p.lam *= 4.0
                if p.lam > 1e12:
                    p.done = True
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


def covariance(p: Problem, win: Windows) -> Covariance:
    """Return s² times the shared block of (JᵀJ)⁻¹ (Schur complement) and the first state's.

    s² is the residual variance with every fitted value counted: m − p − 2 W degrees of freedom.
    """
    assert p.jac is not None and p.jac_states is not None and p.residual is not None
    m = p.residual.size
    dof = max(m - p.theta.size - 2 * win.count, 1)
    s2 = float(p.residual @ p.residual) / dof
    dg = np.linalg.norm(p.jac, axis=0)
    dg = np.where(dg > 0, dg, 1.0)
    ds = np.sqrt(np.add.reduceat(p.jac_states ** 2, win.bounds[:-1], axis=0))
    ds = np.where(ds > 0, ds, 1.0)
    a, b, c, _, _ = _blocks(p.jac / dg, p.jac_states / ds[win.row_window], p.residual,
                            win.bounds)
    cinv = _inv2(c)
    try:
        sinv = np.linalg.inv(_schur(a, b, cinv))
    except np.linalg.LinAlgError:
        sinv = np.full(a.shape, np.nan)
    shared = s2 * sinv / np.outer(dg, dg)
    # The first window's state: C⁻¹ + C⁻¹ Bᵀ S⁻¹ B C⁻¹ of its block.
    c0, b0 = cinv[0], b[0]
    first = s2 * (c0 + c0 @ b0.T @ sinv @ b0 @ c0) / np.outer(ds[0], ds[0])
    return Covariance(shared=shared, first_state=first, s2=s2, dof=dof)


__all__ = ['Covariance', 'Problem', 'Series', 'Windows', 'covariance', 'cut', 'schedule',
           'simulate', 'solve']
