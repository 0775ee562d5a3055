"""Campaign keys beside the step task: task: swing_up, goal_box, disturbances, grid spaces, and
several campaigns' episodes in one batch, a fault in it failing only its own episode."""
from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import pytest
import yaml

from pendulum_sim.testing import CampaignError, closed_loop
from pendulum_sim.testing.campaign.episode import run_episode, run_episodes_parts
from pendulum_sim.testing.campaign.sandbox import Fault, run_parts
from pendulum_sim.testing.campaign.scenarios import episode_scenario
from pendulum_sim.testing.campaign.spec import Grid, parse_spec
from pendulum_sim.testing.examples import energy_lqr

SUPPORT = Path(__file__).resolve().parents[1] / 'support'
SWING = {'controller': 'pendulum_sim.testing.examples:energy_lqr', 'scene': 'swing_up',
         'task': 'swing_up', 'episodes': 4, 'seed': 9, 'periods': 600}


def text(**changes: Any) -> str:
    return yaml.safe_dump({**SWING, **changes}, sort_keys=False)


def test_a_swing_up_campaign_measures_the_swing_up_into_its_box() -> None:
    spec = parse_spec(text(goal_box=[0.2, 0.3], requirements=['stays == 1',
                                                               'swing_up_time < 1.5']))
    assert (spec.task, spec.target, spec.goal_box) == ('swing_up', math.pi, (0.2, 0.3))
    assert spec.metric_names[:3] == ('success', 'swing_up_time', 'stays')
    row = run_episode(spec.text, 0, None)
    run = closed_loop(energy_lqr, scene='swing_up', periods=600)
    want = run.swing_up_metrics(math.pi, (0.2, 0.3))
    assert {k: row[k] for k in spec.metric_names} == want.as_dict()
    assert row['stays'] is True and row['passed'] is False
    assert row['reason'] == f"swing_up_time = {row['swing_up_time']:.6g} (not < 1.5)"


def test_grids_cover_a_plane_and_pulses_are_drawn_after_the_target() -> None:
    spec = parse_spec(text(episodes=6, parameters={
        'phi0': {'grid': [0.0, 1.0, 3]}, 'dphi0': {'grid': [-2.0, 2.0, 2], 'stride': 3}},
        disturbances=[{'torque': {'distribution': 'uniform', 'low': -1.0, 'high': 1.0},
                       'start': [0.5, 1.0], 'duration': 0.25}]))
    assert spec.parameters[1] == ('dphi0', Grid(-2.0, 2.0, 2, 3))
    plane = [(episode_scenario(spec, i).values['phi0'], episode_scenario(spec, i).values[
        'dphi0']) for i in range(6)]
    assert plane == [(0.0, -2.0), (0.5, -2.0), (1.0, -2.0), (0.0, 2.0), (0.5, 2.0), (1.0, 2.0)]
    pulses = [episode_scenario(spec, i).values['disturbance.pulses'] for i in range(4)]
    torques = [float(p.split()[0]) for p in pulses]
    assert len(set(torques)) == 4 and all(-1.0 <= x < 1.0 for x in torques)
    assert [p.split()[1:] for p in pulses] == [['0.5', '0.25'], ['1.0', '0.25']] * 2
    assert spec.scenario_names == ('phi0', 'dphi0', 'disturbance.pulses', 'target')
    # A file without disturbances draws what it drew before (the pulses come last).
    plain = parse_spec(text(parameters={'phi0': {'distribution': 'uniform', 'low': 0,
                                                 'high': 1}}))
    with_pulses = parse_spec(text(parameters={'phi0': {'distribution': 'uniform', 'low': 0,
                                                       'high': 1}},
                                  disturbances=[{'torque': 0.1, 'start': 1, 'duration': 1}]))
    assert episode_scenario(plain, 2).values['phi0'] == episode_scenario(
        with_pulses, 2).values['phi0']


@pytest.mark.parametrize(('changes', 'message'), [
    ({'task': 'balance'}, "task must be one of step, swing_up, got 'balance'"),
    ({'task': 'step'}, "campaign file: missing key 'target'"),
    ({'goal_box': [0.0, 0.1]}, 'goal_box: box[0] (rad) must be a finite number > 0, got 0.0'),
    ({'goal_box': 0.1}, 'goal_box must be [angle rad, rate rad/s], two numbers > 0, got 0.1'),
    ({'task': 'step', 'target': 0.5, 'goal_box': [0.1, 0.1]},
     'goal_box is a key of task: swing_up'),
    ({'requirements': ['overshoot < 3']}, "requirement 'overshoot < 3' names an unknown metric "
     "'overshoot'; metrics: success, swing_up_time, stays, settle_time, energy, "
     'effort_energy, smoothness, max_effort, saturation_fraction, swings'),
    ({'disturbances': [{'torque': 1.0, 'start': 0.5}]},
     "disturbances[0] must be a pulse {torque, start, duration} (N m, s, s), got "
     "{'torque': 1.0, 'start': 0.5}"),
    ({'disturbances': [{'torque': 'x', 'start': 0.5, 'duration': 1}]},
     "disturbances[0].torque must be a number, got 'x'"),
    ({'disturbances': [{'torque': 1, 'start': 0, 'duration': 1}],
      'parameters': {'disturbance.pulses': '1 0 1'}},
     'parameters.disturbance.pulses and disturbances both set the pulses; give them in one'),
    ({'parameters': {'phi0': {'grid': [1.0, 0.0, 3]}}},
     'parameters.phi0: a grid needs low < high, got low = 1, high = 0'),
    ({'parameters': {'phi0': {'grid': [0.0, 1.0]}}},
     "parameters.phi0: a grid reads {grid: [low, high, count], stride: S}, got "
     "{'grid': [0.0, 1.0]}"),
    ({'parameters': {'phi0': {'grid': [0.0, 1.0, 0]}}},
     'parameters.phi0.grid count must be an integer in [1, 10000000], got 0'),
    ({'keep_failures': 'no'}, "keep_failures must be true or false, got 'no'"),
])
def test_bad_keys_are_refused_with_one_line(changes: dict[str, Any], message: str) -> None:
    with pytest.raises(CampaignError) as info:
        parse_spec(text(**changes))
    assert str(info.value) == message


