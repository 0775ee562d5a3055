"""The paper's figures 3-9, reproduced from the core, plus the long-time decay law for n > 1.

Quiroga and Ospina-Henao (2017): x0 = 2 rad, x1 = 0, m = 0.2 kg, l = 1 m, I = 0.2 kg m²
(ω0² = 9.8 s⁻²), RK4 at h = 1 ms. Every figure's data is also written as CSV, and the summary
states the checkable facts each figure shows (no zero crossing for the overdamped case, energy
never increasing, Q → 16, the decay law's slope), measured on the same data.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..core.analysis import (
    convergence_quotient,
    decay_law_amplitude,
    linear_exact_solution,
    turning_points,
    undamped_period,
)
from ..core.model import PendulumParams
from ..core.simulate import Trajectory, simulate
from ..core.tableaus import RK4
from . import plotting
from .output import Progress, Summary, markdown_table, write_csv
from .plain import plain_run

FloatArray = npt.NDArray[np.float64]

X0 = 2.0
NS = (1, 2, 3, 4, 5)
MAX_CSV_ROWS = 2001


@dataclass(frozen=True)
class PaperGrid:
    """Step and horizons of the reproduction."""

    h: float
    t_end: float
    q_h: float
    q_t_end: float
    decay_h: float
    decay_t_end: float
    quick: bool


FULL = PaperGrid(h=1e-3, t_end=20.0, q_h=1e-3, q_t_end=20.0, decay_h=5e-3, decay_t_end=300.0,
                 quick=False)
QUICK = PaperGrid(h=1e-2, t_end=5.0, q_h=1e-2, q_t_end=5.0, decay_h=2e-2, decay_t_end=40.0,
                  quick=True)


def _params(gamma: float, n: float) -> PendulumParams:
    return PendulumParams(gamma=gamma, n=float(n))


def _thin(k: int) -> int:
    return max(1, math.ceil(k / MAX_CSV_ROWS))


def _series_csv(path: Path, t: FloatArray, series: dict[str, FloatArray]) -> None:
    step = _thin(len(t))
    idx = np.arange(0, len(t), step)
    if idx[-1] != len(t) - 1:
        idx = np.append(idx, len(t) - 1)
    rows = [{'t': float(t[i]), **{k: float(v[i]) for k, v in series.items()}} for i in idx]
    write_csv(path, rows, ['t', *series])


def run_paper(out: Path, grid: PaperGrid, progress: bool = True) -> dict[str, Any]:
    """Reproduce figures 3-9 and the decay law into ``out``; return the facts table."""
    bar = Progress('paper', 8, enabled=progress)
    runs: dict[tuple[float, int], Trajectory] = {}
    for g in (1.0, 10.0, 100.0, 1000.0):
        for n in NS:
            if g == 100.0 and n != 2:
                continue
            runs[(g, n)] = simulate(_params(g, n), X0, 0.0, grid.t_end, grid.h)
    t = runs[(1.0, 1)].t
    bar.tick('runs for figs 3-7')
    facts: list[dict[str, Any]] = []
    figures: list[str] = []
    plt = plotting.pyplot() if plotting.have_matplotlib() else None

    # Figs 3 and 5: φ(t), φ'(t) for n = 1..5 at γ = 1 and 10.
    for var, fig_no, label in (('phi', 3, 'φ (rad)'), ('dphi', 5, "φ' (rad/s)")):
        series = {f'{var}_g{g:g}_n{n}': getattr(runs[(g, n)], var) for g in (1.0, 10.0)
                  for n in NS}
        _series_csv(out / f'fig{fig_no}_{var}.csv', t, series)
        if plt is not None:
            fig, axes = plt.subplots(1, 2, figsize=(11, 4))
            for ax, g in zip(axes, (1.0, 10.0), strict=False):
                for n in NS:
                    ax.plot(t, getattr(runs[(g, n)], var), label=f'n = {n}')
                plotting.label_axes(ax, 't (s)', label, f'γ = {g:g} s^(n−2)')
            figures.append(plotting.save(fig, out, f'fig{fig_no}_{var}.png'))
    over = runs[(10.0, 1)]
    facts.append({'figure': 3, 'fact': 'n = 1, γ = 10 is overdamped: min φ over the run '
                  '(no zero crossing when > 0)', 'value': float(np.min(over.phi))})
    facts.append({'figure': 3, 'fact': 'zero crossings of φ, n = 1, γ = 1',
                  'value': float(_crossings(runs[(1.0, 1)].phi))})
    bar.tick('figs 3, 5')

    # Fig 4: n = 2 over γ; all n at γ = 1000.
    series = {f'phi_g{g:g}_n2': runs[(g, 2)].phi for g in (1.0, 10.0, 100.0, 1000.0)}
    series.update({f'phi_g1000_n{n}': runs[(1000.0, n)].phi for n in NS})
    _series_csv(out / 'fig4_phi.csv', t, series)
    if plt is not None:
        fig, axes = plt.subplots(1, 2, figsize=(11, 4))
        for g in (1.0, 10.0, 100.0, 1000.0):
            axes[0].plot(t, runs[(g, 2)].phi, label=f'γ = {g:g}')
        axes[0].set_title('n = 2')
        for n in NS:
            axes[1].plot(t, runs[(1000.0, n)].phi, label=f'n = {n}')
        axes[1].set_title('γ = 1000 s^(n−2)')
        for ax in axes:
            plotting.label_axes(ax, 't (s)', 'φ (rad)')
        figures.append(plotting.save(fig, out, 'fig4_phi.png'))
    for n in NS:
        facts.append({'figure': 4, 'fact': f'φ(t_end), γ = 1000, n = {n}',
                      'value': float(runs[(1000.0, n)].phi[-1])})
    bar.tick('fig 4')

    # Fig 6: energy decay (and its monotonicity without input).
    series = {f'E_g{g:g}_n{n}': runs[(g, n)].energy for g in (1.0, 10.0) for n in NS}
    _series_csv(out / 'fig6_energy.csv', t, series)
    worst = max(float(np.max(np.diff(r.energy))) for r in runs.values())
    facts.append({'figure': 6, 'fact': 'largest increase of E between steps, all runs (J)',
                  'value': worst})
    facts.append({'figure': 6, 'fact': 'largest |energy-balance residual|, all runs (J)',
                  'value': max(float(np.max(np.abs(r.residual))) for r in runs.values())})
    if plt is not None:
        fig, axes = plt.subplots(1, 2, figsize=(11, 4))
        for ax, g in zip(axes, (1.0, 10.0), strict=False):
            for n in NS:
                ax.semilogy(t, np.maximum(runs[(g, n)].energy, 1e-16), label=f'n = {n}')
            plotting.label_axes(ax, 't (s)', 'E (J)', f'Energy, γ = {g:g}')
        figures.append(plotting.save(fig, out, 'fig6_energy.png'))
    bar.tick('fig 6')

    # Fig 7: phase portraits with the undamped closed curve from x0 = 2.
    p0 = _params(0.0, 1)
    phis = np.linspace(-X0, X0, 801)
    closed = np.sqrt(np.maximum(2.0 * p0.omega0_sq * (np.cos(phis) - math.cos(X0)), 0.0))
    period = undamped_period(p0.omega0_sq, X0)
    undamped = simulate(p0, X0, 0.0, period, period / 4000)
    facts.append({'figure': 7, 'fact': 'undamped run back at its start after one period '
                  f"T = 4K/ω0 = {period:.13g} s: |Δ(φ, φ')|",
                  'value': float(math.hypot(undamped.phi[-1] - X0, undamped.dphi[-1]))})
    inside = max(float(np.max(r.dphi**2 - 2.0 * r.params.omega0_sq * (np.cos(r.phi)
                                                                      - math.cos(X0))))
                 for r in runs.values())
    facts.append({'figure': 7, 'fact': "max of φ'² − 2ω0²(cos φ − cos x0) over damped runs "
                  '(≤ 0: inside the γ = 0 curve)', 'value': inside})
    rows = [{'phi': float(a), 'dphi_upper': float(b)} for a, b in zip(phis, closed, strict=False)]
    write_csv(out / 'fig7_undamped_curve.csv', rows)
    if plt is not None:
        fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
        for ax, g in zip(axes, (1.0, 10.0), strict=False):
            ax.plot(phis, closed, 'k-', lw=1, label='γ = 0')
            ax.plot(phis, -closed, 'k-', lw=1)
            for n in NS:
                r = runs[(g, n)]
                ax.plot(r.phi, r.dphi, lw=0.8, label=f'n = {n}')
            plotting.label_axes(ax, 'φ (rad)', "φ' (rad/s)", f'Phase portrait, γ = {g:g}')
        figures.append(plotting.save(fig, out, 'fig7_phase.png'))
    bar.tick('fig 7')

    # Fig 8: exact vs numerical for the linearised case.
    figures += _fig8(out, grid, facts, plt)
    bar.tick('fig 8')
    figures += _fig9(out, grid, facts, plt)
    bar.tick('fig 9')
    figures += _decay(out, grid, facts, plt)
    bar.tick('decay law')

    write_csv(out / 'paper_facts.csv', facts, ['figure', 'fact', 'value'])
    text = _summary(grid, facts, figures)
    (out / 'paper.md').write_text(text, encoding='utf-8')
    return {'facts': facts, 'figures': figures, 'summary': text}


def _crossings(x: FloatArray) -> int:
    s = np.signbit(x[x != 0.0])
    return int(np.count_nonzero(s[1:] != s[:-1]))


def linear_rk4(gamma: float, omega0_sq: float, x0: float, v0: float, t_end: float,
               h: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Integrate x'' + γ x' + ω0² x = 0 with the core's RK4 tableau (the paper's linear check).

    The core's vector field has sin φ; the paper's Fig 8 integrates the harmonic approximation,
    so this loop applies the same tableau (``tableaus.RK4``, generic stages) to the linear field.
    """
    A, B = RK4.A, RK4.B
    s = RK4.stages
    steps = round(t_end / h)
    xs, vs = np.empty(steps + 1), np.empty(steps + 1)
    x, v = x0, v0
    xs[0], vs[0] = x, v
    for k in range(1, steps + 1):
        kx, kv = [0.0] * s, [0.0] * s
        for i in range(s):
            xi = x + h * sum(A[i, j] * kx[j] for j in range(i))
            vi = v + h * sum(A[i, j] * kv[j] for j in range(i))
            kx[i], kv[i] = vi, -gamma * vi - omega0_sq * xi
        x += h * sum(B[i] * kx[i] for i in range(s))
        v += h * sum(B[i] * kv[i] for i in range(s))
        xs[k], vs[k] = x, v
    return np.arange(steps + 1, dtype=float) * h, xs, vs


