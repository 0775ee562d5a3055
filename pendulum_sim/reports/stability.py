"""Stability on stiff and extreme cases: where plain RK4 breaks, and what the guard does there.

A matrix over γ (up to 1e6), n (0 to 10, non-integer too), h (1e-5 to 0.1) and initial states
(the paper's, near the top, beyond the top, spinning, very fast, with a torque input). Per cell:
whether plain RK4 is stable at that h by the h·λ criterion (the linearised eigenvalues along the
trajectory, against RK4's stability function, as ``guard.py`` does) and by an actual unguarded
run, what the guard did (``Trajectory.stats``), the largest energy increase without input, any
non-finite value, the error against the reference where one can be had, and the time cost.
"""
from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..core.guard import real_axis_bound
from ..core.model import PendulumParams, energy
from ..core.simulate import simulate
from ..core.tableaus import RK4
from . import plotting
from .output import Progress, Summary, markdown_table, write_csv
from .plain import plain_run
from .reference import reference, stiffness_work

RK4_REAL_BOUND = real_axis_bound(RK4)  # RK4's interval on the negative real axis: 2.785
GROWTH_TOL = 1e-3  # relative energy excess that flags an unguarded run as unstable
CRITERION_SAMPLES = 400
REFERENCE_WORK_LIMIT = 1e14  # above this |λ| t_end no reference is attempted


@dataclass(frozen=True)
class Scenario:
    """An initial state (and optional constant torque) of the matrix."""

    name: str
    phi0: float
    dphi0: float
    torque: float
    note: str


SCENARIOS = {
    'paper': Scenario('paper', 2.0, 0.0, 0.0, "x0 = 2 rad, x1 = 0 (the paper's)"),
    'near_top': Scenario('near_top', math.pi - 1e-3, 0.0, 0.0, 'x0 = π − 1e-3, at rest'),
    'beyond_top': Scenario('beyond_top', 4.0, 0.0, 0.0, 'x0 = 4 rad (past the top), at rest'),
    'rotation': Scenario('rotation', 0.0, 10.0, 0.0, 'x0 = 0, x1 = 10 rad/s: goes over the top'),
    'fast': Scenario('fast', 0.0, 100.0, 0.0, 'x0 = 0, x1 = 100 rad/s'),
    'torque': Scenario('torque', 2.0, 0.0, 3.0, 'x0 = 2, τ = 3 N m (τ/I = 15 > ω0²: spins up)'),
}


@dataclass(frozen=True)
class StabilityGrid:
    """The matrix: base grid (paper state) and the reduced grid of the other scenarios."""

    t_end: float
    gammas: tuple[float, ...]
    ns: tuple[float, ...]
    hs: tuple[float, ...]
    extra_scenarios: tuple[str, ...]
    extra_gammas: tuple[float, ...]
    extra_ns: tuple[float, ...]
    extra_hs: tuple[float, ...]
    quick: bool


FULL = StabilityGrid(
    t_end=1.0,
    gammas=(1.0, 10.0, 100.0, 1e3, 1e4, 1e5, 1e6),
    ns=(0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 5.0, 10.0),
    hs=(1e-5, 1e-4, 1e-3, 1 / 60, 0.1),
    extra_scenarios=('near_top', 'beyond_top', 'rotation', 'fast', 'torque'),
    extra_gammas=(0.0, 1.0, 1e3, 1e6),
    extra_ns=(0.0, 1.0, 2.0, 2.5, 10.0),
    extra_hs=(1e-4, 1e-3, 1 / 60, 0.1),
    quick=False)

QUICK = StabilityGrid(
    t_end=0.5,
    gammas=(1.0, 1e3, 1e6),
    ns=(0.0, 1.0, 2.0, 2.5),
    hs=(1e-3, 1 / 60, 0.1),
    extra_scenarios=('near_top', 'rotation', 'torque'),
    extra_gammas=(1.0, 1e3),
    extra_ns=(1.0, 2.0),
    extra_hs=(1 / 60,),
    quick=True)


def _rk4_abs_r(z: complex) -> float:
    return abs(RK4.stability_function(z))