def test_several_campaigns_in_one_batch_give_each_episode_its_own_row() -> None:
    roa = text(episodes=4, parameters={'phi0': {'grid': [3.0, 3.3, 2]},
                                       'dphi0': {'grid': [-0.2, 0.2, 2], 'stride': 2}})
    pushed = text(episodes=3, disturbances=[{'torque': 0.3, 'start': 0.5, 'duration': 0.5}])
    together = run_episodes_parts([(roa, [0, 1, 2, 3], None), (pushed, [1, 2], None)])
    alone = [[run_episode(roa, i, None) for i in range(4)],
             [run_episode(pushed, i, None) for i in (1, 2)]]
    keep = ('worker_host', 'worker_pid', 'wall_time_s')
    for got, want in zip(together, alone, strict=True):
        assert [{k: v for k, v in r.items() if k not in keep} for r in got] == [
            {k: v for k, v in r.items() if k not in keep} for r in want]


def test_a_batch_of_several_campaigns_that_faults_fails_only_the_faulty_episode(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The batch dies (os._exit in the law); each campaign is run again alone, and in its
    batch's second fault each episode alone: only the faulty one fails."""
    monkeypatch.setenv('PYTHONPATH', os.pathsep.join(   # the episode process imports the law
        [str(SUPPORT), *filter(None, [os.environ.get('PYTHONPATH')])]))
    base = {'controller': 'campaign_faulty:batch_exit', 'episodes': 3, 'periods': 30,
            'episode_timeout': 60}
    faulty = yaml.safe_dump({**base, 'target': [0.5, 0.4, 0.6]})
    calm = yaml.safe_dump({**base, 'target': 0.5})
    got = run_parts([(faulty, [0, 1, 2], None), (calm, [0, 2], None)], 60.0)
    assert [sorted(r.episode if isinstance(r, Fault) else r['episode'] for r in part)
            for part in got] == [[0, 1, 2], [0, 2]]
    faults = [r for r in got[0] if isinstance(r, Fault)]
    assert faults == [Fault(1, 'law exited with 4')]
    assert all(not isinstance(r, Fault) and r['passed'] for r in got[1])


def test_a_law_of_one_state_is_measured_as_its_vectorised_twin() -> None:
    """The scalar path (one episode at a time) and the batch give the same swing-up rows."""
    scalar = text(controller='campaign_laws:swing_up_one', episodes=2,
                  parameters={'phi0': [0.0, 2.5]})
    batched = text(episodes=2, parameters={'phi0': [0.0, 2.5]})
    keep = ('worker_host', 'worker_pid', 'wall_time_s')
    for i in range(2):
        one, many = run_episode(scalar, i, None), run_episode(batched, i, None)
        assert {k: v for k, v in one.items() if k not in keep} == {
            k: v for k, v in many.items() if k not in keep}


def test_the_results_of_a_campaign_with_pulses_and_grids_are_written(tmp_path: Path) -> None:
    from pendulum_sim.testing.campaign.summary import write_results

    spec = parse_spec(text(episodes=4, parameters={'phi0': {'grid': [3.0, 3.001, 2]}},
                           disturbances=[{'torque': {'distribution': 'uniform', 'low': -0.1,
                                                     'high': 0.1}, 'start': 1.0,
                                          'duration': 0.5}]))
    rows = run_episodes_parts([(spec.text, [0, 1, 2, 3], None)])[0]
    write_results(spec, rows, tmp_path)
    summary = (tmp_path / 'summary.md').read_text()
    assert 'Nearly point-like scenario: phi0 3 to 3.001 (' in summary   # the grid is measured
    header = (tmp_path / 'episodes.csv').read_text().splitlines()[0].split(',')
    assert header[:4] == ['episode', 'phi0', 'disturbance.pulses', 'target']
    assert {p.name for p in (tmp_path / 'figures').iterdir()} >= {'metric_distributions.png'}
