"""Write the reference tables of the docs from the code's own data.

One generator for every table: the node's parameters (``pendulum_sim.joint.parameters.SPECS``),
its ``/diagnostics`` keys (``pendulum_sim.node.diagnostics.KEYS``), the scenes
(``config/*.yaml``) and the options of every console script the package installs (their
argparse parsers). The Sphinx build runs it first (this module is also a Sphinx extension), so
the tables are never stale; ``make docs-reference`` runs it alone::

    python docs/_ext/reftables.py docs/reference/_generated
"""
from __future__ import annotations

import argparse
import importlib
import importlib.metadata
import math
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
GENERATED = ROOT / 'docs' / 'reference' / '_generated'
DISTRIBUTION = 'pendulum_sim'
DASH = '—'


def cell(text: object) -> str:
    """Return ``text`` as one Markdown table cell (pipes escaped, no line breaks)."""
    return str(text).replace('|', '\\|').replace('\n', ' ').strip() or DASH


def code(text: object) -> str:
    """Return ``text`` as inline code for a table cell."""
    return f'`{str(text).replace("|", "¦")}`'


def table(header: list[str], rows: list[list[str]]) -> str:
    """Return a Markdown pipe table."""
    lines = ['| ' + ' | '.join(header) + ' |', '|' + '---|' * len(header)]
    lines += ['| ' + ' | '.join(row) + ' |' for row in rows]
    return '\n'.join(lines) + '\n'


# ---------------------------------------------------------------- node parameters
def type_name(value: object) -> str:
    """Return the ROS parameter type of a default value."""
    if isinstance(value, bool):
        return 'bool'
    if isinstance(value, int):
        return 'integer'
    if isinstance(value, float):
        return 'double'
    return 'string'


def default_text(value: object) -> str:
    """Return a default as written in a scene file (YAML)."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float) and math.isinf(value):
        return '.inf' if value > 0 else '-.inf'
    if isinstance(value, str):
        return f"'{value}'"
    return repr(value)


def range_text(spec: Any) -> str:
    """Return the allowed values of a parameter as its descriptor declares them."""
    if spec.low is not None and spec.high is not None:
        if isinstance(spec.default, int):
            return f'[{int(spec.low)}, {int(spec.high)}]'
        return f'[{float(spec.low)!r}, {float(spec.high)!r}]'
    if spec.constraints:
        return spec.constraints
    return 'any'


def parameters_markdown() -> str:
    """Return the table of every node parameter: default, type, unit, range, live."""
    from pendulum_sim.joint.parameters import SPECS

    rows = [[code(s.name), code(default_text(s.default)), type_name(s.default), cell(s.unit),
             cell(range_text(s)), 'read-only' if s.read_only else 'live', cell(s.description)]
            for s in SPECS]
    return table(['name', 'default', 'type', 'unit', 'range', 'live', 'meaning'], rows)


def controller_markdown() -> str:
    """Return the table of the example controller's parameters (all live)."""
    from pendulum_sim.controller import node_base
    from pendulum_sim.controller import pd_controller as pd

    rows = [[code(name), code(default_text(default)), 'double', f'[{low:g}, {high:g}]',
             cell(text)] for name, default, text, (low, high) in pd._FLOATS]
    rows.append([code('joint_name'), code(default_text(node_base.DEFAULT_JOINT)), 'string',
                 'any', node_base.JOINT_NAME_TEXT])
    return table(['name', 'default', 'type', 'range', 'meaning'], rows)


# ---------------------------------------------------------------- diagnostics keys
def diagnostics_markdown() -> str:
    """Return the table of every ``/diagnostics`` key: type, unit, when present, meaning."""
    from pendulum_sim.node.diagnostics import KEYS

    rows = [[code(k.name), k.type, cell(k.unit), cell(k.when), cell(k.description)]
            for k in KEYS]
    return table(['key', 'type', 'unit', 'present', 'meaning'], rows)


# ---------------------------------------------------------------- scenes
def scene_files() -> list[Path]:
    """Return the scene files of the source tree, sorted by name."""
    return sorted((ROOT / 'config').glob('*.yaml'))


def scene_summary(path: Path) -> str:
    """Return the leading comment of a scene file as one paragraph."""
    lines = []
    for line in path.read_text(encoding='utf-8').splitlines():
        if not line.startswith('#'):
            break
        lines.append(line.lstrip('#').strip())
    return ' '.join(lines)


