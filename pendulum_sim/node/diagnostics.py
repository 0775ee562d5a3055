"""Build the node's ``/diagnostics`` message (diagnostic_msgs/DiagnosticArray)."""
from __future__ import annotations

import math
from collections.abc import Mapping

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

OK = DiagnosticStatus.OK
WARN = DiagnosticStatus.WARN
ERROR = DiagnosticStatus.ERROR


def format_value(value: object) -> str:
    """Return a KeyValue string: floats with 9 significant digits, the rest with str()."""
    if isinstance(value, float):
        return 'nan' if math.isnan(value) else f'{value:.9g}'
    return str(value)


def status_array(stamp: Time, name: str, hardware_id: str, level: bytes, message: str,
                 values: Mapping[str, object]) -> DiagnosticArray:
    """Return a DiagnosticArray with one status holding ``values`` as key/value pairs."""
    status = DiagnosticStatus(level=level, name=name, message=message,
                              hardware_id=hardware_id)
    status.values = [KeyValue(key=k, value=format_value(v)) for k, v in values.items()]
    array = DiagnosticArray()
    array.header.stamp = stamp
    array.status = [status]
    return array


def values_of(array: DiagnosticArray) -> dict[str, str]:
    """Return the key/value pairs of the first status (for tests and the bench)."""
    return {kv.key: kv.value for kv in array.status[0].values} if array.status else {}
