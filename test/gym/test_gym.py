"""The Gymnasium environments: Gymnasium's checker, seeding, the vector env, the bridge, errors."""
from __future__ import annotations

import dataclasses
import math
import re
import subprocess
import sys
import warnings
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import pytest
from gym_parity import scalar_run
from gymnasium.envs.classic_control.pendulum import PendulumEnv, angle_normalize
from gymnasium.utils.env_checker import check_env

import pendulum_sim.gym as pg
from pendulum_sim.gym import GymError, policy_law
from pendulum_sim.gym.examples import energy_swing_up, tracking, tracking_batch
from pendulum_sim.testing import closed_loop
from pendulum_sim.testing.campaign.episode import run_episode, run_episodes
from pendulum_sim.testing.campaign.scenarios import episode_scenario
from pendulum_sim.testing.campaign.spec import parse_spec

SWING, STEP = pg.ENV_IDS
# Every damping law the core has: viscous, quadratic, fractional, dry (Coulomb).
MIXED = {'gamma': {'distribution': 'uniform', 'low': 0.05, 'high': 0.5},
         'n': [1.5, 0.0, 2.0, 1.0]}


def episode(env: Any, policy: Any, steps: int, seed: int | None = None
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
    """Run ``steps`` steps of ``policy``; return the angles, speeds (K + 1) and rewards."""
    obs, info = env.reset(seed=seed)
    p = env.unwrapped.runner.pendulums
    phi, vel, rewards = [p.phi[0]], [p.vel[0]], []
    for _ in range(steps):
        obs, reward, terminated, truncated, _ = env.step(policy(obs))
        assert not terminated and not truncated
        phi.append(p.phi[0])
        vel.append(p.vel[0])
        rewards.append(reward)
    return np.array(phi), np.array(vel), np.array(rewards), info


# ------------------------------------------------------------------ Gymnasium's own checks
@pytest.mark.parametrize('env_id', pg.ENV_IDS)
def test_gymnasiums_checker_passes_without_a_warning(env_id: str) -> None:
    env = gymnasium.make(env_id, render_mode='rgb_array')
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        check_env(env.unwrapped)
    obs, _ = env.reset(seed=0)
    assert obs.dtype == np.float64 and obs in env.observation_space
    assert env.action_space.shape == (1,) and env.action_space.high[0] == 1.0


def test_a_frame_shows_the_bob_where_the_angle_puts_it() -> None:
    env = gymnasium.make(SWING, render_mode='rgb_array',
                         parameters={'phi0': 0.0, 'dphi0': 0.0})
    env.reset(seed=0)
    down = env.render()
    assert down.shape == (256, 256, 3) and down.dtype == np.uint8
    c, reach = 127, int(0.4 * 256)
    # φ = 0 hangs down: the bob (red) below the pivot, nothing above it.
    assert tuple(down[c + reach, c]) == (200, 70, 40)
    assert tuple(down[c - reach, c]) == (255, 255, 255)
    env = gymnasium.make(SWING, render_mode='rgb_array',
                         parameters={'phi0': math.pi, 'dphi0': 0.0})
    env.reset(seed=0)
    assert tuple(env.render()[c - reach, c]) == (200, 70, 40)
    assert pg.DampedPendulumEnv().render() is None


def test_the_environments_are_found_in_a_fresh_process_and_by_the_entry_point() -> None:
    # Gymnasium 1.x reads no plugin entry points: the bare id needs the import first.
    bare = subprocess.run([sys.executable, '-c', 'import gymnasium\n'
                           "gymnasium.make('pendulum_sim/DampedPendulum-v0')"],
                          capture_output=True, text=True, timeout=120)
    assert 'NamespaceNotFound: Namespace pendulum_sim not found.' in bare.stderr
    code = ('import gymnasium, sys\n'
            "env = gymnasium.make('pendulum_sim.gym:pendulum_sim/DampedPendulum-v0')\n"
            'obs, _ = env.reset(seed=1)\n'
            "assert 'rclpy' not in sys.modules, 'the environment imported rclpy'\n"
            "vec = gymnasium.make_vec('pendulum_sim/StepResponse-v0', num_envs=3, "
            "vectorization_mode='vector_entry_point')\n"
            'print(obs.shape, vec.reset(seed=1)[0].shape)\n')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == '(3,) (3, 4)'
    from importlib.metadata import entry_points

    found = [e for e in entry_points(group='gymnasium.envs') if e.name == 'pendulum_sim']
    assert [e.value for e in found] == ['pendulum_sim.gym:register_envs']
    found[0].load()()   # registering again changes nothing
    assert gymnasium.spec(SWING).max_episode_steps == 1000


# ------------------------------------------------------------------ rewards and seeding
def test_the_swing_up_reward_is_pendulum_v1s_on_the_same_state_and_torque() -> None:
    """Gymnasium's Pendulum-v1, set to our state (θ from upright), pays the same reward."""
    env = gymnasium.make(SWING)
    peer = PendulumEnv()
    peer.reset(seed=0)
    env.reset(seed=5)
    rng = np.random.default_rng(1)
    for _ in range(50):
        p = env.unwrapped.runner.pendulums
        phi, vel = float(p.phi[0]), float(p.vel[0])
        u = rng.uniform(-1.0, 1.0)
        _, reward, *_ = env.step(np.array([u]))
        peer.state = np.array([phi - math.pi, vel])
        _, peer_reward, *_ = peer.step(np.array([u], dtype=np.float32))
        assert reward == pytest.approx(peer_reward, rel=1e-6, abs=1e-6)
        assert -reward >= angle_normalize(phi - math.pi) ** 2 - 1e-12


def test_a_seed_replays_its_episodes_bit_for_bit_and_draws_the_campaigns_scenarios() -> None:
    env = gymnasium.make(SWING, parameters=MIXED)
    rng = np.random.default_rng(3)
    actions = rng.uniform(-2.0, 2.0, (40, 1))
    runs = []
    for _ in range(2):
        obs, info = env.reset(seed=21)
        seen = [obs, *(env.step(a)[0] for a in actions)]
        second = env.reset()[1]
        runs.append((np.array(seen).tobytes(), info, second))
    assert runs[0] == runs[1]
    # Episode k after reset(seed=s) is episode k of a campaign seeded s.
    spec = env.unwrapped.runner.scenarios.spec
    for k, got in ((0, runs[0][1]), (1, runs[0][2])):
        assert got['episode'] == k and got['seed'] == 21
        want = episode_scenario(dataclasses.replace(spec, seed=21), k)
        assert got['parameters'] == want.values
    assert runs[0][1]['parameters'] != runs[0][2]['parameters']
    other = env.reset(seed=22)[1]
    assert other['parameters'] != runs[0][1]['parameters']


# ------------------------------------------------------------------ the vector environment
def test_the_vector_env_is_n_scalar_envs_bit_for_bit_with_next_step_autoreset() -> None:
    n, steps, length = 8, 70, 30
    vec = gymnasium.make_vec(SWING, num_envs=n, vectorization_mode='vector_entry_point',
                             parameters=MIXED, max_episode_steps=length)
    assert vec.metadata['autoreset_mode'] == gymnasium.vector.AutoresetMode.NEXT_STEP
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1.5, 1.5, (steps, n, 1))
    obs, _ = vec.reset(seed=11)
    seen, rewards, ends = [obs], [], []
    laws = set()
    for a in actions:
        laws |= {e.values['n'] for e in vec.unwrapped.runner.episodes}
        obs, reward, terminated, truncated, _ = vec.step(a)
        seen.append(obs)
        rewards.append(reward)
        ends.append(terminated | truncated)
    got, got_r = np.array(seen), np.array(rewards)
    done = np.array(ends)
    assert done[length - 1].all() and done.sum() == 2 * n   # truncated at 30 and 60 steps
    for i in range(n):
        mine, mine_r = scalar_run(SWING, MIXED, length, 11 + i, actions[:, i])
        assert mine.tobytes() == got[:, i].tobytes(), i
        assert mine_r.tobytes() == got_r[:, i].tobytes(), i
    # The episodes drew the fractional, the Coulomb and the quadratic damping law in turn.
    assert laws == {1.5, 0.0, 2.0}
    # Gymnasium's own SyncVectorEnv of the scalar envs (its autoreset, its seeding) agrees.
    sync = gymnasium.make_vec(SWING, num_envs=n, vectorization_mode='sync',
                              parameters=MIXED, max_episode_steps=length)
    obs, _ = sync.reset(seed=11)
    theirs, theirs_r = [obs], []
    for a in actions:
        obs, reward, *_ = sync.step(a)
        theirs.append(obs)
        theirs_r.append(reward)
    assert np.array(theirs).tobytes() == got.tobytes()
    assert np.array(theirs_r).tobytes() == got_r.tobytes()


