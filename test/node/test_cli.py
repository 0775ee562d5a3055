"""pendulum_node's command line, from outside: bad input exits 2 with the reason, signals exit 0.

Every case runs the installed executable in its own process (issue 11 item 13, issue 8 item 5).
"""
from __future__ import annotations

import signal
import subprocess
import time
from pathlib import Path

import pytest
from node_harness import REPO, NodeProcess, Probe, node_command
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import JointState

from pendulum_sim.joint.scenes import is_own_section, unknown_parameter

pytestmark = pytest.mark.ros

SCENES = sorted(p.stem for p in (REPO / 'config').glob('*.yaml'))


def run_node(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    """Run pendulum_node with ``args`` to its end (it must end by itself within 30 s)."""
    return subprocess.run(node_command() + args, cwd=cwd, capture_output=True, text=True,
                          timeout=30)


FILES = {
    'typo.yaml': '/**:\n  ros__parameters:\n    gama: 5.0\n',
    'nested_typo.yaml': '/**:\n  ros__parameters:\n    sensor:\n      seeed: 3\n',
    'broken.yaml': '/**:\n  ros__parameters:\n    gamma: [1.0\n',
    'list.yaml': '- gamma\n- 1.0\n',
    'empty.yaml': '',
    'no_params.yaml': 'pendulum_node:\n  gamma: 1.0\n',
    'far_off.yaml': 'pendulum_node:\n  ros__parameters:\n    zzzzzz: 1\n',
}

CASES = [
    (['--scene', 'typo.yaml'],
     "unknown parameter 'gama' in typo.yaml (did you mean 'gamma'?)"),
    (['--scene', 'nested_typo.yaml'],
     "unknown parameter 'sensor.seeed' in nested_typo.yaml (did you mean 'sensor.seed'?)"),
    (['--ros-args', '--params-file', 'typo.yaml'],
     "unknown parameter 'gama' in typo.yaml (did you mean 'gamma'?)"),
    (['--scene', 'far_off.yaml'], "unknown parameter 'zzzzzz' in far_off.yaml"),
    (['--ros-args', '-p', 'gama:=5.0'],
     "unknown parameter 'gama' in -p gama:=5.0 (did you mean 'gamma'?)"),
    (['--scene', 'default', '--ros-args', '-p', 'publish_rte:=5.0'],
     "unknown parameter 'publish_rte' in -p publish_rte:=5.0 (did you mean 'publish_rate'?)"),
    (['--scene', 'broken.yaml'],
     "broken.yaml is not valid YAML: expected ',' or ']', but got '<stream end>' at line 4, "
     'column 1'),
    (['--ros-args', '--params-file', 'broken.yaml'],
     "broken.yaml is not valid YAML: expected ',' or ']', but got '<stream end>' at line 4, "
     'column 1'),
    (['--scene', 'list.yaml'],
     'list.yaml must map node names to {ros__parameters: {...}}, got a list'),
    (['--scene', 'empty.yaml'],
     'empty.yaml must map node names to {ros__parameters: {...}}, got nothing'),
    (['--scene', 'no_params.yaml'],
     "no_params.yaml: section 'pendulum_node' must hold ros__parameters: {name: value, ...}"),
    (['--scene', 'missing.yaml'], "scene file 'missing.yaml' does not exist"),
    (['--ros-args', '-p'], '-p needs name:=value'),
    (['--ros-args', '-p', 'gamma'], "-p needs name:=value, got 'gamma'"),
    (['--ros-args', '--params-file'], '--params-file needs a YAML file'),
    (['--ros-args', '--params-file', 'missing.yaml'],
     "parameter file 'missing.yaml' does not exist"),
    (['--ros-args', '--log-level', 'bogus'],
     '--log-level must be one of debug, info, warn, error, fatal, unset (or logger:=level), '
     "got 'bogus'"),
    (['--ros-args', '-r', 'foo'], "-r needs from:=to, got 'foo'"),
    (['--ros-args', '--remap', 'a:='], "--remap needs from:=to, got 'a:='"),
    (['--ros-args', '--bogus'],
     "unknown ROS argument '--bogus' (see ros2 run --help or "
     'https://docs.ros.org/en/jazzy/How-To-Guides/Node-arguments.html)'),
    # What only rcl knows (the YAML of a -p value) is still a clean exit 2 with rcl's reason.
    (['--ros-args', '-p', 'gamma:=[1.0'],
     "invalid ROS arguments: Failed to parse ROS arguments: Couldn't parse parameter override "
     "rule: '-p gamma:=[1.0'. Error: Error parsing an event"),
]


@pytest.mark.parametrize(('args', 'reason'), CASES, ids=[' '.join(a) for a, _ in CASES])
def test_bad_input_exits_2_with_the_reason(tmp_path: Path, args: list[str], reason: str) -> None:
    """Each bad argument or file: exit 2, exactly one line 'pendulum_node: <reason>', no trace."""
    for name, text in FILES.items():
        (tmp_path / name).write_text(text)
    done = run_node(args, tmp_path)
    assert (done.returncode, done.stderr, done.stdout) == (2, f'pendulum_node: {reason}\n', '')


def test_closest_name_comes_from_the_declared_parameters() -> None:
    """The hint is difflib's closest declared name; rclpy's own names and QoS overrides pass."""
    assert unknown_parameter('dphi', 'x') == (
        "unknown parameter 'dphi' in x (did you mean 'dphi0'?)")
    assert unknown_parameter('use_sim_time', 'x') is None
    assert unknown_parameter('qos_overrides./joint_states.publisher.depth', 'x') is None
    assert unknown_parameter('recording.overwrite', 'x') is None
    assert [is_own_section(k) for k in ('/**', 'pendulum_node', '/ns/pendulum_node', '/ns/*',
                                        'other_node', '/ns/other', 'pendulum_node_2')] == [
        True, True, True, True, False, False, False]


def _wait_up(probe: Probe, nodes: list[NodeProcess]) -> None:
    """Wait until every node's joint_states publisher is in the graph (the node is built).

    The graph, not a message: a synchronous lockstep scene publishes only when commanded.
    """
    def up() -> bool:
        return all(probe.node.count_publishers(f'{n.namespace}/joint_states') >= 1
                   for n in nodes) or not all(n.alive() for n in nodes)

    probe.spin_until(up, 30.0, 'the joint_states publisher of every node')
    for node in nodes:
        assert node.alive(), node.output()


def _wait_publishing(probe: Probe, node: NodeProcess) -> None:
    """Wait until the node publishes joint_states."""
    got = probe.subscribe(JointState, f'{node.namespace}/joint_states', qos_profile_sensor_data)
    probe.spin_until(lambda: len(got) >= 2 or not node.alive(), 30.0, 'joint_states')
    assert node.alive(), node.output()


@pytest.mark.parametrize('scene', [s if s in ('default', 'minimal') else pytest.param(
    s, marks=pytest.mark.slow) for s in SCENES])
def test_sigint_and_sigterm_exit_0_in_every_scene(tmp_path: Path, scene: str,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """Ctrl-C and SIGTERM while running: exit 0, no FATAL, no traceback, in every scene."""
    monkeypatch.chdir(tmp_path)  # the record scene writes into the working folder
    with NodeProcess(scene) as by_int, NodeProcess(scene) as by_term, Probe() as probe:
        _wait_up(probe, [by_int, by_term])
        for node, sig in ((by_int, signal.SIGINT), (by_term, signal.SIGTERM)):
            code = node.stop(sig)
            out = node.output()
            assert code == 0, out
            assert 'Traceback' not in out and 'FATAL' not in out, out


def _catches_sigterm(pid: int) -> bool:
    """Return True once process ``pid`` handles SIGTERM (its SigCgt mask in /proc says so)."""
    with open(f'/proc/{pid}/status') as fh:
        mask = next(int(line.split()[1], 16) for line in fh if line.startswith('SigCgt:'))
    return bool(mask >> (signal.SIGTERM - 1) & 1)


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_a_signal_during_start_up_exits_0(sig: int) -> None:
    """A signal as soon as main() handles signals (before rclpy is even imported): exit 0."""
    node = NodeProcess('default').start()
    assert node.proc is not None
    end = time.monotonic() + 30.0
    while not _catches_sigterm(node.proc.pid):
        assert node.alive() and time.monotonic() < end, node.output()
        time.sleep(0.001)
    code = node.stop(sig)
    out = node.output()
    assert code == 0, out
    assert 'Traceback' not in out and 'FATAL' not in out, out


def test_other_nodes_sections_are_not_checked(tmp_path: Path) -> None:
    """A params file with sections for other nodes starts; only ours is checked and applied."""
    params = tmp_path / 'shared.yaml'
    params.write_text('/**:\n  ros__parameters:\n    phi0: 0.25\n'
                      'controller_manager:\n  ros__parameters:\n    update_rate: 100\n'
                      '/arm/other_node:\n  ros__parameters:\n    gama: 1.0\n')
    with NodeProcess('minimal', params_file=params) as node, Probe() as probe:
        _wait_publishing(probe, node)
        assert probe.get_parameters(node.fqn, ['phi0']) == {'phi0': 0.25}
        assert node.stop(signal.SIGINT) == 0, node.output()
