"""The pip route: the wheel carries the ament layout that ``ros2 run`` and the scenes rely on."""
from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_wheel_installs_the_ament_marker_package_xml_scenes_and_executables(
        tmp_path: Path) -> None:
    subprocess.run([sys.executable, '-m', 'pip', 'wheel', '--no-deps', '--no-build-isolation',
                    '-q', '-w', str(tmp_path), str(ROOT)], check=True, cwd=tmp_path)
    (wheel,) = tmp_path.glob('pendulum_sim-*.whl')
    names = set(zipfile.ZipFile(wheel).namelist())
    data = 'pendulum_sim-0.1.0.data/data/'
    assert data + 'share/ament_index/resource_index/packages/pendulum_sim' in names
    assert data + 'share/pendulum_sim/package.xml' in names
    scenes = {Path(n).name for n in names if n.startswith(data + 'share/pendulum_sim/config/')}
    assert {p.name for p in (ROOT / 'config').glob('*.yaml')} | {'fastdds_localhost.xml'} == scenes
    assert 'pendulum_sim/py.typed' in names
    assert 'pendulum_sim/foxglove_layout.json' in names   # the Foxglove layout
    assert 'pendulum_sim/testing/swing_up/references.yaml' in names   # benchmark.png's bars
    entry = zipfile.ZipFile(wheel).read('pendulum_sim-0.1.0.dist-info/entry_points.txt').decode()
    for exe in ('pendulum_node', 'pendulum_replay', 'pendulum_report', 'pendulum_demo',
                'pendulum_pd_controller', 'pendulum_swing_up_controller', 'pendulum_benchmark'):
        assert f'{exe} = pendulum_sim.' in entry
    # The ROS-free core ships without ROS in its requirements; the Jazzy wheels are an extra.
    meta = zipfile.ZipFile(wheel).read('pendulum_sim-0.1.0.dist-info/METADATA').decode()
    requires = [ln for ln in meta.splitlines() if ln.startswith('Requires-Dist:')]
    assert all('ros-jazzy' not in ln or 'extra == "ros"' in ln for ln in requires)
    assert any('ros-jazzy-rclpy==7.1.6' in ln for ln in requires)
