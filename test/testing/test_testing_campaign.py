"""Campaigns: the file's checks, seeded scenarios, episodes that fail alone, rerun, resume.

The cluster tests start a real ``dask scheduler`` and ``dask worker`` processes (the venv's
``dask`` command line) on 127.0.0.1, and run ``pendulum_campaign`` as a user does.
"""
from __future__ import annotations

import json
import math
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from dask_harness import dask_cluster as start_dask_cluster
from dask_harness import scheduler_tick, worker_profiling, worker_tick

from pendulum_sim.testing.campaign.cli import main
from pendulum_sim.testing.campaign.episode import RUN_COLUMNS, run_episode
from pendulum_sim.testing.campaign.scenarios import scenario
from pendulum_sim.testing.campaign.spec import parse_spec
from pendulum_sim.testing.metrics import METRIC_NAMES

HERE = Path(__file__).resolve().parents[1] / 'support'
BIN = Path(sys.executable).parent
PD_CONTROLLER = str(BIN / 'pendulum_pd_controller')

FRAGILE = """
controller: campaign_laws:fragile
scene: controller_test
episodes: {episodes}
seed: 3
periods: {periods}
target: 0.5
parameters:
  phi0: {{distribution: uniform, low: 0.8, high: 2.2}}
  gamma: [0.05, 0.2, 1.0]
  sensor.position_noise: {{distribution: loguniform, low: 1.0e-6, high: 1.0e-3}}
  m: {{distribution: normal, mean: 0.2, std: 0.005}}
  inertia: 0.25
requirements:
  - 'settling_time < 2.5'
  - 'overshoot < 20'
"""


@pytest.fixture(autouse=True)
def laws_importable(monkeypatch: pytest.MonkeyPatch) -> None:
    """Let this process and every worker it starts import test/support/campaign_laws.py."""
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setenv('PYTHONPATH', os.pathsep.join(
        [str(HERE), *filter(None, [os.environ.get('PYTHONPATH')])]))


def campaign(tmp: Path, episodes: int = 12, periods: int = 300, text: str = FRAGILE) -> Path:
    path = tmp / 'campaign.yaml'
    path.write_text(text.format(episodes=episodes, periods=periods))
    return path


def cli(*args: str, timeout: float = 300.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(BIN / 'pendulum_campaign'), *args], capture_output=True,
                          text=True, timeout=timeout)


def table(folder: Path) -> list[dict[str, Any]]:
    """Return the Parquet table's rows without the columns that say where and when."""
    import pyarrow.parquet as pq

    rows = pq.read_table(folder / 'episodes.parquet').to_pylist()
    return [{k: v for k, v in row.items() if k not in RUN_COLUMNS} for row in rows]


def stored(folder: Path) -> list[int]:
    """Return the ids of the episodes in the folder's database (read while it is written)."""
    import sqlite3

    if not (folder / 'episodes.sqlite').is_file():
        return []
    db = sqlite3.connect(f'file:{folder / "episodes.sqlite"}?mode=ro', uri=True, timeout=30)
    try:
        return [i for (i,) in db.execute('SELECT episode FROM episodes ORDER BY episode')]
    except sqlite3.OperationalError:   # created, its table not yet
        return []
    finally:
        db.close()


def same_rows(a: list[dict[str, Any]], b: list[dict[str, Any]]) -> bool:
    """Return True for equal rows, NaN equal to NaN, floats compared bit for bit."""
    return [json.dumps(r, sort_keys=True) for r in a] == [json.dumps(r, sort_keys=True)
                                                          for r in b]


# ------------------------------------------------------------------ the campaign file
BASE = {'controller': 'pendulum_sim.testing.examples:pd', 'episodes': 4, 'periods': 50,
        'target': 0.5}


