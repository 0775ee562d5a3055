"""``fit`` and ``compare`` of driven records: the physical joint as a :class:`Fit`.

The estimation itself is ``driven.py`` (the model, the first guess, the windowed fit) over
``windows.py``; here the records a user passes are checked and the solution is reported in
the :class:`~pendulum_sim.identify.fit.Fit` every law's fit returns (BIC and AIC with every
fitted value counted: the shared parameters and two states per window).
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from .checks import MIN_SAMPLES, Progress, as_array, increasing, jit_choice
from .driven import (
    KNOWN_DRIVEN,
    WINDOW_PERIODS,
    DrivenRecord,
    DrivenSolution,
    check_known,
    check_same_joint,
    check_window,
    estimates,
    nested_start,
    prepare_driven,
    solve_sets,
)
from .effort import Effort
from .errors import IdentifyError
from .guess import noise_level
from .laws import COMPARED, get_law
from .result import Fit
from .starts import NESTED

RecordLike = DrivenRecord | Mapping[str, Any]
"""A driven record: :func:`driven_record`'s, or a dict with ``t``, ``position``, ``effort``
(and ``velocity``)."""


def driven_record(t: Any, position: Any, effort: Any, *, velocity: Any = None,
                  source: str = '', joint: str | None = None) -> DrivenRecord:
    """Check a driven record and return it ready to fit (angle unwrapped, times from the first).

    Parameters
    ----------
    t, position : array_like, shape (m,)
        Sample times (s, strictly increasing) and the measured angle (rad).
    effort : array_like, shape (m,), or Effort
        The torque in N m: beside the angle, the torque applied over the sample period that
        ends at each stamp (``JointState.effort`` as ``pendulum_node`` publishes it); or an
        :class:`~pendulum_sim.identify.effort.Effort` (a command stream,
        :func:`~pendulum_sim.identify.effort.from_commands`) on the same clock as ``t``.
    velocity : array_like, shape (m,), optional
        Measured velocity (rad/s): the windows start from it instead of the angle's slope.
    source, joint : str, optional
        Where the record was read and the joint it is of (records of different joints are
        not fitted together).
    """
    tt = as_array('t', t, None)
    if tt.size < MIN_SAMPLES:
        raise IdentifyError(f'a record needs at least {MIN_SAMPLES} samples, got {tt.size}')
    y = as_array('position', position, tt.size)
    v = None if velocity is None else as_array('velocity', velocity, tt.size)
    increasing(tt)
    if not isinstance(effort, Effort):
        effort = _effort_array(effort, tt)
    y = np.unwrap(y)
    span = float(np.ptp(y))
    if span <= max(10.0 * noise_level(y), 1e-9):
        raise IdentifyError(f'the joint does not move: its position spans {span:.3g} rad over '
                            f'the record, within its noise; record a run that moves it')
    return prepare_driven(tt, y, v, effort, source=source, joint=joint)


def _effort_array(effort: Any, t: Any) -> Any:
    try:
        e = np.asarray(effort, dtype=np.float64)
    except (TypeError, ValueError):
        raise IdentifyError(f'effort must be a 1-D array of numbers, got '
                            f'{type(effort).__name__}') from None
    if e.ndim != 1 or e.size != t.size:
        raise IdentifyError(f'effort has shape {e.shape} but t has {t.size} samples')
    return e


def as_records(records: Any) -> list[DrivenRecord]:
    """Return the driven records a list passes (DrivenRecord or dict), or refuse it."""
    if not isinstance(records, (list, tuple)) or not records:
        raise IdentifyError(f'records must be a non-empty list of driven records, got '
                            f'{records!r}'[:200])
    out = []
    for i, r in enumerate(records):
        if isinstance(r, DrivenRecord):
            out.append(r)
        elif isinstance(r, Mapping):
            if 'effort' not in r or r['effort'] is None:
                raise IdentifyError(f'records[{i}] has no effort: records are fitted together '
                                    f'with their effort (a free swing is fitted alone)')
            out.append(driven_record(r.get('t'), r.get('position'), r['effort'],
                                     velocity=r.get('velocity'),
                                     source=str(r.get('source', f'records[{i}]')),
                                     joint=r.get('joint')))
        else:
            raise IdentifyError(f'records[{i}] must be a dict with t, position and effort, or '
                                f'a driven_record(...), got {type(r).__name__}')
    return out


def _unfitted(law_name: str, recs: Sequence[DrivenRecord], why: str, window: float | None
              ) -> Fit:
    names = ('inertia', 'mgl', 'omega0', 'gamma', 'n', 'friction', 'friction_accel',
             'effort_offset', 'command_delay', 'phi_offset', 'phi0', 'dphi0')
    t, y, segments = _joined(recs)
    return Fit(params=dict.fromkeys(names), stderr=dict.fromkeys(names),
               ci95=dict.fromkeys(names), rms_residual=float(np.sqrt(np.mean(y ** 2))),
               aic=math.inf, bic=math.inf, model=law_name, samples=int(y.size), fixed=(),
               reasons=dict.fromkeys(names, why), correlation={}, t=t, position=y,
               fitted=np.full_like(y, np.nan), iterations=0, starts=0, window=window,
               segments=segments, driven=True)


def _joined(recs: Sequence[DrivenRecord]) -> tuple[Any, Any, tuple[int, ...]]:
    t = np.concatenate([r.t + r.t0 for r in recs])
    y = np.concatenate([r.y for r in recs])
    segments = tuple(int(x) for x in np.cumsum([0, *(r.t.size for r in recs[:-1])]))
    return t, y, segments


def _result(sol: DrivenSolution, recs: Sequence[DrivenRecord]) -> Fit:
    p = sol.problem
    assert p.residual is not None
    est = estimates(sol, max(r.effort.peak for r in recs))
    m = p.residual.size
    count = len(p.free) + 2 * sol.windows.count
    rss = float(p.residual @ p.residual)
    loglik = m * math.log(max(rss, 1e-300) / m)
    t, y, segments = _joined(recs)
    # The rows are the windows' samples in order: every record's samples, one after another.
    return Fit(params=est.params, stderr=est.stderr, ci95=est.ci95,
               rms_residual=math.sqrt(rss / m), aic=loglik + 2 * count,
               bic=loglik + count * math.log(m), model=sol.law.name, samples=int(m),
               fixed=est.fixed, reasons=est.reasons, correlation=est.correlation, t=t,
               position=y, fitted=y + p.residual, iterations=p.iterations, starts=sol.starts,
               at_optimum=sol.at_optimum,
               window=sol.window, segments=segments, driven=True)


def joint_fit(model: str, *, inertia: float, mgl: float, gamma: float, n: float,
              friction: float = 0.0, effort_offset: float = 0.0, command_delay: float = 0.0,
              phi_offset: float = 0.0, window: float | None = None) -> Fit:
    """Return a joint given by its parameters as a :class:`Fit`, to validate like a fitted one.

    A joint identified elsewhere (a lab's published parameters, a datasheet's) is validated on
    a record with :func:`~pendulum_sim.identify.validate` as this package's own fits are. Every
    value is held (standard error 0, interval (v, v), all in ``fixed``); the fit has no record
    (``samples`` 0, an infinite BIC). ``window`` is the windows' length the validation's
    residuals and its simulation's first state are fitted over (None: a driven fit's default,
    half the joint's period 2π/ω0). The values are checked as a fit's ``known`` are (in their
    search ranges, ``driven.BOUNDS``), and the message names them so.

    Parameters
    ----------
    model : str
        The law (``viscous``, ``quadratic``, ``coulomb``, ``power``, ``power+coulomb``); ``n``
        must be the law's where it fixes one.
    inertia, mgl, gamma, n, friction, effort_offset, command_delay, phi_offset : float
        The joint in the units of a driven fit (kg m², N m, s^(n−2), -, N m, N m, s, rad).
    """
    law = get_law(model)
    values = check_known({'inertia': inertia, 'mgl': mgl, 'gamma': gamma, 'n': n,
                          'friction': friction, 'effort_offset': effort_offset,
                          'command_delay': command_delay, 'phi_offset': phi_offset},
                         (*KNOWN_DRIVEN, 'gamma'))
    if law.n is not None and n != law.n:
        raise IdentifyError(f'the {model} law has n = {law.n:g}, got n = {n!r}')
    if not law.friction and law.n != 0.0 and friction != 0.0:
        raise IdentifyError(f'the {model} law has no Coulomb friction, got friction = '
                            f'{friction!r}')
    span = check_window(window)
    params: dict[str, float | None] = dict(values)
    omega0 = math.sqrt(values['mgl'] / values['inertia'])
    params['omega0'] = omega0
    if span is None:
        span = WINDOW_PERIODS * 2.0 * math.pi / max(omega0, 1e-3)
    params['friction_accel'] = values['friction'] / values['inertia']
    names = tuple(params)
    empty = np.zeros(0)
    return Fit(params=params, stderr=dict.fromkeys(names, 0.0),
               ci95={k: (v, v) for k, v in params.items() if v is not None},
               rms_residual=math.nan, aic=math.inf, bic=math.inf, model=law.name, samples=0,
               fixed=names, reasons={}, correlation={}, t=empty, position=empty,
               fitted=empty, iterations=0, starts=0, window=span, driven=True)


def fit_sets(sets: Sequence[Sequence[DrivenRecord]], *, model: str = 'power',
             known: Mapping[str, float] | None = None, window: float | None = None,
             jit: bool | None = None, progress: Progress | None = None) -> list[Fit]:
    """Fit ``model`` to each set of driven records (a set's records together), in lockstep."""
    law = get_law(model)
    fixed = check_known(known)
    span = check_window(window)
    for recs in sets:
        check_same_joint(recs)
    sols = solve_sets(law, sets, fixed, span, jit_choice(jit), progress)
    return [_reported(law.name, sol, recs, span) for sol, recs in zip(sols, sets, strict=True)]


def _reported(name: str, sol: DrivenSolution | None, recs: Sequence[DrivenRecord],
              span: float | None) -> Fit:
    if sol is None:
        return _unfitted(name, recs, f'the core cannot simulate any start of the {name} law '
                         f"on the record (its first guesses drive the joint beyond the core's "
                         f'limits)', span)
    return _result(sol, recs)


def fit_driven(records: Sequence[DrivenRecord], *, model: str = 'power',
               known: Mapping[str, float] | None = None, window: float | None = None,
               jit: bool | None = None, progress: Progress | None = None) -> Fit:
    """Fit ``model`` to driven records of one joint, its parameters shared by all."""
    return fit_sets([records], model=model, known=known, window=window, jit=jit,
                    progress=progress)[0]


def compare_driven(records: Sequence[DrivenRecord], *, models: Sequence[str] | None = None,
                   known: Mapping[str, float] | None = None, window: float | None = None,
                   jit: bool | None = None, progress: Callable[[str], None] | None = None
                   ) -> list[Fit]:
    """Fit each model to the driven records of one joint; return the fits ranked by BIC.

    The laws are fitted nested first (``laws.COMPARED``'s order), each one also started from
    the optima of the laws it nests (``starts.NESTED``, ``driven.nested_start``), so that a
    law never ends worse than a law it contains: the ranking compares laws, not the local
    minima one law's first guesses fall in.
    """
    names = list(COMPARED) if models is None else list(models)
    for name in names:
        get_law(name)
    names.sort(key=COMPARED.index)
    fixed = check_known(known)
    span = check_window(window)
    check_same_joint(records)
    use_jit = jit_choice(jit)
    done: dict[str, DrivenSolution | None] = {}
    fits = []
    for name in names:
        if progress is not None:
            progress(name)
        law = get_law(name)
        seeds = [nested_start(sol, law) for k in NESTED[name]
                 if (sol := done.get(k)) is not None]
        done[name] = solve_sets(law, [records], fixed, span, use_jit, seeds=[seeds])[0]
        fits.append(_reported(name, done[name], records, span))
    return sorted(fits, key=lambda f: f.bic)


__all__ = ['as_records', 'compare_driven', 'driven_record', 'fit_driven', 'fit_sets',
           'joint_fit']
