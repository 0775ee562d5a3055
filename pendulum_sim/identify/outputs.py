"""Write what ``pendulum_identify`` found: the scene, the comparison, the figure, the spread.

``fit.yaml`` is a scene (a ROS 2 parameter file ``pendulum_node --scene`` and
``closed_loop(scene=...)`` read): the fitted ω0 is written as ``m`` with ``l``, ``g`` and the
inertia given (ω0² = m g l / I, eq 11), with γ, n, the Coulomb ``friction`` (the fitted
deceleration f/I times that inertia; 0 but for ``power+coulomb``: the ``coulomb`` law is the
dry law n = 0 itself) and the state at the first sample.
``campaign_parameters.yaml`` is a ``parameters:`` block for ``pendulum_campaign``: each fitted
parameter a ``normal`` space from its estimate and standard error, ω0's as g (m, l and I of the
scene held); a driven fit's inertia a space of its own, m g l carried by g, and where l is the
equivalent simple pendulum's, m and l of a body with the same m g l and room below m l² for
the drawn inertia (:meth:`Body.roomy`).
"""
from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from .fit import Fit

COLUMNS = ('omega0', 'gamma', 'n', 'friction', 'friction_accel', 'phi_offset', 'phi0',
           'dphi0', 'inertia', 'mgl', 'effort_offset', 'command_delay')
"""The parameters of ``models.csv``, each with its standard error and 95 % interval:
``friction`` in N m (where the inertia is known), ``friction_accel`` its deceleration f/I;
``inertia`` (kg m²), ``mgl`` (N m), ``effort_offset`` (N m) and ``command_delay`` (s) of a
driven fit (empty for a free swing)."""
ROOM = 6.0
"""Standard errors of the fitted inertia a campaign's body leaves below it (``Body.roomy``)."""
CORRELATED = 0.5
"""Correlations beyond ± this are noted in campaign_parameters.yaml."""


@dataclass(frozen=True)
class Body:
    """What turns ω0 into node parameters: ω0² = m g l / I (eq 11).

    A free swing fixes only ω0. Where the length is not given it is the equivalent simple
    pendulum's, l = g / ω0² (a point mass, I = m l²); given, m follows from it, which needs
    l <= g / ω0² (the node requires I >= m l², the parallel-axis theorem).
    """

    inertia: float
    length: float | None
    g: float
    inertia_known: bool

    def arm(self, omega0: float) -> float:
        """Return l in m for ``omega0``."""
        return self.g / omega0 ** 2 if self.length is None else self.length

    def mass(self, omega0: float) -> float:
        """Return the mass in kg that gives ``omega0`` (m = I ω0² / (g l))."""
        length = self.arm(omega0)
        m = self.inertia * omega0 ** 2 / (self.g * length)
        while m * length ** 2 > self.inertia:   # the last bit of a point mass
            m = math.nextafter(m, 0.0)
        return m

    def roomy(self, omega0: float, inertia_stderr: float) -> tuple[float, float]:
        """Return (m, l) of a body with the scene's m g l whose m l² leaves room for I's spread.

        The equivalent simple pendulum is a point mass, I = m l² exactly: a campaign that draws
        the inertia below its estimate would draw bodies no rigid pendulum has (I >= m l²).
        The dynamics depend on I and m g l alone, so the campaign holds a body with the same
        m g l whose arm is shorter, l = L max(1 − ROOM σ_I / I, 1/2) with L = g / ω0²: its
        m l² = I l / L lies ROOM standard errors below the estimate (at most half of it).
        """
        full = self.arm(omega0)
        length = full * max(1.0 - ROOM * inertia_stderr / self.inertia, 0.5)
        return self.mass(omega0) * full / length, length

    def gravity(self, omega0: float) -> tuple[float, float]:
        """Return g and dg/dω0 with m, l and I of the scene held (g = ω0² I / (m l)).

        The campaign varies ω0 through g: the gravity torque m g l sin φ is what ω0 measures,
        and g, unlike m, l or I, meets no rigid-body bound (I >= m l²) as it varies.
        """
        m, length = self.mass(omega0), self.arm(omega0)
        scale = self.inertia / (m * length)
        return omega0 ** 2 * scale, 2.0 * omega0 * scale


def usable(fits: Sequence[Fit]) -> Fit | None:
    """Return the best-ranked fit whose ω0, γ and n are all determined."""
    for f in fits:
        if all(f.params.get(k) is not None for k in ('omega0', 'gamma', 'n')):
            return f
    return None


def _num(v: float) -> str:
    text = repr(float(v))
    return text if ('.' in text or 'e' in text or 'inf' in text or 'nan' in text) else text + '.0'


