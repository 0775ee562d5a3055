"""The joint a closed loop runs against: a scene's parameters, overrides, synchronous lockstep.

One function builds the parameter set both paths use, so the in-process joint and the
``pendulum_node`` process are configured from the same values: the node's defaults, then the
scene file, then ``overrides`` (names as the node declares them), then the settings every
closed loop needs (synchronous lockstep, started paused, so that exactly ``periods`` control
periods are stepped) and a ``sync_timeout`` of at least :data:`SYNC_TIMEOUT` unless the
overrides set one. The node's own validation decides whether the set is usable.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from pendulum_sim.joint.errors import SceneError
from pendulum_sim.joint.parameters import SPEC_BY_NAME, SPECS, check, start_epoch_ns
from pendulum_sim.joint.scenes import find_scene, read_params_file, unknown_parameter

from .errors import TestingError

Value = bool | int | float | str

# What a closed loop needs from the node, whatever the scene says.
FORCED: dict[str, Value] = {'lockstep': True, 'synchronous': True, 'start_paused': True,
                            'services': True, 'status_line': False}
# Wall-clock seconds the node waits for each answer unless told otherwise: on a loaded machine
# a slow answer is waited for, not run past (a missed answer fails the run).
SYNC_TIMEOUT = 30.0


def scene_values(scene: str, overrides: Mapping[str, Any] | None = None) -> dict[str, Value]:
    """Return the node's parameter values for ``scene`` with ``overrides`` applied.

    Raises
    ------
    TestingError
        If the scene cannot be found or read, an override names a parameter the node does not
        have or has a value of the wrong type, or the whole set is unusable (the node's reason).
    """
    return with_overrides(read_scene(scene), overrides)


def read_scene(scene: str) -> dict[str, Value]:
    """Return the node's defaults with the parameters of ``scene`` (a name or a file) applied.

    Raises
    ------
    TestingError
        If the scene cannot be found or read.
    """

    values: dict[str, Value] = {s.name: s.default for s in SPECS}
    try:
        values.update(read_params_file(find_scene(scene)))
    except SceneError as exc:
        raise TestingError(str(exc)) from None
    return values


def with_overrides(scene: Mapping[str, Value],
                   overrides: Mapping[str, Any] | None = None) -> dict[str, Value]:
    """Return the values :func:`read_scene` gave with ``overrides`` and the closed-loop settings.

    Raises
    ------
    TestingError
        As :func:`scene_values`, for everything but reading the scene.
    """

    values = dict(scene)
    for name, value in (overrides or {}).items():
        reason = unknown_parameter(name, 'overrides')
        if reason is not None:
            raise TestingError(reason)
        if name in ('use_sim_time', 'start_type_description_service'):
            continue
        values[name] = _typed(name, value, SPEC_BY_NAME[name].default)
    forced_changed = [n for n, v in FORCED.items() if n in (overrides or {}) and
                      values[n] != v]
    if forced_changed:
        raise TestingError(f'{forced_changed[0]} is fixed for a closed loop (it is '
                           f'{FORCED[forced_changed[0]]}), got {values[forced_changed[0]]}')
    values.update(FORCED)
    if 'sync_timeout' not in (overrides or {}):
        values['sync_timeout'] = max(float(values['sync_timeout']), SYNC_TIMEOUT)
    reason = check(values)
    if reason is not None:
        raise TestingError(reason)
    return values


def _typed(name: str, value: Any, default: Value) -> Value:
    """Return ``value`` as the parameter's type (an int is a float where a float is wanted)."""
    if isinstance(default, bool):
        ok = isinstance(value, bool)
    elif isinstance(default, int):
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif isinstance(default, float):
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        if ok:
            value = float(value)
    else:
        ok = isinstance(value, str)
    if not ok:
        shown = repr(value)
        shown = shown if len(shown) <= 60 else shown[:57] + '...'
        raise TestingError(f'{name} must be a {type(default).__name__}, got {shown}')
    return value  # type: ignore[no-any-return]


def epoch_ns(values: Mapping[str, Value]) -> int:
    """Return the stamp of step 0 in lockstep: ``start_time`` (s), 0 when negative."""

    return start_epoch_ns(values, 0)   # the node's rule; no wall clock in a test bench run


def finite_limit(values: Mapping[str, Value]) -> float:
    """Return the joint's torque limit ``max_effort`` (N m; inf when unlimited)."""
    limit = float(values['max_effort'])
    return limit if math.isfinite(limit) else math.inf
