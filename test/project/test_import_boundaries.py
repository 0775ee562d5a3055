"""What each layer may import: the ROS-free parts load without ROS (and the light ones without
plotting, scipy or Dask), checked in a fresh interpreter so nothing imported by another test
hides a dependency; and no module of the package imports itself back, through however many
others (every import statement counts, inside a function or under TYPE_CHECKING too)."""
from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / 'pendulum_sim'

ROS = ('rclpy', 'rcl_interfaces', 'sensor_msgs', 'std_msgs', 'rosgraph_msgs',
       'builtin_interfaces')

CASES = {
    'core': ('import pendulum_sim.core, pendulum_sim.core.analysis', ROS),
    'sweep': ('import pendulum_sim.core.sweep', (*ROS, 'scipy', 'matplotlib')),
    'joint': ('import pendulum_sim.joint.joint', ROS),
    'exchange': ('import pendulum_sim.joint.exchange', ROS),
    'controller law': ('import pendulum_sim.controller, pendulum_sim.controller.pd_law', ROS),
    'test bench': ('import pendulum_sim.testing as t; t.step_metrics; t.closed_loop; '
                   't.vectorised; t.ClosedLoopRun; t.twin; t.TwinReport; '
                   'import pendulum_sim.testing.twin_cli; '
                   'import pendulum_sim.testing.pytest_plugin; '
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


def _module_files() -> dict[str, Path]:
    """Return every module of the package by its dotted name (a package by its own)."""
    out = {}
    for path in sorted(PACKAGE.rglob('*.py')):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix('').parts)
        if parts[-1] == '__init__':
            parts.pop()
        out['.'.join(parts)] = path
    return out


def import_graph() -> dict[str, set[str]]:
    """Return, per module, the modules of the package it imports anywhere in its text.

    ``from P import name`` is an import of the module ``P.name`` where there is one, else of
    ``P``; relative imports are resolved against the module's package.
    """
    files = _module_files()
    graph: dict[str, set[str]] = {}
    for name, path in files.items():
        package = name if path.name == '__init__.py' else name.rsplit('.', 1)[0]
        found: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
            if isinstance(node, ast.Import):
                found.update(a.name for a in node.names if a.name in files)
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ''
                if node.level:
                    up = package.rsplit('.', node.level - 1)[0] if node.level > 1 else package
                    base = f'{up}.{base}' if base else up
                for alias in node.names:
                    sub = f'{base}.{alias.name}'
                    if sub in files:
                        found.add(sub)
                    elif base in files:
                        found.add(base)
        graph[name] = found - {name}
    return graph


def find_circle(graph: dict[str, set[str]]) -> list[str]:
    """Return one circle of imports (a list of modules, the first again at the end), or []."""
    state: dict[str, int] = {}   # 1: on the path being walked, 2: done

    def walk(node: str, path: list[str]) -> list[str]:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return [*path[path.index(nxt):], nxt]
            if nxt not in state:
                found = walk(nxt, path)
                if found:
                    return found
        path.pop()
        state[node] = 2
        return []

    for start in sorted(graph):
        if start not in state:
            found = walk(start, [])
            if found:
                return found
    return []


def test_the_import_graph_sees_imports_inside_functions() -> None:
    graph = import_graph()
    # closed_loop imports the DDS path and the recorder only when it needs them.
    assert graph['pendulum_sim.testing.loop'] >= {'pendulum_sim.testing.ros',
                                                  'pendulum_sim.testing.record',
                                                  'pendulum_sim.testing.run'}
    assert find_circle({'a': {'b'}, 'b': {'c'}, 'c': {'a'}, 'd': {'a'}}) == ['a', 'b', 'c', 'a']


def test_no_module_imports_itself_back() -> None:
    circle = find_circle(import_graph())
    assert circle == [], 'import circle: ' + ' -> '.join(circle)


def test_the_test_bench_imports_nothing_of_the_reports() -> None:
    # The reports draw the test bench's runs; the test bench never reaches up into them.
    graph = import_graph()
    up = sorted(f'{m} -> {d}' for m, deps in graph.items() if m.startswith('pendulum_sim.testing')
                for d in deps if d.startswith('pendulum_sim.reports'))
    assert up == []


LAYERS = ('pendulum_sim.testing', 'pendulum_sim.gym', 'pendulum_sim.identify',
          'pendulum_sim.joint')


@pytest.mark.parametrize('layer', LAYERS)
def test_nothing_below_the_node_reaches_into_it(layer: str) -> None:
    # The joint, the test bench, Gymnasium and identification drive the ROS-free joint; only
    # the ROS adapter (and the DDS path's command line, by process) stands above it.
    graph = import_graph()
    up = sorted(f'{m} -> {d}' for m, deps in graph.items() if m.startswith(layer)
                for d in deps if d.startswith('pendulum_sim.node'))
    assert up == []


def test_the_joint_imports_only_the_core_and_itself() -> None:
    graph = import_graph()
    allowed = ('pendulum_sim.joint', 'pendulum_sim.core', 'pendulum_sim.dds')
    out = sorted(f'{m} -> {d}' for m, deps in graph.items() if m.startswith('pendulum_sim.joint')
                 for d in deps if not d.startswith(allowed))
    assert out == []


@pytest.mark.parametrize('name', ['joint', 'parameters', 'scenes', 'servo', 'urdf'])
def test_an_old_joint_name_imports_the_moved_module_with_a_warning(name: str) -> None:
    code = ('import importlib, sys, warnings\n'
            'with warnings.catch_warnings(record=True) as seen:\n'
            '    warnings.simplefilter("always")\n'
            f'    old = importlib.import_module("pendulum_sim.node.{name}")\n'
            f'new = importlib.import_module("pendulum_sim.joint.{name}")\n'
            'print(old is new, old.__spec__.name, [str(w.message) for w in seen '
            'if w.category is DeprecationWarning])')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == (f"True pendulum_sim.joint.{name} ['pendulum_sim.node.{name} moved to "
                   f"pendulum_sim.joint.{name}; import it from there']")