@pytest.mark.parametrize(('change', 'msg'), [
    ({'parameters': {'gama': 1.0}},
     "unknown parameter 'gama' in parameters (did you mean 'gamma'?)"),
    ({'parameters': {'m': {'distribution': 'uniform', 'low': 0.3, 'high': 0.2}}},
     'parameters.m: uniform needs low < high, got low = 0.3, high = 0.2'),
    ({'parameters': {'gamma': {'distribution': 'loguniform', 'low': 0.0, 'high': 1.0}}},
     'parameters.gamma: loguniform needs low > 0, got low = 0'),
    ({'parameters': {'m': {'distribution': 'normal', 'mean': 0.2, 'std': -1.0}}},
     'parameters.m: normal needs std >= 0, got std = -1'),
    ({'parameters': {'m': {'distribution': 'gauss', 'mean': 0.2}}},
     "parameters.m: distribution must be one of uniform, normal, loguniform, got 'gauss'"),
    ({'parameters': {'m': {'distribution': 'normal', 'mean': 0.2}}},
     'parameters.m: a normal distribution takes mean, std, got mean'),
    ({'requirements': ['settle_time < 3.0']},
     "requirement 'settle_time < 3.0' names an unknown metric 'settle_time'; metrics: "
     + ', '.join(METRIC_NAMES)),
    ({'requirements': ['settling_time about 3']},
     "requirement 'settling_time about 3' must read 'metric op number' with op one of <, <=, "
     '>, >=, ==, !='),
    ({'controller': 'no_such_module:law'},
     "controller 'no_such_module:law' cannot be imported: ModuleNotFoundError: No module "
     "named 'no_such_module'"),
    ({'controller': 'pendulum_sim.testing.examples:nope'},
     "controller 'pendulum_sim.testing.examples:nope' cannot be imported: AttributeError: "
     "module 'pendulum_sim.testing.examples' has no attribute 'nope'"),
    ({'controller': ['no-such-controller', '--fast']},
     "controller command 'no-such-controller' cannot be started: no such executable"),
    ({'episodes': 0}, 'episodes must be an integer in [1, 10000000], got 0'),
    ({'scene': 'nope'}, "unknown scene 'nope'; known scenes: "),
    ({'parameters': {'synchronous': False}}, 'parameters.synchronous is fixed for a closed '
     'loop'),
    ({'controller': 'campaign_laws:hold',
      'target': {'distribution': 'uniform', 'low': 0.2, 'high': 0.8}},
     "target varies per episode but controller 'campaign_laws:hold' takes no keyword argument "
     'target to receive it'),
    ({'controller': [PD_CONTROLLER, '--ros-args', '-p', 'target:=0.5'], 'target': [0.3, 0.6]},
     'target varies per episode but the controller command line has no {target} placeholder '
     "to receive it (e.g. '-p', 'target:={target}')"),
    ({'target': {'distribution': 'uniform', 'low': 1.0, 'high': 0.5}},
     'target: uniform needs low < high, got low = 1, high = 0.5'),
    ({'target': [0.3, 'up']}, "target must be a number, got 'up'"),
    ({'target': []}, 'target: a list of values must not be empty'),
    ({'target': {'low': 0.1}}, 'target: distribution must be one of uniform, normal, '
     'loguniform, got None'),
    ({'episode': 3}, "campaign.yaml: unknown key 'episode'; keys: controller, scene, episodes, "
     'seed, periods, target, parameters, requirements'),
])
def test_a_bad_campaign_file_exits_2_with_one_line_saying_why(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], change: dict[str, Any],
        msg: str) -> None:
    import yaml

    path = tmp_path / 'campaign.yaml'
    path.write_text(yaml.safe_dump({**BASE, **change}))
    assert main([str(path), '--out', str(tmp_path / 'out'), '--no-progress']) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1
    assert err.startswith(f'pendulum_campaign: error: {msg}')
    assert not (tmp_path / 'out').exists()


PD = 'controller: pendulum_sim.testing.examples:pd\nepisodes: 4\nperiods: 50\ntarget: 0.5\n'
# Nested anchors, "billion laughs": 9 strings, then 9 aliases of the one before, 6 deep.
LAUGHS = '[&a [' + ', '.join(['lol'] * 9) + '], ' + ', '.join(
    f'&{k} [' + ', '.join([f'*{p}'] * 9) + ']'
    for p, k in zip('abcde', 'bcdef', strict=True)) + ']'


def bomb(key: str) -> str:
    """Return a campaign whose ``key`` (an accepted one) holds :data:`LAUGHS`."""
    if key == 'controller':
        return PD.replace('pendulum_sim.testing.examples:pd', LAUGHS)
    return PD + {'scene': f'scene: {LAUGHS}\n',
                 'requirement': f'requirements: [{LAUGHS}]\n',
                 'low': f'parameters: {{m: {{distribution: uniform, low: {LAUGHS}, '
                        'high: 1.0}}\n'}[key]


