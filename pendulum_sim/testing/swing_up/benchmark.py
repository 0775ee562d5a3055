"""``benchmark``: the swing-up task's criteria as campaigns on Dask, and what they add up to.

Each criterion (:mod:`.criteria`) is a campaign of ``task: swing_up`` in
``OUT/campaigns/<criterion>/`` (its ``campaign.yaml``, episode store, ``episodes.csv`` and
``summary.md``); the criteria run together on one Dask cluster (a local one by default, or
``scheduler``), a vectorised law's episodes in batches, and ``resume`` continues an
interrupted benchmark. Then ``OUT/benchmark.yaml`` holds the results with each criterion's
parameters, ``benchmark.png`` sets them beside the shipped reference controllers',
``roa.png`` maps the region of attraction and ``swing_up.gif`` animates the nominal run.

The results (:data:`~.criteria.KEYS`): ``swing_up_time`` (s), ``energy`` (J) and
``smoothness`` (N m), the mean over the nominal runs; ``consistency``, ``robustness`` and
``sensitivity``, the % of their episodes that swing up (enter the goal box and stay);
``min_torque_limit`` (N m); ``frequency``, the controller's calls per second (an in-process
law called on the nominal run's states one at a time, timed alone after the campaigns; a
command line's answers per wall-clock second of its nominal closed loop, DDS and node
included); ``roa_area`` (rad²/s).
A result whose criterion did not run is null.
"""
from __future__ import annotations

import math
import shlex
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import yaml

from ..errors import BenchmarkError, CampaignError, TestingError
from .criteria import (
    CRITERIA,
    KEYS,
    ROA_SPAN,
    UNITS,
    Settings,
    campaign_text,
    cell_area,
    check_settings,
    described,
    periods,
)
from .criteria import torque_limit as limit_of
from .metrics import BOX, GOAL

TASKS = ('swing_up',)
RESULT_FILE = 'benchmark.yaml'
CAMPAIGNS = 'campaigns'


@dataclass(frozen=True)
class BenchmarkResult:
    """What a benchmark found: each result, each criterion's parameters and outcome.

    Attributes
    ----------
    values : dict
        ``{key: value}`` for each of :data:`~.criteria.KEYS` (None where not measured).
    criteria : dict
        ``{criterion: {parameters..., 'swung_up', 'failed', 'reasons'}}``.
    out : Path
        The output folder.
    files : list of Path
        What was written besides the campaigns.
    """

    values: dict[str, float | None]
    criteria: dict[str, dict[str, Any]]
    out: Path
    settings: dict[str, Any] = field(default_factory=dict)
    files: list[Path] = field(default_factory=list)

    def table(self) -> str:
        """Return the results as a table, one line each, with units and the criterion."""
        source = {'swing_up_time': 'nominal', 'energy': 'nominal', 'smoothness': 'nominal',
                  'frequency': 'nominal', 'min_torque_limit': 'torque_limit',
                  'roa_area': 'roa'}
        lines = [f'{"criterion":<18} {"value":>12}  {"unit":<8} from']
        for key in KEYS:
            value = self.values.get(key)
            shown = '-' if value is None else f'{value:.6g}'
            crit = source.get(key, key)
            extra = self.criteria.get(crit, {})
            note = (f'{crit} ({extra["episodes"]} episodes, {extra["failed"]} failed)'
                    if extra else f'{crit} (not run)')
            lines.append(f'{key:<18} {shown:>12}  {UNITS[key]:<8} {note}')
        return '\n'.join(lines)


def controller_name(controller: str | Sequence[str] | Callable[..., Any]
                    ) -> str | tuple[str, ...]:
    """Return the campaign's ``controller``: ``module:function``, or a command line.

    A callable is named by its module and qualified name (it must be importable so); a
    string with a space, or without a ``:``, is a command line (split as a shell would).
    """
    if callable(controller):
        name = f'{controller.__module__}:{controller.__qualname__}'
        from ..campaign.spec import load_controller

        if load_controller(name) is not controller:
            raise BenchmarkError(f'controller {controller!r} cannot be imported by name as '
                                 f'{name}; give it as module:function')
        return name
    if isinstance(controller, str):
        if ':' in controller and ' ' not in controller.strip():
            return controller.strip()
        words = shlex.split(controller)
        if not words:
            raise BenchmarkError('controller must be module:function or a command line, got '
                                 "''")
        return tuple(words)
    words = list(controller)
    if not words or not all(isinstance(w, str) for w in words):
        raise BenchmarkError(f'controller must be module:function or a command line, got '
                             f'{controller!r}')
    return tuple(words)


