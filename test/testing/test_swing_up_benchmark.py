"""The swing-up benchmark: the reference controllers, the criteria as campaigns on a real Dask
cluster, the region of attraction against bounds worked out by hand, and bad input."""
from __future__ import annotations

import csv
import math
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import yaml
from dask_harness import dask_cluster as start_dask_cluster

from pendulum_sim.controller import swing_up_law
from pendulum_sim.core.jit_cache import ENV_VAR as JIT_CACHE
from pendulum_sim.joint.parameters import joint_config
from pendulum_sim.testing import BenchmarkResult, benchmark, closed_loop
from pendulum_sim.testing.batch import batchable
from pendulum_sim.testing.campaign.spec import parse_spec
from pendulum_sim.testing.errors import BenchmarkError
from pendulum_sim.testing.examples import (
    SWING_UP,
    energy_lqr,
    lqr_balance,
    reference_balance,
    saturated_pd,
)
from pendulum_sim.testing.scene import scene_values
from pendulum_sim.testing.swing_up.criteria import CRITERIA, Settings, bodies, campaign_text
from pendulum_sim.testing.swing_up.criteria import torque_limit as limit_of

HERE = Path(__file__).resolve().parents[1] / 'support'   # campaign_laws.py, for workers
BALANCE = reference_balance()
PI = math.pi
BIN = Path(sys.executable).parent


# ------------------------------------------------------------------ the reference controllers
@pytest.mark.parametrize('law', [energy_lqr, saturated_pd])
def test_the_swing_up_scene_limits_the_torque_to_half_of_m_g_l(law: object) -> None:
    run = closed_loop(law, scene='swing_up', periods=2000)   # type: ignore[arg-type]
    p = run.parameters
    mgl = float(p['m']) * float(p['g']) * float(p['l'])
    assert run.max_effort == pytest.approx(mgl / 2, rel=1e-15)
    assert (p['phi0'], p['dphi0'], p['publish_rate'], p['h']) == (0.0, 0.0, 200.0, 0.001)
    assert np.max(np.abs(run.effort)) <= run.max_effort


def test_energy_shaping_with_lqr_swings_up_and_balances_under_half_of_m_g_l() -> None:
    run = closed_loop(energy_lqr, scene='swing_up', periods=2000)
    m = run.swing_up_metrics()
    assert m.success and m.stays and m.swing_up_time < 6.0
    assert m.saturation_fraction > 0.1   # it had to pump: the limit is below gravity's torque
    # It ends upright at rest: within a hundredth of the box, the torque near zero.
    assert abs(math.remainder(run.position[-1] - PI, 2 * PI)) < 1e-3
    assert abs(run.velocity[-1]) < 1e-3 and abs(run.effort[-1]) < 1e-2
    # The energy rose to upright's 2 m g l (eq 23) and the joint holds it there.
    energy = 0.5 * 0.2002 * run.velocity ** 2 + 1.96 * (1 - np.cos(run.position))
    assert energy[0] == 0.0 and energy[-1] == pytest.approx(2 * 1.96, rel=1e-4)


def test_the_saturated_pd_cannot_lift_the_pendulum_from_hanging() -> None:
    """The contrast: a PD saturated below m g l holds still where gravity's torque equals its
    limit, short of the horizontal, so it never gets near upright."""
    run = closed_loop(saturated_pd, scene='swing_up', periods=2000)
    assert not run.swing_up_metrics().success
    assert np.max(np.abs(run.position)) < PI / 2


