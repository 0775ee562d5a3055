"""Turn generated source into functions: the core's one place that compiles generated code.

The steps, damping laws and decisions of the core are generated as Python source
(``explicit.py``, ``rosenbrock.py``, ``extrapolation.py``, ``decisions.py``) and specialised by
the names they read (the exponent ``n``, the constants of a pendulum) through the namespace they
are defined in, not through their text. :func:`define` therefore compiles each distinct source
text once and defines it anew in each namespace: a sweep over 2000 distinct non-integer
exponents compiles one step, not 2000. The text of each function it defined is kept
(:func:`source_of`): the compiled sweep writes it to a file for numba's disk cache
(``jit_cache.py``).
"""
from __future__ import annotations

import functools
import re
import string
from types import CodeType
from typing import Any

_SOURCES: dict[CodeType, str] = {}
"""The source text of each function :func:`define` returned, by its code object."""


@functools.lru_cache(maxsize=1024)
def _code(src: str, label: str) -> CodeType:
    return compile(src, label, 'exec')


def define(src: str, name: str, env: dict[str, Any], label: str = '<generated>') -> Any:
    """Return the function ``name`` that ``src`` defines, executed in the namespace ``env``.

    ``label`` names the source in tracebacks; the compiled code is cached per (source, label).
    """
    exec(_code(src, label), env)
    fn = env[name]
    _SOURCES.setdefault(fn.__code__, src)
    return fn


def source_of(fn: Any) -> str | None:
    """Return the source text :func:`define` defined ``fn`` from, or None for another function."""
    return _SOURCES.get(getattr(fn, '__code__', None))  # type: ignore[arg-type]


_BLOCK_HOLE = re.compile(r'^(?P<indent>[ ]*)\$(?P<name>[A-Za-z_][A-Za-z0-9_]*)[ ]*$')


def fill(template: str, **holes: str) -> str:
    """Return ``template``, Python source with named holes (``string.Template``), filled in.

    A hole alone on its line (``$name`` after the indentation) takes a block of lines, each
    indented as the hole is (an empty block removes the line); a hole within a line takes a
    one-line value. Every hole must be given and every value must fill a hole, so a template
    reads as the function it becomes.
    """
    out: list[str] = []
    used: set[str] = set()
    for line in template.splitlines():
        block = _BLOCK_HOLE.match(line)
        if block:
            name = block.group('name')
            if name not in holes:
                raise KeyError(f'the template has a hole ${name} that was not given')
            used.add(name)
            out += [block.group('indent') + x if x.strip() else '' for x in
                    holes[name].splitlines()]
            continue
        tpl = string.Template(line)
        names = set(tpl.get_identifiers())
        for name in names:
            if name not in holes:
                raise KeyError(f'the template has a hole ${name} that was not given')
            if '\n' in holes[name].strip('\n'):
                raise ValueError(f'the hole ${name} is within a line: its value must be one line')
        used |= names
        out.append(tpl.substitute({k: holes[k].strip('\n') for k in names}))
    unused = sorted(set(holes) - used)
    if unused:
        raise KeyError(f'no hole in the template for {", ".join(unused)}')
    return '\n'.join(out) + '\n'


def body_of(src: str) -> str:
    """Return the body of the one function ``src`` defines, its last line (``return``) left out.

    Dedented by one level, to be filled into a template's hole (:func:`fill`): the generated
    steps are inlined into the runs that take them.
    """
    lines = src.splitlines()[1:-1]
    return '\n'.join(x[4:] for x in lines) + '\n'


__all__ = ['body_of', 'define', 'fill', 'source_of']
