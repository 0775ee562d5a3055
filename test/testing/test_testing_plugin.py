"""The pytest plugin: a user's test suite run by a real pytest process, as in CI."""
from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from pendulum_sim.controller.pd_law import PDGains, pd_torque
from pendulum_sim.testing import closed_loop

pytestmark = pytest.mark.ros   # the recording left behind is serialized with rclpy

USER_TESTS = """
from pendulum_sim.controller.pd_law import PDGains, pd_torque

GAINS = PDGains(kd=0.2)


def my_law(t, position, velocity):
    return pd_torque(GAINS, position, velocity)


def test_settles_fast(closed_loop):
    run = closed_loop(my_law, periods=1000)
    assert run.metrics(0.5).settling_time < 0.5


def test_settles_at_all(closed_loop):
    run = closed_loop(my_law, periods=1000)
    assert run.metrics(0.5).settling_time < 100.0
"""


def test_a_failing_controller_test_prints_the_metrics_and_leaves_figure_and_mcap(
        tmp_path: Path) -> None:
    (tmp_path / 'test_user.py').write_text(textwrap.dedent(USER_TESTS))
    proc = subprocess.run([sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider',
                           '--rootdir', str(tmp_path), str(tmp_path / 'test_user.py')],
                          capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert '1 failed, 1 passed' in proc.stdout
    law_run = closed_loop(lambda t, p, v: pd_torque(PDGains(kd=0.2), p, v), periods=1000)
    expected = law_run.metrics(0.5)
    out = proc.stdout
    assert 'closed_loop' in out and 'metrics towards 0.5:' in out
    assert f'settling_time = {expected.settling_time:.6g}' in out
    assert f'overshoot = {expected.overshoot:.6g}' in out
    folder = tmp_path / 'test_settles_fast'
    assert (folder / 'closed_loop.png').read_bytes().startswith(b'\x89PNG')
    assert not (tmp_path / 'test_settles_at_all').exists()   # passed: nothing left behind
    from pendulum_sim.testing.record import load_run

    back = load_run(folder / 'run.mcap')
    assert back.target == 0.5
    np.testing.assert_array_equal(back.position, law_run.position)
    np.testing.assert_array_equal(back.command, law_run.command)
