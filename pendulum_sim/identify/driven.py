"""Fit the joint driven by a known effort: inertia, m g l, damping, friction, offset, dead time.

With the torque τ known the model (Quiroga and Ospina-Henao 2017, eq 15-16, with input) is::

    I φ'' = −m g l sin φ − γ I φ'|φ'|^(n−1) − f sgn φ' + τ(t − d) + τ_off

the recorded effort held over each sample interval (``effort.py``), a dead time d and a
constant torque offset τ_off (a drive's or a torque sensor's bias); the sensor reads
φ + phi_offset. The effort fixes the torque scale: I (kg m²), m g l (N m), γ, n, f (N m), τ_off
and d are each determined where the record moves the joint enough, where a free swing fixes
only ω0² = m g l / I and f / I.

Every trajectory is the core's (a :class:`~pendulum_sim.core.sweep.Sweep` driven by the effort
as a per-step schedule), fitted over windows re-anchored on the measurement (``windows.py``).
The first guess is the inverse dynamics in integral form: the velocity from a local cubic
(Savitzky–Golay) and a bounded linear least squares of the torque's impulse over short blocks on
I Δφ', ∫sin φ, the damping term's integral, ∫sgn φ' and Δt, the law's exponent picked from a
few by its residual
(the identification of the open torque-limited pendulum kits, e.g. Wiebe et al.,
"Torque-limited simple pendulum: a toolkit for getting familiar with robot motion control",
2022, which this fit then refines by output error: noise in φ'' no longer biases it).
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.optimize import lsq_linear  # type: ignore[import-untyped]
from scipy.signal import savgol_filter  # type: ignore[import-untyped]
from scipy.stats import t as student_t  # type: ignore[import-untyped]

from .checks import known_values
from .effort import Effort, from_samples
from .errors import IdentifyError
from .guess import noise_level
from .laws import Law
from .result import exponent_undetermined
from .starts import count_reached
from .windows import Problem, Series, Windows, covariance, cut, schedule, simulate, solve

FloatArray = npt.NDArray[np.float64]
Value = float | None

SHARED = ('inertia', 'mgl', 'damping', 'n', 'friction', 'effort_offset', 'command_delay',
          'phi_offset')
"""The joint's parameters a driven fit shares over every window and record, in θ order.

``damping`` is the law's deceleration at the record's RMS speed v_ref, γ v_ref^n (rad/s²):
the law searched as (damping, n) instead of (γ, n), whose estimates trade along a curved
valley (γ's unit s^(n−2) moves with n); γ = damping / v_ref^n is reported."""
KNOWN_DRIVEN = ('inertia', 'mgl', 'n', 'friction', 'effort_offset', 'command_delay',
                'phi_offset')
"""What ``known`` may fix in a driven fit."""
BOUNDS = {'inertia': (1e-6, 1e4), 'mgl': (0.0, 1e5), 'damping': (0.0, 1e5), 'n': (0.0, 6.0),
          'friction': (0.0, 1e4), 'effort_offset': (-1e4, 1e4), 'command_delay': (0.0, 1.0),
          'phi_offset': (-1e3, 1e3), 'gamma': (0.0, math.inf)}
"""Where the search stays (kg m², N m, rad/s², -, N m, N m, s, rad; γ in s^(n−2))."""
LAW_BOUNDS = {'power+coulomb': {'n': (1.0, 6.0)}}
"""Narrower ranges of a law: beside a dry friction, the power law's exponent is at least 1 (a
sub-linear law beside the friction trades with it, and its infinite slope at rest makes the
model stiff where the joint sticks; ``coulomb`` and ``power`` cover the dry end)."""


def bounds_of(law: Law, name: str) -> tuple[float, float]:
    """Return the search range of parameter ``name`` under ``law``."""
    return LAW_BOUNDS.get(law.name, {}).get(name, BOUNDS[name])


EXPONENTS = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0)
"""The exponents the inverse dynamics tries for the first guess of a free n."""
SMOOTHING = 0.15
"""Span of the Savitzky–Golay cubic of the first guess, s (at least 7 samples)."""
BLOCK = 0.2
"""Span of the blocks the first guess integrates the model over, s."""
STEPS_PER_PERIOD = 64
"""Simulation steps per guessed period, at least (RK4; steps divide the sample period)."""
WINDOW_PERIODS = 0.5
"""The default window, in periods 2π/ω0 of :func:`reference_omega0`: short against the
divergence of a loop near the top (e^π ≈ 23 over it at the rate ω0), long against the sample
period."""
MIN_WINDOW_SAMPLES = 10
FRICTION_SHARE = 0.1
"""A law beside a dry friction also starts with the friction at this share of the effort's RMS
torque: a friction started small can end at zero with the power law taking its share (a local
minimum on the bound)."""
START_SHARE = 0.02
"""A damping or friction the first guess puts at zero starts at this share of the effort's
RMS torque (at the RMS speed)."""
EFFORT_MOTION = 10.0
"""The torque scale is reported as not determined where the effort moves the fitted model's
angle (its simulation with the effort against without it, RMS over the samples) by less than
this many times the angle's noise (the residual's RMS, or the records' noise where that is
smaller): a fit that uses an effort which cannot move the joint (a sensor's noise, scaled up
by a tiny inertia) to chase the noise moves it by about the noise. The noise, not the residual
alone: on a measured run the model's own error can leave a residual of centiradians, and the
effort that drives the joint by tenths of a radian is not the less determined for it."""
TORQUE_SCALE = 0.5
"""The torque scale (the inertia, m g l, the friction and the offset in N m) is reported as not
determined where the inertia's 95 % interval is wider than ± this fraction of it. An effort
that does not move the joint (a sensor's noise) still lowers the misfit by chance, as any added
regressor does, with an input gain 1/I one or two standard errors from zero: an interval of
±50 % and more; an effort that drives the joint fixes the inertia within a few per cent."""


