"""``twin``: does the test predict the joint? A recorded run beside its twin on the fitted joint.

The controller that ran the real joint runs again, in this process
(:func:`~pendulum_sim.testing.loop.closed_loop`), against the fitted joint (a scene, as
``pendulum_identify`` writes ``fit.yaml``), from the record's first state and for the record's
length. The two runs are then compared as system identification compares a model with data:

- the angle's fit in % over the run, MATLAB ``compare``'s normalised root-mean-square error
  (:func:`pendulum_sim.core.analysis.fit_percent`);
- with a target, the step-response metrics of both runs (``step_info``'s, by
  :func:`~pendulum_sim.testing.metrics.step_metrics`, each run measured from its first angle as
  :meth:`~pendulum_sim.testing.run.ClosedLoopRun.metrics` measures it), their difference
  (recorded − simulated), and whether each recorded metric lies inside the spread of a campaign
  over the fit's uncertainty: the episodes of ``campaign_parameters.yaml``'s parameter spaces,
  run as ``pendulum_campaign`` runs them (:mod:`pendulum_sim.testing.campaign`), each from the
  record's first state; the spread is the central :data:`SPREAD` of their values.

The twin starts from the record's first angle and velocity (the recorded velocity, or the
angle's derivative at the first sample by the second-order one-sided difference of
:func:`numpy.gradient` when the record has none) and runs for
``ceil((t_end − t_0) publish_rate)`` + 1 control periods of the scene, enough to cover the
record. Its clock starts at 0 (``start_time`` 0, as ``closed_loop`` runs), and every run, the
recorded one included, is measured on its time since its first sample: a law that reads ``t``
sees the time since the record began, and a settling time is counted from the start.

The simulated samples are compared at the record's times: taken as they are where the record's
samples are the twin's control periods (their times since the start agree to a thousandth of a
period), else interpolated linearly. Nothing here fits anything: the scene is read as a file.
"""
from __future__ import annotations

import csv
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .errors import CampaignError, TestingError
from .metrics import StepMetrics, step_metrics
from .run import ClosedLoopRun, FloatArray
from .scene import finite_limit, scene_values

__all__ = ['COMPARED', 'EPISODES', 'SPREAD', 'Recorded', 'TwinMetric', 'TwinReport',
           'campaign_beside', 'read_recorded', 'twin']

COMPARED = ('rise_time', 'settling_time', 'overshoot', 'iae', 'max_effort')
"""The step-response metrics compared (names of :class:`~pendulum_sim.testing.StepMetrics`)."""
SPREAD = 0.95
"""The central fraction of the campaign's values a recorded metric must lie in."""
EPISODES = 40
"""Campaign episodes run by default."""
CAMPAIGN_FILE = 'campaign_parameters.yaml'
ALIGNED = 1e-3
"""Record samples within this fraction of a control period of the twin's are the same."""
MIN_SAMPLES = 3
FILES = ('twin.csv', 'twin.yaml', 'twin.png')


@dataclass(frozen=True)
class Recorded:
    """The record as read: times (s), angle (rad), velocity and effort where it holds them."""

    t: FloatArray
    position: FloatArray
    velocity: FloatArray | None
    effort: FloatArray | None
    source: str


@dataclass(frozen=True)
class TwinMetric:
    """One step-response metric of the recorded run beside the twin's, and the spread.

    ``difference`` is recorded − simulated; ``spread_low``, ``spread_high`` bound the central
    :data:`SPREAD` of the campaign's values (NaN without a campaign, or where no episode
    defines the metric); ``inside`` says whether the recorded value lies in it (None when that
    cannot be judged: no spread, or a recorded value that is NaN, e.g. a run that never
    settled); ``episodes`` counts the campaign's episodes that define the metric.
    """

    name: str
    recorded: float
    simulated: float
    difference: float
    spread_low: float
    spread_high: float
    inside: bool | None
    episodes: int