def test_the_vector_env_takes_the_joints_coulomb_friction_as_the_scalar_env() -> None:
    # A friction torque beside the law (issue 26) drawn per episode: the vector env's one
    # sweep gives each pendulum the scalar env's states, bit for bit.
    spaces = {**MIXED, 'friction': {'distribution': 'uniform', 'low': 0.05, 'high': 0.3}}
    n, steps = 6, 40
    vec = gymnasium.make_vec(SWING, num_envs=n, vectorization_mode='vector_entry_point',
                             parameters=spaces, max_episode_steps=steps)
    rng = np.random.default_rng(4)
    actions = rng.uniform(-0.3, 0.3, (steps, n, 1))
    obs, _ = vec.reset(seed=5)
    drawn = [e.values['friction'] for e in vec.unwrapped.runner.episodes]
    seen = [obs]
    for a in actions[:-1]:
        seen.append(vec.step(a)[0])
    got = np.array(seen)
    for i in range(n):
        env = gymnasium.make(SWING, parameters=spaces, max_episode_steps=steps)
        mine = [env.reset(seed=5 + i)[0]]
        for a in actions[:-1]:
            mine.append(env.step(a[i])[0])
        assert np.array(mine).tobytes() == got[:, i].tobytes(), i
    assert len(set(drawn)) == n and min(drawn) > 0.0
    bare = gymnasium.make_vec(SWING, num_envs=n, vectorization_mode='vector_entry_point',
                              parameters=MIXED, max_episode_steps=steps)
    other = [bare.reset(seed=5)[0]]
    for a in actions[:-1]:
        other.append(bare.step(a)[0])
    assert np.array(other).tobytes() != got.tobytes()   # the friction made a difference