@dataclass(frozen=True)
class DrivenRecord:
    """A driven record ready to fit: times from its first sample, unwrapped angle, effort.

    ``effort`` is on the record's clock (0 at its first sample); ``velocity`` the measured one
    where the record has it; ``joint`` the joint's name where the file gives one.
    """

    t0: float
    t: FloatArray
    y: FloatArray
    velocity: FloatArray | None
    effort: Effort
    noise: float
    source: str = ''
    joint: str | None = None


def prepare_driven(t: FloatArray, y: FloatArray, velocity: FloatArray | None,
                   effort: Any, *, source: str = '', joint: str | None = None
                   ) -> DrivenRecord:
    """Return a checked record (``t`` increasing, ``y`` unwrapped) with its effort signal.

    ``effort`` is an array beside the angle (the torque over the period ending at each stamp)
    or an :class:`~pendulum_sim.identify.effort.Effort` on the same clock as ``t``.
    """
    signal = effort if isinstance(effort, Effort) else from_samples(t, effort)
    t0 = float(t[0])
    return DrivenRecord(t0=t0, t=t - t0, y=y, velocity=velocity, effort=signal.shifted(t0),
                        noise=noise_level(y), source=source, joint=joint)


def _odd_span(dt: float, size: int) -> int:
    span = max(7, round(SMOOTHING / dt) | 1)
    return min(span, size - 1 if size % 2 == 0 else size)


@dataclass(frozen=True)
class Smoothed:
    """A record's angle and velocity from a local cubic (Savitzky–Golay), on its samples."""

    phi: FloatArray
    dphi: FloatArray
    dt: float


def smoothed(rec: DrivenRecord) -> Smoothed:
    """Return the Savitzky–Golay angle and velocity of ``rec`` (its median spacing)."""
    dt = float(np.median(np.diff(rec.t)))
    span = _odd_span(dt, rec.t.size)
    if span < 5:
        raise IdentifyError(f'a record needs at least 5 samples, got {rec.t.size}')
    return Smoothed(savgol_filter(rec.y, span, 3), savgol_filter(rec.y, span, 3, deriv=1,
                                                                 delta=dt), dt)


def _cumulative(t: FloatArray, f: FloatArray) -> FloatArray:
    """Return the trapezoidal integral of ``f`` from the first sample to each sample."""
    return np.concatenate(([0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(t))))