@dataclass(frozen=True)
class TwinReport:
    """The recorded run and its twin side by side: the fit in %, the metrics, the spread.

    ``predicted``, ``predicted_velocity`` and ``predicted_effort`` are the twin's samples at
    the record's first ``compared`` times (all of them unless the simulation stopped early).
    """

    record: Recorded
    scene: str
    controller: str
    target: float | None
    phi0: float
    dphi0: float
    velocity_from: str
    simulated: ClosedLoopRun
    predicted: FloatArray
    predicted_velocity: FloatArray
    predicted_effort: FloatArray
    fit_percent: float
    metrics: tuple[TwinMetric, ...]
    campaign: str | None
    episodes: int
    episodes_failed: int
    seed: int

    @property
    def compared(self) -> int:
        """Return how many of the record's samples the twin covers."""
        return int(self.predicted.size)

    def metric(self, name: str) -> TwinMetric:
        """Return the comparison of metric ``name``."""
        for m in self.metrics:
            if m.name == name:
                return m
        raise KeyError(name)

    def as_dict(self) -> dict[str, Any]:
        """Return the report as plain values (what ``twin.yaml`` holds)."""
        campaign = None if self.campaign is None else {
            'parameters': self.campaign, 'episodes': self.episodes,
            'failed': self.episodes_failed, 'seed': self.seed, 'spread': SPREAD}
        return {
            'record': self.record.source, 'scene': self.scene, 'controller': self.controller,
            'target': self.target, 'samples': int(self.record.t.size),
            'compared': self.compared, 'periods': int(self.simulated.t.size),
            'initial_state': {'position': self.phi0, 'velocity': self.dphi0,
                              'velocity_from': self.velocity_from},
            'simulation_failed': self.simulated.failed,
            'fit_percent': self.fit_percent,
            'campaign': campaign,
            'metrics': {m.name: {'recorded': m.recorded, 'simulated': m.simulated,
                                 'difference': m.difference, 'spread_low': m.spread_low,
                                 'spread_high': m.spread_high, 'inside': m.inside,
                                 'episodes': m.episodes} for m in self.metrics}}

    def text(self) -> str:
        """Return the comparison as a few lines of text (the command line prints it)."""
        lines = [f'angle fit {self.fit_percent:.2f} % over {self.compared} samples '
                 f'({self.record.t[self.compared - 1] - self.record.t[0]:.6g} s)']
        if self.simulated.failed:
            lines.append(f'the twin stopped early: {self.simulated.failed}')
        if self.metrics:
            head = ('metric', 'recorded', 'simulated', 'difference', 'spread', 'inside')
            rows = [head]
            for m in self.metrics:
                spread = ('—' if math.isnan(m.spread_low) else
                          f'{m.spread_low:.4g} .. {m.spread_high:.4g}')
                inside = {True: 'yes', False: 'NO', None: '—'}[m.inside]
                rows.append((m.name, f'{m.recorded:.4g}', f'{m.simulated:.4g}',
                             f'{m.difference:+.3g}', spread, inside))
            width = [max(len(r[j]) for r in rows) for j in range(len(head))]
            lines += ['  '.join(c.ljust(w) for c, w in zip(r, width, strict=True)).rstrip()
                      for r in rows]
            if self.campaign is not None:
                lines.append(f'spread: the central {100 * SPREAD:g} % of {self.episodes} '
                             f'episodes over {self.campaign} ({self.episodes_failed} failed)')
        return '\n'.join(lines)

    def write(self, folder: str | Path) -> list[Path]:
        """Write ``twin.csv``, ``twin.yaml`` and ``twin.png`` into ``folder``; return them."""
        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        paths = [out / name for name in FILES]
        self._write_csv(paths[0])
        import yaml

        paths[1].write_text(yaml.safe_dump(self.as_dict(), sort_keys=False,
                                           allow_unicode=True))
        self._write_figure(paths[2])
        return paths

    def _write_csv(self, path: Path) -> None:
        """Write the two runs side by side, one row per compared sample of the record."""
        rec, k = self.record, self.compared

        def cells(values: FloatArray | None) -> list[str]:
            return [''] * k if values is None else [repr(float(v)) for v in values[:k]]

        columns = {'t': cells(rec.t - rec.t[0]), 'position_recorded': cells(rec.position),
                   'position_simulated': cells(self.predicted),
                   'velocity_recorded': cells(rec.velocity),
                   'velocity_simulated': cells(self.predicted_velocity),
                   'effort_recorded': cells(rec.effort),
                   'effort_simulated': cells(self.predicted_effort)}
        with path.open('w', newline='') as fh:
            w = csv.writer(fh)
            w.writerow(columns)
            w.writerows(zip(*columns.values(), strict=True))

    def _write_figure(self, path: Path) -> None:
        """Draw ``twin.png``: both angles over time, their difference, both efforts."""
        from pendulum_sim.pyplot_agg import pyplot

        plt = pyplot()
        rec, k = self.record, self.compared
        t = rec.t - rec.t[0]
        sim_t = self.simulated.t - self.simulated.t[0]
        fig, (ax_a, ax_d, ax_e) = plt.subplots(3, 1, figsize=(8.0, 7.5), sharex=True,
                                               gridspec_kw={'height_ratios': [3, 1, 2]})
        ax_a.plot(t, rec.position, '.', ms=2.5, color='0.35', label='recorded')
        ax_a.plot(sim_t, self.simulated.position, '-', lw=1.2, color='C0',
                  label='twin (fitted joint)')
        if self.target is not None:
            ax_a.axhline(self.target, color='k', lw=0.8, ls='--',
                         label=f'target {self.target:g} rad')
        ax_a.set_ylabel('angle (rad)')
        ax_a.legend(loc='best', fontsize=8)
        ax_d.plot(t[:k], rec.position[:k] - self.predicted, '-', lw=1.0, color='C3')
        ax_d.axhline(0.0, color='0.5', lw=0.5)
        ax_d.set_ylabel('recorded − twin\n(rad)')
        if rec.effort is not None:
            ax_e.step(t, rec.effort, where='pre', color='0.35', lw=1.0, label='recorded')
        ax_e.step(sim_t, self.simulated.effort, where='pre', color='C4', lw=1.0,
                  label='twin')
        ax_e.set_ylabel('effort (N m)')
        ax_e.set_xlabel('time since the first sample (s)')
        ax_e.legend(loc='best', fontsize=8)
        for ax in (ax_a, ax_d, ax_e):
            ax.grid(True, alpha=0.3)
        title = f'twin of {self.controller}: angle fit {self.fit_percent:.1f} %'
        outside = [m.name for m in self.metrics if m.inside is False]
        if self.campaign is not None and self.metrics:
            title += ('; every metric inside the spread' if not outside else
                      f"; outside the spread: {', '.join(outside)}")
        ax_a.set_title(title, fontsize=10)
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)


