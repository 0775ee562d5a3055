"""The twin report: a recorded closed loop beside the same controller on the fitted joint.

The strong check: a record made by ``closed_loop`` with a law and a scene, twinned with that law
against that scene, is reproduced exactly (the joint is deterministic, the twin starts from the
record's first state, bit for bit the scene's). Then a perturbed scene, whose metrics differ and
whose campaign spread says so; the command line as a user runs it, its outputs read back, and
bad input refused with one line and nothing written.
"""
from __future__ import annotations

import csv
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from pendulum_sim.core import ModelError
from pendulum_sim.core.analysis import fit_percent
from pendulum_sim.testing import ClosedLoopRun, ControllerFailed, TestingError, closed_loop, twin
from pendulum_sim.testing.examples import pd
from pendulum_sim.testing.twin_cli import main
from pendulum_sim.testing.twin_report import COMPARED, SPREAD, TwinReport

SCRIPT = Path(sys.executable).parent / 'pendulum_twin'
PD = 'pendulum_sim.testing.examples:pd'
TARGET = 0.5
PERIODS = 400
# A joint as pendulum_identify writes it (fit.yaml's keys), with a non-integer n and a friction.
JOINT = {'m': 0.2, 'l': 1.0, 'inertia': 0.2, 'g': 9.8, 'gamma': 0.3, 'n': 1.5,
         'friction': 0.01, 'phi0': 0.1, 'dphi0': 0.0}


def write_scene(path: Path, **changes: float) -> Path:
    params = {**JOINT, **changes}
    path.write_text(yaml.safe_dump({'/**': {'ros__parameters': params}}))
    return path


def write_spaces(path: Path, gamma: float, std: float) -> Path:
    """A campaign_parameters.yaml as pendulum_identify writes it: normal spaces."""
    path.write_text(f'# a fit\nparameters:\n  gamma: {{distribution: normal, mean: {gamma!r}, '
                    f'std: {std!r}}}\n  n: {{distribution: normal, mean: 1.5, std: 0.02}}\n')
    return path


@pytest.fixture(scope='module')
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, ClosedLoopRun]:
    """A closed loop of the PD law on JOINT, recorded as the node records it."""
    folder = tmp_path_factory.mktemp('twin')
    scene = write_scene(folder / 'fit.yaml')
    run = closed_loop(pd, scene=str(scene), periods=PERIODS, target=TARGET,
                      record=folder / 'run.mcap')
    return folder / 'run.mcap', scene, run


def test_fit_percent_is_matlab_compares_nrmse() -> None:
    y = np.array([0.0, 1.0, 2.0, 3.0])
    y_hat = np.array([0.0, 1.0, 2.0, 4.0])
    # ||y - y_hat|| = 1, ||y - mean(y)|| = sqrt(1.5² + 0.5² + 0.5² + 1.5²) = sqrt(5)
    assert fit_percent(y, y_hat) == pytest.approx(100.0 * (1.0 - 1.0 / math.sqrt(5.0)),
                                                  rel=1e-15)
    assert fit_percent(y, y) == 100.0
    assert fit_percent(y, np.full(4, y.mean())) == 0.0   # no better than the mean
    assert fit_percent(y, -y) < 0.0
    assert math.isnan(fit_percent(np.ones(3), np.zeros(3)))   # nothing to scale by
    with pytest.raises(ModelError, match=r'^measured and predicted must be 1-D arrays of one '
                                         r'length \(at least one sample\), got shapes \(4,\) '
                                         r'and \(3,\)$'):
        fit_percent(y, y[:3])
    with pytest.raises(ModelError, match=r'^measured and predicted must be finite$'):
        fit_percent(y, np.array([0.0, math.nan, 2.0, 3.0]))