@pytest.mark.parametrize(('text', 'msg'), [
    (PD + 'parameters: {m: {distribution: uniform, low: -1.0e+308, high: 1.0e+308}}\n',
     'parameters.m: uniform needs high - low finite, got low = -1e+308, high = 1e+308'),
    (PD.replace('target: 0.5', 'target: ' + '[' * 20000 + ']' * 20000),
     'campaign.yaml: lists and mappings are nested more than 32 deep (line 4)'),
    (PD + 'episodes: 7\n', "campaign.yaml: key 'episodes' is given twice (line 5)"),
    (PD + 'parameters: {m: heavy}\n', "m must be a float, got 'heavy'"),
    (PD + 'parameters: {m: -1.0}\n', 'm must be > 0 kg, got -1.0'),
    (PD + 'parameters: {gamma: [0.1, 0.2, -0.5]}\n', 'gamma must be >= 0 s^(n-2), got -0.5'),
    (PD + "requirements: ['overshoot < nan']\n",
     "requirement 'overshoot < nan': the bound must be a number, got nan"),
    (PD + 'scene: {notyaml}\n', "notyaml.yaml is not valid YAML: expected ',' or ']', but got "
     "':' at line 2, column 4"),
    (PD + 'episode_timeout: 0\n', 'episode_timeout must be > 0 s, got 0'),
    (PD + "parameters: {m: '" + 'x' * 1000 + "'}\n", "m must be a float, got '" + 'x' * 56
     + '...'),
])
def test_what_no_episode_could_run_is_refused_before_the_first_with_exit_2(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, msg: str) -> None:
    notyaml = tmp_path / 'notyaml.yaml'
    notyaml.write_text('a: [1, 2\n  b: }{\n')
    path = tmp_path / 'campaign.yaml'
    path.write_text(text.replace('{notyaml}', str(notyaml)))
    assert main([str(path), '--out', str(tmp_path / 'out'), '--no-progress']) == 2
    err = capsys.readouterr().err
    assert err == f'pendulum_campaign: error: {msg}\n'
    assert not (tmp_path / 'out').exists()


@pytest.mark.parametrize('key', ['controller', 'scene', 'requirement', 'low'])
def test_a_yaml_bomb_is_refused_with_a_short_message(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], key: str) -> None:
    path = tmp_path / 'campaign.yaml'
    path.write_text(bomb(key))
    assert len(path.read_bytes()) < 700
    assert main([str(path), '--out', str(tmp_path / 'out'), '--no-progress']) == 2
    err = capsys.readouterr().err
    assert re.fullmatch(r'pendulum_campaign: error: campaign\.yaml: anchors and aliases '
                        r'expand to more than 10000 values \(line \d+\); write the values '
                        r'out\n', err), err
    assert not (tmp_path / 'out').exists()


def test_a_few_aliases_are_read_as_their_values() -> None:
    spec = parse_spec(PD.replace('target: 0.5', 'target: &t 0.4')
                      + 'parameters: {phi0: *t, gamma: [0.1, 0.2]}\n')
    assert spec.target == 0.4 and spec.parameters[0] == ('phi0', 0.4)


