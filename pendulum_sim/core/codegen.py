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


__all__ = ['define', 'source_of']