@pytest.mark.ros
def test_a_record_of_closed_loop_is_twinned_exactly_by_the_same_law_and_scene(
        recorded: tuple[Path, Path, ClosedLoopRun]) -> None:
    path, scene, original = recorded
    report = twin(path, str(scene), PD, target=TARGET, episodes=0)
    # The twin starts from the record's first state, which is the scene's to the bit, and the
    # joint is deterministic: the same run, every sample, every bit.
    assert (report.phi0, report.dphi0, report.velocity_from) == (0.1, 0.0, 'record')
    for name in ('position', 'velocity', 'effort', 'command'):
        assert getattr(report.simulated, name).tobytes() == getattr(original, name).tobytes()
    assert report.compared == PERIODS   # the record's samples are the twin's periods
    assert report.predicted.tobytes() == report.record.position.tobytes()
    assert report.record.effort is not None
    assert report.predicted_effort.tobytes() == report.record.effort.tobytes()
    assert report.fit_percent == 100.0
    # Metrics of the angle and the effort alone are equal to the bit. Those that read the times
    # may differ by round-off only: the record's stamps come back as stamp_ns * 1e-9 where the
    # run holds stamp_ns / 1e9, which differ in the last bit for some stamps; rise and settling
    # times by at most 2 ulps of the run's length, the IAE by 2 ulps of it per unit of Σ|e|
    # (each interval dt) plus the sum's own rounding.
    by_name = {m.name: m for m in report.metrics}
    assert tuple(by_name) == COMPARED
    assert by_name['overshoot'].difference == 0.0
    assert by_name['max_effort'].difference == 0.0
    t_end = float(original.t[-1])
    assert abs(by_name['rise_time'].difference) <= 2 * math.ulp(t_end)
    assert abs(by_name['settling_time'].difference) <= 2 * math.ulp(t_end)
    e = np.abs(original.position - TARGET)
    iae = by_name['iae']
    assert abs(iae.difference) <= 2 * math.ulp(t_end) * e.sum() + PERIODS * 2e-16 * iae.recorded
    assert iae.recorded == pytest.approx(original.metrics(TARGET).iae, rel=0, abs=1e-15)
    # And the metrics are the test bench's own for the recorded run.
    assert by_name['overshoot'].simulated == original.metrics(TARGET).overshoot
    assert all(m.inside is None and math.isnan(m.spread_low) for m in report.metrics)


@pytest.mark.ros
def test_a_recording_pendulum_node_made_over_dds_is_twinned_exactly(tmp_path: Path) -> None:
    """The PD controller's own node against pendulum_node, recorded by the node; then its law
    in this process on the same scene: the in-process joint decides as the node does."""
    scene = write_scene(tmp_path / 'fit.yaml')
    controller = str(Path(sys.executable).parent / 'pendulum_pd_controller')
    run = closed_loop([controller, '--ros-args', '-p', f'target:={TARGET}'], scene=str(scene),
                      periods=300, record=tmp_path / 'dds.mcap')
    report = twin(tmp_path / 'dds.mcap', str(scene), PD, target=TARGET, episodes=0)
    assert report.record.source.endswith('/joint_states, joint pendulum_joint)')
    # The node records the state after the last answer too: one sample more than the run.
    assert report.compared == run.t.size + 1
    assert report.simulated.position[:-1].tobytes() == run.position.tobytes()
    assert report.predicted.tobytes() == report.record.position.tobytes()
    assert report.fit_percent == 100.0
    assert report.metric('overshoot').difference == 0.0


@pytest.mark.ros
def test_a_perturbed_scene_differs_and_the_campaign_spread_says_so(
        recorded: tuple[Path, Path, ClosedLoopRun], tmp_path: Path) -> None:
    path, true_scene, original = recorded
    # A fit that got the damping wrong: four times the joint's gamma, and sure of it.
    wrong = write_scene(tmp_path / 'fit.yaml', gamma=1.2)
    write_spaces(tmp_path / 'campaign_parameters.yaml', 1.2, 0.02)   # found beside the scene
    report = twin(path, str(wrong), PD, target=TARGET, episodes=12, seed=3)
    assert report.campaign == str(tmp_path / 'campaign_parameters.yaml')
    assert (report.episodes, report.episodes_failed) == (12, 0)
    assert 50.0 < report.fit_percent < 99.0   # close, but visibly not the joint
    overshoot = report.metric('overshoot')
    # More damping, less overshoot: the recorded run overshoots more than its twin.
    assert overshoot.recorded == original.metrics(TARGET).overshoot
    assert overshoot.difference > 1.0
    assert overshoot.spread_high < overshoot.recorded and overshoot.inside is False
    assert report.metric('rise_time').inside is False
    # The spread is the central 95 % of the episodes' values, each run from the record's state.
    values = sorted(_episode_overshoots(report, wrong, tmp_path))
    assert (overshoot.spread_low, overshoot.spread_high) == tuple(
        np.quantile(values, [(1 - SPREAD) / 2, (1 + SPREAD) / 2]))
    # A campaign spread around the true damping holds every recorded metric.
    spaces = write_spaces(tmp_path / 'around_truth.yaml', 0.3, 0.02)
    honest = twin(path, str(true_scene), PD, target=TARGET, campaign=spaces, episodes=12, seed=3)
    assert [m.inside for m in honest.metrics] == [True] * len(COMPARED)