def _fig8(out: Path, grid: PaperGrid, facts: list[dict[str, Any]], plt: Any) -> list[str]:
    gamma, x0 = 0.1, 0.1
    p = _params(gamma, 1)
    exact = linear_exact_solution(gamma, p.omega0_sq, x0, 0.0)
    t, xl, _ = linear_rk4(gamma, p.omega0_sq, x0, 0.0, grid.t_end, grid.h)
    xe = exact(t)
    core = simulate(p, x0, 0.0, grid.t_end, grid.h)
    facts.append({'figure': 8, 'fact': 'ω = sqrt(ω0² − γ²/4) (paper: 3.130095845)',
                  'value': exact.omega})
    facts.append({'figure': 8, 'fact': 'α (paper: −0.01597259328)', 'value': exact.alpha})
    facts.append({'figure': 8, 'fact': 'A (paper: 0.1000127575)', 'value': exact.amplitude})
    facts.append({'figure': 8, 'fact': f'max |x_RK4 − x_exact|, linear field, h = {grid.h:g}',
                  'value': float(np.max(np.abs(xl - xe)))})
    facts.append({'figure': 8, 'fact': 'max |φ_core − x_exact| (core integrates sin φ: the '
                  'gap is the nonlinearity, not the method)',
                  'value': float(np.max(np.abs(core.phi - xe)))})
    _series_csv(out / 'fig8_exact_vs_numerical.csv', t,
                {'x_exact': xe, 'x_rk4_linear': xl, 'phi_core_nonlinear': core.phi})
    if plt is None:
        return []
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    axes[0].plot(t, xe, 'k-', lw=2, label='exact (eq 33)')
    axes[0].plot(t, xl, 'r--', lw=1, label='RK4, linear field')
    axes[0].set_ylabel('x (rad)')
    axes[1].semilogy(t, np.maximum(np.abs(xl - xe), 1e-18), label='|RK4 linear − exact|')
    axes[1].semilogy(t, np.maximum(np.abs(core.phi - xe), 1e-18),
                     label='|core (sin φ) − exact linear|')
    axes[1].set_ylabel('difference (rad)')
    for ax in axes:
        plotting.label_axes(ax, 't (s)')
    return [plotting.save(fig, out, 'fig8_exact_vs_numerical.png')]


