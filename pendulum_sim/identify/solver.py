"""Output-error least squares, many problems in lockstep, every trajectory simulated by the core.

A problem is one record and one start: the free parameters θ (some of ``omega0``, ``gamma``,
``n``, ``phi_offset``, ``phi0``, ``dphi0``), the rest fixed. The model's output at the record's
times is the core's trajectory (:func:`pendulum_sim.core.sweep.sweep`, RK4 on a uniform grid
from the first sample, the guard, reversal split and Coulomb sticking included) interpolated
by cubic Hermite from the recorded angle and velocity, plus the sensor's zero offset.

Levenberg–Marquardt, each iteration one ``sweep`` for every problem still going: its candidate
θ and the candidate shifted along each free parameter (the forward-difference Jacobian of the
simulation, not of the data), all in one batch of pendulums. A candidate that lowers the sum of
squares is taken (and its Jacobian with it), otherwise the damping λ grows.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import numpy.typing as npt

from pendulum_sim.core.errors import PendulumError
from pendulum_sim.core.sweep import sweep

FloatArray = npt.NDArray[np.float64]

PARAMETERS = ('omega0', 'gamma', 'n', 'phi_offset', 'phi0', 'dphi0', 'friction_accel')
"""Everything a trajectory depends on, in θ order (``friction_accel``: the Coulomb friction
beside the law per unit inertia, f/I in rad/s², the core sweep's ``friction``)."""
BOUNDS = {'omega0': (1e-3, 1e3), 'gamma': (0.0, 1e3), 'n': (0.0, 6.0),
          'friction_accel': (0.0, 1e3),
          'phi_offset': (-1e3, 1e3), 'phi0': (-1e3, 1e3), 'dphi0': (-100.0, 100.0)}
"""Where the search stays: the core's input limits, tightened to physical joints."""
RELATIVE_STEP = 1e-6
"""Forward-difference step of the Jacobian, relative to the parameter's size."""
MAX_ITERATIONS = 80
LAMBDA_MAX = 1e12
"""The damping λ past which a problem that finds no lower sum of squares stops."""
LAMBDA_MIN = 1e-12
"""The least damping λ an accepted step leaves."""
TOLERANCE = 1e-8
"""Stop when an accepted step lowers the sum of squares by less than this fraction, or the next
step is predicted to (far below what moves an estimate within its standard error)."""


def relaxed(lam: float) -> float:
    """Return the damping λ after an accepted step (a third, at least :data:`LAMBDA_MIN`)."""
    return max(lam / 3.0, LAMBDA_MIN)


def stiffened(lam: float) -> float:
    """Return the damping λ after a refused or uphill step (four times)."""
    return lam * 4.0


class Iterate(Protocol):
    """What :func:`verdict` reads and updates of a problem: its sum of squares (half), the
    damping λ, its Jacobian (None until its start is simulated), and whether it is done."""

    cost: float
    lam: float
    done: bool
    jac: FloatArray | None


def verdict(p: Iterate, cost: float) -> bool:
    """Judge a candidate of sum of squares (half) ``cost`` against ``p``'s; return whether to
    take it.

    Levenberg-Marquardt's rule, one for every solver of the package: a lower cost is taken and
    λ relaxed (``p`` is done where the gain is below :data:`TOLERANCE`); otherwise λ is
    stiffened (``p`` is done past :data:`LAMBDA_MAX`, or at once where the start itself could
    not be simulated).
    """
    if cost < p.cost:
        gain = (p.cost - cost) / cost if math.isfinite(p.cost) and cost > 0 else math.inf
        p.lam = relaxed(p.lam)
        p.done = gain < TOLERANCE
        return True
    if p.jac is None:
        p.done = True          # the start itself cannot be simulated
    else:
        p.lam = stiffened(p.lam)
        p.done = p.lam > LAMBDA_MAX
    return False


@dataclass
class Problem:
    """One record and one start: data, grid, free parameters and the solver's state."""

    t: FloatArray            # s since the first sample
    y: FloatArray            # measured angle, rad
    h: float
    t_end: float
    free: tuple[str, ...]
    fixed: dict[str, float]
    theta: FloatArray
    scale: FloatArray        # typical size of each free parameter (Jacobian steps)
    speed: float = 0.0       # the reference speed of γ's slot of θ (0: θ holds γ itself)
    cost: float = math.inf
    jac: FloatArray | None = None
    residual: FloatArray | None = None
    lam: float = 1e-3
    iterations: int = 0
    done: bool = False
    weights: tuple[npt.NDArray[np.int64], FloatArray] | None = field(default=None, repr=False)

    def _scaled(self) -> bool:
        """Say whether θ holds the damping at ``speed`` in γ's slot (γ and n both free)."""
        return self.speed > 0.0 and 'gamma' in self.free and 'n' in self.free

    def full(self, theta: FloatArray) -> dict[str, float]:
        """Return every parameter for the free values ``theta``."""
        values = dict(self.fixed)
        values.update(zip(self.free, (float(v) for v in theta), strict=True))
        if self._scaled():
            values['gamma'] = values['gamma'] / self.speed ** values['n']
        return values

    def encode(self, values: Mapping[str, float]) -> FloatArray:
        """Return θ for the parameters ``values`` (the inverse of :meth:`full`).

        Where γ and n are both free, γ's slot holds the damping deceleration at the reference
        speed, γ speed^n (rad/s²), instead of γ (in s^(n−2)): a change of n then changes the
        law's shape about that speed, not its size by orders of magnitude, and the valley of
        the sum of squares along which γ and n trade off is nearly straight, where in (γ, n)
        it is curved and Levenberg–Marquardt crawls along it.
        """
        theta = np.array([float(values[k]) for k in self.free])
        if self._scaled():
            theta[self.free.index('gamma')] = float(values['gamma']) * self.speed ** float(
                values['n'])
        return theta

    def physical_jacobian(self) -> FloatArray:
        """Return the Jacobian of the residual in the parameters of :meth:`full` (γ, not θ)."""
        assert self.jac is not None
        jac = np.array(self.jac, copy=True)
        if self._scaled():
            g, n = self.free.index('gamma'), self.free.index('n')
            slot = float(self.theta[g])   # γ speed^n
            jac[:, n] += self.jac[:, g] * slot * math.log(self.speed)
            jac[:, g] *= self.speed ** float(self.theta[n])
        return jac

    def clip(self, theta: FloatArray) -> FloatArray:
        """Return ``theta`` inside the search bounds."""
        lo = np.array([BOUNDS[k][0] for k in self.free])
        hi = np.array([BOUNDS[k][1] for k in self.free])
        return np.clip(theta, lo, hi)


def _hermite(problem: Problem) -> tuple[npt.NDArray[np.int64], FloatArray]:
    """Return the grid interval of each sample and its four cubic Hermite weights."""
    if problem.weights is None:
        steps = max(1, round(problem.t_end / problem.h))
        grid = np.minimum(np.arange(steps + 1) * problem.h, problem.t_end)
        grid[-1] = problem.t_end
        k = np.clip(np.searchsorted(grid, problem.t, side='right') - 1, 0, steps - 1)
        dt = grid[k + 1] - grid[k]
        s = (problem.t - grid[k]) / dt
        w = np.stack([2 * s**3 - 3 * s**2 + 1, (s**3 - 2 * s**2 + s) * dt,
                      -2 * s**3 + 3 * s**2, (s**3 - s**2) * dt])
        problem.weights = (k, w)
    return problem.weights


def simulate_columns(problems: Sequence[Problem], thetas: Sequence[FloatArray], *,
                     jit: bool) -> list[FloatArray | None]:
    """Return the model output of each problem's parameter sets (rows of ``thetas[i]``).

    Problems on the same grid run as one sweep; a batch the core refuses is retried problem by
    problem, and a problem whose candidates it refuses gets None.
    """
    out: list[FloatArray | None] = [None] * len(problems)
    groups: dict[tuple[float, float], list[int]] = {}
    for i, p in enumerate(problems):
        groups.setdefault((p.h, p.t_end), []).append(i)
    for (h, t_end), members in groups.items():
        try:
            results = _run(problems, thetas, members, h, t_end, jit)
        except (PendulumError, FloatingPointError, OverflowError):
            results = {}
            for i in members:
                try:
                    results.update(_run(problems, thetas, [i], h, t_end, jit))
                except (PendulumError, FloatingPointError, OverflowError):
                    results[i] = None
        for i, r in results.items():
            out[i] = r
    return out


def _run(problems: Sequence[Problem], thetas: Sequence[FloatArray], members: list[int],
         h: float, t_end: float, jit: bool) -> dict[int, FloatArray | None]:
    cols: dict[str, list[float]] = {k: [] for k in PARAMETERS}
    for i in members:
        for row in np.atleast_2d(thetas[i]):
            values = problems[i].full(row)
            for k in PARAMETERS:
                cols[k].append(values[k])
    om = np.asarray(cols['omega0'])
    result = sweep(om * om, np.asarray(cols['gamma']), np.asarray(cols['n']),
                   np.asarray(cols['phi0']), np.asarray(cols['dphi0']), t_end, h,
                   record_every=1, jit=jit, friction=np.asarray(cols['friction_accel']))
    assert result.phi_record is not None and result.dphi_record is not None
    phi, dphi = result.phi_record, result.dphi_record
    offsets = np.asarray(cols['phi_offset'])
    out: dict[int, FloatArray | None] = {}
    at = 0
    for i in members:
        rows = np.atleast_2d(thetas[i]).shape[0]
        idx, w = _hermite(problems[i])
        sl = slice(at, at + rows)
        pred = (w[0][:, None] * phi[idx, sl] + w[1][:, None] * dphi[idx, sl]
                + w[2][:, None] * phi[idx + 1, sl] + w[3][:, None] * dphi[idx + 1, sl])
        pred = (pred + offsets[sl]).T
        out[i] = pred if np.all(np.isfinite(pred)) else None
        at += rows
    return out


def _with_steps(p: Problem, theta: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Return θ and θ shifted along each free parameter (rows), and the shifts."""
    steps = RELATIVE_STEP * np.maximum(np.abs(theta), p.scale)
    hi = np.array([BOUNDS[k][1] for k in p.free])
    steps = np.where(theta + steps > hi, -steps, steps)
    rows = np.repeat(theta[None, :], len(p.free) + 1, axis=0)
    rows[1:] += np.diag(steps)
    return rows, steps


def _lm_step(p: Problem) -> tuple[FloatArray, float]:
    """Return the Levenberg–Marquardt candidate from the current θ, J and residual.

    And the decrease of the sum of squares the linearised model predicts for it. The step
    stays within the bounds as a projected step does: a parameter the step would carry past
    its bound moves to the bound and is held there while the others are solved for again
    (each pass holds at least one more), so that a step clipped at a bound (γ or a friction
    at 0, n at its limit) is still a descent step of the rest. Where even that step is
    predicted to raise the sum of squares, λ grows until it is not.
    """
    assert p.jac is not None and p.residual is not None
    d = np.linalg.norm(p.jac, axis=0)
    d = np.where(d > 0, d, 1.0)
    js = p.jac / d
    lo = np.array([BOUNDS[k][0] for k in p.free])
    hi = np.array([BOUNDS[k][1] for k in p.free])
    while True:
        step = np.zeros_like(p.theta)
        held = np.zeros(p.theta.size, dtype=bool)
        for _ in range(p.theta.size):
            move = ~held
            r = p.residual + p.jac[:, held] @ step[held]
            a = js[:, move].T @ js[:, move] + p.lam * np.eye(int(move.sum()))
            g = js[:, move].T @ r
            try:
                delta = -np.linalg.solve(a, g) / d[move]
            except np.linalg.LinAlgError:
                delta = -np.linalg.lstsq(a, g, rcond=None)[0] / d[move]
            step[move] = delta
            out = move & ((p.theta + step < lo) | (p.theta + step > hi))
            if not out.any():
                break
            step[out] = np.clip(p.theta + step, lo, hi)[out] - p.theta[out]
            held |= out
        candidate = p.clip(p.theta + step)
        step = candidate - p.theta
        jd = p.jac @ step
        predicted = -float(p.residual @ jd) - 0.5 * float(jd @ jd)
        if predicted > 0.0 or p.lam > LAMBDA_MAX:
            return candidate, predicted
        p.lam = stiffened(p.lam)


def solve(problems: Sequence[Problem], *, jit: bool,
          progress: Callable[[int, int], None] | None = None,
          max_iterations: int = MAX_ITERATIONS) -> None:
    """Fit every problem in lockstep (each problem's state is updated in place)."""
    candidates = [p.clip(p.theta) for p in problems]
    for it in range(max_iterations + 1):
        active = [i for i, p in enumerate(problems) if not p.done]
        if not active:
            break
        batch = [problems[i] for i in active]
        rows = [_with_steps(p, candidates[i]) for i, p in zip(active, batch, strict=True)]
        preds = simulate_columns(batch, [r for r, _ in rows], jit=jit)
        for i, p, (_, steps), pred in zip(active, batch, rows, preds, strict=True):
            p.iterations = it
            cost = math.inf
            if pred is not None:
                res = pred[0] - p.y
                cost = 0.5 * float(res @ res)
            if verdict(p, cost):
                assert pred is not None
                p.theta, p.cost, p.residual = candidates[i], cost, res
                p.jac = ((pred[1:] - pred[0]) / steps[:, None]).T
            if not p.done:
                candidates[i], predicted = _lm_step(p)
                if np.array_equal(candidates[i], p.theta) or predicted < TOLERANCE * p.cost:
                    p.done = True
        if progress is not None:
            progress(it + 1, sum(p.done for p in problems))