def read_recorded(path: str | Path, *, topic: str | None = None, joint: str | None = None,
                  columns: str = 't,position', units: str = 'rad') -> Recorded:
    """Read the record ``path`` as ``pendulum_identify`` reads it, and check it can be twinned.

    A rosbag2 MCAP file or folder (its JointState stream, ``topic`` and ``joint`` choosing) or a
    CSV (``columns``, ``units``), by :func:`pendulum_sim.identify.inputs.read_record`.

    Raises
    ------
    TestingError
        If the record cannot be read, has fewer than 3 samples, times that do not increase or
        an angle that is not finite.
    """
    from pendulum_sim.identify.errors import IdentifyError
    from pendulum_sim.identify.inputs import read_record

    try:
        samples = read_record(path, topic=topic, joint=joint, columns=columns, units=units)
    except IdentifyError as exc:
        raise TestingError(str(exc)) from None
    t, y, source = samples.t, samples.position, samples.source
    if t.size < MIN_SAMPLES:
        raise TestingError(f'{source} has {t.size} sample(s); a twin needs at least '
                           f'{MIN_SAMPLES}')
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise TestingError(f'{source}: the time of sample {bad[0]} is {t[bad[0]]}; times must '
                           'be finite')
    back = np.flatnonzero(np.diff(t) <= 0.0)
    if back.size:
        i = int(back[0]) + 1
        raise TestingError(f'{source}: sample {i} at t = {t[i]!r} s does not follow sample '
                           f'{i - 1} at t = {t[i - 1]!r} s; times must increase')
    bad = np.flatnonzero(~np.isfinite(y))
    if bad.size:
        raise TestingError(f'{source}: the angle of sample {bad[0]} is {y[bad[0]]}; angles '
                           'must be finite')
    effort = samples.effort
    if effort is not None and not np.all(np.isfinite(effort)):
        effort = None   # an effort missing from some messages is not measured
    return Recorded(t, y, samples.velocity, effort, source)


def first_state(rec: Recorded) -> tuple[float, float, str]:
    """Return the record's first angle and velocity, and where the velocity comes from."""
    if rec.velocity is not None and math.isfinite(float(rec.velocity[0])):
        return float(rec.position[0]), float(rec.velocity[0]), 'record'
    slope = np.gradient(rec.position[:MIN_SAMPLES], rec.t[:MIN_SAMPLES], edge_order=2)
    return float(rec.position[0]), float(slope[0]), 'differentiated'


def campaign_beside(scene: str) -> Path | None:
    """Return ``campaign_parameters.yaml`` beside the scene file ``scene``, if there is one."""
    candidate = Path(scene)
    if candidate.suffix not in ('.yaml', '.yml'):
        return None
    beside = candidate.parent / CAMPAIGN_FILE
    return beside if beside.is_file() else None


def controller_name(controller: str | Callable[..., Any]) -> str | None:
    """Return ``module:function`` that imports ``controller`` (None when none does)."""
    from .campaign.spec import load_controller

    if isinstance(controller, str):
        return controller
    module = getattr(controller, '__module__', None)
    qualname = getattr(controller, '__qualname__', None)
    if not isinstance(module, str) or not isinstance(qualname, str) or '<' in qualname:
        return None
    name = f'{module}:{qualname}'
    try:
        return name if load_controller(name) is controller else None
    except TestingError:
        return None


