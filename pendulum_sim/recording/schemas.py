"""Find ROS 2 message definitions and type hashes as rosbag2 stores them in MCAP schemas.

The ``ros2msg`` schema text follows rosbag2's ``LocalMessageDefinitionSource::get_full_text``
(ros2/rosbag2, ``rosbag2_cpp/src/rosbag2_cpp/message_definitions/
local_message_definition_source.cpp``) and the MCAP specification's ROS 2 profile: the root
``.msg`` text, then every dependency once, depth-first in sorted order, each introduced by a line
of 80 ``=`` and a line ``MSG: <pkg>/<Type>`` (the type as written in the referring ``.msg``).
The ``.msg`` files and the ``RIHS01_`` type hashes are read from the installed interface packages
(``share/<pkg>/msg/<Type>.msg`` and the ``<Type>.json`` type description beside it).
"""
from __future__ import annotations

import functools
import importlib
import importlib.util
import json
import os
import re
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Final

from pendulum_sim.recording.errors import RecorderError

SEPARATOR = '=' * 80

# The same field-type pattern and primitive set as rosbag2's message definition source.
_MSG_FIELD_TYPE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+')
PRIMITIVE_TYPES = frozenset({
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
    'int32', 'uint32', 'int64', 'uint64', 'string',
})
_ROS_NAME = '[a-zA-Z][a-zA-Z0-9_]*'
_TYPE_NAME = re.compile(f'^({_ROS_NAME})/(?:({_ROS_NAME})/)?({_ROS_NAME})$')
_MAX_DEPTH = 50


def type_name_of(msg_type: type) -> str:
    """Return the full ROS type name of a generated message class (``pkg/msg/Type``)."""
    parts = msg_type.__module__.split('.')
    if len(parts) < 2 or not hasattr(msg_type, 'get_fields_and_field_types'):
        raise RecorderError(f'{msg_type!r} is not a generated ROS 2 message class')
    return f'{parts[0]}/{parts[1]}/{msg_type.__name__}'


def split_type_name(type_name: str) -> tuple[str, str, str]:
    """Split ``pkg/Type`` or ``pkg/msg/Type`` into package, namespace and type."""
    match = _TYPE_NAME.match(type_name)
    if match is None:
        raise RecorderError(
            f"type name must look like 'pkg/msg/Type' or 'pkg/Type', got {type_name!r}")
    package, namespace, name = match.groups()
    return package, namespace or 'msg', name


def _prefixes(package: str) -> Iterator[Path]:
    for prefix in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep):
        if prefix:
            yield Path(prefix)
    yield Path(sys.prefix)
    # A ROS install without AMENT_PREFIX_PATH: <prefix>/lib/pythonX.Y/site-packages/<package>.
    spec = importlib.util.find_spec(package)
    if spec is not None and spec.origin is not None:
        yield from Path(spec.origin).parents


@functools.cache
def interface_file(type_name: str, suffix: str) -> Path:
    """Return the installed ``share/<pkg>/<ns>/<Type><suffix>`` file of an interface."""
    package, namespace, name = split_type_name(type_name)
    for prefix in _prefixes(package):
        candidate = prefix / 'share' / package / namespace / f'{name}{suffix}'
        if candidate.is_file():
            return candidate
    raise RecorderError(
        f'no {suffix} file for {package}/{namespace}/{name} in any share directory '
        f'(AMENT_PREFIX_PATH or {sys.prefix})')


def msg_dependencies(text: str, package: str) -> list[str]:
    """Return the non-primitive field types of a ``.msg`` text, sorted, as rosbag2 finds them."""
    found = set()
    for match in _MSG_FIELD_TYPE.finditer(text):
        field_type = match.group(1)
        if field_type in PRIMITIVE_TYPES:
            continue
        found.add(field_type if '/' in field_type else f'{package}/{field_type}')
    return sorted(found)