def inverse_dynamics(recs: Sequence[DrivenRecord], smooth: Sequence[Smoothed], n: float | None,
                     friction: bool, delay: float, offset: float | None = None
                     ) -> tuple[dict[str, float], float]:
    """Return the bounded least-squares inverse dynamics (I, m g l, γ, f, τ_off) and its RSS.

    The model integrated over blocks of BLOCK seconds (the integral form, which differentiates
    the angle once, not twice): I Δφ' + m g l ∫sin φ + γ I ∫φ'|φ'|^(n−1) + f ∫sgn φ' − τ_off Δt
    = ∫u(t − d) dt, every block of every record a row. ``n`` is the damping exponent (None: no
    power-law damping), ``friction`` whether a Coulomb friction is fitted, ``offset`` the
    torque offset held (None: fitted).
    """
    rows, rhs = [], []
    for rec, sm in zip(recs, smooth, strict=True):
        v = sm.dphi
        cols = [v, _cumulative(rec.t, np.sin(sm.phi))]
        if n is not None:
            cols.append(_cumulative(rec.t, v * np.abs(v) ** (n - 1.0) if n != 1.0 else v))
        if friction:
            cols.append(_cumulative(rec.t, np.sign(v)))
        if offset is None:
            cols.append(-rec.t)
        span = max(2, round(BLOCK / sm.dt))
        a = np.arange(0, rec.t.size - span)
        full = np.column_stack(cols)
        rows.append(full[a + span] - full[a])
        work = rec.effort.integral(rec.t - delay) + (0.0 if offset is None else offset * rec.t)
        rhs.append(work[a + span] - work[a])
    a_mat, b = np.concatenate(rows), np.concatenate(rhs)
    lo = [1e-9, 0.0] + [0.0] * (int(n is not None) + int(friction)) + (
        [-np.inf] if offset is None else [])
    norms = np.linalg.norm(a_mat, axis=0)
    norms = np.where(norms > 0, norms, 1.0)
    sol = lsq_linear(a_mat / norms, b, bounds=(np.array(lo) * norms, np.inf))
    x = sol.x / norms
    rss = float(np.sum((a_mat @ x - b) ** 2))
    out = {'inertia': max(float(x[0]), 1e-6), 'mgl': float(x[1])}
    j = 2
    if n is not None:
        out['gamma'] = float(x[j]) / out['inertia']
        j += 1
    if friction:
        out['friction'] = float(x[j])
        j += 1
    out['effort_offset'] = float(x[j]) if offset is None else offset
    return out, rss


def first_guesses(law: Law, recs: Sequence[DrivenRecord], known: Mapping[str, float]
                  ) -> list[dict[str, float]]:
    """Return the starts of ``law``: the inverse dynamics at its best exponent.

    Two of them: with the torque offset fitted, and held at zero (or at its known value). At
    rest under gravity the offset and m g l are one sum (m g l sin φ − τ_off), which only the
    motion parts, and the noise of a differentiated angle blurs that part; a start that
    puts the whole rest torque on gravity is the other side of that valley. A law beside a
    friction adds a third, the friction large (FRICTION_SHARE). A damping or a
    friction the noise hides (0 at its bound) starts at a small share of the effort instead,
    where its exponent still moves the residual.
    """
    ders = [smoothed(r) for r in recs]
    if law.n is not None:
        ns: list[float | None] = [None if law.n == 0.0 else law.n]
    elif 'n' in known:
        ns = [known['n']]
    else:
        lo_n, hi_n = bounds_of(law, 'n')
        ns = [n for n in EXPONENTS if lo_n <= n <= hi_n]
    fric = law.friction or law.n == 0.0
    # The dead time starts at its known value or at 0: the inverse dynamics' residual, blurred
    # by the noise of the differentiated angle, ranks delays poorly; the fit moves it.
    delays = [known.get('command_delay', 0.0)]
    offsets = [known['effort_offset']] if 'effort_offset' in known else [None, 0.0]
    rms = math.sqrt(float(np.mean(np.concatenate([r.effort.values ** 2 for r in recs]))))
    out: list[dict[str, float]] = []
    for held in offsets:
        tried = []
        for d in delays:
            for n in ns:
                guess, rss = inverse_dynamics(recs, ders, n, fric, d, held)
                guess.update({'n': 0.0 if n is None else n, 'command_delay': d})
                tried.append((rss, guess))
        g = min(tried, key=lambda x: x[0])[1]
        inertia = g['inertia']
        v_ref = reference_speed(recs)
        s = {'inertia': inertia, 'mgl': g['mgl'],
             'damping': g.get('gamma', 0.0) * v_ref ** g['n'], 'n': g['n'],
             'friction': g.get('friction', 0.0), 'effort_offset': g['effort_offset'],
             'command_delay': g['command_delay'], 'phi_offset': 0.0}
        if law.n != 0.0:
            s['damping'] = max(s['damping'], START_SHARE * rms / inertia)
        if fric:
            s['friction'] = max(s['friction'], START_SHARE * rms)
        if not law.friction and law.n != 0.0:
            s['friction'] = 0.0
        if law.n == 0.0:
            s['damping'] = 0.0
        s.update(known)
        if s not in out:
            out.append(s)
    if law.friction and 'friction' not in known:   # the dry share large: the friction's side
        out.append({**out[-1], 'friction': max(out[-1]['friction'], FRICTION_SHARE * rms)})
    return out


