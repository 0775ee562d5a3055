"""The in-process test bench needs no ROS: a closed loop and a campaign episode run where
rclpy and the message packages cannot be imported (a Dask worker without ROS installed)."""
from __future__ import annotations

import subprocess
import sys
import textwrap

BLOCKED = ('rclpy', 'rcl_interfaces', 'builtin_interfaces', 'sensor_msgs', 'std_msgs',
           'rosgraph_msgs', 'diagnostic_msgs', 'std_srvs')

SCRIPT = textwrap.dedent('''
    import importlib.abc
    import sys

    BLOCKED = {blocked!r}


    class NoRos(importlib.abc.MetaPathFinder):
        """Refuse every ROS package, as on a machine without ROS."""

        def find_spec(self, name, path=None, target=None):
            if name.split('.')[0] in BLOCKED:
                raise ImportError(f'{{name}} is blocked: no ROS here')
            return None


    sys.meta_path.insert(0, NoRos())
    try:
        import rclpy  # noqa: F401
    except ImportError as exc:
        print('blocked:', exc)
    else:
        raise SystemExit('the blocker lets rclpy through')

    from pendulum_sim.testing import closed_loop
    from pendulum_sim.testing.campaign.episode import run_episode
    from pendulum_sim.testing.examples import pd

    run = closed_loop(pd, periods=300, overrides={{'phi0': 1.0}})
    print('periods', run.t.size, 'failed', run.failed)
    print('final', repr(float(run.position[-1])))
    text = """
    controller: pendulum_sim.testing.examples:pd
    episodes: 2
    periods: 300
    target: 0.5
    parameters:
      gamma: [0.5, 1.0]
    requirements:
      - 'overshoot < 100'
    """
    row = run_episode(text, 1, None)
    print('episode', row['episode'], 'passed', row['passed'], repr(row['reason']),
          'gamma', row['gamma'])
    print('loaded', sorted(m for m in sys.modules if m.split('.')[0] in BLOCKED))
''')


def test_a_closed_loop_and_a_campaign_episode_run_without_rclpy_or_messages() -> None:
    out = subprocess.run([sys.executable, '-c', SCRIPT.format(blocked=BLOCKED)],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0] == 'blocked: rclpy is blocked: no ROS here'
    assert lines[1] == 'periods 300 failed None'
    # Three seconds of the PD loop from 1 rad: the angle is at the law's target, 0.5 rad.
    assert abs(float(lines[2].split()[1]) - 0.5) < 1e-3
    assert lines[3] == "episode 1 passed True '' gamma 1.0"
    assert lines[4] == 'loaded []'
