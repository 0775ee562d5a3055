"""Compile once per machine: the compiled sweep's machine code kept on disk between processes.

numba's own cache (``cache=True``) keeps a function's machine code beside its source file,
keyed by the file's contents and the signature, but it cannot keep a function defined from
generated text by ``exec`` (it has no file) nor one that embeds the address of a Python object
(a compiled function used as a value: numba's "dynamic globals"). The compiled sweep's run is
both (``kernel.kernel_source``, the generated functions it hands to the careful step), so
:func:`kernel_module` writes the text to a module file of the cache directory (named by the
hash of the text) and defines the run and its generated functions from that file, and
``jit.compile_kernel`` compiles them with numba's cache pointed there (:func:`attach`):

- the run takes the generated functions its careful step needs (``plain``, ``branch``,
  ``laws``, ``pair_plain``, ``pair_branch``) as arguments, first-class functions of one
  signature each (``kernel.FUNCTION_ARGS``, passed by ``jit.CachedRun`` at each call),
  instead of reading them as globals;
- the careful step (``careful.careful_step``, ``jit.first_class_twin``) is cached beside them,
  once for all texts, so a new law text in a later process compiles its run alone.

A second process therefore loads every piece of the compiled sweep and compiles nothing.
What numba's cache checks (the file's contents, the bytecode, numba's version, the CPU) does not
cover the functions a cached function calls from other files, so the cache directory is named by
a digest of the package's core sources, the package's version, numba's and Python's
(:func:`cache_dir`): any change of the core starts a new directory.

The cache lives in ``$PENDULUM_SIM_JIT_CACHE``, else ``$XDG_CACHE_HOME/pendulum_sim/jit``, else
``~/.cache/pendulum_sim/jit`` (:func:`cache_root`); deleting it is always safe. Files are
written to a temporary name and renamed (numba does the same for its own), so processes that
compile at once never read half a file; a cache file that cannot be read (truncated, corrupt) is
compiled anew and overwritten. Where the directory cannot be written the compiled paths are
compiled in memory, as without this module, after one warning (:class:`JitCacheWarning`).
"""
from __future__ import annotations

import collections
import contextlib
import functools
import hashlib
import os
import sys
import tempfile
import types
import uuid
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from .codegen import source_of
from .kernel import FUNCTION_ARGS

ENV_VAR = 'PENDULUM_SIM_JIT_CACHE'
"""The environment variable that names the cache directory (:func:`cache_root`)."""

EVENTS: collections.Counter[str] = collections.Counter()
"""What the cache did in this process: ``hits`` and ``misses`` (numba's, summed over every
function it serves), ``unreadable`` (cache files that could not be read and were compiled
anew), ``unwritable`` (a directory that could not be written: compiled in memory)."""


class JitCacheWarning(UserWarning):
    """The compiled paths could not be cached on disk and are compiled in memory."""


def cache_root() -> Path:
    """Return the cache directory the environment names (see the module docstring)."""
    named = os.environ.get(ENV_VAR)
    if named:
        return Path(named).expanduser()
    xdg = os.environ.get('XDG_CACHE_HOME')
    return (Path(xdg) if xdg else Path.home() / '.cache') / 'pendulum_sim' / 'jit'


@functools.cache
def _digest() -> str:
    """Return the version tag of a cache: package, numba and Python versions, core sources."""
    import numba

    from .. import __version__

    sha = hashlib.sha256()
    core = Path(__file__).resolve().parent
    for path in sorted(core.glob('*.py')):
        sha.update(path.name.encode() + b'\0' + path.read_bytes() + b'\0')
    py = f'{sys.version_info[0]}{sys.version_info[1]}'
    return f'{__version__}-numba{numba.__version__}-py{py}-{sha.hexdigest()[:16]}'


def cache_dir() -> Path | None:
    """Return the writable cache directory of this package and numba, or None (in memory)."""
    return _writable(str(cache_root() / _digest()))


@functools.cache
def _writable(path: str) -> Path | None:
    """Return ``path`` made and proven writable, or None after one :class:`JitCacheWarning`."""
    try:
        os.makedirs(path, exist_ok=True)
        tempfile.TemporaryFile(dir=path).close()
    except OSError as exc:
        _warn_unwritable(path, exc)
        return None
    return Path(path)