def test_near_the_speed_bound_the_joint_decides_and_still_in_step() -> None:
    """With max_velocity 1.2 rad/s each period at risk is the joint's own (its velocity limit)."""
    def bang(obs: Any) -> Any:
        return np.array([1.0 if obs[2] >= 0.0 else -1.0])

    params = {'max_velocity': 1.2, 'phi0': 0.0, 'dphi0': 0.0}
    phi, vel, _, info = episode(gymnasium.make(SWING, parameters=params), bang, 300, seed=0)
    run = closed_loop(policy_law(bang), periods=301, overrides=info['parameters'])
    assert phi.tobytes() == run.position.tobytes() and vel.tobytes() == run.velocity.tobytes()
    free = episode(gymnasium.make(SWING, parameters={**params, 'max_velocity': 100.0}), bang,
                   300, seed=0)[1]
    assert np.max(np.abs(free)) > 2 * np.max(np.abs(vel))   # the joint's limit acted
    vec = gymnasium.make_vec(SWING, num_envs=3, vectorization_mode='vector_entry_point',
                             parameters=params)
    obs, _ = vec.reset(seed=0)
    for _ in range(300):
        obs = vec.step(np.array([bang(o) for o in obs]))[0]
    assert vec.unwrapped.runner.pendulums.vel[0] == vel[-1]