def _law(f: Fit) -> str:
    p = f.params
    n = p['n']
    law = f'{f.model}: omega0 = {p["omega0"]:.4g} rad/s'
    if p['gamma'] is not None:
        law += f', gamma = {p["gamma"]:.4g}'
    if n is not None:
        law += f', n = {n:.3g}'
    acc = p.get('friction_accel')
    if f.model == 'power+coulomb' and acc is not None:
        law += f', friction/I = {acc:.4g} rad/s^2'
    return law


def scene_friction(f: Fit, body: Body) -> float:
    """Return the scene's friction in N m: the fitted f/I times the scene's inertia."""
    acc = f.params.get('friction_accel')
    return float(acc) * body.inertia if f.model == 'power+coulomb' and acc else 0.0


def write_scene(path: Path, f: Fit, body: Body, source: str) -> None:
    """Write ``fit.yaml``: the fitted joint as a scene."""
    p = f.params
    assert p['omega0'] is not None and p['gamma'] is not None and p['n'] is not None
    held = ('# The inertia, m g l, friction and torque offset are fitted with the effort (N m)'
            if f.driven else '# The inertia is the one given' if body.inertia_known else
            '# The inertia is not identified (a free swing fixes only omega0^2 = m g l / I): '
            'the\n# default is kept')
    arm = ("l is the equivalent simple pendulum's, g / omega0^2" if body.length is None else
           'l is the one given')
    inertia_note = f'{held}; {arm}; m follows from omega0.'
    lines = [
        f'# fit: {_law(f)} (BIC {f.bic:.1f}, RMS residual {f.rms_residual:.3g} rad),',
        f'# fitted by pendulum_identify to {source}.',
        inertia_note,
        f'# The sensor zero offset (phi_offset = {p["phi_offset"]:.6g} rad) is not a node '
        'parameter.',
        '/**:',
        '  ros__parameters:',
        f'    m: {_num(body.mass(p["omega0"]))}',
        f'    l: {_num(body.arm(p["omega0"]))}',
        f'    inertia: {_num(body.inertia)}',
        f'    g: {_num(body.g)}',
        f'    gamma: {_num(p["gamma"])}',
        f'    n: {_num(p["n"])}',
        f'    friction: {_num(scene_friction(f, body))}',
        f'    phi0: {_num(p["phi0"] or 0.0)}',
        f'    dphi0: {_num(p["dphi0"] or 0.0)}',
    ]
    if f.driven:   # the drive's bias (N m) and the dead time of its commands (s)
        lines += [f'    effort_offset: {_num(p.get("effort_offset") or 0.0)}',
                  f'    command_delay: {_num(p.get("command_delay") or 0.0)}']
    path.write_text('\n'.join(lines) + '\n')


def write_campaign(path: Path, f: Fit, body: Body) -> None:
    """Write ``campaign_parameters.yaml``: a normal space for each fitted node parameter."""
    p, se = f.params, f.stderr
    assert p['omega0'] is not None and se['omega0'] is not None
    lines = [f'# pendulum_identify: {_law(f)}; each fitted parameter a normal space (estimate, '
             'standard error).',
             '# g carries omega0 (omega0^2 = m g l / I, with m, l and the inertia of fit.yaml '
             'held).']
    strong = [(k, r) for k, r in f.correlation.items() if abs(r) >= CORRELATED]
    if strong:
        lines.append('# Correlated estimates (drawn independently here, so the spread is wider '
                     'than the fit allows):')
        lines += [f'#   {k.replace("/", " and ")}: r = {r:+.2f}' for k, r in strong]
    lines.append('parameters:')
    g, slope = body.gravity(p['omega0'])
    std_g = slope * se['omega0']
    if f.driven and se.get('mgl') is not None and se.get('inertia') is not None:
        # g carries m g l (m and l held): g = m g l / (m l); the inertia is its own.
        m, length = body.mass(p['omega0']), body.arm(p['omega0'])
        std_g = se['mgl'] / (m * length)   # type: ignore[operator]
        if body.length is None:
            m, length = body.roomy(p['omega0'], se['inertia'])   # type: ignore[arg-type]
            lines += [f'  m: {_num(m)}   # m g l as fitted; l with room for the drawn inertia',
                      f'  l: {_num(length)}']
        lines.append(f'  inertia: {{distribution: normal, mean: {_num(body.inertia)}, std: '
                     f'{_num(se["inertia"])}}}')   # type: ignore[arg-type]
    lines.append(f'  g: {{distribution: normal, mean: {_num(g)}, std: {_num(std_g)}}}')
    for k in ('gamma', 'n'):
        v, e = p[k], se[k]
        if v is None or e is None:
            continue
        if k in f.fixed:
            lines.append(f'  {k}: {_num(v)}   # fixed by the {f.model} law')
        else:
            lines.append(f'  {k}: {{distribution: normal, mean: {_num(v)}, std: {_num(e)}}}')
    acc_se = se.get('friction_accel')
    if f.driven and f.model == 'power+coulomb' and se.get('friction') is not None:
        lines.append(f'  friction: {{distribution: normal, mean: {_num(scene_friction(f, body))}'
                     f', std: {_num(se["friction"])}}}')   # type: ignore[arg-type]
    elif f.model == 'power+coulomb' and acc_se is not None:
        lines.append(f'  friction: {{distribution: normal, mean: {_num(scene_friction(f, body))}'
                     f', std: {_num(acc_se * body.inertia)}}}')
    path.write_text('\n'.join(lines) + '\n')


