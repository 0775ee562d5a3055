"""The core's structure: imports in one direction, no class over 250 lines, no ROS."""
from __future__ import annotations

import ast
from pathlib import Path

CORE = Path(__file__).resolve().parents[2] / 'pendulum_sim' / 'core'


def _modules() -> dict[str, ast.Module]:
    return {p.stem: ast.parse(p.read_text(encoding='utf-8')) for p in sorted(CORE.glob('*.py'))}


def _imports(tree: ast.Module) -> set[str]:
    """Return the core modules a module imports (``from .x import``, ``from . import x``)."""
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            if node.module:
                out.add(node.module.split('.')[0])
            else:
                out.update(alias.name for alias in node.names)
    return out


def test_core_import_graph_has_no_cycle() -> None:
    mods = _modules()
    graph = {name: _imports(tree) & set(mods) for name, tree in mods.items()}
    assert graph['engine'] >= {'embedded', 'problem', 'careful', 'decisions'}
    # Kahn's algorithm: every module is removed once all it imports is removed.
    left = dict(graph)
    while left:
        ready = [m for m, deps in left.items() if not deps & set(left)]
        assert ready, f'import cycle among {sorted(left)}'
        for m in ready:
            del left[m]


def test_no_import_hides_behind_type_checking() -> None:
    for name, tree in _modules().items():
        names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
        assert 'TYPE_CHECKING' not in names, name


def test_no_core_class_over_250_lines() -> None:
    sizes = {f'{name}.{node.name}': node.end_lineno - node.lineno + 1
             for name, tree in _modules().items() for node in ast.walk(tree)
             if isinstance(node, ast.ClassDef) and node.end_lineno is not None}
    assert sizes['engine.Engine'] > 100
    assert {k: v for k, v in sizes.items() if v > 250} == {}


def test_core_imports_only_stdlib_numpy_and_numba() -> None:
    allowed_third_party = {'numpy', 'numba'}
    for name, tree in _modules().items():
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                tops = {alias.name.split('.')[0] for alias in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                tops = {node.module.split('.')[0]}
            else:
                continue
            for top in tops:
                assert top in allowed_third_party or top in _stdlib(), (name, top)


def _stdlib() -> frozenset[str]:
    import sys

    return frozenset(sys.stdlib_module_names) | {'__future__'}