def _free(law: Law, known: Mapping[str, float]) -> tuple[str, ...]:
    skip = set(known)
    if law.n is not None:
        skip.add('n')
    if law.n == 0.0:
        skip.add('damping')        # the Coulomb law's level is the friction f (N m)
    elif not law.friction:
        skip.add('friction')
    return tuple(k for k in SHARED if k not in skip)


def inputs_for(law: Law, recs: Sequence[DrivenRecord], win: Windows, v_ref: float | None = None
               ) -> Callable[[dict[str, FloatArray], npt.NDArray[np.int64], int], Any]:
    """Return the map from the shared parameters to the sweep's inputs for ``law``.

    ``v_ref`` is the speed ``damping`` is the law's deceleration at (default: the records'
    RMS speed, :func:`reference_speed`; 1 rad/s makes ``damping`` γ itself).
    """
    if v_ref is None:
        v_ref = reference_speed(recs)

    def inputs(col: dict[str, FloatArray], wins: npt.NDArray[np.int64], steps: int) -> Any:
        inertia = col['inertia']
        om2 = col['mgl'] / inertia
        if law.n == 0.0:   # dry friction alone: the core's n = 0 law, its level f/I
            gam, nn, fr = col['friction'] / inertia, np.zeros_like(om2), np.zeros_like(om2)
        else:
            gam, nn = col['damping'] / v_ref ** col['n'], col['n']
            fr = col['friction'] / inertia if law.friction else np.zeros_like(om2)
        sched = np.empty((steps, om2.size))
        owner = win.record[wins]
        for r, rec in enumerate(recs):
            sel = owner == r
            if sel.any():
                sched[:, sel] = schedule(rec.effort, win.t0[wins[sel]], win.h, steps,
                                         col['command_delay'][sel])
        sched = (sched + col['effort_offset'][None, :]) / inertia[None, :]
        return om2, gam, nn, fr, sched, col['phi_offset']
    return inputs


def reference_speed(recs: Sequence[DrivenRecord]) -> float:
    """Return the RMS speed of the records (the local cubic's slope; at least 0.1 rad/s)."""
    speeds = np.concatenate([smoothed(r).dphi for r in recs])
    return max(math.sqrt(float(np.mean(speeds ** 2))), 0.1)


def reference_omega0(recs: Sequence[DrivenRecord], known: Mapping[str, float]) -> float:
    """Return ω0 = √(m g l / I) of the viscous inverse dynamics of ``recs`` (``known`` held).

    It sets the default window and the simulation step of every law fitted to the records, so
    that the laws a ``compare`` ranks are fitted to the same windows: their residuals, and so
    their BIC, are of the same samples on the same grid.
    """
    guess, _ = inverse_dynamics(recs, [smoothed(r) for r in recs], 1.0, False,
                                known.get('command_delay', 0.0), known.get('effort_offset'))
    guess.update({k: known[k] for k in ('inertia', 'mgl') if k in known})
    return math.sqrt(max(guess['mgl'], 1e-9) / guess['inertia'])


def anchors(rec: DrivenRecord) -> FloatArray:
    """Return the velocity each window starts from: measured, else the local cubic's slope."""
    if rec.velocity is not None:
        return rec.velocity
    return smoothed(rec).dphi


def grid_step(recs: Sequence[DrivenRecord], omega0: float) -> float:
    """Return the simulation step: the median sample period over a whole number of steps,
    at most a STEPS_PER_PERIOD-th of the period 2π/ω0."""
    dt = float(np.median(np.concatenate([np.diff(r.t) for r in recs])))
    most = 2.0 * math.pi / max(omega0, 1e-3) / STEPS_PER_PERIOD
    return dt / max(1, math.ceil(dt / most - 1e-9))