def criterion(params: PendulumParams, h: float, phi: np.ndarray,
              dphi: np.ndarray) -> tuple[bool, float]:
    """Return (stable, max h|λ|): |R(hλ)| ≤ 1 for every decaying eigenvalue along the states.

    The eigenvalues are those of the linearisation [[0, 1], [−ω0² cos φ, −γ n |φ'|^(n−1)]]
    (the paper's eq 18-19, linearised) at up to CRITERION_SAMPLES states of the trajectory;
    eigenvalues with non-negative real part (above the horizontal) are physics, not a
    stability limit.
    """
    idx = np.unique(np.linspace(0, len(phi) - 1, min(len(phi), CRITERION_SAMPLES)).astype(int))
    stable = True
    zmax = 0.0
    for i in idx:
        for lam in params.jacobian_eigenvalues(float(phi[i]), float(dphi[i])):
            if not lam.real < 0.0:
                continue
            if math.isinf(lam.real):
                return False, math.inf
            z = h * lam
            zmax = max(zmax, abs(z))
            if stable and _rk4_abs_r(z) > 1.0:
                stable = False
    return stable, zmax


def _unguarded(params: PendulumParams, sc: Scenario, t_end: float,
               h: float) -> dict[str, Any]:
    """Run a plain RK4 loop (``plain.plain_run``: no guard, no reversal splitting, no energy
    check, as the paper ran it) and judge it: blown up, energy growth, or stable."""
    _, phi, dphi = plain_run(params, sc.phi0, sc.dphi0, t_end, h, 'rk4', torque=sc.torque)
    if not (np.all(np.isfinite(phi)) and np.all(np.isfinite(dphi))):
        return {'rk4_outcome': 'non-finite', 'rk4_unstable_run': True,
                'rk4_energy_excess': math.inf}
    scale = float(energy(params, phi[0], dphi[0])) + params.mgl
    with np.errstate(over='ignore', invalid='ignore'):
        # A constant torque's work is τ (φ − φ0).
        balance = energy(params, phi, dphi) - energy(params, phi[0], dphi[0]) \
            - sc.torque * (phi - phi[0])
        excess = float(np.max(balance)) / scale
    if not math.isfinite(excess):
        outcome = 'non-finite'
    elif excess > GROWTH_TOL:
        outcome = 'energy growth'
    else:
        outcome = 'stable'
    return {'rk4_outcome': outcome, 'rk4_unstable_run': outcome != 'stable',
            'rk4_energy_excess': excess}


def _cell(params: PendulumParams, sc: Scenario, t_end: float, h: float,
          ref_final: tuple[float, float] | None) -> dict[str, Any]:
    t0 = time.process_time()
    run = simulate(params, sc.phi0, sc.dphi0, t_end, h, 'rk4', torque=sc.torque)
    cpu = time.process_time() - t0
    stats = run.stats
    finite = bool(np.all(np.isfinite(run.phi)) and np.all(np.isfinite(run.dphi)))
    stable, zmax = criterion(params, h, run.phi, run.dphi) if finite else (False, math.inf)
    scale = float(run.energy[0] + params.mgl)
    de = np.diff(run.energy - run.input_work)
    step_increase = float(np.max(de)) if len(de) else 0.0
    excess = float(np.max(run.energy - run.energy[0] - run.input_work))
    err = math.nan
    if ref_final is not None and finite:
        err = math.hypot(run.phi[-1] - ref_final[0], run.dphi[-1] - ref_final[1])
    row: dict[str, Any] = {
        'scenario': sc.name, 'gamma': params.gamma, 'n': params.n, 'h': h,
        'h_lambda_max': zmax, 'rk4_criterion_stable': stable,
        'guarded_finite': finite,
        'substeps': stats.substeps, 'fallbacks': stats.fallbacks,
        'reversals': stats.reversals, 'sticks': stats.sticks,
        'energy_rejections': stats.energy_rejections,
        'max_step_energy_increase_rel': step_increase / scale,
        'max_energy_excess_rel': excess / scale,
        'error_final': err, 'cpu_s': cpu, 'cpu_us_per_step': cpu / max(stats.steps, 1) * 1e6,
        'final_phi': float(run.phi[-1]), 'final_dphi': float(run.dphi[-1]),
    }
    row.update(_unguarded(params, sc, t_end, h))
    row['max_speed'] = float(np.max(np.abs(run.dphi))) if finite else math.inf
    return row


