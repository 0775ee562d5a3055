"""Batched episodes: a vectorised law on N joints in lockstep decides as the scalar joint."""
from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pendulum_sim.core.jit import available as jit_available
from pendulum_sim.joint.lockstep import LockstepStats
from pendulum_sim.testing import TestingError, vectorised
from pendulum_sim.testing.batch import BatchStats, batchable, run_batch
from pendulum_sim.testing.campaign.episode import RUN_COLUMNS, run_episode, run_episodes
from pendulum_sim.testing.campaign.spec import parse_spec
from pendulum_sim.testing.errors import CampaignError
from pendulum_sim.testing.examples import pd, pd_batch
from pendulum_sim.testing.loop import ClosedLoopRun, run_in_process
from pendulum_sim.testing.scene import scene_values

FIELDS = ('t', 'position', 'velocity', 'effort', 'command')


def scenarios(count: int, seed: int = 5) -> list[dict[str, Any]]:
    """Episodes over every damping law the core has: dry, viscous, fractional, quadratic."""
    rng = np.random.default_rng(seed)
    return [scene_values('controller_test', {
        'gamma': float(rng.uniform(0.05, 1.5)), 'n': float(rng.choice([0.0, 1.0, 1.5, 2.0])),
        'phi0': float(rng.uniform(-2.0, 2.5)), 'dphi0': float(rng.uniform(-1.0, 1.0)),
        'm': float(rng.uniform(0.15, 0.2)), 'max_effort': float(rng.uniform(1.0, 6.0))})
        for _ in range(count)]


def scalar(t: float, position: float, velocity: float) -> float:
    return float(pd_batch(t, np.array([position]), np.array([velocity]))[0])


def assert_the_scalar_run(values: dict[str, Any], got: Any) -> ClosedLoopRun:
    """Assert that a batched run is the scalar joint's (bytes for integer n); return that."""
    assert isinstance(got, ClosedLoopRun)
    want = run_in_process(scalar, values, 300)
    for name in FIELDS:
        if values['n'] == int(values['n']):
            assert getattr(got, name).tobytes() == getattr(want, name).tobytes(), name
        else:
            assert np.max(np.abs(getattr(got, name) - getattr(want, name))) <= 1e-12
    return want


def test_vectorised_sets_the_flag_and_keeps_the_law() -> None:
    def law(t: float, p: Any, v: Any) -> Any:
        return -p

    assert vectorised(law) is law and law.vectorised is True  # type: ignore[attr-defined]
    assert getattr(pd, 'vectorised', False) is False


def test_the_numpy_law_is_the_example_controllers_law_to_round_off() -> None:
    rng = np.random.default_rng(0)
    p, v = rng.uniform(-7, 7, 2000), rng.uniform(-5, 5, 2000)
    batch = pd_batch(0.0, p, v)
    # numpy's sin and remainder against math's: the same law, the last bits apart.
    scalar_law = np.array([pd(0.0, a, b) for a, b in zip(p, v, strict=True)])
    assert np.max(np.abs(batch - scalar_law)) <= 1e-13


def test_a_batch_gives_each_episode_the_scalar_joints_run() -> None:
    """Bit for bit for the integer damping laws; to round-off for fractional n.

    For n = 1.5 numpy's |φ'|^n and the C library's pow (the Stepper's) may differ in the last
    bit, and the difference then stays at round-off in the stable loop; every decision (the
    saturation, the guard's) is the same.
    """
    episodes = scenarios(48)
    runs = run_batch(pd_batch, episodes, 300)
    saturated = 0
    for values, got in zip(episodes, runs, strict=True):
        want = assert_the_scalar_run(values, got)
        np.testing.assert_array_equal(np.abs(got.effort) == values['max_effort'],
                                      np.abs(want.effort) == values['max_effort'])
        saturated += int(np.any(np.abs(got.effort) == values['max_effort']))
    assert saturated > 0      # the saturation decision was exercised, and taken the same way
    # A batch's episodes do not depend on the batch: each alone gives the same bytes.
    alone = run_batch(pd_batch, episodes[:3], 300)
    for a, b in zip(alone, runs[:3], strict=True):
        assert isinstance(a, ClosedLoopRun) and isinstance(b, ClosedLoopRun)
        assert a.position.tobytes() == b.position.tobytes()


def test_a_batch_takes_the_joints_coulomb_friction_as_the_scalar_joint() -> None:
    """A friction torque beside the law (issue 26) in the batch: each episode the scalar joint's
    run, bit for bit for the integer laws, sticking where it sticks (φ' exactly 0)."""
    rng = np.random.default_rng(9)
    episodes = [dict(values, friction=float(rng.uniform(0.05, 0.4)))
                for values in scenarios(24, seed=8)]
    runs = run_batch(pd_batch, episodes, 300)
    stuck = 0
    for values, got in zip(episodes, runs, strict=True):
        assert_the_scalar_run(values, got)
        stuck += int(np.count_nonzero(got.velocity == 0.0) > 1)
    assert stuck > 0   # the friction held some joints at rest, in the batch as alone
    # Without the friction the same episodes end elsewhere: the batch did not drop it.
    bare = run_batch(pd_batch, [dict(v, friction=0.0) for v in episodes], 300)
    assert all(isinstance(a, ClosedLoopRun) and isinstance(b, ClosedLoopRun)
               and a.position[-1] != b.position[-1] for a, b in zip(bare, runs, strict=True))


