"""What each layer may import: the ROS-free parts load without ROS (and the light ones without
plotting, scipy or Dask), checked in a fresh interpreter so nothing imported by another test
hides a dependency."""
from __future__ import annotations

import subprocess
import sys

import pytest

ROS = ('rclpy', 'rcl_interfaces', 'sensor_msgs', 'std_msgs', 'rosgraph_msgs',
       'builtin_interfaces')

CASES = {
    'core': ('import pendulum_sim.core, pendulum_sim.core.analysis', ROS),
    'sweep': ('import pendulum_sim.core.sweep', (*ROS, 'scipy', 'matplotlib')),
    'joint': ('import pendulum_sim.node.joint', ROS),
    'exchange': ('import pendulum_sim.node.exchange', ROS),
    'controller law': ('import pendulum_sim.controller, pendulum_sim.controller.pd_law', ROS),
    'test bench': ('import pendulum_sim.testing as t; t.step_metrics; t.closed_loop; '
                   't.vectorised; t.ClosedLoopRun; import pendulum_sim.testing.pytest_plugin; '
                   'import pendulum_sim.testing.campaign.cli, '
                   'pendulum_sim.testing.campaign.execute',
                   (*ROS, 'matplotlib', 'dask', 'distributed')),
    'identify': ('import pendulum_sim.identify as i; i.fit; i.compare; '
                 'import pendulum_sim.identify.cli, pendulum_sim.identify.outputs',
                 (*ROS, 'matplotlib')),
}


@pytest.mark.parametrize('name', CASES)
def test_a_layer_imports_only_what_it_needs(name: str) -> None:
    statement, forbidden = CASES[name]
    code = (f'import sys; {statement}; '
            f'print(sorted({{m.split(".")[0] for m in sys.modules}} & {set(forbidden)!r}))')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == '[]', f'{name} imports {out.stdout.strip()}'
