"""One episode: its scenario, the closed loop, the metrics, the requirements, a table row.

:func:`run_episode` runs one episode, :func:`run_episodes` a batch of a vectorised law; both
take the campaign file's text (so a process on another machine needs only pendulum_sim) and
return table rows. A failing episode's run is also written to ``failures/episode-NNNNNN.mcap``
under the output folder; for a controller that raised or gave an answer that is not a finite
number, the run up to that state. A controller that raises, answers NaN or cannot run fails
its episode with the reason; the campaign goes on. The scene is read once per process
(:func:`scene_base`). The campaign runs these in an episode process of its own
(:mod:`~pendulum_sim.testing.campaign.sandbox`), which also fails an episode whose law exits,
is killed, runs out of memory or does not answer (:func:`fault_row`).
"""
from __future__ import annotations

import functools
import math
import os
import socket
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import ControllerFailed, TestingError
from ..loop import ClosedLoopRun, closed_loop, run_in_process
from ..metrics import StepMetrics
from ..run import runs_metrics, runs_swing_up_metrics
from ..scene import Value, read_scene, with_overrides
from ..swing_up.metrics import SwingUpMetrics
from ..target import bind_target
from ..vector import is_vectorised
from .scenarios import episode_scenario
from .spec import CampaignSpec, load_controller, parse_spec
from .watch import loop_done, watched

if TYPE_CHECKING:
    from ..batch import BatchStats

# Columns that say where and when an episode ran: not part of its result.
RUN_COLUMNS = ('worker_host', 'worker_pid', 'wall_time_s')


@functools.lru_cache(maxsize=8)
def cached_spec(text: str) -> CampaignSpec:
    """Return the parsed campaign (parsed once per process)."""
    return parse_spec(text)


@functools.lru_cache(maxsize=8)
def _scene(scene: str) -> dict[str, Value] | TestingError:
    try:
        return read_scene(scene)
    except TestingError as exc:
        return exc


def scene_base(scene: str) -> dict[str, Value]:
    """Return the node's values of ``scene`` before overrides (read once per process)."""
    base = _scene(scene)
    if isinstance(base, TestingError):
        raise base
    return base


def episode_values(spec: CampaignSpec, values: dict[str, Value]) -> dict[str, Value]:
    """Return the node parameters of an episode drawn ``values`` (TestingError if unusable)."""
    return with_overrides(scene_base(spec.scene), values)


def failure_path(out: Path, episode: int) -> Path:
    """Return where the recording of failing episode ``episode`` is kept."""
    return out / 'failures' / f'episode-{episode:06d}.mcap'


Measured = StepMetrics | SwingUpMetrics


def verdict(spec: CampaignSpec, metrics: Measured | dict[str, Any]) -> str:
    """Return why the metrics fail the requirements ('' when they meet them all)."""
    values = metrics if isinstance(metrics, dict) else metrics.as_dict()
    reasons = [r.check(values[r.metric]) for r in spec.requirements]
    return '; '.join(r for r in reasons if r)


def measure(spec: CampaignSpec, run: ClosedLoopRun, target: float) -> Measured:
    """Return the metrics of the campaign's task of ``run`` towards ``target``.

    ``step``: ``run.metrics(target)``; ``swing_up``: ``run.swing_up_metrics(target,
    spec.goal_box)``. Raises the TestingError they raise.
    """
    if spec.task == 'swing_up':
        return run.swing_up_metrics(target, spec.goal_box)
    return run.metrics(target)


def measure_runs(spec: CampaignSpec, runs: list[ClosedLoopRun],
                 targets: list[float]) -> list[Measured | TestingError]:
    """Return :func:`measure` of each run, computed together (a batch's runs)."""
    if spec.task == 'swing_up':
        return list(runs_swing_up_metrics(runs, targets, spec.goal_box))
    return list(runs_metrics(runs, targets))