def test_episodes_the_batch_cannot_follow_go_to_the_scalar_joint() -> None:
    noisy = scene_values('controller_test', {'sensor.position_noise': 1e-3})
    delayed = scene_values('controller_test', {'command_delay': 0.003})
    fast = scene_values('controller_test', {'max_velocity': 0.5})   # the joint cuts torque
    plain = scene_values('controller_test', {})
    assert batchable(noisy) == 'the sensor is not ideal'
    assert batchable(delayed) == 'command_delay is not 0'
    assert batchable(plain) == ''
    runs = run_batch(pd_batch, [noisy, delayed, fast, plain], 200)
    for values, got in zip([noisy, delayed, fast, plain], runs, strict=True):
        assert isinstance(got, ClosedLoopRun)
        want = run_in_process(scalar, values, 200)
        assert got.position.tobytes() == want.position.tobytes()


@vectorised
def nan_when_low(t: float, p: Any, v: Any) -> Any:
    out = pd_batch(t, p, v)
    return np.where(p < 0.45, math.nan, out)


@vectorised
def wrong_shape(t: float, p: Any, v: Any) -> Any:
    return np.zeros(3)


def test_a_nan_answer_fails_only_its_episode_with_the_scalar_reason() -> None:
    episodes = [scene_values('controller_test', {'phi0': x}) for x in (0.6, 1.6)]
    runs = run_batch(nan_when_low, episodes, 300)
    assert isinstance(runs[0], ClosedLoopRun)
    assert isinstance(runs[1], TestingError)
    with pytest.raises(TestingError) as scalar_failure:
        run_in_process(lambda t, p, v: float(nan_when_low(t, np.array([p]),
                                                          np.array([v]))[0]),
                       episodes[1], 300)
    assert str(runs[1]) == str(scalar_failure.value)
    assert str(runs[1]).startswith('the controller returned nan at t = ')
    # Both keep the run up to the fault, the same one.
    batched, scalar = runs[1].run, scalar_failure.value.run   # type: ignore[union-attr]
    assert isinstance(batched, ClosedLoopRun) and isinstance(scalar, ClosedLoopRun)
    assert batched.t.size == scalar.t.size > 2
    for name in ('t', 'position', 'velocity', 'effort', 'command'):
        assert np.array_equal(getattr(batched, name), getattr(scalar, name)), name
    with pytest.raises(TestingError, match=re.escape(
            'a vectorised law must answer one command per state: got shape (3,) for 2 states')):
        run_batch(wrong_shape, episodes, 5)


@vectorised
def strings(t: float, position: Any, velocity: Any) -> Any:
    """Answer the example torques as strings after 0.1 s ('0.5' reads as a number)."""
    tau = pd_batch(t, position, velocity)
    return tau.astype(str) if t > 0.1 else tau


def test_a_string_answer_is_refused_by_the_batch_as_by_the_scalar_joint() -> None:
    episodes = [scene_values('controller_test', {'phi0': x}) for x in (0.6, 1.6)]
    runs = run_batch(strings, episodes, 50)
    assert all(isinstance(r, TestingError) for r in runs)
    assert [re.sub(r"'[^']*'", "'…'", str(r)) for r in runs] == [
        "the controller returned '…' at t = 0.11 s; a command is a number"] * 2


CAMPAIGN = """
controller: pendulum_sim.testing.examples:{law}
episodes: 24
seed: 9
periods: 250
target: 0.5
parameters:
  gamma: {{distribution: loguniform, low: 0.02, high: 2.0}}
  n: [1.0, 2.0, 0.0]
  phi0: {{distribution: uniform, low: 0.6, high: 1.6}}
requirements: ['settling_time < 2.0']
"""


def test_a_batched_campaign_has_the_rows_of_the_scalar_episodes(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[1] / 'support'))
    text = CAMPAIGN.format(law='pd_batch')
    batched = run_episodes(text, list(range(24)), None)
    scalar_text = text.replace('pendulum_sim.testing.examples:pd_batch',
                               'campaign_laws:pd_batch_one')
    one_by_one = [run_episode(scalar_text, i, None) for i in range(24)]
    # A rerun of one episode runs a batch of one: the same row.
    assert repr(run_episode(text, 7, None)['settling_time']) == repr(
        batched[7]['settling_time'])
    for a, b in zip(batched, one_by_one, strict=True):
        for key in a:
            if key not in RUN_COLUMNS:
                assert repr(a[key]) == repr(b[key]), key
    assert {r['passed'] for r in batched} == {True, False}