def _warn_unwritable(path: str, exc: Exception) -> None:
    """Count and warn that ``path`` cannot be written: the compiled paths stay in memory."""
    EVENTS['unwritable'] += 1
    reason = exc.strerror if isinstance(exc, OSError) else str(exc)
    warnings.warn(f'pendulum_sim: the jit cache {path} is not writable ({reason}); '
                  f'compiling in memory (set {ENV_VAR} to a writable directory)',
                  JitCacheWarning, stacklevel=5)


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file renamed over it."""
    tmp = path.with_name(f'.{path.name}.{uuid.uuid4().hex[:12]}.tmp')
    try:
        tmp.write_text(text, encoding='utf-8')
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def module_file(directory: Path, text: str) -> Path:
    """Return the module file of ``directory`` that holds ``text``, written if it does not yet.

    Named by the hash of the text; a file of that name with other contents (half written by
    a killed process, corrupted) is written anew.
    """
    path = directory / f'k_{hashlib.sha256(text.encode()).hexdigest()[:24]}.py'
    try:
        if path.read_text(encoding='utf-8') == text:
            return path
    except (OSError, UnicodeDecodeError):
        pass
    write_atomic(path, text)
    return path


@functools.cache
def _cache_class(path: str) -> Any:
    """Return numba's function cache class with its files in ``path``, robust to bad files."""
    from numba.core import caching

    class Locator(caching._SourceFileBackedLocatorMixin,  # type: ignore[misc, unused-ignore]
                  caching._CacheLocator):
        """Cache every function in ``path`` (numba's locators choose by the source file)."""

        def __init__(self, py_func: Any, py_file: str) -> None:
            self._py_file = py_file
            self._lineno = py_func.__code__.co_firstlineno

        def get_cache_path(self) -> str:
            return path

    class Impl(caching.CompileResultCacheImpl):  # type: ignore[misc, unused-ignore]
        _locator_classes = [Locator]  # noqa: RUF012 - numba reads the class attribute

    base: Any = caching.FunctionCache

    class Cache(base):  # type: ignore[misc, valid-type, unused-ignore]
        """numba's cache; a file it cannot read is a miss (compiled anew and overwritten)."""

        _impl_class = Impl

        def load_overload(self, sig: Any, target_context: Any) -> Any:
            try:
                data = base.load_overload(self, sig, target_context)
            except Exception:  # any unreadable file: compile anew
                EVENTS['unreadable'] += 1
                data = None
            EVENTS['misses' if data is None else 'hits'] += 1
            return data

        def save_overload(self, sig: Any, data: Any) -> None:
            try:
                try:
                    base.save_overload(self, sig, data)
                except OSError:
                    raise
                except Exception:  # an unreadable index: start anew
                    self._cache_file.flush()
                    base.save_overload(self, sig, data)
            except OSError as exc:
                warnings.warn(f'pendulum_sim: could not write the jit cache {path} '
                              f'({exc.strerror}); this compile is kept in memory only',
                              JitCacheWarning, stacklevel=2)

    return Cache


_ATTACHED: set[int] = set()


def attach(dispatcher: Any, part: str) -> bool:
    """Keep ``dispatcher``'s compiles in the cache's folder ``part``; return False without one.

    Its Python function must be defined in a real file (a module of the package, or one
    :func:`module_file` wrote). Attaching twice is attaching once.
    """
    directory = cache_dir()
    if directory is None:
        return False
    if id(dispatcher) not in _ATTACHED:
        try:
            cache = _cache_class(str(directory / part))(dispatcher.py_func)
        except (OSError, RuntimeError) as exc:  # the folder went away or cannot be made
            _warn_unwritable(str(directory / part), exc)
            return False
        _ATTACHED.add(id(dispatcher))
        dispatcher._cache = cache
    return True


def kernel_module(fn: Any) -> dict[str, Any] | None:
    """Return the namespace of a sweep run's module file: the run and its generated functions.

    ``fn`` is the run ``kernel.compile_kernel`` defined; its text is written to a module
    file of the cache directory (:func:`module_file`) and imported from there, in a module of
    its own (registered in ``sys.modules``: numba imports it where it loads the functions'
    environment) holding the names the run reads. None where the cache directory is not
    writable (then the caller compiles in memory).
    """
    directory = cache_dir()
    text = source_of(fn)
    if directory is None or text is None:
        return None
    try:
        path = module_file(directory, text)
    except OSError as exc:  # the directory was removed or made read-only since
        _warn_unwritable(str(directory), exc)
        return None
    module = sys.modules.get(f'pendulum_sim_jit_{path.stem}')
    if module is None:
        module = types.ModuleType(f'pendulum_sim_jit_{path.stem}')
        module.__dict__.update((name, value) for name, value in fn.__globals__.items()
                               if name not in ('__builtins__', '__name__'))
        module.__file__ = str(path)
        exec(compile(text, str(path), 'exec'), module.__dict__)
        sys.modules[module.__name__] = module
    env = module.__dict__
    if not all(isinstance(env.get(name), types.FunctionType)
               for name in (*FUNCTION_ARGS, 'kernel')):
        return None
    return env


@contextlib.contextmanager
def compiling(callback: Callable[[bool], None]) -> Iterator[None]:
    """Call ``callback(cached)`` once when numba starts compiling inside the ``with`` block.

    numba compiles only what its cache does not hold (``numba:compile`` events fire on a cache
    miss, not on a load), so the call says that this run compiles: the first on a machine,
    or every run where the cache directory cannot be written. ``cached`` is True where the
    compiled code is being kept on disk for later processes (:func:`cache_dir`), False where
    it is compiled in memory only. Nothing is called where numba is not installed or nothing
    compiles.
    """
    try:
        from numba.core import event
    except ImportError:
        yield
        return
    told = [False]

    class Listener(event.Listener):  # type: ignore[misc, unused-ignore]
        def on_start(self, ev: Any) -> None:
            if not told[0]:
                told[0] = True
                callback(cache_dir() is not None)

        def on_end(self, ev: Any) -> None:
            pass

    with event.install_listener('numba:compile', Listener()):
        yield


__all__ = ['ENV_VAR', 'EVENTS', 'JitCacheWarning', 'attach', 'cache_dir', 'cache_root',
           'compiling', 'kernel_module', 'module_file', 'write_atomic']