def window_length(window: float | None, recs: Sequence[DrivenRecord], omega0: float,
                  dt: float) -> float | None:
    """Return the window in s: ``window``, or WINDOW_PERIODS of the guessed period."""
    span = max(float(r.t[-1]) for r in recs)
    if window is None:
        window = WINDOW_PERIODS * 2.0 * math.pi / max(omega0, 1e-3)
    window = max(window, MIN_WINDOW_SAMPLES * dt)
    return None if window >= span else window


def check_window(window: object) -> float | None:
    """Return ``window`` (s > 0, or None for the default) or refuse it."""
    if window is None:
        return None
    if isinstance(window, bool) or not isinstance(window, (int, float)) or not (
            math.isfinite(window) and window > 0):
        raise IdentifyError(f'window must be a time in s > 0 (or None for half a period), got '
                            f'{window!r}')
    return float(window)


@dataclass(frozen=True)
class DrivenSolution:
    """The best start of a law on the windows: its problem, windows and covariance."""

    law: Law
    problem: Problem
    windows: Windows
    starts: int
    window: float | None
    v_ref: float
    at_optimum: int = 0   # starts that ended within starts.REACHED of the best on BIC
    effort_motion: float = math.inf   # RMS of the angle the effort moves in the fitted model
    noise: float = math.inf   # the records' angle noise (RMS over the records), rad


RATIO = {'inertia': 4.0, 'mgl': 4.0}
"""The most a step scales the joint's inertia and m g l by (up or down)."""
def _problem(free: tuple[str, ...], start: Mapping[str, float], states: FloatArray,
             win: Windows, recs: Sequence[DrivenRecord], omega0: float, law: Law) -> Problem:
    """Return a start of the windowed fit with ``free`` parameters."""
    dt = float(np.median(np.concatenate([np.diff(r.t) for r in recs])))
    peak = max(r.effort.peak for r in recs)
    amp = max(float(np.max(np.abs(r.y))) for r in recs)
    typical = {'inertia': start['inertia'], 'mgl': max(start['mgl'], 1e-3 * peak, 1e-6),
               'damping': max(start['damping'], 1e-3), 'n': 1.0,
               'friction': max(start['friction'], 1e-3 * peak, 1e-6),
               'effort_offset': max(abs(start['effort_offset']), 1e-3 * peak, 1e-6),
               'command_delay': dt, 'phi_offset': max(amp, 0.1)}
    lo = np.array([bounds_of(law, k)[0] for k in free])
    hi = np.array([bounds_of(law, k)[1] for k in free])
    return Problem(free=free, fixed={k: v for k, v in start.items() if k not in free},
                   theta=np.clip(np.array([start[k] for k in free]), lo, hi),
                   states=states.copy(), scale=np.array([typical[k] for k in free]),
                   state_scale=np.column_stack([np.full(win.count, max(amp, 0.1)),
                                                np.full(win.count, max(amp, 0.1) * omega0)]),
                   bounds=(lo, hi), win=win, inputs=inputs_for(law, recs, win),
                   ratio=np.array([RATIO.get(k, 0.0) for k in free]))


def solve_law(law: Law, recs: Sequence[DrivenRecord], known: Mapping[str, float],
              window: float | None, jit: bool,
              progress: Callable[[int, int], None] | None = None) -> DrivenSolution | None:
    """Fit ``law`` to the records together; return its best start or None."""
    return solve_sets(law, [recs], known, window, jit, progress)[0]


