"""The package builds in a colcon workspace and installs what ``ros2 run`` and scenes need.

A real ``colcon build`` of this repository into a temporary workspace, then the executable is
resolved through the ament index exactly as ``ros2 run pendulum_sim pendulum_node`` does
(``get_package_prefix`` + ``lib/<package>/<executable>``), and run from there.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
VENV_BIN = Path(sys.executable).parent

pytestmark = pytest.mark.slow


@pytest.fixture(scope='module')
def workspace(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Build the package with colcon into a fresh workspace; return the workspace."""
    colcon = VENV_BIN / 'colcon'
    if not colcon.is_file():
        pytest.fail(f'colcon is not installed in the venv ({colcon})')
    ws = tmp_path_factory.mktemp('colcon_ws')
    env = dict(os.environ, PATH=f'{VENV_BIN}{os.pathsep}{os.environ.get("PATH", "")}')
    result = subprocess.run(
        [str(colcon), '--log-base', str(ws / 'log'), 'build', '--base-paths', str(REPO),
         '--build-base', str(ws / 'build'), '--install-base', str(ws / 'install')],
        cwd=ws, env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    assert 'Finished <<< pendulum_sim' in result.stdout
    return ws


def installed_env(prefix: Path) -> dict[str, str]:
    """Return the environment a sourced workspace would give: ament index and Python path."""
    site = next((prefix / 'lib').glob('python3*/site-packages'))
    return dict(os.environ, AMENT_PREFIX_PATH=str(prefix), PYTHONPATH=str(site))


def test_executable_resolves_like_ros2_run(workspace: Path,
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """get_package_prefix finds the install; lib/pendulum_sim/pendulum_node is executable."""
    from ament_index_python.packages import get_package_prefix, get_package_share_directory

    install = workspace / 'install' / 'pendulum_sim'
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(install))
    prefix = Path(get_package_prefix('pendulum_sim'))
    assert prefix == install
    for name in ('pendulum_node', 'pendulum_pd_controller'):
        exe = prefix / 'lib' / 'pendulum_sim' / name
        assert exe.is_file(), name
        assert os.access(exe, os.X_OK), name
    share = Path(get_package_share_directory('pendulum_sim'))
    assert (share / 'package.xml').read_text() == (REPO / 'package.xml').read_text()
    installed = sorted(p.name for p in (share / 'config').glob('*.yaml'))
    assert installed == sorted(p.name for p in (REPO / 'config').glob('*.yaml'))
    assert {'default.yaml', 'paper.yaml', 'stiff.yaml', 'noisy_sensor.yaml', 'lockstep.yaml',
            'minimal.yaml'} <= set(installed)
    assert (share / 'urdf' / 'pendulum.urdf').is_file()


def test_installed_node_finds_installed_scenes(workspace: Path) -> None:
    """Run from the workspace, the node lists the scenes of its share folder."""
    prefix = workspace / 'install' / 'pendulum_sim'
    env = installed_env(prefix)
    exe = prefix / 'lib' / 'pendulum_sim' / 'pendulum_node'
    result = subprocess.run([str(exe), '--list-scenes'], env=env, cwd=workspace,
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == sorted(p.stem for p in (REPO / 'config').glob('*.yaml'))
    assert 'controller_test' in result.stdout.split()
    # The example controller runs from the workspace too (its help needs no DDS).
    ctl = prefix / 'lib' / 'pendulum_sim' / 'pendulum_pd_controller'
    result = subprocess.run([str(ctl), '--help'], env=env, cwd=workspace,
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith('usage: pendulum_pd_controller')
    probe = ('import pendulum_sim.joint.scenes as s; print(s.__file__); '
             "print(s.find_scene('paper'))")
    result = subprocess.run([sys.executable, '-c', probe], env=env, cwd=workspace,
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    module, scene = result.stdout.split()
    assert Path(module).is_relative_to(prefix)
    assert Path(scene) == prefix / 'share' / 'pendulum_sim' / 'config' / 'paper.yaml'