def _reference_final(params: PendulumParams, sc: Scenario,
                     t_end: float) -> tuple[tuple[float, float] | None, str]:
    work = stiffness_work(params, sc.dphi0, sc.torque, t_end)
    if work > REFERENCE_WORK_LIMIT:
        return None, 'too stiff for a reference'
    ref = reference(params, sc.phi0, sc.dphi0, np.array([0.0, t_end]), torque=sc.torque,
                    cross_check=False)
    if ref is None or not np.isfinite(ref.phi[-1]):
        return None, 'no reference (solver gave up)'
    return (float(ref.phi[-1]), float(ref.dphi[-1])), ref.solver


def _boundaries(cells: Sequence[dict[str, Any]]) -> dict[float, list[tuple[float, float]]]:
    """Return, per n, the RK4 boundary h = 2.785/|λ| with |λ| the largest along the run."""
    out: dict[float, list[tuple[float, float]]] = {}
    base = [c for c in cells if c['scenario'] == 'paper']
    for n in sorted({c['n'] for c in base}):
        pts = []
        for g in sorted({c['gamma'] for c in base}):
            sel = [c for c in base if c['n'] == n and c['gamma'] == g and c['guarded_finite']]
            if not sel:
                continue
            finest = min(sel, key=lambda c: c['h'])
            lam = finest['h_lambda_max'] / finest['h']
            if math.isfinite(lam) and lam > 0.0:
                pts.append((g, RK4_REAL_BOUND / lam))
        out[n] = pts
    return out


def run_stability(out: Path, grid: StabilityGrid, progress: bool = True) -> dict[str, Any]:
    """Run the matrix into ``out`` (CSV, heat map, ``stability.md``); return its tables."""
    plan: list[tuple[Scenario, float, float, tuple[float, ...]]] = []
    for g in grid.gammas:
        for n in grid.ns:
            plan.append((SCENARIOS['paper'], g, n, grid.hs))
    for name in grid.extra_scenarios:
        for g in grid.extra_gammas:
            for n in grid.extra_ns:
                plan.append((SCENARIOS[name], g, n, grid.extra_hs))
    bar = Progress('stability', len(plan), enabled=progress)
    cells: list[dict[str, Any]] = []
    for sc, g, n, hs in plan:
        params = PendulumParams(gamma=g, n=n)
        ref_final, ref_how = _reference_final(params, sc, grid.t_end)
        for h in hs:
            row = _cell(params, sc, grid.t_end, h, ref_final)
            row['reference'] = ref_how
            cells.append(row)
        bar.tick(f'{sc.name} γ={g:g} n={n:g} ({len(hs)} steps)')
    boundaries = _boundaries(cells)
    write_csv(out / 'stability.csv', cells)
    figures = plotting.stability_heatmaps(out, cells, boundaries)
    text = _summary(grid, cells, figures)
    (out / 'stability.md').write_text(text, encoding='utf-8')
    return {'cells': cells, 'boundaries': boundaries, 'summary': text, 'figures': figures}


