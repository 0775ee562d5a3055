"""The target as a scenario dimension: drawn per episode, given to the controller, measured.

A law with a keyword ``target`` gets each episode's target (bound once per episode), a
vectorised law an array of them, a command line the number in place of ``{target}``; the
metrics are measured towards the episode's target, and ``--rerun`` reproduces the episode.
The PD law with gravity compensation and the true m g l leaves the linear error dynamics
``I e'' = -Kp e - (Kd + gamma I) e'`` (no static error), which is the oracle of the tracking
test: every episode must end within the decay envelope of its own step.
"""
from __future__ import annotations

import json
import math
import os
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pendulum_sim.testing import ClosedLoopRun, TestingError
from pendulum_sim.testing import closed_loop as run_closed_loop
from pendulum_sim.testing.campaign.cli import main
from pendulum_sim.testing.campaign.episode import RUN_COLUMNS, run_episode, run_episodes
from pendulum_sim.testing.campaign.scenarios import episode_scenario, scenario
from pendulum_sim.testing.campaign.spec import parse_spec
from pendulum_sim.testing.examples import GAINS, pd
from pendulum_sim.testing.target import bind_target, substitute_target, takes_target

HERE = Path(__file__).resolve().parents[1] / 'support'
PD_CONTROLLER = str(Path(sys.executable).parent / 'pendulum_pd_controller')

DRAWN = """
controller: pendulum_sim.testing.examples:{law}
episodes: {episodes}
seed: 21
periods: {periods}
target: {{distribution: uniform, low: 0.1, high: 0.8}}
parameters:
  gamma: {{distribution: loguniform, low: 0.02, high: 0.5}}
requirements: ['overshoot < 20']
"""


@pytest.fixture(autouse=True)
def laws_importable(monkeypatch: pytest.MonkeyPatch) -> None:
    """Let this process and every worker it starts import test/support/campaign_laws.py."""
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setenv('PYTHONPATH', os.pathsep.join(
        [str(HERE), *filter(None, [os.environ.get('PYTHONPATH')])]))


def result(row: dict[str, Any]) -> str:
    """Return a row without where and when it ran, floats exact (NaN equal to NaN)."""
    return json.dumps({k: v for k, v in row.items() if k not in RUN_COLUMNS}, sort_keys=True)


# ------------------------------------------------------------------ the controller gets it
def test_a_law_receives_the_target_by_keyword_and_a_command_line_by_placeholder() -> None:
    def plain(t: float, position: float, velocity: float) -> float:
        return 0.0

    assert takes_target(pd) and not takes_target(plain) and not takes_target(math.sin)
    assert bind_target(plain, 0.3) is plain
    bound = bind_target(pd, 0.3)
    assert bound(0.0, 1.0, 0.2) == pd(0.0, 1.0, 0.2, target=0.3) != pd(0.0, 1.0, 0.2)
    target = 0.1 + 0.2      # 0.30000000000000004: the text must read back as this float
    cmd = substitute_target(['c', '--ros-args', '-p', 'target:={target}', '-p', 'kp:=4'],
                            target)
    assert cmd == ['c', '--ros-args', '-p', 'target:=0.30000000000000004', '-p', 'kp:=4']
    assert float(cmd[3].split(':=')[1]) == target
    assert substitute_target(['c', '-x'], None) == ['c', '-x']


def test_closed_loop_gives_the_target_to_the_law_and_keeps_it_for_the_metrics() -> None:
    run = run_closed_loop(pd, periods=400, target=0.2)
    fixed = run_closed_loop(pd, periods=400)
    assert run.target == 0.2 and fixed.target is None
    # pd towards 0.2 settles at 0.2; without a target it holds its default, 0.5.
    assert abs(run.position[-1] - 0.2) < 1e-3 and abs(fixed.position[-1] - GAINS.target) < 1e-3
    assert run.metrics() == run.metrics(0.2)
    # A law without the keyword is not given the target: the run only measures towards it.
    held = run_closed_loop(lambda t, p, v: pd(t, p, v), periods=400, target=0.2)
    assert held.position.tobytes() == fixed.position.tobytes() and held.target == 0.2