def _episode_overshoots(report: TwinReport, scene: Path, folder: Path) -> list[float]:
    """Run the campaign's episodes by hand: each drawn gamma, n, from the twin's first state."""
    from pendulum_sim.testing.campaign.scenarios import episode_rng

    out = []
    for i in range(report.episodes):
        rng = episode_rng(report.seed, i)
        gamma, n = rng.normal(1.2, 0.02), rng.normal(1.5, 0.02)
        run = closed_loop(pd, scene=str(scene), periods=report.simulated.t.size, target=TARGET,
                          overrides={'gamma': gamma, 'n': n, 'phi0': report.phi0,
                                     'dphi0': report.dphi0, 'start_time': 0.0})
        out.append(run.metrics(TARGET).overshoot)
    return out


@pytest.mark.ros
def test_a_csv_at_half_the_rate_without_velocity_is_twinned_from_the_differentiated_state(
        recorded: tuple[Path, Path, ClosedLoopRun], tmp_path: Path) -> None:
    _, scene, original = recorded
    every = slice(0, None, 2)   # 50 Hz against the scene's 100 Hz: interpolated
    rows = np.c_[original.t[every], original.position[every], original.effort[every]]
    csv_path = tmp_path / 'lab.csv'
    np.savetxt(csv_path, rows, delimiter=',', header='t,position,effort', comments='',
               fmt='%.17g')
    report = twin(csv_path, str(scene), pd, target=TARGET, episodes=0,
                  columns='t,position,effort')
    y, h = original.position, original.t[2] - original.t[0]
    assert report.velocity_from == 'differentiated'
    # numpy.gradient's second-order one-sided difference on a uniform grid.
    assert report.dphi0 == pytest.approx((-3 * y[0] + 4 * y[2] - y[4]) / (2 * h), rel=1e-12)
    assert report.compared == rows.shape[0]
    # The twin's samples at the record's times are its own periods 0, 2, 4, ...: its angle
    # follows the record but for the start's velocity error, which the controller corrects.
    assert report.fit_percent > 99.0
    assert report.simulated.t.size == PERIODS - 1   # covers the record's last sample
    assert report.controller == PD   # the callable is named by what imports it