def _summary(grid: StabilityGrid, cells: Sequence[dict[str, Any]],
             figures: Sequence[str]) -> str:
    s = Summary('Stability on stiff and extreme cases')
    total = len(cells)
    nonfinite = sum(1 for c in cells if not c['guarded_finite'])
    unstable = sum(1 for c in cells if c['rk4_unstable_run'])
    crit_unstable = sum(1 for c in cells if not c['rk4_criterion_stable'])
    agree = sum(1 for c in cells if c['rk4_unstable_run'] == (not c['rk4_criterion_stable']))
    free = [c for c in cells if SCENARIOS[c['scenario']].torque == 0.0 and c['gamma'] > 0.0]
    worst_step = max((c['max_step_energy_increase_rel'] for c in free), default=math.nan)
    worst_excess = max((c['max_energy_excess_rel'] for c in free), default=math.nan)
    errs = [c['error_final'] for c in cells if math.isfinite(c['error_final'])]
    s.section(
        'Set-up',
        f"{total} cells, t_end = {grid.t_end:g} s each, method RK4 (the paper's). Scenarios: "
        + '; '.join(f'`{k}`: {v.note}' for k, v in SCENARIOS.items()
                    if k == 'paper' or k in grid.extra_scenarios) + '. '
        f'The paper state runs over γ ∈ {{{", ".join(f"{g:g}" for g in grid.gammas)}}}, '
        f'n ∈ {{{", ".join(f"{n:g}" for n in grid.ns)}}}, '
        f'h ∈ {{{", ".join(f"{h:.3g}" for h in grid.hs)}}}; the other scenarios over '
        f'γ ∈ {{{", ".join(f"{g:g}" for g in grid.extra_gammas)}}}, '
        f'n ∈ {{{", ".join(f"{n:g}" for n in grid.extra_ns)}}}, '
        f'h ∈ {{{", ".join(f"{h:.3g}" for h in grid.extra_hs)}}}.'
        + (' Quick grid (for the test suite).' if grid.quick else ''),
        'Columns: `rk4_criterion_stable` — |R(hλ)| ≤ 1 for RK4 at every decaying eigenvalue '
        'of the linearisation along the (guarded) trajectory; `rk4_outcome` — an actual '
        'plain RK4 loop (`plain.plain_run`: no guard, no reversal splitting), judged unstable '
        f'when it overflows, goes non-finite, or its energy exceeds E(0) + input work by more '
        f'than {GROWTH_TOL:g}·(E0 + m g l); `substeps`, `fallbacks`, `reversals`, '
        '`energy_rejections` — what the guarded run did; `max_step_energy_increase_rel` — the '
        'largest one-sample increase of E − W_in, relative to E0 + m g l; `error_final` — the '
        'final state against the reference (scipy DOP853 or Radau restarted at reversals), '
        'where one could be had.')
    s.section(
        'Results',
        f'- Guarded runs with a non-finite value: **{nonfinite} of {total}**.\n'
        f'- Unguarded RK4 unstable in the actual run: {unstable} of {total} cells; unstable '
        f'by the h·λ criterion: {crit_unstable}; the two agree on {agree} cells (the criterion '
        'is linear and local, so it is pessimistic for n < 1, whose slope is unbounded at '
        'rest, and for transients it only sees on a few states).\n'
        f'- Largest energy increase between samples without input (γ > 0), relative to '
        f'E0 + m g l: {worst_step:.3g}; largest E(t) − E(0): {worst_excess:.3g}.\n'
        + (f'- Final-state error against the reference: median {np.median(errs):.3g}, '
           f'max {max(errs):.3g} over {len(errs)} cells.' if errs else ''))
    interesting = [c for c in cells if c['rk4_unstable_run'] or c['fallbacks']
                   or c['energy_rejections']]
    cols = ['scenario', 'gamma', 'n', 'h', 'h_lambda_max', 'rk4_criterion_stable', 'rk4_outcome',
            'guarded_finite', 'substeps', 'fallbacks', 'reversals', 'energy_rejections',
            'max_step_energy_increase_rel', 'error_final', 'cpu_us_per_step']
    s.section('Cells where plain RK4 fails or the guard had to act',
              f'{len(interesting)} cells; the full matrix is in `stability.csv`.',
              markdown_table(interesting, cols))
    worst = sorted((c for c in cells if math.isfinite(c['error_final'])),
                   key=lambda c: -c['error_final'])[:12]
    s.section(
        'Largest final-state errors (accuracy, not stability)',
        'A finite, energy-decreasing run can still be wrong: these are the cells farthest from '
        'the reference at t_end. Errors that do not shrink as h falls point at the step itself '
        '(e.g. an implicit fallback across a violent power-law transient, or Coulomb friction '
        'stopping), not at the step size.',
        markdown_table(worst, ['scenario', 'gamma', 'n', 'h', 'error_final', 'final_phi',
                               'substeps', 'fallbacks', 'reversals', 'sticks',
                               'energy_rejections', 'reference']))
    s.section('Figures', '\n'.join(f'- `{f}`' for f in figures) if figures else
              plotting.missing_note())
    return s.text()
