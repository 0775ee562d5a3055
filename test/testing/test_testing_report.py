"""pendulum_report closed-loop and ClosedLoopRun.plot: the verdict and the figure of a run."""
from __future__ import annotations

import csv
import re
import subprocess
import sys
from dataclasses import replace
from functools import partial
from pathlib import Path

import pytest

from pendulum_sim.controller.pd_law import PDGains, pd_torque
from pendulum_sim.testing import closed_loop

pytestmark = pytest.mark.ros   # recordings are serialized with rclpy

PD_CONTROLLER = str(Path(sys.executable).parent / 'pendulum_pd_controller')
PNG = b'\x89PNG\r\n\x1a\n'


def report(*args: str) -> subprocess.CompletedProcess[str]:
    script = Path(sys.executable).parent / 'pendulum_report'
    return subprocess.run([str(script), 'closed-loop', *args], capture_output=True, text=True,
                          timeout=120)


def pd(t: float, position: float, velocity: float) -> float:
    return pd_torque(PDGains(), position, velocity)


def read_metrics(path: Path) -> dict[str, float]:
    with path.open() as fh:
        return {row['metric']: float(row['value']) for row in csv.DictReader(fh)}


def test_the_report_of_a_node_recording_has_the_metrics_of_the_in_process_run(
        tmp_path: Path) -> None:
    mcap = tmp_path / 'node.mcap'
    closed_loop([PD_CONTROLLER], periods=200, record=mcap)
    out = tmp_path / 'report'
    proc = report(str(mcap), '--out', str(out), '--target', '0.5')
    assert proc.returncode == 0, proc.stderr
    from pendulum_sim.testing.record import load_run

    # The node records states 0..200 and the answers it took: the run in the file is every
    # answered state (the answer to state 200 may arrive before or after the node stops).
    n = load_run(mcap).t.size
    assert n in (200, 201)
    expected = closed_loop(pd, periods=n).metrics(0.5).as_dict()
    got = read_metrics(out / 'metrics.csv')
    assert got == expected          # bit for bit: the same run, read back from the node's file
    summary = (out / 'summary.md').read_text()
    assert summary.startswith('# Closed loop: node.mcap\n')
    assert f'| settling_time | {expected["settling_time"]:.6g} |' in summary
    assert '![closed loop](closed_loop.png)' in summary
    assert (out / 'closed_loop.png').read_bytes().startswith(PNG)


def test_plot_draws_the_same_figure_and_a_recording_keeps_a_known_target(
        tmp_path: Path) -> None:
    from pendulum_sim.testing.record import load_run, write_run

    run = closed_loop(partial(pd), periods=150).with_target(0.5)
    path = run.plot(tmp_path / 'plot.png')
    assert path.read_bytes().startswith(PNG)
    mcap = write_run(run, tmp_path / 'run.mcap')
    assert load_run(mcap).target == 0.5
    proc = report(str(mcap), '--out', str(tmp_path / 'r'))     # the target from the file
    assert proc.returncode == 0, proc.stderr
    assert read_metrics(tmp_path / 'r' / 'metrics.csv') == run.metrics().as_dict()


def test_a_joint_name_with_a_nul_is_refused_before_anything_is_written(tmp_path: Path) -> None:
    # rclpy's serialization passes C strings: the NUL would end the recorded name at 'a'.
    from pendulum_sim.testing.errors import TestingError
    from pendulum_sim.testing.record import write_run

    run = closed_loop(pd, periods=5)
    message = ("joint_name must hold no control characters (a URDF or a log would not show "
               "them), got 'a\\x00b' with '\\x00'")
    with pytest.raises(TestingError, match=f'^{re.escape(message)}$'):
        write_run(run, tmp_path / 'run.mcap', joint_name='a\x00b')
    with pytest.raises(TestingError, match=f'^{re.escape(message)}$'):
        write_run(replace(run, parameters={**run.parameters, 'joint_name': 'a\x00b'}),
                  tmp_path / 'run.mcap')
    assert not (tmp_path / 'run.mcap').exists()


def test_a_recording_without_target_or_closed_loop_exits_2_with_the_reason(
        tmp_path: Path) -> None:
    mcap = tmp_path / 'run.mcap'
    closed_loop(pd, periods=20, record=mcap)
    proc = report(str(mcap), '--out', str(tmp_path / 'r'))
    assert proc.returncode == 2
    assert proc.stderr.splitlines()[-1] == (f'pendulum_report closed-loop: error: {mcap} does '
                                            'not say its target; give it with --target')
    proc = report(str(tmp_path / 'none.mcap'), '--out', str(tmp_path / 'r'))
    assert proc.returncode == 2
    assert re.search(r"error: recording '.*none\.mcap' does not exist$", proc.stderr.strip())