def write_models(path: Path, fits: Sequence[Fit]) -> None:
    """Write ``models.csv``: one row per law, ranked by BIC.

    ``starts`` is how many starts the law's fit ran, ``starts_at_optimum`` how many of them
    ended at its optimum (``starts.REACHED``): one start that alone found the best says the
    law's landscape is rugged there.
    """
    with path.open('w', newline='') as fh:
        w = csv.writer(fh)
        head = ['rank', 'model', 'bic', 'aic', 'rms_residual', 'samples']
        for k in COLUMNS:
            head += [k, f'{k}_stderr', f'{k}_ci95_low', f'{k}_ci95_high']
        w.writerow([*head, 'starts', 'starts_at_optimum', 'not_determined'])
        for rank, f in enumerate(fits, 1):
            row: list[object] = [rank, f.model, f'{f.bic:.6f}', f'{f.aic:.6f}',
                                 f'{f.rms_residual:.6g}', f.samples]
            for k in COLUMNS:
                v, e, c = f.params.get(k), f.stderr.get(k), f.ci95.get(k)
                row += ['' if v is None else repr(v), '' if e is None else repr(e),
                        '' if c is None else repr(c[0]), '' if c is None else repr(c[1])]
            row += [f.starts, f.at_optimum]
            row.append('; '.join(f'{k}: {why}' for k, why in f.reasons.items()))
            w.writerow(row)


def write_figure(path: Path, f: Fit) -> None:
    """Write ``fit.png``: data and fitted angle over time, residuals below, the law on top."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(9, 6),
                                      gridspec_kw={'height_ratios': [3, 1]})
    t = _record_time(f)
    top.plot(t, f.position, '.', ms=2, color='0.4', label='measured')
    fitted_label = 'fitted' if f.window is None else f'fitted (windows of {f.window:.3g} s)'
    for k, (a, b) in enumerate(zip(f.segments, (*f.segments[1:], f.t.size), strict=True)):
        top.plot(t[a:b], f.fitted[a:b], '-', lw=1, color='C0',
                 label=fitted_label if k == 0 else None)
        if k:
            top.axvline(t[a], color='0.7', lw=0.5)
    top.set_ylabel('angle (rad)')
    top.legend(loc='upper right')
    top.set_title(_law(f), fontsize=10)
    bottom.plot(t, f.residual, '.', ms=2, color='C3')
    bottom.axhline(0.0, color='0.5', lw=0.5)
    bottom.set_ylabel('residual (rad)')
    bottom.set_xlabel('t (s)')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _record_time(f: Fit) -> npt.NDArray[np.float64]:
    """Return the times of the figure: the records one after another, each from its end."""
    t = f.t.astype(float).copy()
    for a in f.segments[1:]:
        step = t[a - 1] - t[a - 2] if a >= 2 else 0.0
        t[a:] += t[a - 1] + step - t[a]
    return np.asarray(t)


def _pm(f: Fit, k: str) -> str:
    v, e = f.params.get(k), f.stderr.get(k)
    if v is None:
        return '—'
    if e is None or e == 0.0 or not math.isfinite(e):
        return f'{v:.4g}'
    return f'{v:.4g} ± {e:.2g}'


def summary(fits: Sequence[Fit]) -> str:
    """Return the comparison as a text table (estimate ± standard error; — not determined)."""
    driven = any(f.driven for f in fits)
    extra = ('inertia (kg m^2)', 'offset (N m)') if driven else ()
    head = ('rank', 'model', 'omega0 (rad/s)', 'gamma', 'n', 'friction (N m)', *extra,
            'rms (rad)', 'BIC', 'starts at optimum')
    rows = [head]
    for i, f in enumerate(fits, 1):
        more = (_pm(f, 'inertia'), _pm(f, 'effort_offset')) if driven else ()
        rows.append((str(i), f.model, _pm(f, 'omega0'), _pm(f, 'gamma'), _pm(f, 'n'),
                     _pm(f, 'friction'), *more, f'{f.rms_residual:.3g}', f'{f.bic:.1f}',
                     f'{f.at_optimum} of {f.starts}'))
    width = [max(len(r[j]) for r in rows) for j in range(len(head))]
    lines = ('  '.join(c.ljust(w) for c, w in zip(r, width, strict=True)).rstrip() for r in rows)
    return '\n'.join(lines)