def row_of(spec: CampaignSpec, episode: int, values: dict[str, Any], target: float,
           run: ClosedLoopRun | None, reason: str, started: float,
           measured: Measured | TestingError | None = None) -> dict[str, Any]:
    """Return the table row of an episode (a run of None failed before it had samples).

    The metrics of the campaign's task are measured towards the episode's ``target``, over
    the run up to its fault when ``reason`` says why it stopped early; ``measured`` is
    :func:`measure` (or the TestingError it raises) when the caller has it already (a batch's
    runs, measured together by :func:`measure_runs`). A metric not measured is NaN.
    """
    metrics: dict[str, Any] = {name: math.nan for name in spec.metric_names}
    if run is not None:
        if measured is None:
            try:
                measured = measure(spec, run, target)
            except TestingError as exc:
                measured = exc
        if isinstance(measured, TestingError):
            reason = reason or str(measured)
        else:
            metrics = measured.as_dict()
            reason = reason or (f'the simulation stopped: {run.failed}' if run.failed else
                                verdict(spec, metrics))
    return {'episode': episode, **values, 'target': target, **metrics, 'passed': not reason,
            'reason': reason,
            'worker_host': socket.gethostname(), 'worker_pid': os.getpid(),
            'wall_time_s': time.perf_counter() - started}


def fault_row(spec: CampaignSpec, episode: int, reason: str) -> dict[str, Any]:
    """Return the row of an episode whose process ended without its row (the reason why)."""
    drawn = episode_scenario(spec, episode)
    row = row_of(spec, episode, drawn.values, drawn.target, None, reason, time.perf_counter())
    row['wall_time_s'] = 0.0
    return row


def failed_run(exc: TestingError) -> ClosedLoopRun | None:
    """Return the run up to the fault that ``exc`` carries (a controller's), or None."""
    run = exc.run if isinstance(exc, ControllerFailed) else None
    return run if isinstance(run, ClosedLoopRun) else None


def _keep_failure(out: str | None, row: dict[str, Any], run: ClosedLoopRun | None) -> None:
    """Write a failing episode's run to :func:`failure_path` (with the target)."""
    if out is not None and not row['passed'] and run is not None and run.t.size:
        from ..record import write_run

        path = failure_path(Path(out), int(row['episode']))
        path.parent.mkdir(parents=True, exist_ok=True)
        write_run(run, path)


def run_episode(text: str, episode: int, out: str | None,
                foxglove_port: int = 0) -> dict[str, Any]:
    """Run episode ``episode`` of the campaign ``text``; return its row.

    When ``out`` is given, a failing episode's run is written to
    :func:`failure_path` (with the target, so ``pendulum_report closed-loop`` reads it). A
    vectorised law runs as a batch of one (the batched path decides for it, as in the
    campaign). With ``foxglove_port`` (0 = off) the episode is served live to Foxglove while
    it runs (``closed_loop(..., foxglove_port=)``); a batch is not.
    """
    spec = cached_spec(text)
    if batched(spec):
        return run_episodes(text, [episode], out)[0]
    started = time.perf_counter()
    drawn = episode_scenario(spec, episode)
    run: ClosedLoopRun | None = None
    reason = ''
    try:
        if isinstance(spec.controller, tuple):
            run = closed_loop(list(spec.controller), scene=spec.scene, periods=spec.periods,
                              overrides=drawn.values, target=drawn.target,
                              foxglove_port=foxglove_port)
        else:
            law = watched(bind_target(load_controller(spec.controller), drawn.target))
            values = episode_values(spec, drawn.values)
            if foxglove_port:
                values['foxglove_port'] = foxglove_port
            try:
                run = run_in_process(law, values, spec.periods,
                                     drawn.target).with_target(drawn.target)
            finally:
                loop_done()
    except TestingError as exc:
        reason = str(exc).splitlines()[0]
        run = failed_run(exc)
        run = None if run is None else run.with_target(drawn.target)
    row = row_of(spec, episode, drawn.values, drawn.target, run, reason, started)
    _keep_failure(out if spec.keep_failures else None, row, run)
    return row


def run_episodes(text: str, episodes: list[int], out: str | None,
                 stats: BatchStats | None = None) -> list[dict[str, Any]]:
    """Run the episodes of a campaign whose law is vectorised, as one batch; return the rows.

    ``wall_time_s`` of each row is the batch's time divided by its size. ``stats``, when
    given, is filled with how the batch ran them (``testing.batch.BatchStats``: in lockstep,
    or one by one on the scalar joint and why).
    """
    return run_episodes_parts([(text, episodes, out)], stats)[0]