def prepare(settings: Settings) -> tuple[Settings, dict[str, Any]]:
    """Return the settings with the scene read, and each criterion's checked campaign.

    Raises
    ------
    BenchmarkError
        If no benchmark could run so (each check's reason, one line).
    """
    from ..campaign.check import check_values
    from ..campaign.spec import parse_spec
    from ..scene import read_scene, with_overrides

    check_settings(settings)
    try:
        base = read_scene(settings.scene)
        if settings.torque_limit is not None:
            base['max_effort'] = settings.torque_limit
        with_overrides(base, {})
    except TestingError as exc:
        raise BenchmarkError(str(exc).splitlines()[0]) from None
    settings = replace(settings, base=base)
    limit_of(settings)   # > 0
    specs = {}
    for criterion in settings.criteria:
        try:
            spec = parse_spec(campaign_text(settings, criterion), f'{criterion} campaign')
            check_values(spec)
        except CampaignError as exc:
            raise BenchmarkError(str(exc).splitlines()[0]) from None
        specs[criterion] = spec
    return settings, specs


def _check_out(out: Path, resume: bool) -> None:
    if out.exists() and not out.is_dir():
        raise BenchmarkError(f"--out '{out}' exists and is not a folder")
    if resume:
        if not (out / CAMPAIGNS).is_dir():
            raise BenchmarkError(f"--resume: '{out}' holds no benchmark ({CAMPAIGNS}/ is "
                                 'missing)')
    elif out.is_dir() and any(out.iterdir()):
        raise BenchmarkError(f"--out '{out}' is not empty; use --resume to continue the "
                             'benchmark in it')


def benchmark(controller: str | Sequence[str] | Callable[..., Any], *, out: str | Path,
              task: str = 'swing_up', scene: str = 'swing_up', duration: float = 10.0,
              episodes: int = 100, seed: int = 0, goal_box: Sequence[float] = BOX,
              torque_limit: float | None = None, criteria: Sequence[str] = CRITERIA,
              roa_grid: int = 50,
              roa_span: tuple[tuple[float, float], tuple[float, float]] = ROA_SPAN,
              limits: int = 20, scheduler: str | None = None, workers: int | None = None,
              resume: bool = False, progress: bool = False, jit: bool = False,
              figures: bool = True, gif: bool = True) -> BenchmarkResult:
    """Run the swing-up benchmark of ``controller``; write its results into ``out``.

    Parameters
    ----------
    controller : str, list of str or callable
        ``module:function`` (a law ``(t, position, velocity) -> command``, vectorised or
        not), an importable function, or a command line (a ROS node, as a list or one
        string).
    out : path
        The output folder (new or empty; with ``resume``, the benchmark to continue).
    task : str
        The task; ``swing_up`` is the one there is.
    scene, duration, episodes, seed, goal_box, torque_limit, criteria : see Settings
        As :class:`~.criteria.Settings` says; so do ``roa_grid``, ``roa_span``, ``limits``
        and ``jit``.
    scheduler : str, optional
        A Dask scheduler's address (``tcp://host:8786``); a local cluster where None.
    workers : int, optional
        The local cluster's worker processes (the core count where None).
    resume : bool
        Continue the benchmark in ``out`` (each criterion's finished episodes kept).
    progress : bool
        Show the campaigns' progress bar on stderr.
    figures, gif : bool
        Draw ``benchmark.png`` and ``roa.png`` / write ``swing_up.gif``.

    Raises
    ------
    BenchmarkError
        If the benchmark cannot run as asked; nothing is written then.
    """
    if task not in TASKS:
        raise BenchmarkError(f'unknown task {task!r}; tasks: {", ".join(TASKS)}')
    if scheduler is not None and workers is not None:
        raise BenchmarkError('workers sizes the local cluster; it cannot go with scheduler')
    name = controller_name(controller)
    box = tuple(goal_box)
    if len(box) != 2:
        raise BenchmarkError(f'goal box must be (angle rad, rate rad/s), got {box!r}')
    settings, specs = prepare(Settings(
        controller=name, scene=scene, duration=duration, episodes=episodes, seed=seed,
        goal_box=(float(box[0]), float(box[1])), torque_limit=torque_limit,
        criteria=tuple(criteria), roa_grid=roa_grid, roa_span=roa_span, limits=limits,
        jit=jit))
    root = Path(out)
    _check_out(root, resume)
    if scheduler is not None:
        from ..campaign.execute import check_address

        check_address(scheduler)
    from ..campaign.execute import run_campaigns
    from ..campaign.store import CAMPAIGN_FILE
    from ..campaign.summary import import_writers, write_summary, write_table

    folders = {c: root / CAMPAIGNS / c for c in settings.criteria}
    jobs = [(specs[c], folders[c], resume and (folders[c] / CAMPAIGN_FILE).is_file())
            for c in settings.criteria]
    # Meanwhile this process runs the nominal episode again (for the animation) and imports
    # what it writes with: it mostly waits for the cluster.
    side = Nominal(settings, gif) if 'nominal' in settings.criteria else None
    waiting = [import_writers()] if figures else []
    if side is not None:
        side.start()
    results = run_campaigns(jobs, scheduler=scheduler, workers=workers, progress=progress)
    rows = dict(zip(settings.criteria, results, strict=True))
    for c in settings.criteria:
        write_table(specs[c], rows[c], folders[c])
        write_summary(specs[c], rows[c], folders[c], [])
    values, outcome = summarise(settings, specs, rows)
    files: list[Path] = []
    if side is not None:
        side.join()
        values['frequency'] = side.frequency()
    result = BenchmarkResult(values, outcome, root, _settings_record(settings), files)
    files.append(write_yaml(result))
    for thread in waiting:
        thread.join()
    if figures:
        from .figures import comparison_figure, roa_figure

        drawn = comparison_figure(result, root / 'benchmark.png')
        if drawn is not None:
            files.append(drawn)
        if 'roa' in settings.criteria:
            drawn = roa_figure(settings, rows['roa'], values['roa_area'], estimate(settings),
                               root / 'roa.png')
            if drawn is not None:
                files.append(drawn)
    if side is not None and side.animation is not None:
        path = root / 'swing_up.gif'
        path.write_bytes(side.animation)
        files.append(path)
    return result