def solve_sets(law: Law, sets: Sequence[Sequence[DrivenRecord]], known: Mapping[str, float],
               window: float | None, jit: bool,
               progress: Callable[[int, int], None] | None = None,
               seeds: Sequence[Sequence[NestedStart]] | None = None
               ) -> list[DrivenSolution | None]:
    """Fit ``law`` to each set of records (the records of a set together), all in lockstep.

    Every start of every set is one problem of one :func:`windows.solve`; the start of a set
    that ends lowest is its fit. ``seeds[i]`` are further starts of set ``i`` beside its
    first guesses (the optima of the laws ``law`` nests, :func:`nested_start`), solved in a
    second round where they are below what the first guesses reached (each starts at its
    nested optimum's cost, on the same windows, and a step is only taken downhill): so that
    ``law`` never ends above a law it nests, at the cost of a second round only where its own
    starts fell short of one.
    """
    free = _free(law, known)
    problems: list[Problem] = []
    owner: list[int] = []
    made: list[tuple[Windows, float, float | None]] = []
    waiting: list[tuple[int, bool, float, Problem]] = []   # set, same windows, cost, start
    for i, recs in enumerate(sets):
        starts = first_guesses(law, recs, known)
        omega0 = reference_omega0(recs, known)
        dt = float(np.median(np.concatenate([np.diff(r.t) for r in recs])))
        span = window_length(window, recs, omega0, dt)
        series = [Series(t=r.t, y=r.y, effort=r.effort, anchor=anchors(r)) for r in recs]
        win = cut(series, span, grid_step(recs, omega0))
        made.append((win, omega0, span))
        measured = np.column_stack([
            np.array([recs[r].y[a] for r, a in zip(win.record, win.start, strict=True)]),
            np.array([series[r].anchor[a]
                      for r, a in zip(win.record, win.start, strict=True)])])
        for s in starts:
            st = measured.copy()
            st[:, 0] -= s['phi_offset']
            problems.append(_problem(free, s, st, win, recs, omega0, law))
            owner.append(i)
        for seed in [] if seeds is None else seeds[i]:
            st = measured.copy()
            st[:, 0] -= seed.values['phi_offset']
            same = _same_windows(seed.windows, win)
            if same:
                st = seed.states
            waiting.append((i, same, seed.cost,
                            _problem(free, seed.values, st, win, recs, omega0, law)))
    solve(problems, jit=jit, progress=progress)
    reached = [min((p.cost for p, o in zip(problems, owner, strict=True) if o == i),
                   default=math.inf) for i in range(len(sets))]
    second = [(i, p) for i, same, cost, p in waiting if not same or cost < reached[i]]
    if second:
        solve([p for _, p in second], jit=jit, progress=progress)
        problems += [p for _, p in second]
        owner += [i for i, _ in second]
    out: list[DrivenSolution | None] = []
    for i in range(len(sets)):
        mine = [p for p, o in zip(problems, owner, strict=True) if o == i]
        best = min(mine, key=lambda p: p.cost, default=None)
        if best is None or best.jac is None:
            out.append(None)
        else:
            ended = [p for p in mine if p.jac is not None and p.residual is not None]
            out.append(DrivenSolution(law=law, problem=best, windows=best.win,
                                      starts=owner.count(i), window=made[i][2],
                                      v_ref=reference_speed(sets[i]),
                                      effort_motion=effort_motion(law, sets[i], best, jit),
                                      noise=math.sqrt(float(np.mean(
                                          [r.noise ** 2 for r in sets[i]]))),
                                      at_optimum=count_reached(
                                          [p.cost for p in ended], [1] * len(ended),
                                          best.win.y.size)))
    return out


@dataclass(frozen=True)
class NestedStart:
    """The optimum of a nested law as a start: its shared parameters, windows and states."""

    values: dict[str, float]
    windows: Windows
    states: FloatArray
    cost: float
    """The nested fit's cost (half its sum of squares) on ``windows``."""


def nested_start(sol: DrivenSolution, law: Law) -> NestedStart:
    """Return the optimum of a law that ``law`` nests (``starts.NESTED``) as a start of ``law``.

    The nested fit's shared parameters and its windows' fitted states (used where ``law``'s
    windows are the same, as they are on the same records: ``reference_omega0``). The
    Coulomb law's level is its friction f: as a start of the power law it is the deceleration
    f/I at n = 0 (``damping`` at n = 0 is γ itself), beside a power law it stays the friction,
    the damping 0. Both laws share the records, so ``damping`` (at their RMS speed) carries
    over as it is; ``n`` is clipped into ``law``'s range by the problem. Where the start is the
    nested optimum itself (``viscous`` in ``power``), ``law``'s fit starts at that residual
    and, its steps accepted only downhill, ends no worse.
    """
    p = sol.problem
    values = p.full(p.theta)
    if sol.law.n == 0.0 and law.n != 0.0:
        if law.friction:
            values['damping'] = 0.0
        else:
            values['damping'] = values['friction'] / values['inertia']
            values['friction'] = 0.0
    return NestedStart(values, sol.windows, p.states.copy(), p.cost)