def test_the_joint_keywords_set_the_nodes_parameters() -> None:
    """integrator=, h=, control_period= and target= are the node's own settings."""
    env = pg.StepResponseEnv(integrator='midpoint', h=0.002, control_period=0.02, target=0.3)
    phi, vel, _, info = episode(env, tracking, 50, seed=1)
    assert info['target'] == 0.3 and env.metadata['render_fps'] == 50
    run = closed_loop(policy_law(tracking, task='StepResponse'), periods=51, target=0.3,
                      overrides={**info['parameters'], 'integrator': 'midpoint', 'h': 0.002,
                                 'publish_rate': 50.0})
    assert run.t[1] == 0.02
    assert phi.tobytes() == run.position.tobytes() and vel.tobytes() == run.velocity.tobytes()
    rk4 = episode(pg.StepResponseEnv(h=0.002, control_period=0.02, target=0.3), tracking, 50,
                  seed=1)[0]
    assert rk4.tobytes() != phi.tobytes()


# ------------------------------------------------------------------ the bridge to the bench
@pytest.mark.parametrize(('env_id', 'task', 'policy'), [(SWING, 'DampedPendulum', energy_swing_up),
                                                         (STEP, 'StepResponse', tracking)])
def test_a_policy_through_closed_loop_runs_the_environments_episode(
        env_id: str, task: str, policy: Any) -> None:
    phi, vel, rewards, info = episode(gymnasium.make(env_id), policy, 200, seed=4)
    law = policy_law(policy, task=task)
    target = info['target'] if task == 'StepResponse' else None
    run = closed_loop(law, periods=201, overrides=info['parameters'], target=target)
    assert run.failed is None
    assert run.position.tobytes() == phi.tobytes()
    assert run.velocity.tobytes() == vel.tobytes()
    if task == 'StepResponse':
        # The return is the bench's verdict: −iae of the same samples.
        assert rewards.sum() == pytest.approx(-run.metrics().iae, rel=1e-12)


CAMPAIGN = ('controller: pendulum_sim.gym.examples:tracking_law\n'
            'scene: controller_test\nepisodes: 4\nseed: 9\nperiods: 301\n'
            'target: {distribution: uniform, low: -0.5, high: 0.5}\n'
            'parameters:\n  gamma: {distribution: uniform, low: 0.05, high: 0.3}\n'
            '  phi0: 0.0\n  max_effort: 1.0\n'
            "requirements:\n  - 'settling_time < 2.5'\n")


def test_a_policy_gets_the_campaigns_verdict_on_the_environments_episodes(
        tmp_path: Path) -> None:
    text = CAMPAIGN
    path = tmp_path / 'campaign.yaml'
    path.write_text(text)
    env = gymnasium.make(STEP, parameters=path)
    for k in range(4):
        row = run_episode(text, k, None)
        _, _, rewards, info = episode(env, tracking, 300, seed=9 if k == 0 else None)
        assert info['episode'] == k
        assert row['target'] == info['target'] and row['gamma'] == info['parameters']['gamma']
        assert rewards.sum() == pytest.approx(-row['iae'], rel=1e-12)
        assert row['passed'], row['reason']