class Nominal(threading.Thread):
    """The nominal episode run again in this process, its animation and the call rate.

    :meth:`run` (in a thread, while the campaigns run on the cluster) makes the closed loop
    and, with ``gif``, the animation's bytes; :meth:`frequency` (after the campaigns, on a
    quiet process) times the law's calls.
    """

    def __init__(self, settings: Settings, gif: bool) -> None:
        super().__init__(name='nominal-run', daemon=True)
        self.settings = settings
        self.gif = gif
        self.closed: Any = None
        self.wall = math.nan
        self.animation: bytes | None = None

    def run(self) -> None:
        """Run the nominal closed loop; draw its animation."""
        s = self.settings
        overrides = {'max_effort': s.torque_limit} if s.torque_limit is not None else None
        controller = list(s.controller) if isinstance(s.controller, tuple) else one_state_law(
            s.controller)
        began = time.perf_counter()
        try:
            self.closed = closed_loop_of(controller, s.scene, periods(s), overrides)
        except TestingError:
            return
        self.wall = time.perf_counter() - began
        if self.gif and self.closed.t.size:
            from io import BytesIO

            from .animation import write_gif

            buffer = BytesIO()
            try:
                write_gif(self.closed, buffer, goal=GOAL)
            except TestingError:
                return   # no Pillow: the benchmark stands without its animation
            self.animation = buffer.getvalue()

    def frequency(self) -> float:
        """Return the controller's calls per second (the module's ``frequency``)."""
        run = self.closed
        if run is None or run.t.size == 0:
            return math.nan
        if isinstance(self.settings.controller, tuple):
            return float(run.t.size / self.wall)
        law = one_state_law(self.settings.controller)
        began = time.perf_counter()
        for t, position, velocity in zip(run.t.tolist(), run.position.tolist(),
                                         run.velocity.tolist(), strict=True):
            law(t, position, velocity)
        return float(run.t.size / (time.perf_counter() - began))


def one_state_law(name: str) -> Callable[[float, float, float], Any]:
    """Return the law ``name`` as a law of one state (a vectorised one on 1-element arrays,
    as a campaign runs it alone), with the goal as its ``target`` if it takes one."""
    from ..batch import scalar_law
    from ..campaign.spec import load_controller
    from ..target import bind_target, takes_target
    from ..vector import is_vectorised

    law = load_controller(name)
    if is_vectorised(law):
        return scalar_law(law, GOAL if takes_target(law) else None)
    return bind_target(law, GOAL)


