"""Fit a damping law to a record of a free swing: ``fit``, ``compare`` and the ``Fit`` they return.

Output-error least squares (``solver.py``): the core simulates each candidate, the residual is
the measured angle minus the simulated one. Several starts from a physically reasoned first
guess (``guess.py``) run in one batch; the best is kept. The covariance is the Gauss–Newton
one, s² (JᵀJ)⁻¹ with s² the residual variance, and the 95 % intervals are Student-t intervals
with m − p degrees of freedom. ``aic`` and ``bic`` are those of Gaussian errors of unknown
variance: m ln(RSS/m) + 2p and m ln(RSS/m) + p ln m.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.stats import t as student_t  # type: ignore[import-untyped]

from .checks import MIN_SAMPLES, Progress, as_array, increasing, jit_choice, known_values
from .errors import IdentifyError
from .guess import Guess, best_exponent, envelope_gamma, first_look
from .laws import COMPARED, MODELS, Law, get_law
from .record import Record
from .result import Fit, Value, exponent_undetermined
from .solver import BOUNDS, Problem, simulate_columns, solve
from .starts import EXPONENTS, FRICTION_EXPONENTS, NESTED, reached, search, seed

FloatArray = npt.NDArray[np.float64]

STEPS_PER_PERIOD = 64
"""Simulation steps per guessed period, at least (RK4; the output is interpolated to the
samples)."""
KNOWN = ('omega0', 'gamma', 'n', 'phi_offset', 'inertia')
"""What ``known`` may fix."""


def prepare(t: Any, position: Any, velocity: Any = None, effort: Any = None) -> Record:
    """Check a record and return it ready to fit (angle unwrapped, times from the first)."""
    tt = as_array('t', t, None)
    if tt.size < MIN_SAMPLES:
        raise IdentifyError(f'a record needs at least {MIN_SAMPLES} samples, got {tt.size}')
    y = as_array('position', position, tt.size)
    if velocity is not None:
        as_array('velocity', velocity, tt.size)
    if effort is not None:
        e = as_array('effort', effort, tt.size)
        if np.any(e != 0.0):
            raise IdentifyError(
                f'effort is not zero (up to {np.abs(e).max():.3g} N m): a driven record is '
                'fitted with its effort (fit(..., effort=...), prepare_driven); prepare '
                'takes a free swing')
    increasing(tt)
    y = np.unwrap(y)   # an encoder's wrap at ±π: a jump of more than π between samples
    guess = first_look(tt - tt[0], y)
    span = float(np.ptp(y))
    if span <= max(10.0 * guess.noise, 1e-9):
        raise IdentifyError(f'the joint is at rest: its position spans {span:.3g} rad over the '
                            f'record, within its noise; record a free swing from a release '
                            f'angle')
    return Record(t0=float(tt[0]), t=tt - tt[0], y=y, guess=guess)


def _check_known(known: Mapping[str, float] | None) -> dict[str, float]:
    def limit(key: str, value: float) -> str | None:
        if key in ('omega0', 'inertia') and value <= 0:
            return '> 0'
        if key in ('gamma', 'n') and value < 0:
            return '>= 0'
        return None
    return known_values(known, KNOWN, '', limit)


def _starts(law: Law, rec: Record, known: dict[str, float]) -> list[Mapping[str, float]]:
    """Return the starting points of ``law`` for ``rec``: the guess and its variants."""
    g = rec.guess
    om = known.get('omega0', g.omega0)
    assert om is not None
    base = {'omega0': om, 'phi_offset': known.get('phi_offset', g.offset), 'phi0': g.phi0,
            'dphi0': g.dphi0, 'friction_accel': 0.0}
    if law.n is not None:
        ns = [known.get('n', law.n)]
    elif 'n' in known:
        ns = [known['n']]
    else:
        ns = list(dict.fromkeys([best_exponent(om, g.peaks_t, g.peaks_a),
                                 *(FRICTION_EXPONENTS if law.friction else EXPONENTS)]))
    out: list[Mapping[str, float]] = []
    for n in ns:
        gam = envelope_gamma(n, om, g.peaks_t, g.peaks_a)[0]
        gam = known.get('gamma', max(gam, 1e-4))
        if law.friction:
            out += friction_starts(base, n, gam, om, g, 'gamma' in known)
            continue
        scales = (1.0,) if 'gamma' in known else ((1.0, 0.5, 2.0) if len(ns) == 1 else (1.0,))
        for s in scales:
            out.append({**base, 'n': n, 'gamma': gam * s})
    return out


def friction_starts(base: dict[str, float], n: float, gam: float, om: float, g: Guess,
                    gamma_known: bool) -> list[dict[str, float]]:
    """Return the starts of a power law beside a Coulomb friction, for exponent ``n``.

    The envelope read under the power law alone (γ) and under Coulomb friction alone (its
    linear decay, the friction deceleration c: ``guess.envelope_gamma`` at n = 0) bound the
    two shares; the starts split the decay between them: half each, mostly the law, mostly
    the friction, and the law alone (the nested ``power`` law, so that the fit ends no worse
    than it where the record asks for no friction).
    """
    c = max(envelope_gamma(0.0, om, g.peaks_t, g.peaks_a)[0], 1e-4)
    shares = ((0.5, 0.5), (0.9, 0.1), (0.1, 0.9), (1.0, 0.0))
    return [{**base, 'n': n, 'gamma': gam if gamma_known else gam * a,
             'friction_accel': c * b} for a, b in shares]


def _problem(law: Law, rec: Record, start: Mapping[str, float], known: dict[str, float]
             ) -> Problem:
    om = start['omega0']
    # A power of two at or below a 64th of the period, and the end rounded up to 64 steps:
    # records alike share one grid (one sweep), and a record's grid depends only on itself.
    h = 2.0 ** math.floor(math.log2(min(2.0 * math.pi / om / STEPS_PER_PERIOD,
                                        float(rec.t[-1]) / 4.0)))
    t_end = math.ceil(float(rec.t[-1]) / (STEPS_PER_PERIOD * h)) * STEPS_PER_PERIOD * h
    free = tuple(k for k in ('omega0', 'gamma', 'n', 'phi_offset', 'phi0', 'dphi0',
                             'friction_accel')
                 if k not in known and not (k == 'n' and law.n is not None)
                 and not (k == 'friction_accel' and not law.friction))
    fixed = {k: v for k, v in start.items() if k not in free}
    amp = float(np.max(np.abs(rec.y - start['phi_offset'])))
    # The record's own typical speed (one value for all its starts): θ holds the damping
    # there where n is free (``Problem.encode``).
    speed = float(np.max(np.abs(rec.y - rec.guess.offset))) * (rec.guess.omega0 or om)
    problem = Problem(t=rec.t, y=rec.y, h=h, t_end=t_end, free=free, fixed=fixed,
                      theta=np.zeros(len(free)), scale=np.ones(len(free)), speed=speed)
    problem.theta = problem.encode(start)
    slot = dict(zip(free, problem.theta, strict=True))
    typical = {'omega0': om, 'gamma': max(slot.get('gamma', start['gamma']), 1e-3), 'n': 1.0,
               'phi_offset': amp, 'phi0': amp, 'dphi0': amp * om,
               'friction_accel': max(start['friction_accel'], 1e-3)}
    problem.scale = np.array([typical[k] for k in free])
    return problem


def model_angle(rec: Record, model: str, params: Mapping[str, float], *,
                jit: bool | None = None) -> FloatArray:
    """Return the angle ``model`` gives at the record's samples with ``params``, as fitted.

    ``params`` holds ``omega0``, ``gamma``, ``n``, ``phi_offset``, ``phi0``, ``dphi0`` and
    ``friction_accel`` (as a ``Fit``'s); the simulation is the fit's own (its grid, the core's
    sweep, the cubic Hermite output): a fit's ``rms_residual`` is that of the data minus this
    at its parameters. NaN everywhere where the core cannot simulate them.
    """
    law = get_law(model)
    problem = _problem(law, rec, params, {})
    out = simulate_columns([problem], [problem.theta[None, :]], jit=jit_choice(jit))[0]
    return np.full_like(rec.y, np.nan) if out is None else np.asarray(out[0])


def _unfitted(law: Law, rec: Record, known: dict[str, float], why: str) -> Fit:
    names = ('omega0', 'gamma', 'n', 'friction', 'friction_accel', 'phi_offset', 'phi0',
             'dphi0')
    params: dict[str, Value] = dict.fromkeys(names)
    params['phi_offset'] = rec.guess.offset
    reasons = {k: why for k in names if k != 'phi_offset'}
    if 'inertia' in known:
        params['inertia'] = known['inertia']
    fitted = np.full_like(rec.y, rec.guess.offset)
    return Fit(params=params, stderr=dict.fromkeys(params), ci95=dict.fromkeys(params),
               rms_residual=float(np.sqrt(np.mean((rec.y - fitted) ** 2))), aic=math.inf,
               bic=math.inf, model=law.name, samples=int(rec.y.size), fixed=(),
               reasons=reasons, correlation={}, t=rec.t + rec.t0, position=rec.y,
               fitted=fitted, iterations=0, starts=0)


def _result(law: Law, rec: Record, best: Problem, starts: int, known: dict[str, float],
            at_optimum: int) -> Fit:
    assert best.jac is not None and best.residual is not None
    m, p = rec.y.size, len(best.free)
    rss = 2.0 * best.cost
    values = best.full(best.theta)
    s2 = rss / max(m - p, 1)
    reasons: dict[str, str] = {}
    try:
        jac = best.physical_jacobian()
        cov = s2 * np.linalg.inv(jac.T @ jac)
        var = np.diag(cov)
        # A variance <= 0 (round-off of a near-singular J^T J) is no standard error: the
        # parameter is reported as not determined, never with an interval of zero width.
        se = np.sqrt(np.where(var > 0.0, var, np.nan))
    except np.linalg.LinAlgError:
        cov = np.full((p, p), np.nan)
        se = np.full(p, np.nan)
    q = float(student_t.ppf(0.975, max(m - p, 1)))
    params: dict[str, Value] = {k: values[k] for k in ('omega0', 'gamma', 'n', 'phi_offset',
                                                       'phi0', 'dphi0', 'friction_accel')}
    stderr: dict[str, Value] = {}
    ci: dict[str, tuple[float, float] | None] = {}
    for k, v in list(params.items()):
        if k in best.free:
            e = float(se[best.free.index(k)])
            if not math.isfinite(e):
                params[k], stderr[k], ci[k] = None, None, None
                reasons[k] = f'{k} is not determined by the record (the fit is singular in it)'
                continue
            # The interval within the parameter's physical range (a friction, γ, n >= 0).
            lo_b, hi_b = BOUNDS[k]
            stderr[k], ci[k] = e, (max(float(v) - q * e, lo_b),   # type: ignore[arg-type]
                                   min(float(v) + q * e, hi_b))   # type: ignore[arg-type]
        else:
            stderr[k], ci[k] = 0.0, (float(v), float(v))   # type: ignore[arg-type]
    if law.n is None and 'n' in best.free and stderr['n'] is not None:
        swing = rec.guess.peaks_a
        decay = (1.0 - swing[-1] / swing[0]) * 100.0 if swing.size >= 2 else 0.0
        exponent_undetermined(q * stderr['n'], f' (the amplitude falls by only {decay:.1f} % '
                              f'over the record); record a longer or more damped swing, or fit '
                              f'a fixed law', params, stderr, ci, reasons)
    _friction(law, known, params, stderr, ci, reasons)
    fixed = tuple(k for k in ('omega0', 'gamma', 'n', 'phi_offset') if k not in best.free)
    if law.name != 'coulomb' and not law.friction:
        fixed = (*fixed, 'friction', 'friction_accel')
    if 'inertia' in known:
        params['inertia'], stderr['inertia'] = known['inertia'], 0.0
        ci['inertia'] = (known['inertia'], known['inertia'])
        fixed = (*fixed, 'inertia')
    corr: dict[str, float] = {}
    d = se
    for i in range(p):
        for j in range(i + 1, p):
            if d[i] > 0 and d[j] > 0:
                corr[f'{best.free[i]}/{best.free[j]}'] = float(cov[i, j] / (d[i] * d[j]))
    fitted = rec.y + best.residual
    loglik = m * math.log(max(rss, 1e-300) / m)
    return Fit(params=params, stderr=stderr, ci95=ci,
               rms_residual=float(math.sqrt(rss / m)), aic=loglik + 2 * p,
               bic=loglik + p * math.log(m), model=law.name, samples=int(m), fixed=fixed,
               reasons=reasons, correlation=corr, t=rec.t + rec.t0, position=rec.y,
               fitted=fitted, iterations=best.iterations, starts=starts,
               at_optimum=at_optimum)


def _friction(law: Law, known: dict[str, float], params: dict[str, Value],
              stderr: dict[str, Value], ci: dict[str, tuple[float, float] | None],
              reasons: dict[str, str]) -> None:
    """Set ``friction`` (N m) from the fitted deceleration: ``friction_accel`` times I.

    The Coulomb law's deceleration is its γ (n = 0); ``power+coulomb`` fits the core's friction
    f beside the law as f/I. A torque needs the inertia (``known``); without it, None.
    """
    if law.name == 'coulomb':
        params['friction_accel'] = params['gamma']
        stderr['friction_accel'], ci['friction_accel'] = stderr['gamma'], ci['gamma']
    elif not law.friction:
        for k in ('friction', 'friction_accel'):
            params[k], stderr[k], ci[k] = 0.0, 0.0, (0.0, 0.0)
        return
    acc, acc_se, acc_ci = params['friction_accel'], stderr['friction_accel'], ci['friction_accel']
    if 'inertia' in known and acc is not None:
        inertia = known['inertia']
        params['friction'] = acc * inertia
        stderr['friction'] = None if acc_se is None else acc_se * inertia
        ci['friction'] = None if acc_ci is None else (acc_ci[0] * inertia, acc_ci[1] * inertia)
    else:
        params['friction'], stderr['friction'], ci['friction'] = None, None, None
        what = 'gamma is' if law.name == 'coulomb' else 'friction_accel is'
        reasons['friction'] = (f'friction = {what.split()[0]} * inertia (N m) needs the '
                               f"inertia: pass known={{'inertia': ...}}; {what} the friction "
                               'deceleration in rad/s^2')


REST_BAND = 4.0
"""A record has come to rest where its angle stays within this many noise levels of its end."""
REST_MIN = 0.05
"""The least fraction of a record its final rest must span to be fitted in two stages."""


def moving_part(rec: Record) -> Record | None:
    """Return ``rec`` up to where it comes to rest for good (a Coulomb stick), or None.

    Its last samples within REST_BAND noise levels of its final angle (the median of its last
    fiftieth) are the rest; where they span at least REST_MIN of the record and what comes
    before still oscillates, the record up to the rest's first sample is returned. A law with a
    Coulomb part is fitted to it first: the stick makes the cost of the whole record a rugged
    function of the parameters near it (the model sticks a few mrad away and the fit stalls
    there), while the moving part's is smooth; the whole record is then fitted from that result
    as well as from the guess (:func:`fit_records`).
    """
    y = rec.y
    band = REST_BAND * rec.guess.noise
    final = float(np.median(y[-max(5, y.size // 50):]))
    away = np.flatnonzero(np.abs(y - final) > band)
    if band <= 0.0 or away.size == 0:
        return None
    k = int(away[-1]) + 2   # up to and with the first sample at rest
    if y.size - k < REST_MIN * y.size or k < MIN_SAMPLES:
        return None
    part = Record(t0=rec.t0, t=rec.t[:k], y=y[:k], guess=first_look(rec.t[:k], y[:k]))
    return part if part.guess.omega0 is not None else None




def fit_records(records: Sequence[Record], *, model: str = 'power',
                known: Mapping[str, float] | None = None, jit: bool | None = None,
                progress: Progress | None = None,
                seeds: Sequence[Sequence[Mapping[str, float]]] | None = None) -> list[Fit]:
    """Fit ``model`` to each prepared record, all starts of all records in one lockstep.

    Each start is fitted over growing windows of its record (``starts.search``); ``seeds[i]``
    are more starts of ``records[i]`` (``compare`` passes the fits of the laws ``model``
    nests).
    """
    law = get_law(model)
    fixed = _check_known(known)
    use_jit = jit_choice(jit)
    out: list[Fit | None] = [None] * len(records)
    starts: list[list[Mapping[str, float]]] = [[] for _ in records]
    for i, rec in enumerate(records):
        g = rec.guess
        if g.omega0 is None and 'omega0' not in fixed:
            why = ('no oscillation: the angle never crosses its centre' if not g.oscillates
                   else f'the record is shorter than one period ({g.crossings} zero '
                        f'crossing{"s" if g.crossings != 1 else ""}, a period needs 3)')
            out[i] = _unfitted(law, rec, fixed, why)
            continue
        starts[i] = _starts(law, rec, fixed)
    for i, start in _moving_starts(law, records, out, fixed, use_jit):
        starts[i].append(start)
    runs = search(records, starts, lambda rec, start: _problem(law, rec, start, fixed),
                  jit=use_jit, progress=progress,
                  seeds=[[] if out[i] is not None else list(seeds[i])
                         for i in range(len(records))] if seeds is not None else None)
    for i, rec in enumerate(records):
        if out[i] is not None:
            continue
        best = min((r.problem for r in runs[i]), key=lambda p: p.cost)
        if best.jac is None:
            out[i] = _unfitted(law, rec, fixed, 'the core cannot simulate the first guess')
        else:
            out[i] = _result(law, rec, best, sum(r.starts for r in runs[i]), fixed,
                             reached(runs[i]))
    return [f for f in out if f is not None]


def _moving_starts(law: Law, records: Sequence[Record], out: list[Fit | None],
                   fixed: dict[str, float], use_jit: bool) -> list[tuple[int, dict[str, float]]]:
    """Return (record, start) pairs from fits of the moving parts of records that stick.

    For a law with a Coulomb part (``coulomb``, ``power+coulomb``), each record that comes to
    rest for good (:func:`moving_part`) is fitted up to its rest first; the best parameters
    are one more start of the whole record's fit.
    """
    if not (law.friction or law.n == 0.0):
        return []
    parts = {i: moving_part(rec) for i, rec in enumerate(records) if out[i] is None}
    stage: list[Problem] = []
    owner: list[int] = []
    for i, part in parts.items():
        if part is not None:
            for start in _starts(law, part, fixed):
                stage.append(_problem(law, part, start, fixed))
                owner.append(i)
    if not stage:
        return []
    solve(stage, jit=use_jit)
    starts = []
    for i in dict.fromkeys(owner):
        best = min((p for p, o in zip(stage, owner, strict=True) if o == i),
                   key=lambda p: p.cost)
        if best.jac is not None:
            starts.append((i, best.full(best.theta)))
    return starts


def _driven(t: Any, position: Any, velocity: Any, effort: Any) -> list[Any] | None:
    """Return the driven records the arguments pass, or None for a free swing.

    A list of records in ``t`` (``position`` None) is fitted together; one record is driven
    where its effort is not all zero (a NaN in it is the effort's to report).
    """
    from .driven_fit import as_records, driven_record
    from .effort import Effort

    if position is None and isinstance(t, (list, tuple)):
        return as_records(t)
    if effort is None:
        return None
    if not isinstance(effort, Effort):
        try:
            e = np.asarray(effort, dtype=np.float64)
        except (TypeError, ValueError):
            raise IdentifyError(f'effort must be a 1-D array of numbers, got '
                                f'{type(effort).__name__}') from None
        if not np.any(e != 0.0):   # all zero: a free swing, today's fit
            return None
    return [driven_record(t, position, effort, velocity=velocity)]


def fit(t: Any, position: Any = None, *, velocity: Any = None, effort: Any = None,
        model: str = 'power', known: Mapping[str, float] | None = None,
        window: float | None = None, jit: bool | None = None,
        progress: Progress | None = None) -> Fit:
    """Fit a damping law to a record of a free swing, or the joint to driven records.

    Parameters
    ----------
    t : array_like, shape (m,), or list of records
        Sample times in s, strictly increasing (irregular spacing is fine). Or a list of
        driven records of one joint fitted together, sharing its parameters: each a dict
        ``{'t': ..., 'position': ..., 'effort': ..., 'velocity': ...}`` or a
        :func:`~pendulum_sim.identify.driven_record` (``position`` then None).
    position : array_like, shape (m,)
        Measured angle in rad (an encoder's wrap at ±π is undone; a zero offset is fitted).
    velocity : array_like, shape (m,), optional
        Measured velocity (a driven fit's windows start from it; checked otherwise).
    effort : array_like, shape (m,), or Effort, optional
        The torque in N m over the sample period that ends at each stamp (as
        ``JointState.effort`` of ``pendulum_node``), or a command stream
        (:func:`~pendulum_sim.identify.effort.from_commands`). Not all zero: the joint is
        fitted driven (``driven.py``), with ``inertia``, ``mgl``, ``friction`` in N m,
        ``effort_offset`` and ``command_delay``; all zero or None: a free swing, as before.
    model : str
        ``'viscous'``, ``'quadratic'``, ``'coulomb'``, ``'power'`` or ``'power+coulomb'``
        (the power law beside the core's Coulomb ``friction``).
    known : dict, optional
        Values to hold fixed: for a free swing ``omega0``, ``gamma``, ``n``, ``phi_offset``,
        and ``inertia`` (kg m², which turns the Coulomb deceleration into a friction torque);
        for a driven fit any of ``inertia``, ``mgl``, ``n``, ``friction``,
        ``effort_offset``, ``command_delay``, ``phi_offset`` (``driven.KNOWN_DRIVEN``).
    window : float, optional
        A driven fit's window in s (``windows.py``; default half a period of the records'
        viscous inverse dynamics, ``driven.reference_omega0``, the same for every law; a
        window as long as the record is one simulation of it).
    jit : bool or None
        Simulate with the core's compiled sweep (None: where numba is installed).
    progress : callable, optional
        Called as ``progress(iteration, starts_done)`` after each iteration.

    Returns
    -------
    Fit
    """
    driven = _driven(t, position, velocity, effort)
    if driven is not None:
        from .driven_fit import fit_driven

        return fit_driven(driven, model=model, known=known, window=window, jit=jit,
                          progress=progress)
    _no_window(window)
    rec = prepare(t, position, velocity, effort)
    return fit_records([rec], model=model, known=known, jit=jit, progress=progress)[0]


def _no_window(window: object) -> None:
    if window is not None:
        raise IdentifyError(f'window (got {window!r}) is the window of a fit with effort; a '
                            f'free swing is fitted by one simulation of the whole record')


def compare_records(records: Sequence[Record], *, models: Sequence[str] | None = None,
                    known: Mapping[str, float] | None = None, jit: bool | None = None,
                    progress: Callable[[str], None] | None = None) -> list[list[Fit]]:
    """Fit each model to each prepared record; return each record's fits ranked by BIC.

    The laws are fitted nested first (``laws.COMPARED``'s order), each one also started from
    the fits of the laws it nests (``starts.NESTED``).
    """
    names = list(COMPARED) if models is None else list(models)
    for name in names:
        get_law(name)
    names.sort(key=COMPARED.index)
    done: dict[str, list[Fit]] = {}
    for name in names:
        if progress is not None:
            progress(name)
        seeds = [[s for k in NESTED[name] if k in done
                  for s in (seed(done[k][i].params),) if s is not None]
                 for i in range(len(records))]
        done[name] = fit_records(records, model=name, known=known, jit=jit, seeds=seeds)
    return [sorted((done[name][i] for name in names), key=lambda f: f.bic)
            for i in range(len(records))]


def compare(t: Any, position: Any = None, *, velocity: Any = None, effort: Any = None,
            models: Sequence[str] | None = None, known: Mapping[str, float] | None = None,
            window: float | None = None, jit: bool | None = None,
            progress: Callable[[str], None] | None = None) -> list[Fit]:
    """Fit each model (default: all five, ``laws.COMPARED``) and rank them by BIC.

    ``models`` names the laws to fit instead, of viscous, quadratic, coulomb, power and
    power+coulomb. The arguments are those of :func:`fit`: with effort (or a list of driven
    records) each law is fitted to the driven joint.
    """
    driven = _driven(t, position, velocity, effort)
    if driven is not None:
        from .driven_fit import compare_driven

        return compare_driven(driven, models=models, known=known, window=window, jit=jit,
                              progress=progress)
    _no_window(window)
    rec = prepare(t, position, velocity, effort)
    return compare_records([rec], models=models, known=known, jit=jit, progress=progress)[0]


__all__ = ['MODELS', 'Fit', 'Record', 'compare', 'compare_records', 'fit', 'fit_records',
           'model_angle', 'prepare']