def test_a_batched_policy_runs_a_campaigns_episodes_together_as_one_by_one() -> None:
    """The @vectorised law of a batched policy: N episodes in lockstep, each as run alone."""
    law = policy_law(tracking_batch, task='StepResponse', batched=True)
    assert law.vectorised is True  # type: ignore[attr-defined]
    text = CAMPAIGN.replace('tracking_law', 'tracking_batch_law').replace('episodes: 4',
                                                                          'episodes: 6')
    together = run_episodes(text, list(range(6)), None)
    spec = parse_spec(text)
    # The same policy one observation at a time, on the scalar joint: the same run.
    one = policy_law(lambda obs: tracking_batch(obs[None])[0], task='StepResponse')
    scalar_law = text.replace('tracking_batch_law', 'tracking_law')
    for k, row in enumerate(together):
        drawn = episode_scenario(spec, k)
        run = closed_loop(one, periods=spec.periods, overrides=drawn.values,
                          target=drawn.target)
        assert row['episode'] == k and row['target'] == drawn.target
        assert row['iae'] == run.metrics().iae and row['passed']
        # numpy's arctan2 and sin against math's: the scalar example to round-off.
        assert row['iae'] == pytest.approx(run_episode(scalar_law, k, None)['iae'], rel=1e-9)
    with pytest.raises(GymError, match=re.escape('action must have shape (3, 1) (torques in '
                                                 'N m), got shape (3,)')):
        policy_law(lambda obs: obs[:, 0], batched=True)(0.0, np.zeros(3), np.zeros(3))


