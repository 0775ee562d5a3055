"""Keep old imports working: ``pendulum_sim.node.<module>`` for the modules now in joint/.

The simulated joint's ROS-free modules moved to :mod:`pendulum_sim.joint` (0.13). Importing one
by its old name gives the module itself (one module object, so classes and checks stay one)
and a :class:`DeprecationWarning` naming the new place.
"""
from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import warnings
from types import ModuleType

MOVED = ('commands', 'drivers', 'exchange', 'foxglove', 'joint', 'parameters', 'realtime',
         'replies', 'scenes', 'sensors', 'servo', 'status', 'telemetry', 'urdf')
"""The modules of ``pendulum_sim.node`` that now live in ``pendulum_sim.joint``."""
OLD = 'pendulum_sim.node'
NEW = 'pendulum_sim.joint'


class _Alias(importlib.abc.Loader):
    """Load an old name as the moved module itself."""

    def __init__(self, new: str) -> None:
        self.new = new

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        warnings.warn(f'{spec.name} moved to {self.new}; import it from there',
                      DeprecationWarning, stacklevel=2)
        module = importlib.import_module(self.new)
        self._spec = module.__spec__
        return module

    def exec_module(self, module: ModuleType) -> None:
        module.__spec__ = self._spec   # the import machinery set the alias's spec on it


class MovedFinder(importlib.abc.MetaPathFinder):
    """Find ``pendulum_sim.node.<moved>`` as an alias of ``pendulum_sim.joint.<moved>``."""

    def find_spec(self, fullname: str, path: object = None, target: object = None
                  ) -> importlib.machinery.ModuleSpec | None:
        head, _, tail = fullname.rpartition('.')
        if head != OLD or tail not in MOVED:
            return None
        return importlib.machinery.ModuleSpec(fullname, _Alias(f'{NEW}.{tail}'))


def install() -> None:
    """Put the finder first on ``sys.meta_path`` (once)."""
    if not any(isinstance(f, MovedFinder) for f in sys.meta_path):
        sys.meta_path.insert(0, MovedFinder())