def closed_loop_of(controller: Any, scene: str, steps: int,
                   overrides: dict[str, Any] | None) -> Any:
    """Return the closed loop of ``controller`` on ``scene`` towards upright."""
    from ..loop import closed_loop

    return closed_loop(controller, scene=scene, periods=steps, overrides=overrides,
                       target=None if callable(controller) else GOAL).with_target(GOAL)


def _settings_record(s: Settings) -> dict[str, Any]:
    return {'controller': list(s.controller) if isinstance(s.controller, tuple) else
            s.controller, 'task': 'swing_up', 'scene': s.scene, 'duration': s.duration,
            'periods': periods(s), 'control_rate': float(s.base['publish_rate']),
            'h': float(s.base['h']), 'seed': s.seed, 'goal': GOAL,
            'goal_box': list(s.goal_box), 'torque_limit': limit_of(s),
            'requirement': 'enters the goal box and stays to the end (stays == 1)'}


def _error(spec: Any, row: dict[str, Any]) -> str:
    """Return why ``row`` failed otherwise than by not swinging up ('' if it did not)."""
    if not row['reason']:
        return ''
    missed = spec.requirements[0].check(row['stays']) if isinstance(row['stays'], bool) else None
    return '' if row['reason'] == missed else str(row['reason'])


def summarise(s: Settings, specs: dict[str, Any], rows: dict[str, list[dict[str, Any]]]
              ) -> tuple[dict[str, float | None], dict[str, dict[str, Any]]]:
    """Return the results and each criterion's parameters and outcome, from the rows."""
    values: dict[str, float | None] = dict.fromkeys(KEYS)
    outcome: dict[str, dict[str, Any]] = {}
    for c, mine in rows.items():
        errors = [e for e in (_error(specs[c], r) for r in mine) if e]
        record = described(s, c)
        record.update({'swung_up': sum(1 for r in mine if r['passed']), 'failed': len(errors),
                       'reasons': sorted(set(errors))[:3]})
        outcome[c] = record
        share = 100.0 * sum(1 for r in mine if r['passed']) / max(len(mine), 1)
        if c in ('consistency', 'robustness', 'sensitivity'):
            values[c] = share
        elif c == 'nominal':
            for key in ('swing_up_time', 'energy', 'smoothness'):
                got = [float(r[key]) for r in mine]
                values[key] = sum(got) / len(got) if got else math.nan
        elif c == 'torque_limit':
            by_limit = sorted((float(r['max_effort']), bool(r['passed'])) for r in mine)
            record['swung_up_at'] = [limit for limit, ok in by_limit if ok]
            lowest = math.nan
            for limit, ok in reversed(by_limit):
                if not ok:
                    break
                lowest = limit
            values['min_torque_limit'] = lowest
        elif c == 'roa':
            values['roa_area'] = sum(1 for r in mine if r['passed']) * cell_area(s)
    return values, outcome


def estimate(s: Settings) -> Any:
    """Return the controller's region-of-attraction estimate, or None.

    A law provides one as its attribute ``roa_estimate``: an ellipse (``center``,
    ``matrix``, ``level``, ``area()``, as :class:`pendulum_sim.controller.swing_up_law.Ellipse`)
    or a function of no arguments returning one.
    """
    if isinstance(s.controller, tuple):
        return None
    from ..campaign.spec import load_controller

    found = getattr(load_controller(s.controller), 'roa_estimate', None)
    return found() if callable(found) else found


def write_yaml(result: BenchmarkResult) -> Path:
    """Write ``benchmark.yaml``: the settings, each result, each criterion's parameters."""
    doc: dict[str, Any] = dict(result.settings)
    doc.update({k: _plain(v) for k, v in result.values.items()})
    doc['criteria'] = {c: {k: _plain(v) for k, v in record.items()}
                       for c, record in result.criteria.items()}
    path = result.out / RESULT_FILE
    path.write_text(yaml.safe_dump(doc, sort_keys=False, width=99), encoding='utf-8')
    return path


def _plain(value: Any) -> Any:
    """Return ``value`` as YAML writes it plainly (floats as floats, lists as lists)."""
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, bool) or value is None or isinstance(value, (int, str)):
        return value
    return float(value)


def read_result(path: str | Path) -> dict[str, Any]:
    """Return a ``benchmark.yaml`` as written (``float('nan')`` and ``inf`` as YAML has them)."""
    data = yaml.safe_load(Path(path).read_text(encoding='utf-8'))
    if not isinstance(data, dict):
        raise BenchmarkError(f"'{path}' is not a benchmark result")
    return data