def test_plot_draws_towards_the_target_the_metrics_were_last_asked_for(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from pendulum_sim.testing import figure

    drawn: list[float] = []
    draw = figure.closed_loop_figure

    def spy(run: Any, target: float, path: Path, *args: Any) -> Path:
        drawn.append(target)
        return draw(run, target, path, *args)

    monkeypatch.setattr(figure, 'closed_loop_figure', spy)
    run = run_closed_loop(pd, periods=300, target=0.5)
    run.plot(tmp_path / 'own.png')                   # nothing asked yet: the run's own target
    asked = run.metrics(0.3)
    run.plot(tmp_path / 'asked.png')                 # the target the metrics were asked for
    assert run.metrics() == asked
    with pytest.raises(TestingError, match='target must be finite, got nan'):
        run.metrics(math.nan)
    run.plot(tmp_path / 'kept.png')                  # a refused target is not kept: 0.3 holds
    run.plot(tmp_path / 'given.png', target=0.1)     # a target given to plot() counts too
    assert run.metrics() == run.metrics(0.1) != asked
    assert drawn == [0.5, 0.3, 0.3, 0.1]
    assert all((tmp_path / f'{name}.png').stat().st_size > 0
               for name in ('own', 'asked', 'kept', 'given'))
    # Another run of the same samples starts from its own target again.
    assert run.with_target(0.2).metrics() == run.metrics(0.2)


def test_the_pytest_fixture_passes_the_target_on(
        closed_loop: Callable[..., ClosedLoopRun]) -> None:
    run = closed_loop(pd, periods=300, target=-0.4)
    assert run.target == -0.4
    assert abs(run.metrics().steady_state_error) < 0.01


@pytest.mark.parametrize(('controller', 'target', 'msg'), [
    ([PD_CONTROLLER, '--ros-args', '-p', 'target:={target}'], None,
     'the controller command line has a {target} placeholder but no target was given '
     '(closed_loop(..., target=...))'),
    (pd, math.nan, 'target must be a finite number (rad), got nan'),
    (pd, '0.5', "target must be a finite number (rad), got '0.5'"),
])
def test_closed_loop_refuses_a_missing_or_bad_target(controller: Any, target: Any,
                                                     msg: str) -> None:
    with pytest.raises(TestingError, match=re.escape(msg)):
        run_closed_loop(controller, periods=10, target=target)


# ------------------------------------------------------------------ campaigns
def test_each_episode_tracks_its_own_drawn_target() -> None:
    periods, episodes = 400, 12
    text = DRAWN.format(law='pd', episodes=episodes, periods=periods)
    spec = parse_spec(text)
    rows = [run_episode(text, i, None) for i in range(episodes)]
    targets = np.array([r['target'] for r in rows])
    assert targets.tolist() == [episode_scenario(spec, i).target for i in range(episodes)]
    assert targets.min() >= 0.1 and targets.max() < 0.8 and np.ptp(targets) > 0.3
    # Error dynamics I e'' = -Kp e - (Kd + gamma I) e': |e(t)| <= |e0| exp(-s t) / sqrt(1 - z^2)
    # with s = (Kd + gamma I) / (2 I), z = s sqrt(I / Kp). Twice that envelope at the last state
    # leaves room for the 100 Hz sampling of the law; tracking another target misses by far more.
    inertia, t_end = 0.2002, (periods - 1) / 100
    for r in rows:
        s = (GAINS.kd + r['gamma'] * inertia) / (2 * inertia)
        zeta = s * math.sqrt(inertia / GAINS.kp)
        bound = 2 * abs(r['target'] - 1.0) * math.exp(-s * t_end) / math.sqrt(1 - zeta ** 2)
        assert abs(r['steady_state_error']) < bound, r
        assert bound < 1e-3 * abs(r['target'])
        assert r['passed'] and r['reason'] == ''
    # The parameters draw as they would with a fixed target: the target is drawn after them.
    fixed = parse_spec(text.replace('{distribution: uniform, low: 0.1, high: 0.8}', '0.5'))
    assert [scenario(fixed, i) for i in range(episodes)] == [scenario(spec, i)
                                                             for i in range(episodes)]


def test_a_list_target_is_taken_in_episode_order() -> None:
    text = DRAWN.format(law='pd', episodes=4, periods=400).replace(
        '{distribution: uniform, low: 0.1, high: 0.8}', '[0.3, -0.2, 0.7]')
    rows = [run_episode(text, i, None) for i in range(4)]
    assert [r['target'] for r in rows] == [0.3, -0.2, 0.7, 0.3]
    for r in rows:
        assert abs(r['steady_state_value'] - r['target']) < 1e-3
    assert result(rows[0]).replace('"episode": 0', '') != result(rows[3]).replace(
        '"episode": 3', '')   # same target, other damping: not a copied row


def test_a_vectorised_law_gets_each_episodes_target_as_the_scalar_episodes_do() -> None:
    text = DRAWN.format(law='pd_batch', episodes=16, periods=300)
    batched = run_episodes(text, list(range(16)), None)
    one_by_one = [run_episode(text.replace('pendulum_sim.testing.examples:pd_batch',
                                           'campaign_laws:pd_batch_one_to'), i, None)
                  for i in range(16)]
    assert [result(r) for r in batched] == [result(r) for r in one_by_one]
    assert len({r['target'] for r in batched}) == 16
    assert all(abs(r['steady_state_error']) < 0.01 for r in batched)
    # A rerun of one episode is a batch of one: the same row.
    assert result(run_episode(text, 5, None)) == result(batched[5])


@pytest.mark.ros
def test_a_command_line_gets_each_episodes_target_through_the_placeholder_over_dds() -> None:
    """Two ROS episodes of the example controller, each the in-process PD law's bit for bit."""
    ros = DRAWN.format(law='pd', episodes=2, periods=60).replace(
        'pendulum_sim.testing.examples:pd',
        f"['{PD_CONTROLLER}', '--ros-args', '-p', 'target:={{target}}']")
    assert parse_spec(ros).is_command_line
    in_process = DRAWN.format(law='pd', episodes=2, periods=60)
    rows = [run_episode(ros, i, None) for i in range(2)]
    assert rows[0]['target'] != rows[1]['target']
    for i, r in enumerate(rows):
        assert r['reason'] == '' or r['reason'].startswith('overshoot'), r['reason']
        assert result(r) == result(run_episode(in_process, i, None))


@pytest.mark.slow
def test_rerun_reproduces_an_episode_with_a_drawn_target(tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]) \
        -> None:
    import pyarrow.parquet as pq

    path = tmp_path / 'campaign.yaml'
    path.write_text(DRAWN.format(law='pd', episodes=6, periods=200))
    out = tmp_path / 'out'
    assert main([str(path), '--out', str(out), '--workers', '1', '--no-progress']) in (0, 1)
    table = pq.read_table(out / 'episodes.parquet')
    assert table.column_names[:3] == ['episode', 'gamma', 'target']
    spec = parse_spec(path.read_text())
    assert table.column('target').to_pylist() == [episode_scenario(spec, i).target
                                                  for i in range(6)]
    # Where or in which order the episodes ran does not matter: backwards here, the same rows.
    here = [run_episode(spec.text, i, None) for i in reversed(range(6))][::-1]
    assert [result(r) for r in table.to_pylist()] == [result(r) for r in here]
    capsys.readouterr()
    assert main(['--rerun', str(out), '4']) == 0
    assert capsys.readouterr().out.startswith('episode 4 reproduced bit for bit (')
    import sqlite3

    db = sqlite3.connect(out / 'episodes.sqlite')
    with db:
        row = json.loads(db.execute('SELECT row FROM episodes WHERE episode = 4').fetchone()[0])
        drawn = row['target']
        row['target'] = 0.5
        db.execute('UPDATE episodes SET row = ? WHERE episode = 4', (json.dumps(row),))
    db.close()
    assert main(['--rerun', str(out), '4']) == 1
    assert capsys.readouterr().out.startswith(
        f'episode 4 differs from the stored result in target (0.5 then, {drawn!r} now)')
