"""Build the node's ``/diagnostics`` message (diagnostic_msgs/DiagnosticArray)."""
from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

OK = DiagnosticStatus.OK
WARN = DiagnosticStatus.WARN
ERROR = DiagnosticStatus.ERROR


@dataclass(frozen=True)
class Key:
    """One key of the node's ``/diagnostics`` status: name, value type, unit, meaning.

    ``name`` is a key, or a family of keys with one ``<placeholder>`` (``guard_<counter>``).
    ``when`` says in which runs the key is present.
    """

    name: str
    type: str
    unit: str
    description: str
    when: str = 'always'

    def matches(self, key: str) -> bool:
        """Return True if ``key`` is this key or a member of this family."""
        if '<' not in self.name:
            return key == self.name
        pattern = '.+'.join(re.escape(part) for part in re.split(r'<[^>]+>', self.name))
        return re.fullmatch(pattern, key) is not None


GUARD = 'counted over the whole run, across resets (core GuardStats)'
SYNC = 'synchronous mode'
FOXGLOVE = 'foxglove_port set'

# Every key the node's status holds, in the order it publishes them.
KEYS: tuple[Key, ...] = (
    Key('sim_time', 'float', 's', 'Simulated time since the start (goes on through resets).'),
    Key('steps', 'int', 'steps', 'Steps of h taken since the start.'),
    Key('epoch_ns', 'int', 'ns', 'Stamp of simulated time 0 (start_time).'),
    Key('paused', 'bool', '', 'True while the simulation is paused.'),
    Key('real_time_factor_target', 'float', '1', 'The real_time_factor parameter.'),
    Key('real_time_factor_achieved', 'float', '1',
        'Simulated over running wall time since the previous status.'),
    Key('real_time_factor_total', 'float', '1', 'The same over the whole run.'),
    Key('wake_latency_p50_us', 'float', 'us',
        'Median lateness of the loop wakes since the previous status.'),
    Key('wake_latency_p99_us', 'float', 'us', '99th percentile of the same.'),
    Key('wake_latency_max_us', 'float', 'us', 'Largest of the same.'),
    Key('wake_latency_p99_us_total', 'float', 'us', '99th percentile over the whole run.'),
    Key('wake_latency_max_us_total', 'float', 'us', 'Largest over the whole run.'),
    Key('steps_per_wake', 'float', 'steps', 'Mean steps per wake since the previous status.'),
    Key('steps_per_wake_max', 'int', 'steps', 'Most steps in one wake over the whole run.'),
    Key('wakes', 'int', '', 'Wakes of the loop.'),
    Key('overruns', 'int', '', 'Wakes whose work ran past the next wake.'),
    Key('missed_wakes', 'int', '', 'Wakes skipped because the loop was late.'),
    Key('schedule_slips', 'int', '',
        'Times the schedule was moved because more work was due than one wake may do.'),
    Key('parameter_sets', 'int', '', 'Live parameter sets accepted (validated and noted).'),
    Key('reconfigures', 'int', '',
        'Times the accepted sets were applied to the joint: at most once a wake, all sets '
        'noted since the previous wake at once.'),
    Key('guard_steps', 'int', 'steps', 'Steps of h the core took; ' + GUARD + '.'),
    Key('guard_substeps', 'int', 'steps',
        'Extra substeps the stability guard took; ' + GUARD + '.'),
    Key('guard_fallbacks', 'int', 'steps',
        'Steps handed to the implicit fallback; ' + GUARD + '.'),
    Key('guard_reversals', 'int', 'steps',
        'Steps split at a velocity reversal; ' + GUARD + '.'),
    Key('guard_sticks', 'int', '',
        'Times the pendulum came to rest under static friction (n = 0); ' + GUARD + '.'),
    Key('guard_energy_rejections', 'int', 'steps',
        'Explicit steps redone because energy rose without input; ' + GUARD + '.'),
    Key('guard_projections', 'int', 'steps',
        'Steps projected onto the energy balance after the redo rose too; ' + GUARD + '.'),
    Key('energy', 'float', 'J', 'Energy of the true state (nan once the joint failed).'),
    Key('energy_residual', 'float', 'J',
        'Energy balance E(t) - E(0) + dissipated - input work: the truncation error.'),
    Key('local_error_estimate', 'float', 'rad, rad/s',
        "Step-doubling estimate of the next step's local error (2-norm over angle and "
        'velocity).'),
    Key('local_error_max', 'float', 'rad, rad/s', 'Largest finite estimate so far.'),
    Key('commands_received', 'int', '', 'Commands taken from any command topic.'),
    Key('commands_rejected_nonfinite', 'int', '', 'Commands refused for a nan or inf value.'),
    Key('commands_saturated', 'int', '', 'Commands clipped to max_effort.'),
    Key('commands_limited', 'int', '',
        'Commands limited to max_velocity or the position limits.'),
    Key('command_timeouts', 'int', '',
        'Times the command returned to its safe value after command_timeout.'),
    Key('commands_dropped', 'int', '', 'Commands dropped, all topics and reasons.'),
    Key('commands_dropped[<topic>: <reason>]', 'int', '',
        'Commands dropped on one topic for one reason.', 'once such a command came'),
    Key('torque', 'float', 'N m', 'Torque applied in the current step.'),
    Key('phase_time_since_reset', 'float', 's', 'Simulated time since the last reset.'),
    Key('sync_answered', 'int', '', 'States answered by a command.', SYNC),
    Key('sync_timeouts', 'int', '',
        'States not answered within sync_timeout (sync_timeout_action applied).', SYNC),
    Key('sync_late', 'int', '',
        'Commands for an earlier state (given up or replaced by a reset), dropped.', SYNC),
    Key('sync_duplicates', 'int', '',
        'Second commands for a state already answered, dropped.', SYNC),
    Key('sync_ahead', 'int', '', 'Commands for a state not yet published, dropped.', SYNC),
    Key('sync_republished', 'int', '',
        'Awaited states published again after a stop timeout, when stepping resumed.', SYNC),
    Key('foxglove_subscriptions', 'int', '',
        'Subscriptions of Foxglove clients to channels now (0: the tick does no live work).',
        FOXGLOVE),
    Key('foxglove_sent', 'int', '', 'States sent to Foxglove clients.', FOXGLOVE),
    Key('foxglove_dropped', 'int', '',
        "States dropped, the oldest first, from the live view's full queue.", FOXGLOVE),
    Key('incompatible_qos[<topic>]', 'int', '',
        "Publishers or subscribers on a topic whose QoS cannot match the node's.",
        'once such an endpoint was seen'),
)


def declared(key: str) -> Key | None:
    """Return the declared key (or family) that ``key`` belongs to, or None."""
    return next((k for k in KEYS if k.matches(key)), None)


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