def scenes_markdown() -> str:
    """Return one section per scene: what it is for and every parameter it sets."""
    from pendulum_sim.joint.parameters import SPEC_BY_NAME
    from pendulum_sim.joint.scenes import read_params_file

    out = [table(['scene', 'what it is for'],
                 [[f'[{p.stem}](#scene-{p.stem})', cell(scene_summary(p))]
                  for p in scene_files()])]
    for path in scene_files():
        values = read_params_file(path)
        rows = []
        for name, value in values.items():
            spec = SPEC_BY_NAME.get(name)
            default = code(default_text(spec.default)) if spec is not None else DASH
            rows.append([code(name), code(default_text(value)), default])
        out.append(f'(scene-{path.stem})=\n## `{path.stem}`\n\n'
                   f'`config/{path.name}`: {scene_summary(path)}\n\n'
                   + table(['parameter', 'value', 'default'], rows))
    return '\n'.join(out)


# ---------------------------------------------------------------- console scripts
class _Captured(Exception):
    def __init__(self, parser: argparse.ArgumentParser) -> None:
        super().__init__(parser.prog)
        self.parser = parser


@contextmanager
def _capture_parse() -> Iterator[None]:
    """Make any ArgumentParser raise itself instead of parsing."""
    saved = argparse.ArgumentParser.parse_known_args

    def capture(self: argparse.ArgumentParser, *args: Any, **kwargs: Any) -> Any:
        raise _Captured(self)

    argparse.ArgumentParser.parse_known_args = capture  # type: ignore[method-assign]
    try:
        yield
    finally:
        argparse.ArgumentParser.parse_known_args = saved  # type: ignore[method-assign]


def console_scripts() -> list[tuple[str, str]]:
    """Return (name, 'module:function') of every console script the package installs."""
    dist = importlib.metadata.distribution(DISTRIBUTION)
    return sorted((ep.name, ep.value) for ep in dist.entry_points
                  if ep.group == 'console_scripts')


def parser_of(target: str) -> argparse.ArgumentParser:
    """Return the argparse parser of a console script ``module:function``.

    A module function named ``build_parser`` or ``_parser`` is called; otherwise the script's
    ``main`` (or the function itself) is called with ``--help`` and stopped where it parses.
    """
    module_name, _, func_name = target.partition(':')
    module = importlib.import_module(module_name)
    for name in ('build_parser', '_parser'):
        builder = getattr(module, name, None)
        if callable(builder):
            parser = builder()
            if isinstance(parser, argparse.ArgumentParser):
                return parser
    main: Callable[..., Any] = getattr(module, 'main', None) or getattr(module, func_name)
    with _capture_parse():
        try:
            main(['--help'])
        except _Captured as captured:
            return captured.parser
    raise RuntimeError(f'{target} did not build an argparse parser')


def option_rows(parser: argparse.ArgumentParser) -> list[list[str]]:
    """Return one row per argument: flags, default, allowed values, help."""
    rows = []
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction):
            continue
        flags = ', '.join(action.option_strings) or (action.metavar or action.dest)
        if action.option_strings and action.nargs != 0:
            flags += f' {action.metavar or action.dest.upper()}'
        if action.nargs == 0 or action.default is None or action.default is argparse.SUPPRESS:
            default = DASH   # a flag, or no default
        else:
            default = code(action.default)
        choices = ', '.join(map(str, action.choices)) if action.choices else DASH
        help_text = (action.help or '') % {'default': action.default, 'prog': parser.prog} \
            if action.help and '%(' in action.help else (action.help or '')
        rows.append([code(flags), default, cell(choices), cell(help_text)])
    return rows


def cli_markdown() -> str:
    """Return one section per console script with its usage and options."""
    out = []
    for name, target in console_scripts():
        parser = parser_of(target)
        usage = ' '.join(parser.format_usage().split())
        out.append(f'(cli-{name})=\n## `{name}`\n\n'
                   f'{cell(parser.description or "")}\n\n'
                   f'```text\n{usage}\n```\n\n'
                   + table(['option', 'default', 'choices', 'meaning'], option_rows(parser))
                   + (f'\n{cell(parser.epilog)}\n' if parser.epilog else ''))
    return '\n'.join(out)


# ---------------------------------------------------------------- benchmark results
def benchmarks_markdown() -> str:
    """Return a table of the benchmarks under bench/: what each measures and its results file.

    The figures stay in ``bench/results/<script>.txt`` (``make bench`` writes them, with the
    machine, the date and the load of that run); the docs name the file, not one run's figures.
    """
    import ast

    rows = []
    for script in sorted((ROOT / 'bench').glob('bench_*.py')):
        doc = ast.get_docstring(ast.parse(script.read_text(encoding='utf-8'))) or ''
        result = ROOT / 'bench' / 'results' / f'{script.stem}.txt'
        stored = f'`bench/results/{result.name}`' if result.is_file() else 'not stored'
        rows.append([f'`bench/{script.name}`', cell(doc.split('\n\n')[0]), stored])
    return table(['benchmark', 'what it measures', 'recorded output'], rows)