@pytest.mark.slow
def test_pendulum_campaign_runs_a_policy_law_on_its_dask_cluster(tmp_path: Path) -> None:
    """The console script, unchanged, on a local Dask cluster: the environment's verdict."""
    path = tmp_path / 'campaign.yaml'
    path.write_text(CAMPAIGN)
    out = tmp_path / 'out'
    script = Path(sys.executable).parent / 'pendulum_campaign'
    proc = subprocess.run([str(script), str(path), '--out', str(out), '--workers', '1',
                           '--no-progress'], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    import pyarrow.parquet as pq

    rows = pq.read_table(out / 'episodes.parquet').to_pylist()
    env = gymnasium.make(STEP, parameters=path)
    for k, row in enumerate(rows):
        _, _, rewards, info = episode(env, tracking, 300, seed=9 if k == 0 else None)
        assert row['episode'] == k and row['passed'] and row['target'] == info['target']
        assert rewards.sum() == pytest.approx(-row['iae'], rel=1e-12)


# ------------------------------------------------------------------ bad input
def test_bad_actions_are_refused_and_a_torque_beyond_the_limit_saturates() -> None:
    with pytest.raises(GymError, match=re.escape('step() before reset(): call reset() first')):
        pg.DampedPendulumEnv().step(np.array([0.0]))
    env = gymnasium.make(SWING)
    env.reset(seed=0)
    cases = [(np.array(0.5), 'action must have shape (1,) (torques in N m), got shape ()'),
             (np.zeros((1, 1)), 'action must have shape (1,) (torques in N m), got shape (1, 1)'),
             (np.array([math.nan]), 'action must be a finite torque, got nan'),
             (np.array([-math.inf]), 'action must be a finite torque, got -inf'),
             (['x'], "action must be an array of numbers of shape (1,) (torques in N m), "
                     "got ['x']")]
    for action, message in cases:
        with pytest.raises(GymError, match=re.escape(message)):
            env.step(action)
    a = gymnasium.make(SWING)
    b = gymnasium.make(SWING)
    a.reset(seed=3)
    b.reset(seed=3)
    for _ in range(5):
        obs_a, *_, info = a.step(np.array([7.0]))
        obs_b, *_ = b.step(np.array([1.0]))
        assert info['effort'] == 1.0 and obs_a.tobytes() == obs_b.tobytes()
    vec = gymnasium.make_vec(SWING, num_envs=3, vectorization_mode='vector_entry_point')
    vec.reset(seed=0)
    with pytest.raises(GymError, match=re.escape('action must be a finite torque, got nan '
                                                 'for environment 2')):
        vec.step(np.array([[0.0], [1.0], [math.nan]]))
    with pytest.raises(GymError, match=re.escape('action must have shape (3, 1) (torques in '
                                                 'N m), got shape (3,)')):
        vec.step(np.zeros(3))


def test_a_step_after_the_episode_ended_is_refused_until_reset() -> None:
    env = pg.DampedPendulumEnv(max_episode_steps=2)
    env.reset(seed=0)
    env.step(np.zeros(1))
    *_, truncated, _ = env.step(np.zeros(1))
    assert truncated
    with pytest.raises(GymError, match=re.escape(
            'step() after the episode ended (truncated after 2 steps): call reset() first')):
        env.step(np.zeros(1))
    env.reset()
    env.step(np.zeros(1))


def test_a_parameter_file_is_a_scene(tmp_path: Path) -> None:
    path = tmp_path / 'heavy.yaml'
    path.write_text('/**:\n  ros__parameters:\n    m: 0.3\n    inertia: 0.31\n'
                    '    gamma: 0.4\n    n: 2.0\n    publish_rate: 50.0\n')
    env = pg.DampedPendulumEnv(scene=str(path))
    _, info = env.reset(seed=0)
    values = env.runner.episodes[0].values
    assert (values['m'], values['gamma'], values['n'], values['publish_rate']) == (
        0.3, 0.4, 2.0, 50.0)
    assert env.metadata['render_fps'] == 50
    phi, vel, _, info = episode(env, energy_swing_up, 100, seed=0)
    run = closed_loop(policy_law(energy_swing_up), scene=str(path), periods=101,
                      overrides=info['parameters'])
    assert phi.tobytes() == run.position.tobytes() and vel.tobytes() == run.velocity.tobytes()


def test_a_vector_env_refuses_episodes_of_different_steps_naming_both() -> None:
    vec = pg.DampedPendulumVectorEnv(2, parameters={'h': [0.001, 0.002]})
    vec.reset(seed=0)   # every environment's episode 0: h = 1 ms
    vec.step(np.zeros((2, 1)))
    message = ('every pendulum of a vector environment steps with one h, control period, '
               'integrator and guard; episode has h = 0.002 s, 5 steps a period, rk4, guard '
               'True, the others h = 0.001 s, 10 steps a period, rk4, guard True')
    # The environments reset together: episode 0 of seed 0 again (1 ms) for the first, the
    # next episode of its seed (2 ms) for the other.
    with pytest.raises(GymError, match=re.escape(message)):
        vec.reset(seed=[0, None])
    # The refused reset changed nothing: both run their episode 0 on.
    assert vec.unwrapped.runner.index == [0, 0]
    vec.step(np.zeros((2, 1)))
    assert vec.reset()[1]['episode'].tolist() == [1, 1]   # both 2 ms: one step, no refusal


@pytest.mark.parametrize(('keywords', 'message'), [
    ({'scene': 'no_such_scene'}, "unknown scene 'no_such_scene'; known scenes: "),
    ({'parameters': {'no_such_parameter': 1.0}},
     "unknown parameter 'no_such_parameter' in parameters"),
    ({'parameters': {'gamma': {'distribution': 'uniform', 'low': 1.0, 'high': 0.5}}},
     'parameters.gamma: uniform needs low < high, got low = 1, high = 0.5'),
    ({'parameters': {'max_effort': [1.0, 2.0]}},
     'max_effort must be one value: it bounds the action space'),
    ({'parameters': {'h': 0.002}, 'h': 0.001}, 'h is given both as a keyword and in parameters'),
    ({'h': -1.0}, 'h must be a positive number of seconds, got -1.0'),
    ({'integrator': 'dopri5'}, 'this scene cannot: integrator dopri5 is not one of euler, '
                               'midpoint, rk4'),
    ({'scene': 'noisy_sensor'}, 'this scene cannot: sensor.delay is not 0'),
    ({'scene': 'noisy_sensor', 'parameters': {'sensor.delay': 0.0}},
     'this scene cannot: the sensor is not ideal'),
    ({'render_mode': 'human'}, "render_mode must be one of rgb_array or None, got 'human'"),
    ({'parameters': 'missing.yaml'}, "campaign file 'missing.yaml' does not exist"),
])
def test_a_bad_keyword_is_refused_naming_the_fault(keywords: dict[str, Any],
                                                   message: str) -> None:
    with pytest.raises(GymError, match=re.escape(message)):
        env = pg.DampedPendulumEnv(**keywords)
        env.reset(seed=0)