def _fig9(out: Path, grid: PaperGrid, facts: list[dict[str, Any]], plt: Any) -> list[str]:
    h, t_end = grid.q_h, grid.q_t_end
    series: dict[str, FloatArray] = {}
    t = None
    for n in NS:
        q = convergence_quotient(_params(1.0, n), X0, 0.0, t_end, h)
        t = q.t
        series[f'Q_n{n}'] = q.q
        facts.append({'figure': 9, 'fact': f'median Q(t), n = {n}, core (reversal located), '
                      f'h = {h:g}', 'value': float(np.nanmedian(q.q[1:]))})
    assert t is not None
    p2 = _params(1.0, 2)
    ys = [plain_run(p2, X0, 0.0, t_end, h / 2**k, 'rk4', record_every=2**k) for k in range(3)]
    d1 = np.hypot(ys[0][1] - ys[1][1], ys[0][2] - ys[1][2])
    d2 = np.hypot(ys[1][1] - ys[2][1], ys[1][2] - ys[2][2])
    with np.errstate(divide='ignore', invalid='ignore'):
        q_plain = np.where(d2 > 0.0, d1 / d2, np.nan)
    series['Q_n2_plain_rk4'] = q_plain
    qp = q_plain[1:]
    facts.append({'figure': 9, 'fact': f'median Q(t), n = 2, plain RK4 loop (no reversal '
                  f'location), h = {h:g}', 'value': float(np.nanmedian(qp))})
    facts.append({'figure': 9, 'fact': 'fraction of t with Q outside [12, 20], n = 2, plain RK4',
                  'value': float(np.mean((qp < 12) | (qp > 20)))})
    facts.append({'figure': 9, 'fact': 'fraction of t with Q outside [12, 20], n = 2, core',
                  'value': float(np.mean((series['Q_n2'][1:] < 12)
                                         | (series['Q_n2'][1:] > 20)))})
    _series_csv(out / 'fig9_convergence_quotient.csv', t, series)
    if plt is None:
        return []
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for n in NS:
        axes[0].plot(t[1:], series[f'Q_n{n}'][1:], lw=0.8, label=f'n = {n}')
    axes[0].set_title(f'Q(t), core RK4 with reversal location, h = {h:g} s')
    axes[1].plot(t[1:], q_plain[1:], 'r-', lw=0.8, label='n = 2, plain RK4 (paper)')
    axes[1].plot(t[1:], series['Q_n2'][1:], 'b-', lw=0.8, label='n = 2, core (reversal located)')
    axes[1].set_title("n = 2: why the paper's Q wandered")
    for ax in axes:
        ax.axhline(16.0, color='k', lw=0.5, ls=':')
        ax.set_yscale('log')
        plotting.label_axes(ax, 't (s)', 'Q')
    return [plotting.save(fig, out, 'fig9_convergence_quotient.png')]


