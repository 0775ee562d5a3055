"""Turn generated source into functions: the core's one place that compiles generated code.

The steps, damping laws and decisions of the core are generated as Python source
(``explicit.py``, ``rosenbrock.py``, ``extrapolation.py``, ``decisions.py``) and specialised by
the names they read (the exponent ``n``, the constants of a pendulum) through the namespace they
are defined in, not through their text. :func:`define` therefore compiles each distinct source
text once and defines it anew in each namespace: a sweep over 2000 distinct non-integer
exponents compiles one step, not 2000.
"""
from __future__ import annotations

import functools
from types import CodeType
from typing import Any


@functools.lru_cache(maxsize=1024)
def _code(src: str, label: str) -> CodeType:
    return compile(src, label, 'exec')


def define(src: str, name: str, env: dict[str, Any], label: str = '<generated>') -> Any:
    """Return the function ``name`` that ``src`` defines, executed in the namespace ``env``.

    ``label`` names the source in tracebacks; the compiled code is cached per (source, label).
    """
    exec(_code(src, label), env)
    return env[name]


__all__ = ['define']