# ---------------------------------------------------------------- Python API pages
def api_pages() -> dict[str, str]:
    """Return one autodoc page per package of pendulum_sim: {file name: MyST text}."""
    import pkgutil

    import pendulum_sim

    packages: dict[str, list[str]] = {}
    for info in pkgutil.walk_packages(pendulum_sim.__path__, 'pendulum_sim.'):
        if info.name.endswith('__main__'):
            continue
        package = info.name if info.ispkg else info.name.rsplit('.', 1)[0]
        packages.setdefault(package, [])
        if not info.ispkg:
            packages[package].append(info.name)
    packages.setdefault('pendulum_sim', [])
    pages = {}
    for package, modules in sorted(packages.items()):
        parts = [f'# `{package}`\n', '```{eval-rst}', f'.. automodule:: {package}',
                 '   :no-members:', '']
        parts += _package_names(package)
        parts.append('```\n')
        for module in sorted(modules):
            parts.append(f'## `{module}`\n\n```{{eval-rst}}\n.. automodule:: {module}\n```\n')
        pages[f'{package}.md'] = '\n'.join(parts)
    return pages


def _package_names(package: str) -> list[str]:
    """Return a line naming what a package exports (its ``__all__``), each linked."""
    names = getattr(importlib.import_module(package), '__all__', ())
    if not names:
        return []
    module = importlib.import_module(package)
    links = ', '.join(f':py:obj:`~{package}.{name}`' if callable(getattr(module, name))
                      else f'``{name}``' for name in names)
    return [f'Exported names (documented below, in the module that defines them): {links}.', '']


def exported_target(target: str) -> str | None:
    """Return where a package's exported name ``pkg.name`` is defined, or None if it is not."""
    package, _, name = target.rpartition('.')
    if not package.startswith('pendulum_sim'):
        return None
    try:
        module = importlib.import_module(package)
    except ImportError:
        return None
    if name not in getattr(module, '__all__', ()):
        return None
    obj = getattr(module, name)
    home = getattr(obj, '__module__', None)
    if not isinstance(home, str) or home == package:
        home = next((m for m, mod in sorted(sys.modules.items())
                     if m.startswith(package + '.') and getattr(mod, name, None) is obj), None)
    return None if home is None else f'{home}.{name}'


def _resolve_exported(app: Any, env: Any, node: Any, contnode: Any) -> Any:
    """Resolve ``pkg.name`` to the module that defines a name the package exports."""
    if node.get('refdomain') != 'py':
        return None
    real = exported_target(node['reftarget'])
    if real is None:
        return None
    domain = env.get_domain('py')
    for role in (node['reftype'], 'obj'):
        found = domain.resolve_xref(env, node['refdoc'], app.builder, role, real, node,
                                    contnode)
        if found is not None:
            return found
    return None


# ---------------------------------------------------------------- writing
TABLES: dict[str, Callable[[], str]] = {
    'parameters.md': parameters_markdown,
    'diagnostics.md': diagnostics_markdown,
    'scenes.md': scenes_markdown,
    'cli.md': cli_markdown,
    'benchmarks.md': benchmarks_markdown,
    'controller.md': controller_markdown,
}


NOTICE = '<!-- Generated by docs/_ext/reftables.py from the code; do not edit. -->\n\n'


def _write(path: Path, text: str) -> Path:
    """Write ``text`` to ``path`` unless it holds it already (Sphinx rereads changed files)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.is_file() or path.read_text(encoding='utf-8') != text:
        path.write_text(text, encoding='utf-8')
    return path


def write_all(folder: Path = GENERATED) -> list[Path]:
    """Write every table into ``folder`` and the API pages beside it; return the paths."""
    written = [_write(folder / name, NOTICE + make()) for name, make in TABLES.items()]
    api = folder.parent / 'api'
    pages = api_pages()
    for stale in api.glob('pendulum_sim*.md'):
        if stale.name not in pages:
            stale.unlink()
    written += [_write(api / name, text) for name, text in pages.items()]
    return written


def _on_builder_inited(app: Any) -> None:
    write_all(Path(app.srcdir) / 'reference' / '_generated')


def _escape_bars(app: Any, what: str, name: str, obj: Any, options: Any,
                 lines: list[str]) -> None:
    """Read ``|x|`` in docstrings as an absolute value, not a reST substitution."""
    for i, line in enumerate(lines):
        pieces = line.split('``')
        pieces[::2] = [p.replace('|', '\\|') for p in pieces[::2]]
        lines[i] = '``'.join(pieces)


def setup(app: Any) -> dict[str, Any]:
    """Register with Sphinx: write the tables before the sources are read."""
    app.connect('builder-inited', _on_builder_inited)
    app.connect('autodoc-process-docstring', _escape_bars)
    app.connect('missing-reference', _resolve_exported)
    return {'parallel_read_safe': True, 'parallel_write_safe': True}


if __name__ == '__main__':
    for written_path in write_all(Path(sys.argv[1]) if len(sys.argv) > 1 else GENERATED):
        print(written_path)