def _decay(out: Path, grid: PaperGrid, facts: list[dict[str, Any]], plt: Any) -> list[str]:
    """Compare simulated turning-point amplitudes with A^(1−n) = A0^(1−n) + (n−1)γ c_n ω0^(n−1) t.

    The law is the small-oscillation average, so it starts at the first turning point with
    amplitude below 0.3 rad; the tail's log-log slope is fitted against −1/(n−1).
    """
    rows: list[dict[str, Any]] = []
    curves = []
    for n in (2, 3, 4, 5):
        p = _params(1.0, n)
        run = simulate(p, X0, 0.0, grid.decay_t_end, grid.decay_h, record_every=1)
        tt, amp = turning_points(run.t, run.phi, run.dphi)
        start = int(np.argmax(amp < 0.3))
        tt, amp = tt[start:], amp[start:]
        law = decay_law_amplitude(float(n), 1.0, p.omega0_sq, float(amp[0]), tt - tt[0])
        tail = tt > tt[0] + 0.5 * (tt[-1] - tt[0])
        slope = float(np.polyfit(np.log(tt[tail]), np.log(amp[tail]), 1)[0])
        ratio_end = float(amp[-1] / law[-1])
        facts.append({'figure': 'decay', 'fact': f'n = {n}: A_sim / A_law at the last turning '
                      f'point (t = {tt[-1]:.4g} s)', 'value': ratio_end})
        facts.append({'figure': 'decay', 'fact': f'n = {n}: log-log slope of the tail (law: '
                      f'−1/(n−1) = {-1.0 / (n - 1):.4g} asymptotically)', 'value': slope})
        for a, b, c in zip(tt, amp, law, strict=False):
            rows.append({'n': n, 't': float(a), 'amplitude_sim': float(b),
                         'amplitude_law': float(c)})
        curves.append((n, tt, amp, law))
    write_csv(out / 'decay_law.csv', rows, ['n', 't', 'amplitude_sim', 'amplitude_law'])
    if plt is None:
        return []
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for n, tt, amp, law in curves:
        line = ax.loglog(tt, amp, '.', ms=3, label=f'n = {n}, turning points')[0]
        ax.loglog(tt, law, '-', color=line.get_color(), lw=1, label=f'n = {n}, law')
    plotting.label_axes(ax, 't (s)', 'amplitude (rad)',
                        'Long-time decay, γ = 1: A ∝ t^(−1/(n−1))', fontsize=7, which='both')
    from matplotlib.ticker import NullFormatter
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.yaxis.set_minor_formatter(NullFormatter())
    return [plotting.save(fig, out, 'decay_law.png')]