Part = tuple[str, list[int], str | None]   # a campaign's text, episodes, output folder


def same_batch(spec: CampaignSpec) -> tuple[Any, ...]:
    """Return what campaigns must share for their episodes to run in one batch: the law, the
    episode length, the compiled sweep or not."""
    return (spec.controller, spec.periods, spec.jit)


def run_episodes_parts(parts: list[Part], stats: BatchStats | None = None
                       ) -> list[list[dict[str, Any]]]:
    """Run the episodes of several campaigns of one vectorised law in one batch; return each
    campaign's rows.

    The campaigns must agree on :func:`same_batch` (the benchmark's criteria do); each
    episode is drawn, run and measured by its own campaign's rules, as :func:`run_episodes`
    runs them alone. ``wall_time_s`` of each row is the batch's time divided by its size;
    ``stats`` as :func:`run_episodes` says.
    """
    from ..batch import run_batch, warm_up_batch

    started = time.perf_counter()
    specs = [cached_spec(text) for text, _, _ in parts]
    if len({same_batch(spec) for spec in specs}) != 1:
        raise TestingError('campaigns of one batch must share their law, periods and jit')
    first = specs[0]
    law = watched(load_controller(str(first.controller)))
    drawn = [[episode_scenario(spec, i) for i in episodes]
             for spec, (_, episodes, _) in zip(specs, parts, strict=True)]
    params: list[list[Any]] = []
    for spec, mine in zip(specs, drawn, strict=True):
        params.append([])
        for d in mine:
            try:
                params[-1].append(episode_values(spec, d.values))
            except TestingError as exc:
                params[-1].append(exc)
    ok = [(j, i) for j, mine in enumerate(params) for i, p in enumerate(mine)
          if not isinstance(p, TestingError)]
    results: list[list[Any]] = [list(mine) for mine in params]
    if first.jit and ok:   # compiled (or loaded from the disk cache) before the clock starts
        warm_up_batch([params[j][i] for j, i in ok])
        started = time.perf_counter()
    try:
        batch = run_batch(law, [params[j][i] for j, i in ok], first.periods,
                          targets=[drawn[j][i].target for j, i in ok], jit=first.jit,
                          stats=stats)
    finally:
        loop_done()
    for (j, i), res in zip(ok, batch, strict=True):
        results[j][i] = res
    total = sum(len(episodes) for _, episodes, _ in parts)
    out_rows = []
    for spec, (_, episodes, out), mine, got in zip(specs, parts, drawn, results, strict=True):
        runs = [res if isinstance(res, ClosedLoopRun) else failed_run(res) for res in got]
        runs = [None if run is None else run.with_target(d.target)
                for run, d in zip(runs, mine, strict=True)]
        measured = iter(measure_runs(spec, [run for run in runs if run is not None],
                                     [d.target for run, d in zip(runs, mine, strict=True)
                                      if run is not None]))
        rows = []
        for i, d, res, run in zip(episodes, mine, got, runs, strict=True):
            reason = str(res).splitlines()[0] if isinstance(res, TestingError) else ''
            row = row_of(spec, i, d.values, d.target, run, reason, started,
                         None if run is None else next(measured))
            row['wall_time_s'] = (time.perf_counter() - started) / total
            _keep_failure(out if spec.keep_failures else None, row, run)
            rows.append(row)
        out_rows.append(rows)
    return out_rows


def run_chunk(text: str, episodes: list[int], out: str | None,
              foxglove_port: int = 0) -> list[dict[str, Any]]:
    """Run several episodes in this process (a batch for a vectorised law); return their rows.

    Episodes run one by one are served live on ``foxglove_port`` (0 = off); a batch is not.
    """
    if batched(cached_spec(text)):
        return run_episodes(text, episodes, out)
    return [run_episode(text, i, out, foxglove_port) for i in episodes]


def batched(spec: CampaignSpec) -> bool:
    """Return True when the campaign's law is declared vectorised (episodes run in batches)."""
    return not spec.is_command_line and is_vectorised(load_controller(str(spec.controller)))