@functools.cache
def ros2msg_schema(type_name: str) -> str:
    """Return the ``ros2msg`` schema text of a type: its ``.msg`` then each dependency once."""
    seen: set[str] = set()

    def append(name: str, depth: int) -> str:
        if depth <= 0:
            raise RecorderError(f'reached the maximum depth resolving the definition of '
                                f'{type_name}')
        text = interface_file(name, '.msg').read_text(encoding='utf-8')
        result = text
        for dependency in msg_dependencies(text, split_type_name(name)[0]):
            if dependency not in seen:
                seen.add(dependency)
                result += f'\n{SEPARATOR}\nMSG: {dependency}\n'
                result += append(dependency, depth - 1)
        return result

    return append(type_name, _MAX_DEPTH)


@functools.cache
def type_hash(type_name: str) -> str:
    """Return the ``RIHS01_...`` type description hash of a type, from its ``.json`` file."""
    package, namespace, name = split_type_name(type_name)
    full_name = f'{package}/{namespace}/{name}'
    description: dict[str, Any] = json.loads(
        interface_file(full_name, '.json').read_text(encoding='utf-8'))
    for entry in description.get('type_hashes', []):
        if entry.get('type_name') == full_name:
            return str(entry['hash_string'])
    raise RecorderError(f'no type hash for {full_name} in its type description')


# Type names read from a file are untrusted: only a message of an interface package listed here,
# named exactly ``pkg/msg/Type`` and installed (its ``.msg`` file is in a share directory), is
# ever imported. The packages are the ROS 2 common interfaces and the core rcl ones.
INTERFACE_PACKAGES: Final = frozenset({
    'action_msgs', 'actionlib_msgs', 'builtin_interfaces', 'control_msgs', 'diagnostic_msgs',
    'geometry_msgs', 'lifecycle_msgs', 'nav_msgs', 'rcl_interfaces', 'rosgraph_msgs',
    'sensor_msgs', 'service_msgs', 'shape_msgs', 'statistics_msgs', 'std_msgs', 'stereo_msgs',
    'tf2_msgs', 'trajectory_msgs', 'type_description_interfaces', 'unique_identifier_msgs',
    'visualization_msgs',
})
_MESSAGE_TYPE = re.compile(r'([a-z][a-z0-9_]*)/msg/([A-Z][A-Za-z0-9]*)')


def check_message_type(type_name: str) -> tuple[str, str]:
    """Return ``(package, Type)`` of a message type a file names, if it may be imported.

    Raises
    ------
    RecorderError
        The name is not exactly ``pkg/msg/Type``, the package is not in
        :data:`INTERFACE_PACKAGES`, or the message is not installed.
    """
    match = _MESSAGE_TYPE.fullmatch(type_name)
    if match is None:
        raise RecorderError(f'message type {type_name!r} is refused: it is not a name of the '
                            f"form 'pkg/msg/Type'")
    package, name = match.groups()
    if package not in INTERFACE_PACKAGES:
        raise RecorderError(f'message type {type_name!r} is refused: {package} is not one of '
                            f'the allowed interface packages (std_msgs, sensor_msgs, ...: '
                            f'pendulum_sim.recording.schemas.INTERFACE_PACKAGES)')
    try:
        interface_file(type_name, '.msg')
    except RecorderError as exc:
        raise RecorderError(f'unknown message type {type_name}: {exc}') from None
    return package, name


@functools.cache
def message_class(type_name: str) -> type:
    """Import and return the generated Python class of a message type a file names.

    Only what :func:`check_message_type` allows is imported.
    """
    package, name = check_message_type(type_name)
    try:
        module = importlib.import_module(f'{package}.msg')
        cls = getattr(module, name)
    except (ImportError, AttributeError) as exc:
        raise RecorderError(f'unknown message type {type_name}: no {name} in the Python module '
                            f'{package}.msg') from exc
    if not (isinstance(cls, type) and hasattr(cls, 'get_fields_and_field_types')):
        raise RecorderError(f'unknown message type {type_name}: {package}.msg.{name} is not a '
                            f'generated message class')
    return cls