def _load(controller: str | Callable[..., Any]) -> tuple[Callable[..., Any], str]:
    """Return the law and the name it is reported by (``module:function``, or its repr)."""
    from .campaign.spec import load_controller

    if isinstance(controller, str):
        return load_controller(controller), controller
    if not callable(controller):
        raise TestingError(f"controller must be 'module:function' or a callable (t, position, "
                           f'velocity) -> command, got {controller!r}')
    return controller, controller_name(controller) or repr(controller)


def _campaign_parameters(path: Path) -> dict[str, Any]:
    """Return the ``parameters:`` mapping of a campaign parameters file (as identify writes)."""
    from .campaign.spec import load_yaml

    try:
        text = path.read_text(encoding='utf-8')
    except FileNotFoundError:
        raise TestingError(f"campaign parameters file '{path}' does not exist") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise TestingError(f"cannot read campaign parameters file '{path}': {exc}") from None
    data = load_yaml(text, str(path))
    params = data.get('parameters') if isinstance(data, dict) else None
    if not isinstance(params, dict):
        raise TestingError(f"{path} must hold a 'parameters:' mapping of node parameters to "
                           'values or distributions (as pendulum_identify writes it)')
    return params


def _periods(rec: Recorded, rate: float) -> int:
    """Return the control periods that cover the record at ``rate`` (Hz)."""
    steps = (float(rec.t[-1]) - float(rec.t[0])) * rate
    return math.ceil(steps - ALIGNED) + 1