def _same_windows(a: Windows, b: Windows) -> bool:
    return a.h == b.h and a.steps == b.steps and np.array_equal(a.record, b.record) and (
        np.array_equal(a.start, b.start) and np.array_equal(a.stop, b.stop))


def effort_motion(law: Law, recs: Sequence[DrivenRecord], p: Problem, jit: bool) -> float:
    """Return the RMS of the angle the effort moves in the fitted model (rad).

    The fitted windows simulated again with the effort zero (its offset kept), against the
    fit's own simulation. NaN where the core cannot simulate it.
    """
    zero = [dataclasses.replace(r, effort=Effort(r.effort.knots, np.zeros_like(r.effort.values),
                                                 'zero')) for r in recs]
    still = dataclasses.replace(p, inputs=inputs_for(law, zero, p.win,
                                                     reference_speed(recs)))
    free = simulate([still], [(p.theta[None], p.states[None])], jit=jit)[0]
    if free is None or p.residual is None:
        return math.nan
    return math.sqrt(float(np.mean((p.residual + p.win.y - free[:, 0]) ** 2)))


def _delta(grad: dict[str, float], free: tuple[str, ...], cov: FloatArray) -> float | None:
    """Return the standard error of a function of the parameters by its gradient (delta method).

    Only the parameters the function depends on enter: one the record does not determine (its
    row of ``cov`` NaN, e.g. n where the damping is 0) leaves undetermined only what moves
    with it, not ω0 = √(m g l / I) or f / I.
    """
    use = [i for i, k in enumerate(free) if grad.get(k, 0.0) != 0.0]
    g = np.array([grad[free[i]] for i in use])
    var = float(g @ cov[np.ix_(use, use)] @ g) if use else 0.0
    return math.sqrt(var) if math.isfinite(var) and var >= 0.0 else None


@dataclass(frozen=True)
class Estimates:
    """A driven law's values, standard errors, intervals and what is not determined."""

    params: dict[str, Value]
    stderr: dict[str, Value]
    ci95: dict[str, tuple[float, float] | None]
    reasons: dict[str, str]
    correlation: dict[str, float]
    fixed: tuple[str, ...]