@pytest.mark.ros
def test_the_command_line_writes_the_report_and_its_files_agree(
        recorded: tuple[Path, Path, ClosedLoopRun], tmp_path: Path) -> None:
    path, scene, original = recorded
    out = tmp_path / 'twin'
    res = subprocess.run([str(SCRIPT), str(path), '--scene', str(scene), '--controller', PD,
                          '--target', str(TARGET), '--out', str(out)], capture_output=True,
                         text=True, timeout=300, check=False)
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith(f'angle fit 100.00 % over {PERIODS} samples (3.99 s)\n')
    assert sorted(p.name for p in out.iterdir()) == ['twin.csv', 'twin.png', 'twin.yaml']
    assert (out / 'twin.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    summary = yaml.safe_load((out / 'twin.yaml').read_text())
    assert summary['fit_percent'] == 100.0 and summary['campaign'] is None
    assert summary['initial_state'] == {'position': 0.1, 'velocity': 0.0,
                                        'velocity_from': 'record'}
    assert summary['metrics']['overshoot']['recorded'] == original.metrics(TARGET).overshoot
    with (out / 'twin.csv').open() as fh:
        table = list(csv.DictReader(fh))
    assert len(table) == PERIODS
    for column, values in (('position_recorded', original.position),
                           ('position_simulated', original.position),
                           ('effort_simulated', original.effort)):
        assert [float(r[column]) for r in table] == values.tolist()


BAD_RECORD = b'not an mcap file at all'


@pytest.mark.ros
@pytest.mark.parametrize('case, message', [
    ('no record', '{tmp}/none.mcap does not exist; pass a .mcap recording or a .csv file'),
    ('malformed record', '{tmp}/bad.mcap is not an MCAP file (it does not start with the MCAP '
                         'magic bytes); pass a rosbag2 MCAP file or a CSV'),
    ('no scene', "scene file '{tmp}/none.yaml' does not exist"),
    ('malformed scene', "bad.yaml is not valid YAML: expected ',' or ']', but got "
                        "'<stream end>' at line 4, column 1"),
    ('unusable scene', 'm must be > 0 kg, got -1.0'),
    ('controller not importable', "controller 'twin_laws:missing' cannot be imported: "
                                  "AttributeError: module 'twin_laws' has no attribute "
                                  "'missing'"),
    ('controller raises', 'the controller raised ZeroDivisionError: no torque today at '
                          't = 0 s'),
    ('malformed campaign', "{tmp}/spaces.yaml must hold a 'parameters:' mapping of node "
                           'parameters to values or distributions (as pendulum_identify '
                           'writes it)'),
    ('target at the start', 'target 0.1 equals the initial value 0.1: a step of zero size has '
                            'no rise or settling time'),
])
def test_bad_input_exits_2_with_one_line_and_writes_nothing(
        recorded: tuple[Path, Path, ClosedLoopRun], tmp_path: Path, case: str, message: str,
        capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    path, scene, _ = recorded
    (tmp_path / 'twin_laws.py').write_text(
        'def bad(t, position, velocity):\n    raise ZeroDivisionError("no torque today")\n')
    monkeypatch.syspath_prepend(str(tmp_path))
    (tmp_path / 'bad.mcap').write_bytes(BAD_RECORD)
    (tmp_path / 'bad.yaml').write_text('/**:\n  ros__parameters:\n    m: [1\n')
    (tmp_path / 'spaces.yaml').write_text('gamma: 0.3\n')
    args = {'record': str(path), '--scene': str(scene), '--controller': PD,
            '--target': str(TARGET)}
    args.update({
        'no record': {'record': str(tmp_path / 'none.mcap')},
        'malformed record': {'record': str(tmp_path / 'bad.mcap')},
        'no scene': {'--scene': str(tmp_path / 'none.yaml')},
        'malformed scene': {'--scene': str(tmp_path / 'bad.yaml')},
        'unusable scene': {'--scene': str(write_scene(tmp_path / 'neg.yaml', m=-1.0))},
        'controller not importable': {'--controller': 'twin_laws:missing'},
        'controller raises': {'--controller': 'twin_laws:bad'},
        'malformed campaign': {'--campaign': str(tmp_path / 'spaces.yaml')},
        'target at the start': {'--target': '0.1'},
    }[case])
    out = tmp_path / 'out'
    argv = [args.pop('record'), *[x for kv in args.items() for x in kv], '--out', str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err == f'pendulum_twin: error: {message.format(tmp=tmp_path)}\n'
    assert not out.exists()


@pytest.mark.ros
def test_a_controller_that_raises_fails_the_twin_in_its_own_process(
        recorded: tuple[Path, Path, ClosedLoopRun], tmp_path: Path) -> None:
    path, scene, _ = recorded
    (tmp_path / 'twin_laws.py').write_text(
        'def late(t, position, velocity):\n'
        '    if t >= 0.5:\n        raise RuntimeError("lost the encoder")\n    return 0.0\n')
    out = tmp_path / 'out'
    res = subprocess.run([str(SCRIPT), str(path), '--scene', str(scene), '--controller',
                          'twin_laws:late', '--out', str(out)], capture_output=True, text=True,
                         timeout=300, check=False, cwd=tmp_path,
                         env={**os.environ, 'PYTHONPATH': os.pathsep.join(
                             [str(tmp_path), os.environ.get('PYTHONPATH', '')])})
    assert (res.returncode, res.stdout) == (2, '')
    assert res.stderr == ('pendulum_twin: error: the controller raised RuntimeError: lost the '
                          'encoder at t = 0.5 s\n')
    assert not out.exists()


@pytest.mark.ros
def test_the_api_refuses_what_it_cannot_run(recorded: tuple[Path, Path, ClosedLoopRun],
                                            tmp_path: Path) -> None:
    path, scene, _ = recorded
    write_spaces(tmp_path / 'spaces.yaml', 0.3, 0.02)
    with pytest.raises(TestingError, match=r"^a campaign needs the controller by name "
                                           r"\('module:function'\); <function \S+<lambda> "
                                           r'at 0x[0-9a-f]+> cannot be imported by one: pass '
                                           r'its name, or episodes=0$'):
        twin(path, str(scene), lambda t, x, v: 0.0, target=TARGET,
             campaign=tmp_path / 'spaces.yaml')
    with pytest.raises(TestingError, match=r'^episodes must be an integer >= 0, got -1$'):
        twin(path, str(scene), PD, episodes=-1)
    with pytest.raises(TestingError, match=r'^target must be a finite number \(rad\), got nan$'):
        twin(path, str(scene), PD, target=math.nan)
    with pytest.raises(ControllerFailed, match=r'^the controller returned nan at t = 0 s; a '
                                               r'command must be finite$'):
        twin(path, str(scene), lambda t, x, v: math.nan)
    # Without a target there is a fit and no metrics; a lambda needs no name then.
    report = twin(path, str(scene), lambda t, x, v: pd(t, x, v, target=TARGET))
    assert report.fit_percent == 100.0 and report.metrics == ()