def test_the_lqr_gain_solves_the_riccati_equation_with_or_without_python_control(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    a, b = SWING_UP.linearised()
    q, r = np.diag(SWING_UP.q), np.array([[SWING_UP.r]])
    monkeypatch.setenv(JIT_CACHE, str(tmp_path / 'with'))   # solved here, not read back
    k, s = swing_up_law.lqr(a, b, q, r)
    # The continuous algebraic Riccati equation and K = R^-1 B^T S.
    residual = a.T @ s + s @ a - s @ b @ np.linalg.solve(r, b.T @ s) + q
    assert np.abs(residual).max() < 1e-10
    np.testing.assert_allclose(k, np.linalg.solve(r, b.T @ s), rtol=1e-12)
    assert np.all(np.linalg.eigvals(a - b @ k).real < 0)
    monkeypatch.setitem(sys.modules, 'control', None)   # python-control not installed
    monkeypatch.setenv(JIT_CACHE, str(tmp_path / 'without'))
    k2, s2 = swing_up_law.lqr(a, b, q, r)
    np.testing.assert_allclose(k2, k, rtol=1e-9)
    np.testing.assert_allclose(s2, s, rtol=1e-9)


LQR_IN_A_PROCESS = """
import json, sys
import numpy as np
from pendulum_sim.controller import swing_up_law
from pendulum_sim.testing.examples import SWING_UP
a, b = SWING_UP.linearised()
k, s = swing_up_law.lqr(a, b, np.diag(SWING_UP.q), np.array([[SWING_UP.r]]))
print(json.dumps([[x.hex() for x in k.reshape(-1).tolist()],
                  [x.hex() for x in s.reshape(-1).tolist()], 'control' in sys.modules]))
"""


def test_a_later_process_reads_the_lqr_gain_from_disk_without_python_control(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """The first process solves with python-control and keeps (K, S) on disk; the next reads
    them, to the bit, and never imports python-control; a corrupt file is solved again."""
    monkeypatch.setenv(JIT_CACHE, str(tmp_path))
    env = dict(os.environ)

    def solve() -> list[object]:
        done = subprocess.run([sys.executable, '-c', LQR_IN_A_PROCESS], env=env, check=True,
                              capture_output=True, text=True, timeout=120)
        return list(yaml.safe_load(done.stdout))

    a, b = SWING_UP.linearised()
    q, r = np.diag(SWING_UP.q), np.array([[SWING_UP.r]])
    # The oracle: python-control's lqr itself, in this process.
    import control  # type: ignore[import-untyped]

    gain, riccati, _ = control.lqr(a, b, q, r)
    expected = [[x.hex() for x in np.asarray(gain).reshape(-1).tolist()],
                [x.hex() for x in np.asarray(riccati).reshape(-1).tolist()]]
    first = solve()
    assert first == [*expected, True]
    kept = swing_up_law.lqr_cache_file(a, b, q, r)
    assert kept is not None and kept.parent.parent == tmp_path and kept.is_file()
    assert solve() == [*expected, False]
    kept.write_text('{"gain": ["0x1.0p+0"', encoding='utf-8')   # cut short
    assert solve() == [*expected, True]
    assert solve() == [*expected, False]
    # Another problem (here R) is another file.
    assert swing_up_law.lqr_cache_file(a, b, q, 2.0 * r) != kept


def test_the_ellipse_is_the_largest_level_set_where_the_torque_does_not_saturate() -> None:
    from pendulum_sim.testing.swing_up.figures import ellipse_points

    phi, rate = ellipse_points(BALANCE.region, 4000)
    torque = BALANCE.gain[0] * (phi - PI) + BALANCE.gain[1] * rate
    assert np.max(np.abs(torque)) == pytest.approx(SWING_UP.max_effort, rel=1e-5)
    assert BALANCE.region.area() == pytest.approx(
        PI * BALANCE.region.level / math.sqrt(np.linalg.det(BALANCE.riccati)), rel=1e-15)
    assert BALANCE.region.contains(PI + 2 * PI, 0.0) and not BALANCE.region.contains(0.0, 0.0)


# ------------------------------------------------------------------ the criteria
def settings(**changes: object) -> Settings:
    from pendulum_sim.testing.scene import read_scene

    base: dict[str, object] = {'controller': 'pendulum_sim.testing.examples:energy_lqr',
                               'episodes': 7}
    base.update(changes)
    return Settings(base=read_scene('swing_up'), **base)  # type: ignore[arg-type]


def test_each_criterion_is_a_campaign_of_the_swing_up_task() -> None:
    s = settings()
    for criterion in CRITERIA:
        spec = parse_spec(campaign_text(s, criterion))
        assert (spec.task, spec.target, spec.periods) == ('swing_up', PI, 2000)
        assert [str(r) for r in spec.requirements] == ['stays == 1']
    roa = parse_spec(campaign_text(s, 'roa'))
    assert roa.episodes == 2500
    from pendulum_sim.testing.campaign.scenarios import scenario

    corners = [scenario(roa, i) for i in (0, 49, 50, 2499)]
    cell = (2 * PI / 50, 6 * PI / 50)
    assert corners[0] == pytest.approx({'phi0': cell[0] / 2, 'dphi0': -3 * PI + cell[1] / 2})
    assert corners[1]['phi0'] == pytest.approx(2 * PI - cell[0] / 2)
    assert corners[2]['dphi0'] == pytest.approx(-3 * PI + 1.5 * cell[1])
    assert corners[3] == pytest.approx({'phi0': 2 * PI - cell[0] / 2,
                                        'dphi0': 3 * PI - cell[1] / 2})


def test_the_sensitivity_bodies_are_rigid_and_the_pulses_are_batched() -> None:
    s = settings(episodes=50)
    drawn = bodies(s)
    for m, length, inertia in zip(drawn['m'], drawn['l'], drawn['inertia'], strict=True):
        assert inertia - m * length ** 2 == pytest.approx(0.2002 - 0.2, abs=1e-12)
    assert 0.18 <= min(drawn['m']) < max(drawn['m']) <= 0.22
    spec = parse_spec(campaign_text(s, 'robustness'))
    from pendulum_sim.testing.campaign.scenarios import scenario

    values = scene_values('swing_up', scenario(spec, 3))
    pulses = joint_config(values).all_pulses
    assert [p.start_step for p in pulses] == [500, 2000, 3500, 5000]
    assert all(p.steps == 1000 and abs(p.torque) <= 0.49 for p in pulses)
    assert batchable(values) == ''   # on 5 ms periods: the batch steps them
    assert limit_of(s) == 0.98


# ------------------------------------------------------------------ on a real Dask cluster
@pytest.fixture(scope='module')
def cluster(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """A scheduler and two workers on 127.0.0.1 that import test/campaign_laws.py."""
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join([str(HERE), *filter(None, [env.get('PYTHONPATH')])])
    with start_dask_cluster(tmp_path_factory.mktemp('dask'), 2, env=env) as running:
        yield running.address


def episodes(folder: Path) -> dict[str, np.ndarray]:
    """Return a campaign's ``episodes.csv`` as columns of strings."""
    with (folder / 'episodes.csv').open(encoding='utf-8') as fh:
        rows = list(csv.DictReader(fh))
    return {name: np.array([r[name] for r in rows]) for name in rows[0]}


def energy_like(x: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """Return H = ½ I φ'² + m g l (cos x − 1) + τ_max |x| (x from upright, wrapped)."""
    return (0.5 * SWING_UP.inertia * rate ** 2 + SWING_UP.mgl * (np.cos(x) - 1)
            + SWING_UP.max_effort * np.abs(x))


def test_the_region_of_attraction_of_the_lqr_balance_lies_within_its_bounds(
        tmp_path: Path, cluster: str) -> None:
    """The LQR balance alone near upright, mapped by a campaign on the cluster.

    Inner bound: the linearised estimate, the ellipse where the torque does not saturate.
    Outer bound, worked out by hand: with x = wrap(φ − π) and the torque saturated at τ_max
    away from upright, H = ½ I φ'² + m g l (cos x − 1) + τ_max |x| never grows for |x| > π/6
    (dH/dt = −γ I φ'² + (τ + τ_max sgn x) φ', and τ = −τ_max sgn x whenever x φ' > 0 there),
    and its hump between upright and the fall, at |x| = π/6 where m g l sin x = τ_max, is
    H* = m g l (cos π/6 − 1) + τ_max π/6. A start beyond |x| = π/6 with H < H* never gets
    back over it, so never reaches the goal box.
    """
    span = ((PI - 1.2, PI + 1.2), (-3.0, 3.0))
    result = benchmark('pendulum_sim.testing.examples:lqr_balance', out=tmp_path / 'out',
                       criteria=('nominal', 'roa'), roa_grid=16, roa_span=span, duration=4.0,
                       scheduler=cluster)
    assert isinstance(result, BenchmarkResult)
    rows = yaml.safe_load((tmp_path / 'out' / 'benchmark.yaml').read_text())
    table = episodes(tmp_path / 'out' / 'campaigns' / 'roa')
    phi, rate = table['phi0'].astype(float), table['dphi0'].astype(float)
    passed = table['passed'] == 'true'
    inner = BALANCE.region.contains(phi, rate)
    x = phi - PI
    hump = SWING_UP.mgl * (math.cos(PI / 6) - 1) + SWING_UP.max_effort * PI / 6
    outer = (np.abs(x) > PI / 6 + 0.05) & (energy_like(x, rate) < hump - 0.02)
    assert inner.sum() >= 4 and outer.sum() >= 20      # both bounds are tested
    assert passed[inner].all() and not passed[outer].any()
    assert 0 < passed.sum() < passed.size
    cell = 2.4 / 16 * 6.0 / 16
    assert rows['roa_area'] == pytest.approx(passed.sum() * cell, rel=1e-12)
    assert rows['criteria']['roa']['cell_area'] == pytest.approx(cell, rel=1e-12)
    # The nominal start hangs: the balance alone cannot swing up.
    assert rows['swing_up_time'] == math.inf and rows['criteria']['nominal']['swung_up'] == 0
    assert rows['frequency'] > 0
    for name in ('roa.png', 'benchmark.png', 'swing_up.gif'):
        assert (tmp_path / 'out' / name).stat().st_size > 1000
    # Each cell is the closed loop of its start state, as run in this process.
    for i in (0, int(np.flatnonzero(inner)[0]), int(np.flatnonzero(outer)[0])):
        run = closed_loop(lqr_balance, scene='swing_up', periods=800,
                          overrides={'phi0': float(phi[i]), 'dphi0': float(rate[i])})
        assert run.swing_up_metrics().stays == passed[i]


def test_the_command_line_benchmarks_a_law_and_fails_bad_episodes_alone(
        tmp_path: Path, cluster: str) -> None:
    """Episodes whose law answers NaN or raises fail with their reason; the benchmark runs."""
    out = tmp_path / 'out'
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join([str(HERE), *filter(None, [env.get('PYTHONPATH')])])
    res = subprocess.run(
        [str(BIN / 'pendulum_benchmark'), 'campaign_laws:brittle_swing_up', '--out', str(out),
         '--criteria', 'nominal,consistency,torque_limit', '--episodes', '12', '--limits',
         '4', '--duration', '6', '--seed', '5', '--scheduler', cluster, '--no-progress'],
        capture_output=True, text=True, env=env, timeout=600, check=False)
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert lines[0].split() == ['criterion', 'value', 'unit', 'from']
    assert [line.split()[0] for line in lines[1:]] == [
        'swing_up_time', 'energy', 'smoothness', 'consistency', 'robustness', 'sensitivity',
        'min_torque_limit', 'frequency', 'roa_area']
    doc = yaml.safe_load((out / 'benchmark.yaml').read_text())
    consistency = doc['criteria']['consistency']
    # Starts faster than 8 rad/s make the law answer NaN at once: those episodes fail alone.
    table = episodes(out / 'campaigns' / 'consistency')
    fast = np.abs(table['dphi0'].astype(float)) > 8.0
    assert fast.any() and not fast.all()
    assert consistency['failed'] >= int(fast.sum())
    assert all(r.startswith('the controller ') for r in consistency['reasons'])
    assert doc['consistency'] == pytest.approx(100.0 * consistency['swung_up'] / 12)
    assert consistency['swung_up'] <= 12 - int(fast.sum())
    assert doc['robustness'] is None and doc['roa_area'] is None
    assert doc['min_torque_limit'] in [0.98 * k / 4 for k in range(1, 5)]


@pytest.mark.parametrize(('args', 'message'), [
    (['--criteria', 'nominal,speed'], "unknown criterion 'speed'; criteria: nominal, "
     'consistency, robustness, sensitivity, torque_limit, roa'),
    (['--goal-box', '0', '0.1'], 'goal box: box[0] (rad) must be a finite number > 0, got 0.0'),
    (['--goal-box', '0.1', '-1'],
     'goal box: box[1] (rad/s) must be a finite number > 0, got -1.0'),
    (['--torque-limit', '0'], 'torque limit must be a finite number of N m > 0, got 0.0'),
    (['--task', 'balance'], "unknown task 'balance'; tasks: swing_up"),
    (['--criteria', 'roa,nominal,roa'], "criterion 'roa' is given twice"),
    (['--criteria', ','], 'no criterion to run; criteria: nominal, consistency, robustness, '
     'sensitivity, torque_limit, roa'),
    (['--scene', 'nosuch'], "unknown scene 'nosuch'; known scenes: "),
])
def test_impossible_input_exits_2_with_one_line_and_writes_nothing(
        tmp_path: Path, args: list[str], message: str) -> None:
    out = tmp_path / 'out'
    res = subprocess.run([str(BIN / 'pendulum_benchmark'),
                          'pendulum_sim.testing.examples:energy_lqr', '--out', str(out), *args],
                         capture_output=True, text=True, timeout=120, check=False)
    assert res.returncode == 2
    assert res.stderr.startswith(f'pendulum_benchmark: error: {message}')
    assert res.stderr.count('\n') == 1 and res.stdout == ''
    assert not out.exists()


def test_a_scene_without_torque_is_refused_and_a_used_folder_too(tmp_path: Path) -> None:
    scene = tmp_path / 'limp.yaml'
    scene.write_text('/**:\n  ros__parameters:\n    max_effort: 0.0\n')
    with pytest.raises(BenchmarkError, match=r"^the swing-up task needs a torque limit > 0 N m; "
                       r"scene '.*limp.yaml' has max_effort = 0$"):
        benchmark(energy_lqr, out=tmp_path / 'a', scene=str(scene))
    (tmp_path / 'b').mkdir()
    (tmp_path / 'b' / 'x').write_text('')
    with pytest.raises(BenchmarkError, match=r"^--out '.*b' is not empty; use --resume to "
                       r'continue the benchmark in it$'):
        benchmark(energy_lqr, out=tmp_path / 'b')
    with pytest.raises(BenchmarkError, match=r"^--resume: '.*c' holds no benchmark"):
        benchmark(energy_lqr, out=tmp_path / 'c', resume=True)
    assert not (tmp_path / 'a').exists() and not (tmp_path / 'c').exists()


# ------------------------------------------------------------------ animations
def test_the_gif_shows_the_runs_frames_in_real_time(tmp_path: Path) -> None:
    from PIL import Image

    from pendulum_sim.frames import frame
    from pendulum_sim.testing.swing_up.animation import frame_indices, write_gif

    run = closed_loop(energy_lqr, scene='swing_up', periods=400)   # 2 s
    path = write_gif(run, tmp_path / 'run.gif', goal=PI, fps=10, size=64)
    index = frame_indices(run.t, 10)
    assert index.tolist() == [round(k * 20) for k in range(20)]   # 10 frames a second
    with Image.open(path) as gif:
        assert gif.info['duration'] == 100 and gif.info['loop'] == 0
        shown = []
        for k in range(gif.n_frames):
            gif.seek(k)
            shown.append(np.asarray(gif.convert('RGB')))
    # Each frame is the environments' frame of its sample (equal frames are merged in a GIF).
    want = [frame(float(run.position[i]), float(run.effort[i]), 0.98, PI, size=64)
            for i in index]
    merged = [w for k, w in enumerate(want) if k == 0 or not np.array_equal(w, want[k - 1])]
    assert len(shown) == len(merged) and all(
        np.array_equal(a, b) for a, b in zip(shown, merged, strict=True))


@pytest.mark.ros
def test_pendulum_report_animates_a_recording(tmp_path: Path) -> None:
    from PIL import Image

    from pendulum_sim.testing.record import write_run

    run = closed_loop(energy_lqr, scene='swing_up', periods=300).with_target(PI)
    write_run(run, tmp_path / 'run.mcap')
    gif = tmp_path / 'run.gif'
    cmd = [str(BIN / 'pendulum_report'), 'animate', str(tmp_path / 'run.mcap'), '--out',
           str(gif), '--fps', '20', '--size', '48']
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=False)
    assert res.returncode == 0, res.stderr
    assert res.stderr == f'wrote {gif} (1.495 s of the run)\n'
    with Image.open(gif) as image:
        assert image.size == (48, 48) and image.info['duration'] == 50
    again = subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=False)
    assert (again.returncode, again.stderr) == (
        2, f"pendulum_report animate: error: --out '{gif}' exists; --force replaces it\n")


# ------------------------------------------------------------------ the reference as a ROS node
@pytest.mark.ros
def test_the_swing_up_node_answers_as_the_in_process_law_bit_for_bit() -> None:
    """pendulum_swing_up_controller against pendulum_node over DDS, in synchronous lockstep."""
    node = closed_loop([str(BIN / 'pendulum_swing_up_controller')], scene='swing_up',
                       periods=900)
    local = closed_loop(energy_lqr, scene='swing_up', periods=900)
    for name in ('t', 'position', 'velocity', 'effort', 'command'):
        assert getattr(node, name).tobytes() == getattr(local, name).tobytes(), name
    assert node.swing_up_metrics().success   # it is up within 4.5 s


@pytest.mark.ros
def test_the_swing_up_node_refuses_bad_parameters_with_one_line() -> None:
    res = subprocess.run([str(BIN / 'pendulum_swing_up_controller'), '--ros-args', '-p',
                          'max_effort:=0.0'], capture_output=True, text=True, timeout=60,
                         check=False)
    assert res.returncode == 2
    assert 'pendulum_swing_up_controller: max_effort must be a finite number > 0, got 0.0' \
        in res.stderr


def test_an_interrupted_benchmark_resumes_with_the_same_results(tmp_path: Path,
                                                                cluster: str) -> None:
    """Episodes lost to an interruption run again on --resume; the finished ones are kept."""
    import sqlite3

    out = tmp_path / 'out'
    kwargs: dict[str, object] = {'criteria': ('nominal', 'torque_limit'), 'limits': 4,
                                 'duration': 5.0, 'scheduler': cluster, 'figures': False,
                                 'gif': False}
    first = benchmark('pendulum_sim.testing.examples:energy_lqr', out=out, **kwargs)
    store = out / 'campaigns' / 'torque_limit' / 'episodes.sqlite'
    with sqlite3.connect(store) as db:   # as if the run had stopped before these ended
        db.execute('DELETE FROM episodes WHERE episode >= 2')
    (out / 'benchmark.yaml').unlink()
    with pytest.raises(BenchmarkError, match='is not empty; use --resume'):
        benchmark('pendulum_sim.testing.examples:energy_lqr', out=out, **kwargs)
    again = benchmark('pendulum_sim.testing.examples:energy_lqr', out=out, resume=True,
                      **kwargs)
    assert {k: v for k, v in again.values.items() if k != 'frequency'} == {
        k: v for k, v in first.values.items() if k != 'frequency'}
    assert again.criteria == first.criteria
    with sqlite3.connect(store) as db:
        assert db.execute('SELECT COUNT(*) FROM episodes').fetchone() == (4,)


def test_a_gymnasium_policy_is_benchmarked_through_policy_law(tmp_path: Path,
                                                              cluster: str) -> None:
    """policy_law's law of a batched policy runs in the benchmark, batched; its nominal
    figures are the metrics DampedPendulum-v0's info gives the same episode at its end."""
    from pendulum_sim.gym import DampedPendulumEnv
    from pendulum_sim.gym.examples import energy_swing_up_batch

    result = benchmark('pendulum_sim.gym.examples:energy_swing_up_batch_law',
                       out=tmp_path / 'out', criteria=('nominal', 'consistency'), episodes=6,
                       duration=5.0, scheduler=cluster, figures=False, gif=False)
    assert result.criteria['nominal']['swung_up'] == 1
    table = episodes(tmp_path / 'out' / 'campaigns' / 'consistency')
    assert result.values['consistency'] == pytest.approx(
        100.0 * np.mean(table['passed'] == 'true'), rel=1e-12)
    periods = 1000   # 5 s at 200 Hz
    env = DampedPendulumEnv(scene='swing_up', max_episode_steps=periods - 1,
                            parameters={'phi0': 0.0, 'dphi0': 0.0, 'max_effort': 0.98})
    obs, _ = env.reset(seed=0)
    truncated = False
    while not truncated:
        obs, _, _, truncated, info = env.step(energy_swing_up_batch(obs[np.newaxis])[0])
    assert info['stays'] and 2.0 < info['swing_up_time'] < 4.0
    for key in ('swing_up_time', 'energy', 'smoothness'):
        assert result.values[key] == info[key], key