def _at_record_times(rec: Recorded, run: ClosedLoopRun,
                     rate: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Return the twin's angle, velocity and effort at the record's times it covers."""
    t = rec.t - rec.t[0]
    sim_t = run.t - run.t[0]
    k = int(np.searchsorted(t, sim_t[-1] + ALIGNED / rate, side='right'))
    if k <= sim_t.size and np.all(np.abs(t[:k] - sim_t[:k]) <= ALIGNED / rate):
        return run.position[:k].copy(), run.velocity[:k].copy(), run.effort[:k].copy()
    position, velocity, effort = (np.interp(t[:k], sim_t, column)
                                  for column in (run.position, run.velocity, run.effort))
    return position, velocity, effort


def _measure(t: FloatArray, position: FloatArray, effort: FloatArray | None, target: float,
             limit: float) -> StepMetrics:
    """Return the metrics of a run measured from its first angle, as ``run.metrics`` does."""
    return step_metrics(t, position, target, initial=float(position[0]), effort=effort,
                        effort_limit=limit)


def _spread(rows: Sequence[dict[str, Any]], name: str) -> tuple[float, float, int]:
    """Return the central :data:`SPREAD` of the campaign's values of metric ``name``."""
    values = np.array([float(r[name]) for r in rows], dtype=np.float64)
    values = values[np.isfinite(values)]
    if values.size == 0:
        return math.nan, math.nan, 0
    tail = (1.0 - SPREAD) / 2.0
    low, high = np.quantile(values, [tail, 1.0 - tail])
    return float(low), float(high), int(values.size)


def twin(record: str | Path, scene: str | Path, controller: str | Callable[..., Any], *,
         target: float | None = None, campaign: str | Path | None = None,
         episodes: int = EPISODES, seed: int = 0, topic: str | None = None,
         joint: str | None = None, columns: str = 't,position',
         units: str = 'rad') -> TwinReport:
    """Run ``controller`` on the fitted joint from the record's first state; compare the runs.

    Parameters
    ----------
    record : path
        The recorded run: a rosbag2 MCAP file or folder, or a CSV (``columns``, ``units``).
    scene : str or path
        The fitted joint: a scene file (``fit/fit.yaml``) or a scene name.
    controller : str or callable
        ``module:function`` (what ``pendulum_campaign`` imports), or the law itself,
        ``(t, position, velocity) -> command``; given a ``target``, a law with a keyword
        ``target`` gets it.
    target : float, optional
        The reference (rad): the step metrics of both runs, and the campaign, need it.
    campaign : path, optional
        A file whose ``parameters:`` block spans the fit's uncertainty; by default
        ``campaign_parameters.yaml`` beside the scene file when there is one.
    episodes : int
        Campaign episodes (0: no campaign, no spread).
    seed : int
        The campaign's seed (episode ``i`` draws from it as ``pendulum_campaign`` does).
    topic, joint, columns, units
        Which stream of the record to read, as ``pendulum_identify`` takes them.

    Raises
    ------
    TestingError
        If the record, the scene, the controller or the campaign file cannot be used (the
        reason names which), or ``target`` equals the first angle.
    ControllerFailed
        If the controller raises or answers what is not a finite number in the twin's run.
    """
    from pendulum_sim.core.analysis import fit_percent

    from .loop import closed_loop

    scene = str(scene)
    if target is not None and (isinstance(target, bool) or not isinstance(target, (int, float))
                               or not math.isfinite(target)):
        raise TestingError(f'target must be a finite number (rad), got {target!r}')
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 0:
        raise TestingError(f'episodes must be an integer >= 0, got {episodes!r}')
    rec = read_recorded(record, topic=topic, joint=joint, columns=columns, units=units)
    phi0, dphi0, velocity_from = first_state(rec)
    overrides = {'phi0': phi0, 'dphi0': dphi0, 'start_time': 0.0}
    values = scene_values(scene, overrides)
    law, name = _load(controller)
    rate = float(values['publish_rate'])
    periods = _periods(rec, rate)
    spec_text = None
    parameters_file = None
    if target is not None and episodes > 0:
        parameters_file = Path(campaign) if campaign is not None else campaign_beside(scene)
    if parameters_file is not None:
        spec_text = _campaign_text(parameters_file, scene, controller, episodes, seed,
                                   periods, float(target), overrides)   # type: ignore[arg-type]
    run = closed_loop(law, scene=scene, periods=periods, overrides=overrides, target=target)
    if run.t.size < 2:
        raise TestingError(f'the twin stopped after {run.t.size} sample(s): {run.failed}')
    predicted, velocity, effort = _at_record_times(rec, run, rate)
    k = predicted.size
    fit = fit_percent(rec.position[:k], predicted)
    metrics: list[TwinMetric] = []
    failed = 0
    if target is not None:
        limit = finite_limit(values)
        since = rec.t - rec.t[0]
        recorded = _measure(since, rec.position, rec.effort, target, limit).as_dict()
        simulated = _measure(run.t, run.position, run.effort, target, limit).as_dict()
        rows = _run_campaign(spec_text, episodes) if spec_text is not None else []
        failed = sum(1 for r in rows if r['reason'])
        good = [r for r in rows if not r['reason']]
        for m in COMPARED:
            low, high, count = _spread(good, m) if spec_text is not None else (
                math.nan, math.nan, 0)
            value = recorded[m]
            inside = (None if math.isnan(low) or math.isnan(value) else
                      bool(low <= value <= high))
            metrics.append(TwinMetric(m, value, simulated[m], value - simulated[m], low, high,
                                      inside, count))
    return TwinReport(
        record=rec, scene=scene, controller=name, target=None if target is None else
        float(target), phi0=phi0, dphi0=dphi0, velocity_from=velocity_from, simulated=run,
        predicted=predicted, predicted_velocity=velocity, predicted_effort=effort,
        fit_percent=fit, metrics=tuple(metrics),
        campaign=None if spec_text is None else str(parameters_file),
        episodes=episodes if spec_text is not None else 0, episodes_failed=failed, seed=seed)


def _campaign_text(path: Path, scene: str, controller: str | Callable[..., Any],
                   episodes: int, seed: int, periods: int, target: float,
                   overrides: dict[str, float]) -> str:
    """Return the campaign file of the spread: the fit's spaces, from the record's state.

    Checked as ``pendulum_campaign`` checks a file (and episode 0's values against the
    scene), so that a campaign no episode could run fails before the twin runs.
    """
    import yaml

    from .campaign.check import check_values
    from .campaign.spec import parse_spec

    name = controller_name(controller)
    if name is None:
        raise TestingError(f"a campaign needs the controller by name ('module:function'); "
                           f'{controller!r} cannot be imported by one: pass its name, or '
                           'episodes=0')
    where = Path(scene)
    spec = {'controller': name,
            'scene': str(where.resolve()) if where.suffix in ('.yaml', '.yml') else scene,
            'episodes': episodes, 'seed': seed, 'periods': periods, 'target': target,
            'parameters': {**_campaign_parameters(path), **overrides}}
    text = yaml.safe_dump(spec, sort_keys=False)
    try:
        check_values(parse_spec(text, str(path)))
    except CampaignError as exc:
        raise TestingError(f'{path}: {exc}') from None
    return text


def _run_campaign(text: str, episodes: int) -> list[dict[str, Any]]:
    """Run the campaign's episodes in this process (a vectorised law in batches)."""
    from .campaign.episode import run_chunk

    return run_chunk(text, list(range(episodes)), None)