def test_the_scheduler_address_is_checked_before_anything_is_written(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / 'campaign.yaml'
    path.write_text(PD)
    assert main([str(path), '--out', str(tmp_path / 'out'), '--scheduler',
                 'not an address']) == 2
    assert capsys.readouterr().err == ('pendulum_campaign: error: --scheduler must be an '
                                       "address such as tcp://host:8786, got 'not an "
                                       "address'\n")
    assert not (tmp_path / 'out').exists()


def test_a_missing_key_and_a_missing_file_exit_2(tmp_path: Path) -> None:
    path = tmp_path / 'c.yaml'
    path.write_text('controller: pendulum_sim.testing.examples:pd\nepisodes: 3\nperiods: 5\n')
    proc = cli(str(path), '--out', str(tmp_path / 'out'))
    assert proc.returncode == 2
    assert proc.stderr == "pendulum_campaign: error: c.yaml: missing key 'target'\n"
    proc = cli(str(tmp_path / 'none.yaml'), '--out', str(tmp_path / 'out'))
    assert proc.returncode == 2
    assert proc.stderr == (f"pendulum_campaign: error: campaign file '{tmp_path / 'none.yaml'}'"
                           ' does not exist\n')


# ------------------------------------------------------------------ scenarios and episodes
def test_each_episode_draws_from_its_own_seed_whatever_ran_before() -> None:
    spec = parse_spec(FRAGILE.format(episodes=4000, periods=10))
    forward = [scenario(spec, i) for i in range(4000)]
    backward = [scenario(spec, i) for i in reversed(range(4000))][::-1]
    assert forward == backward
    phi0 = np.array([s['phi0'] for s in forward])
    noise = np.array([s['sensor.position_noise'] for s in forward])
    m = np.array([s['m'] for s in forward])
    assert phi0.min() >= 0.8 and phi0.max() < 2.2
    assert noise.min() >= 1e-6 and noise.max() < 1e-3
    # log-uniform: log10 is uniform on [-6, -3], mean -4.5, sd 3/sqrt(12); normal: mean, sd.
    n = phi0.size
    assert abs(np.log10(noise).mean() + 4.5) < 4 * (3 / math.sqrt(12)) / math.sqrt(n)
    assert abs(m.mean() - 0.2) < 4 * 0.005 / math.sqrt(n)
    assert abs(m.std() / 0.005 - 1.0) < 4 / math.sqrt(2 * n)
    assert [s['gamma'] for s in forward[:5]] == [0.05, 0.2, 1.0, 0.05, 0.2]
    # Another seed, other draws.
    other = parse_spec(FRAGILE.format(episodes=4, periods=10).replace('seed: 3', 'seed: 4'))
    assert scenario(other, 0)['phi0'] != forward[0]['phi0']


def test_a_controller_that_raises_or_answers_nan_fails_its_episode_with_the_reason(
        tmp_path: Path) -> None:
    from pendulum_sim.testing import closed_loop
    from pendulum_sim.testing.examples import pd  # what campaign_laws:fragile answers
    from pendulum_sim.testing.record import load_run

    text = FRAGILE.format(episodes=40, periods=300)
    rows = [run_episode(text, i, str(tmp_path)) for i in range(40)]
    reasons = {r['reason'].split(' at t = ')[0].split(' rad/s')[0] for r in rows
               if not r['passed']}
    raised = [r for r in rows if r['reason'].startswith('the controller raised RuntimeError: '
                                                        'velocity ')]
    nan = [r for r in rows if r['reason'].startswith('the controller returned nan at t = ')]
    assert raised and nan, reasons
    passed = [r for r in rows if r['passed']]
    assert passed and all(r['reason'] == '' and r['settling_time'] < 2.5 for r in passed)
    # Fast swings (large phi0) raise: the reason follows the physics, not the episode id.
    assert min(r['phi0'] for r in raised) > max(r['phi0'] for r in passed)
    # The run up to the fault is kept: its recording replays the states the law answered,
    # which are the same episode's states run without the fault, and the row's metrics are
    # that run's.
    spec = parse_spec(text)
    for r in raised + nan:
        fault_t = float(r['reason'].split(' at t = ')[1].split(' s')[0])
        run = load_run(tmp_path / 'failures' / f'episode-{r["episode"]:06d}.mcap')
        assert run.t.size >= 2 and run.t[-1] < fault_t and run.target == 0.5
        values = scenario(spec, r['episode'])
        whole = closed_loop(pd, scene=spec.scene, periods=run.t.size, overrides=values)
        for name in ('t', 'position', 'velocity', 'effort'):
            assert np.array_equal(getattr(run, name), getattr(whole, name)), name
        assert same_rows([{m: r[m] for m in METRIC_NAMES}], [run.metrics().as_dict()])


def test_the_scene_is_read_once_per_process(tmp_path: Path,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    from pendulum_sim.joint import scenes
    from pendulum_sim.testing import scene as test_scene
    from pendulum_sim.testing.campaign import episode

    reads: list[object] = []
    real = scenes.read_params_file

    def counted(path: Any) -> Any:
        reads.append(path)
        return real(path)

    monkeypatch.setattr(test_scene, 'read_params_file', counted)   # where the bench reads it
    episode.cached_spec.cache_clear()
    episode._scene.cache_clear()
    scene = tmp_path / 'scene.yaml'
    scene.write_text(scenes.find_scene('controller_test').read_text())
    text = (PD.replace('episodes: 4', 'episodes: 20') + f'scene: {scene}\n'
            + 'parameters: {gamma: {distribution: uniform, low: 0.1, high: 1.0}}\n')
    rows = [run_episode(text, i, None) for i in range(10)]
    rows += episode.run_episodes(text.replace('examples:pd', 'examples:pd_batch'),
                                 list(range(10, 20)), None)
    assert [r['episode'] for r in rows] == list(range(20)) and all(r['passed'] for r in rows)
    assert reads == [scene.resolve()]   # not once per episode


# ------------------------------------------------------------------ local runs, rerun, resume
@pytest.mark.slow
def test_a_campaign_writes_its_table_summary_figures_and_failing_recordings(
        tmp_path: Path) -> None:
    text = FRAGILE.replace("  - 'overshoot < 20'", "  - 'overshoot < 9'")
    path = campaign(tmp_path, episodes=10, periods=250, text=text)
    out = tmp_path / 'out'
    proc = cli(str(path), '--out', str(out), '--workers', '2')
    assert proc.returncode == 1, proc.stderr         # some episodes fail their requirements
    assert re.search(r'10/10 episodes, pass rate \d+\.\d %, ETA 0 s', proc.stderr)
    rows = table(out)
    assert [r['episode'] for r in rows] == list(range(10))
    import pyarrow.parquet as pq

    assert pq.read_table(out / 'episodes.parquet').column_names == [
        'episode', 'phi0', 'gamma', 'sensor.position_noise', 'm', 'inertia', 'target',
        *METRIC_NAMES,
        'passed', 'reason', *RUN_COLUMNS]
    assert (out / 'episodes.csv').read_text().splitlines()[0].startswith(
        'episode,phi0,gamma,sensor.position_noise,m,inertia,target,rise_time,')
    spec = parse_spec(path.read_text())
    for r in rows:
        assert same_rows([r], [{k: v for k, v in run_episode(spec.text, r['episode'],
                                                             None).items()
                                if k not in RUN_COLUMNS}])
    slow = [r for r in rows if not r['passed'] and r['reason'].startswith('overshoot = ')]
    assert slow
    summary = (out / 'summary.md').read_text()
    n_pass = sum(r['passed'] for r in rows)
    assert summary.startswith(f'# Campaign: 10 episodes, {n_pass} passed '
                              f'({100 * n_pass / 10:.1f} %)')
    assert (out / 'figures' / 'metric_distributions.png').stat().st_size > 0
    assert (out / 'figures' / 'pass_rate.png').stat().st_size > 0
    # The recording of a failing episode opens in pendulum_report closed-loop.
    mcap = out / 'failures' / f'episode-{slow[0]["episode"]:06d}.mcap'
    report = subprocess.run([str(BIN / 'pendulum_report'), 'closed-loop', str(mcap), '--out',
                             str(tmp_path / 'report')], capture_output=True, text=True)
    assert report.returncode == 0, report.stderr
    assert f'| overshoot | {slow[0]["overshoot"]:.6g} |' in (
        tmp_path / 'report' / 'summary.md').read_text()
    # --rerun reproduces an episode bit for bit, and says so when the stored one differs.
    again = cli('--rerun', str(out), str(slow[0]['episode']))
    assert again.returncode == 0
    assert again.stdout == (f'episode {slow[0]["episode"]} reproduced bit for bit (failed: '
                            f'{slow[0]["reason"]})\n')
    import sqlite3

    with sqlite3.connect(out / 'episodes.sqlite') as db:
        (text,) = db.execute('SELECT row FROM episodes WHERE episode = ?',
                             (slow[0]['episode'],)).fetchone()
        row = json.loads(text)
        row['overshoot'] = 1.0
        db.execute('UPDATE episodes SET row = ? WHERE episode = ?',
                   (json.dumps(row), slow[0]['episode']))
    db.close()
    again = cli('--rerun', str(out), str(slow[0]['episode']))
    assert again.returncode == 1
    assert again.stdout.startswith(f'episode {slow[0]["episode"]} differs from the stored '
                                   'result in overshoot (1.0 then, ')
    # A finished folder is not overwritten.
    proc = cli(str(path), '--out', str(out))
    assert proc.returncode == 2
    assert proc.stderr == (f"pendulum_campaign: error: --out '{out}' is not empty; use "
                           '--resume to continue the campaign in it\n')


def _alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


@pytest.mark.slow
def test_a_campaign_killed_half_way_and_resumed_has_every_episode_once(tmp_path: Path) -> None:
    path = campaign(tmp_path, episodes=40, periods=800)
    out = tmp_path / 'out'
    proc = subprocess.Popen([str(BIN / 'pendulum_campaign'), str(path), '--out', str(out),
                             '--workers', '1', '--no-progress'], start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    end = time.monotonic() + 120
    while len(stored(out)) < 10:
        assert proc.poll() is None and time.monotonic() < end, 'the campaign did not start'
        time.sleep(0.02)
    os.killpg(proc.pid, signal.SIGKILL)   # the campaign, its cluster and its workers at once
    proc.wait()
    end = time.monotonic() + 30
    while _alive(proc.pid):
        assert time.monotonic() < end
        time.sleep(0.05)
    before = stored(out)
    assert 10 <= len(before) < 40
    resumed = cli(str(path), '--out', str(out), '--resume', '--workers', '2')
    assert resumed.returncode in (0, 1), resumed.stderr
    rows = table(out)
    assert [r['episode'] for r in rows] == list(range(40))
    text = path.read_text()
    for r in rows:   # nothing lost, nothing repeated, nothing torn: each row is the episode's
        expected = {k: v for k, v in run_episode(text, r['episode'], None).items()
                    if k not in RUN_COLUMNS}
        assert same_rows([r], [expected])


def _cells(rows: list[dict[str, Any]]) -> list[list[tuple[str, type, str]]]:
    """Return each row's cells as (column, type, repr): equal only for the same values, of
    the same types, in the same order (NaN equal to NaN)."""
    return [[(k, type(v), repr(v)) for k, v in r.items()] for r in rows]


def test_the_rows_a_campaign_returns_are_those_its_store_reads_back(tmp_path: Path) -> None:
    # The rows run now are returned as stored, not decoded again: the same cells and types as
    # the JSON the store reads back (failed episodes with NaN metrics among them), also for
    # a resumed campaign whose earlier rows are read back.
    import sqlite3

    from pendulum_sim.testing.campaign.execute import run_campaign
    from pendulum_sim.testing.campaign.store import EpisodeStore

    spec = parse_spec(campaign(tmp_path, episodes=12, periods=200).read_text())
    out = tmp_path / 'out'
    rows = run_campaign(spec, out, workers=1, progress=False)
    assert any(not r['passed'] for r in rows) and any(r['passed'] for r in rows)
    assert any(math.isnan(r['settling_time']) for r in rows)
    store = EpisodeStore(out)
    assert _cells(rows) == _cells(store.rows())
    db = sqlite3.connect(out / 'episodes.sqlite')
    with db:
        db.execute('DELETE FROM episodes WHERE episode % 3 = 1')
    db.close()
    again = run_campaign(spec, out, workers=1, resume=True, progress=False)
    assert _cells(again) == _cells(store.rows())
    assert [r['episode'] for r in again] == list(range(12))
    store.close()


# ------------------------------------------------------------------ a real Dask cluster
@pytest.fixture
def dask_cluster(tmp_path: Path) -> Iterator[tuple[str, list[subprocess.Popen[bytes]]]]:
    """Start ``dask scheduler`` and two ``dask worker`` processes on 127.0.0.1.

    Yield the scheduler's address and the two worker processes (no nanny: the process is the
    worker, so a signal to it is a worker dying), with the campaign tutorial's Dask settings.
    """
    env = {**os.environ, 'DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED': 'False',
           'DASK_DISTRIBUTED__ADMIN__TICK__INTERVAL': '200ms'}
    with start_dask_cluster(tmp_path, nanny=False, env=env) as running:
        yield running.address, running.workers


def test_the_local_cluster_runs_without_the_profiler_and_with_slower_ticks() -> None:
    import dask
    import distributed  # its defaults join dask.config

    from pendulum_sim.testing.campaign.execute import make_client

    assert distributed.__version__
    assert dask.config.get('distributed.worker.profile.enabled') is True   # Dask's defaults
    assert dask.config.get('distributed.admin.tick.interval') == '20ms'
    client = make_client(None, 1)
    cluster = client.cluster
    try:
        assert list(client.run(worker_profiling).values()) == [False]
        assert list(client.run(worker_tick).values()) == [0.2]
        assert client.run_on_scheduler(scheduler_tick) == 0.2
    finally:
        client.close()
        cluster.close()


ROS_CAMPAIGN = f"""
controller: ['{PD_CONTROLLER}']
episodes: 2
seed: 11
periods: 80
target: 0.5
parameters:
  phi0: {{distribution: uniform, low: 0.7, high: 1.3}}
  gamma: [0.1, 0.5]
requirements: ['overshoot < 30']
"""


@pytest.mark.slow
@pytest.mark.ros
def test_a_campaign_on_a_dask_cluster_gets_exactly_the_local_table(
        tmp_path: Path, dask_cluster: tuple[str, list[subprocess.Popen[bytes]]]) -> None:
    address, _ = dask_cluster
    from distributed import Client

    with Client(address, timeout='30s') as client:   # the documented settings took effect
        assert list(client.run(worker_profiling).values()) == [False, False]
        assert list(client.run(worker_tick).values()) == [0.2, 0.2]
    path = campaign(tmp_path, episodes=50, periods=150)
    remote = cli(str(path), '--out', str(tmp_path / 'remote'), '--scheduler', address)
    local = cli(str(path), '--out', str(tmp_path / 'local'), '--workers', '2')
    assert remote.returncode == local.returncode == 1, remote.stderr + local.stderr
    a, b = table(tmp_path / 'remote'), table(tmp_path / 'local')
    assert len(a) == 50 and same_rows(a, b)
    assert {r['passed'] for r in a} == {True, False}
    # ROS episodes (the example controller as a command line) on the same cluster: each is
    # the in-process PD law's episode bit for bit.
    ros = tmp_path / 'ros.yaml'
    ros.write_text(ROS_CAMPAIGN)
    proc = cli(str(ros), '--out', str(tmp_path / 'ros'), '--scheduler', address)
    assert proc.returncode == 0, proc.stderr
    rows = table(tmp_path / 'ros')
    assert [r['episode'] for r in rows] == [0, 1] and all(r['passed'] for r in rows)
    in_process = ROS_CAMPAIGN.replace(f"['{PD_CONTROLLER}']", 'pendulum_sim.testing.examples:pd')
    for r in rows:
        twin = {k: v for k, v in run_episode(in_process, r['episode'], None).items()
                if k not in RUN_COLUMNS}
        assert same_rows([r], [twin])


def test_rerun_and_resume_refuse_a_folder_without_a_campaign(tmp_path: Path) -> None:
    proc = cli('--rerun', str(tmp_path), '3')
    assert proc.returncode == 2
    assert proc.stderr == (f"pendulum_campaign: error: --rerun: '{tmp_path}' holds no campaign "
                           '(campaign.yaml is missing)\n')
    path = campaign(tmp_path, episodes=3)
    proc = cli(str(path), '--out', str(tmp_path / 'none'), '--resume')
    assert proc.returncode == 2
    assert proc.stderr == (f"pendulum_campaign: error: --resume: '{tmp_path / 'none'}' holds "
                           'no campaign (campaign.yaml is missing)\n')


@pytest.mark.slow
def test_a_worker_killed_mid_campaign_has_its_episodes_rerun_on_another(
        tmp_path: Path, dask_cluster: tuple[str, list[subprocess.Popen[bytes]]]) -> None:
    address, workers = dask_cluster
    long = campaign(tmp_path, episodes=30, periods=800)
    out = tmp_path / 'killed'
    proc = subprocess.Popen([str(BIN / 'pendulum_campaign'), str(long), '--out', str(out),
                             '--scheduler', address, '--no-progress'],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    end = time.monotonic() + 120
    while len(stored(out)) < 4:
        assert proc.poll() is None and time.monotonic() < end, 'the campaign did not start'
        time.sleep(0.02)
    workers[0].kill()
    workers[0].wait()
    assert proc.poll() is None     # killed while the campaign ran ...
    assert len(stored(out)) < 30    # ... with episodes to go
    _, err = proc.communicate(timeout=300)
    assert proc.returncode in (0, 1), err
    rows = table(out)
    assert [r['episode'] for r in rows] == list(range(30))
    text = long.read_text()
    for r in rows:
        assert same_rows([r], [{k: v for k, v in run_episode(text, r['episode'], None).items()
                                if k not in RUN_COLUMNS}])


# ------------------------------------------------------------------ the earlier JSON layout
OLD = PD.replace('episodes: 4', 'episodes: 6') + 'parameters: {gamma: [0.1, 0.4, 1.0]}\n'


def json_layout(tmp: Path, episodes: range) -> tuple[Path, Path]:
    """Return a campaign file and a folder of the earlier layout holding ``episodes``."""
    path = tmp / 'campaign.yaml'
    path.write_text(OLD)
    out = tmp / 'old'
    (out / 'episodes').mkdir(parents=True)
    (out / 'campaign.yaml').write_text(OLD)
    for i in episodes:
        (out / 'episodes' / f'{i:06d}.json').write_text(json.dumps(run_episode(OLD, i, None)))
    return path, out


def test_a_folder_of_the_json_layout_resumes_into_the_database(tmp_path: Path) -> None:
    path, out = json_layout(tmp_path, range(4))
    (out / 'episodes' / '000004.4242.tmp').write_text('{"episode": 4, "rea')   # cut short
    proc = cli(str(path), '--out', str(out), '--resume', '--workers', '1', '--no-progress')
    assert proc.returncode == 0, proc.stderr
    assert stored(out) == list(range(6))
    assert not (out / 'episodes').exists()     # the rows moved, the leftover went
    rows = table(out)
    assert same_rows(rows, [{k: v for k, v in run_episode(OLD, i, None).items()
                             if k not in RUN_COLUMNS} for i in range(6)])


def test_a_cut_short_row_of_the_json_layout_is_refused_with_nothing_written(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path, out = json_layout(tmp_path, range(3))
    row = out / 'episodes' / '000002.json'
    row.write_text(row.read_text()[:40])
    before = sorted(p.name for p in out.rglob('*'))
    assert main([str(path), '--out', str(out), '--resume', '--no-progress']) == 2
    assert capsys.readouterr().err == (f"pendulum_campaign: error: '{row}' is not a whole "
                                       'episode row; delete it and --resume runs episode 2 '
                                       'again\n')
    assert sorted(p.name for p in out.rglob('*')) == before


FRICTION = """
controller: pendulum_sim.testing.examples:pd
scene: controller_test
episodes: 4
seed: 5
periods: 150
target: 0.5
parameters:
  friction: {distribution: uniform, low: 0.0, high: 0.6}
"""


def test_a_campaign_draws_the_friction_and_the_joint_feels_it(tmp_path: Path) -> None:
    """friction is a physical parameter like the others: drawn per episode, in its row, and the
    episode's joint runs under it (the drawn value's run is closed_loop's with it, to the bit,
    and differs from the run without friction)."""
    from pendulum_sim.testing import closed_loop
    from pendulum_sim.testing.examples import pd

    spec = parse_spec(FRICTION)
    drawn = [float(scenario(spec, i)['friction']) for i in range(4)]  # type: ignore[arg-type]
    assert all(0.0 <= f <= 0.6 for f in drawn) and len(set(drawn)) == 4
    rows = [run_episode(FRICTION, i, str(tmp_path)) for i in range(2)]
    assert [r['friction'] for r in rows] == drawn[:2]
    with_f = closed_loop(pd, scene=spec.scene, periods=150, overrides={'friction': drawn[0]},
                         target=0.5)
    without = closed_loop(pd, scene=spec.scene, periods=150, overrides={'friction': 0.0},
                          target=0.5)
    assert same_rows([{m: rows[0][m] for m in METRIC_NAMES}], [with_f.metrics().as_dict()])
    assert not np.array_equal(with_f.position, without.position)