@pytest.mark.skipif(not jit_available(), reason='needs numba (the jit extra)')
def test_a_compiled_campaign_has_the_rows_of_the_numpy_one() -> None:
    # jit: true puts a vectorised law's batches on the compiled sweep, warmed up (or loaded
    # from the disk cache) before the clock starts: the same rows, the integer laws and the
    # Coulomb law here, to the bit, a friction beside them included.
    text = CAMPAIGN.format(law='pd_batch').replace(
        'requirements:', '  friction: [0.0, 0.03]\nrequirements:')
    numpy_rows = run_episodes(text, list(range(24)), None)
    compiled = run_episodes(text.replace('episodes: 24', 'episodes: 24\njit: true'),
                            list(range(24)), None)
    for a, b in zip(numpy_rows, compiled, strict=True):
        for key in a:
            if key not in RUN_COLUMNS:
                assert repr(a[key]) == repr(b[key]), key
    assert {r['friction'] for r in compiled} == {0.0, 0.03}


@pytest.mark.parametrize(('value', 'message'), [
    ("'yes'", "jit must be true or false, got 'yes'"), ('1', 'jit must be true or false, got 1')])
def test_the_jit_key_is_a_bool(value: str, message: str) -> None:
    text = CAMPAIGN.format(law='pd_batch').replace('episodes: 24', f'episodes: 24\njit: {value}')
    with pytest.raises(CampaignError, match=re.escape(message)):
        parse_spec(text)


# ------------------------------------------------------------------ one lockstep, counted
def test_a_batch_runs_every_batchable_episode_in_its_lockstep_and_says_so() -> None:
    """BatchStats fails a batch that silently leaves the lockstep for the scalar joint."""
    episodes = scenarios(12, seed=3)
    stats = BatchStats()
    runs = run_batch(pd_batch, episodes, 120, stats=stats)
    assert all(isinstance(r, ClosedLoopRun) and r.failed is None for r in runs)
    assert (stats.lockstep, stats.scalar, stats.groups) == (12, {}, 1)
    assert stats.periods == LockstepStats(swept=12 * 120, by_joint=0, prepared=1)
    # Off the common path, or past the speed bound: the stats say which way each went.
    noisy = scene_values('controller_test', {'sensor.position_noise': 1e-3})
    fast = scene_values('controller_test', {'max_velocity': 0.5})
    stats = BatchStats()
    run_batch(pd_batch, [episodes[0], noisy, fast], 120, stats=stats)
    assert (stats.lockstep, stats.scalar) == (2, {1: 'the sensor is not ideal'})
    assert stats.periods.by_joint > 0   # the fast joint's periods near max_velocity


def test_episodes_of_other_steps_run_in_a_lockstep_of_their_own_as_alone() -> None:
    """Another h, and an h of no whole nanoseconds (its stamps rounded as the joint's)."""
    plain = scenarios(3, seed=4)
    other = [dict(v, h=0.002) for v in scenarios(2, seed=6)]
    odd = [dict(v, h=1.0 / 3000.0) for v in scenarios(2, seed=7)]
    episodes = [plain[0], other[0], odd[0], plain[1], odd[1], other[1], plain[2]]
    stats = BatchStats()
    runs = run_batch(pd_batch, episodes, 150, stats=stats)
    assert (stats.lockstep, stats.scalar, stats.groups) == (7, {}, 3)
    for values, got in zip(episodes, runs, strict=True):
        assert isinstance(got, ClosedLoopRun)
        want = run_in_process(scalar, values, 150)
        for name in FIELDS:
            assert getattr(got, name).tobytes() == getattr(want, name).tobytes(), name
    assert runs[2].t[1] == 0.01 and runs[1].t[1] == 0.01   # type: ignore[union-attr]


@vectorised
def push(t: float, p: Any, v: Any) -> Any:
    return np.full_like(p, 0.001)


def test_the_batch_cuts_the_torque_at_the_joints_speed_bound_as_the_joint() -> None:
    """max_velocity may be up to 1e6 rad/s, but the joint's bound is the core's 1e4 rad/s.

    Bounded by max_velocity alone, the batch pushed on at 1e4 rad/s where the joint cuts the
    torque (its speed_bound), and this run differed from the joint's (by 2e-5 rad in 20 periods).
    """
    values = scene_values('controller_test', {'gamma': 0.0, 'max_velocity': 1e6, 'phi0': 0.0,
                                              'dphi0': 1e4, 'max_effort': 1.0})
    stats = BatchStats()
    got = run_batch(push, [values], 20, stats=stats)[0]
    want = run_in_process(lambda t, p, v: 0.001, values, 20)
    assert isinstance(got, ClosedLoopRun) and stats.scalar == {}
    for name in FIELDS:
        assert getattr(got, name).tobytes() == getattr(want, name).tobytes(), name
    assert 0.0 in got.effort[1:].tolist()   # the joint cut the torque at its bound
    assert stats.periods.by_joint == 20


def test_a_batched_campaign_runs_all_its_episodes_in_lockstep() -> None:
    stats = BatchStats()
    rows = run_episodes(CAMPAIGN.format(law='pd_batch'), list(range(24)), None, stats=stats)
    assert len(rows) == 24 and (stats.lockstep, stats.scalar) == (24, {})
    assert stats.periods.by_joint == 0 and stats.periods.swept > 0