def _summary(grid: PaperGrid, facts: Sequence[dict[str, Any]], figures: Sequence[str]) -> str:
    s = Summary("The paper's figures, reproduced from the core")
    s.section(
        'Set-up',
        f'x0 = 2 rad, x1 = 0, m = 0.2 kg, l = 1 m, I = 0.2 kg m² (ω0² = 9.8 s⁻²), core RK4 '
        f'(guard, reversal location and energy check on) at h = {grid.h:g} s to '
        f't = {grid.t_end:g} s; Q(t) from h = {grid.q_h:g}, h/2, h/4; decay law over '
        f'{grid.decay_t_end:g} s at h = {grid.decay_h:g} s.'
        + (' Quick grid (for the test suite).' if grid.quick else ''),
        "Fig 8 integrates the harmonic approximation x'' + γx' + ω0²x = 0 with the core's RK4 "
        "tableau (the core's own field has sin φ); the core's nonlinear run is shown beside it. "
        'Fig 9 shows, for n = 2, the core (step split at the velocity reversal, located by '
        'Hermite interpolation) beside a plain RK4 loop of the same tableau with no splitting '
        "(what the paper ran): at a reversal the plain step's local error drops to O(h³), "
        'so Q leaves 16 and wanders.')
    s.section('What the figures show, measured', markdown_table(facts, ['figure', 'fact', 'value'],
                                                                 digits=6))
    s.section('Figures', '\n'.join(f'- `{f}`' for f in figures) if figures else
              plotting.missing_note())
    return s.text()