def estimates(sol: DrivenSolution, peak: float) -> Estimates:
    """Return the physical joint of a solved law, each value with its error and interval."""
    p, law = sol.problem, sol.law
    cov = covariance(p)
    values = p.full(p.theta)
    q = float(student_t.ppf(0.975, cov.dof))
    se_free = np.sqrt(np.where(np.diag(cov.shared) > 0, np.diag(cov.shared), np.nan))
    params: dict[str, Value] = {}
    stderr: dict[str, Value] = {}
    ci: dict[str, tuple[float, float] | None] = {}
    reasons: dict[str, str] = {}

    def put(k: str, v: float, e: float | None, bounds: tuple[float, float]) -> None:
        params[k] = v
        if e is None or not math.isfinite(e):
            params[k], stderr[k], ci[k] = None, None, None
            reasons[k] = f'{k} is not determined by the record (the fit is singular in it)'
            return
        stderr[k] = e
        ci[k] = (max(v - q * e, bounds[0]), min(v + q * e, bounds[1]))

    for k in SHARED:
        if k in p.free:
            put(k, values[k], float(se_free[p.free.index(k)]), bounds_of(law, k))
        else:
            params[k], stderr[k], ci[k] = values[k], 0.0, (values[k], values[k])
    inertia, mgl, f = values['inertia'], values['mgl'], values['friction']
    om = math.sqrt(max(mgl, 0.0) / inertia)
    grad_om = {'inertia': -0.5 * om / inertia,
               'mgl': 0.5 / math.sqrt(max(mgl * inertia, 1e-300))}
    put('omega0', om, _delta(grad_om, p.free, cov.shared), (0.0, math.inf))
    if law.n == 0.0:   # the Coulomb law's γ is its deceleration f/I
        put('gamma', f / inertia, _delta({'friction': 1 / inertia,
                                          'inertia': -f / inertia ** 2}, p.free, cov.shared),
            (0.0, math.inf))
        put('friction_accel', f / inertia, stderr['gamma'], (0.0, math.inf))
    else:   # γ = damping / v_ref^n
        v_ref = sol.v_ref
        gamma = values['damping'] / v_ref ** values['n']
        put('gamma', gamma, _delta({'damping': v_ref ** -values['n'],
                                    'n': -gamma * math.log(v_ref)}, p.free, cov.shared),
            bounds_of(law, 'gamma'))
    if law.n == 0.0:
        pass
    elif law.friction:
        put('friction_accel', f / inertia, _delta({'friction': 1 / inertia,
                                                   'inertia': -f / inertia ** 2}, p.free,
                                                  cov.shared), (0.0, math.inf))
    else:
        params['friction_accel'], stderr['friction_accel'] = 0.0, 0.0
        ci['friction_accel'] = (0.0, 0.0)
    first = np.sqrt(np.where(np.diag(cov.first_state) > 0, np.diag(cov.first_state), np.nan))
    for j, k in enumerate(('phi0', 'dphi0')):
        put(k, float(p.states[0, j]), float(first[j]), (-math.inf, math.inf))
    if law.n is None and 'n' in p.free and values['damping'] == 0.0:
        params['n'], stderr['n'], ci['n'] = None, None, None
        reasons['n'] = ('n is not determined: the damping is 0 (at its bound), where the '
                        'exponent does not act; the law predicts without it')
    elif law.n is None and 'n' in p.free and stderr['n'] is not None:
        exponent_undetermined(q * stderr['n'], '; drive the joint over a wider range of speeds, '
                              'or fit a fixed law', params, stderr, ci, reasons)
    se_i = stderr.get('inertia')
    assert p.residual is not None
    rms = math.sqrt(float(p.residual @ p.residual) / p.residual.size)
    if 'inertia' in p.free and (se_i is None or q * se_i > TORQUE_SCALE * inertia
                                or sol.effort_motion < EFFORT_MOTION * min(rms, sol.noise)):
        why = (f'the torque scale is not determined: the effort (up to {peak:.3g} N m) does not '
               f'move the joint measurably beside gravity and damping (in the fitted model it '
               f'moves the angle by less than {EFFORT_MOTION:g} times its noise, or the '
               f"inertia's 95 % interval is wider than ±{TORQUE_SCALE:.0%} of it); check the "
               f'effort and its unit, or drive the joint harder')
        for k in ('inertia', 'mgl', 'friction', 'effort_offset'):
            params[k], stderr[k], ci[k] = None, None, None
            reasons[k] = why
    for d in (params, stderr, ci):
        d.pop('damping', None)
    fixed = tuple('gamma' if k == 'damping' else k for k in SHARED if k not in p.free)
    corr: dict[str, float] = {}
    sd = np.sqrt(np.abs(np.diag(cov.shared)))
    for i in range(len(p.free)):
        for j in range(i + 1, len(p.free)):
            if sd[i] > 0 and sd[j] > 0:
                corr[f'{p.free[i]}/{p.free[j]}'] = float(cov.shared[i, j] / (sd[i] * sd[j]))
    return Estimates(params=params, stderr=stderr, ci95=ci, reasons=reasons,
                     correlation=corr, fixed=fixed)


def check_known(known: Mapping[str, float] | None,
                allowed: Sequence[str] = KNOWN_DRIVEN) -> dict[str, float]:
    """Return ``known`` checked for a driven fit (finite numbers of ``allowed`` in BOUNDS)."""
    def limit(key: str, value: float) -> str | None:
        lo, hi = BOUNDS[key]
        return None if lo <= value <= hi else f'in [{lo:g}, {hi:g}]'
    return known_values(known, allowed, 'with effort, ', limit)


def check_same_joint(recs: Sequence[DrivenRecord]) -> None:
    """Refuse records whose files name different joints."""
    named = [(r.joint, r.source) for r in recs if r.joint is not None]
    for joint, source in named[1:]:
        if joint != named[0][0]:
            raise IdentifyError(f'{source} is of joint {joint!r}, {named[0][1]} of '
                                f'{named[0][0]!r}: records fitted together must be of one '
                                f'joint; fit them apart, or pass --joint')


__all__ = ['BOUNDS', 'KNOWN_DRIVEN', 'SHARED', 'WINDOW_PERIODS', 'DrivenRecord',
           'DrivenSolution', 'Estimates', 'NestedStart', 'Smoothed', 'check_known',
           'check_same_joint', 'check_window', 'estimates', 'first_guesses',
           'inverse_dynamics', 'nested_start', 'prepare_driven', 'reference_omega0',
           'smoothed', 'solve_law']
