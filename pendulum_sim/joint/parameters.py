"""The joint's parameters: one table (names, defaults, units, ranges) and their validation.

The table feeds the node's ROS declarations (:mod:`pendulum_sim.node.declare`), the docs and
the in-process test bench alike. rclpy checks types, ranges and read-only flags from the
descriptors before any callback runs (``Node._apply_descriptor``). What a range cannot say (a
mass > 0, a known integrator, a factor that is 0 only in lockstep) is checked here, in one
function that sees the whole proposed set so cross-parameter rules hold; its messages are the
reasons the set is rejected with.
"""
from __future__ import annotations

import math
import unicodedata
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pendulum_sim.core import METHODS, ModelError, PendulumError, PendulumParams
from pendulum_sim.core.model import (
    dissipated_power,
    kinetic_energy,
    potential_energy,
    states_accepted,
    validate_state,
)

from .errors import JointError
from .foxglove import check_port
from .joint import INTERFACES, JointConfig, SimulatedJoint, check_config

Value = bool | int | float | str
FloatArray = NDArray[np.float64]

FIXED = 'Read-only: fixed when the node starts (restart the node to change it).'
SWITCH = 'Read-only: a scene builds only what it enables.'
SAMPLED = ('Refused beyond the stability limit of the servo loop sampled at h (with the other '
           'gains as set; the message states the limit).')


@dataclass(frozen=True)
class Spec:
    """One parameter: name, default (its type is the parameter's type), meaning, limits."""

    name: str
    default: Value
    description: str
    read_only: bool = False
    low: float | None = None
    high: float | None = None
    constraints: str = ''
    unit: str = ''  # SI unit of a number ('1' if it has none); '' for a flag or a name


SPECS: tuple[Spec, ...] = (
    # The body: fixed, since changing it mid-run would break the energy balance.
    Spec('m', 0.2, 'Mass in kg (> 0).', read_only=True, unit='kg'),
    Spec('l', 1.0, 'Distance from the pivot to the centre of mass in m (> 0).', read_only=True,
         unit='m'),
    Spec('inertia', 0.2, 'Moment of inertia about the pivot in kg m^2 (> 0).', read_only=True,
         unit='kg m^2'),
    Spec('g', 9.8, 'Gravitational acceleration in m/s^2 (>= 0).', read_only=True, unit='m/s^2'),
    # Damping: live.
    Spec('gamma', 1.0, 'Damping coefficient in s^(n-2). Live: applies from the next step, the '
         'state is kept.', low=0.0, high=1e6, unit='s^(n-2)'),
    Spec('n', 1.0, 'Damping exponent: 0 dry (Coulomb), 1 viscous, 2 quadratic drag. Live: '
         'applies from the next step, the state is kept.', low=0.0, high=10.0, unit='1'),
    Spec('friction', 0.0, 'Coulomb friction torque in N m beside the power law (>= 0): '
         '-friction sgn(dphi), and at rest the joint sticks while |gravity + effort| <= '
         'friction. Every integrator. Live: applies from the next step, the state is kept.',
         low=0.0, high=1e6, unit='N m'),
    Spec('phi0', 0.0, 'Initial angle in rad. Live: used by the next ~/reset.', unit='rad'),
    Spec('dphi0', 0.0, 'Initial angular velocity in rad/s. Live: used by the next ~/reset.',
         unit='rad/s'),
    # Integration and timing.
    Spec('h', 1e-3, 'Fixed integration step in s.', read_only=True, low=1e-6, high=0.1, unit='s'),
    Spec('integrator', 'rk4', 'Integration method of the core.', read_only=True,
         constraints='one of: ' + ', '.join(sorted(METHODS))),
    Spec('guard', True, 'Keep explicit steps inside their stability region (substeps or an '
         'implicit fallback).', read_only=True),
    Spec('publish_rate', 100.0, 'Wake and publish rate in Hz (wall clock).', read_only=True,
         low=0.1, high=10000.0, unit='Hz'),
    Spec('real_time_factor', 1.0, 'Simulated seconds per wall second. In lockstep mode 0 means '
         'as fast as possible. Live.', low=0.0, high=10000.0, unit='1'),
    Spec('lockstep', False, 'Lockstep mode: publish /clock, step as fast as possible (or at '
         'real_time_factor) and stamp from simulated time. ' + SWITCH, read_only=True),
    Spec('synchronous', False, 'Synchronous lockstep (needs lockstep): each control period '
         '(1/publish_rate of simulated time) publish /clock and joint_states, wait for the '
         "controller's command answering that state, apply it for the next period. " + SWITCH,
         read_only=True),
    Spec('sync_timeout', 1.0, 'Synchronous mode: wall-clock seconds to wait for the command '
         'answering a state before sync_timeout_action. Live.', low=0.001, high=3600.0,
         unit='s (wall clock)'),
    Spec('sync_timeout_action', 'hold', "Synchronous mode, when no command came within "
         "sync_timeout: 'hold' keeps the last command for the next period (counted), 'stop' "
         'pauses the simulation (resume with ~/pause or ~/step). Live.',
         constraints='one of: hold, stop'),
    Spec('start_paused', False, 'Start paused: nothing is stepped or published until ~/step or '
         '~/pause false.', read_only=True),
    Spec('publish_clock', True, 'In lockstep, publish /clock (switch off when another joint or '
         'simulator owns the clock). ' + SWITCH, read_only=True),
    Spec('start_time', -1.0, 'Epoch in s (since 1970) that simulated time 0 is stamped as; < 0 '
         'means the wall clock when the simulation starts (0 in lockstep).', read_only=True,
         low=-1.0, high=1e10, unit='s'),
    Spec('joint_name', 'pendulum_joint', 'Joint name in joint_states and the URDF.',
         read_only=True),
    # Effort input.
    Spec('max_effort', 10.0, 'Commanded torques are saturated at +-max_effort N m. Live.',
         low=0.0, high=1e6, unit='N m'),
    Spec('command_timeout', 0.5, 'Simulated seconds after the last command at which it returns '
         'to its safe value: no torque (effort), no speed (velocity), the same target '
         '(position). Rounded to steps of h, at least one step; 0 holds the last command for '
         'ever. Live.', low=0.0, high=3600.0, unit='s'),
    Spec('command_delay', 0.0, 'Transport delay of commands in simulated seconds, rounded to '
         'steps of h. Live.', low=0.0, high=1.0, unit='s'),
    Spec('command_interface', 'effort', "What commands set: 'effort' (N m), 'velocity' (rad/s) "
         "or 'position' (rad), the latter two tracked by a joint servo whose torque is "
         'saturated at max_effort.', read_only=True,
         constraints='one of: ' + ', '.join(INTERFACES)),
    Spec('max_velocity', 100.0, 'Velocity limit in rad/s: velocity commands are limited to it '
         'and no torque drives the joint faster. Live.', low=0.0, high=1e6, unit='rad/s'),
    Spec('position_min', -math.inf, 'Lower position limit of position commands, rad (-.inf = '
         'none). Live.', unit='rad'),
    Spec('position_max', math.inf, 'Upper position limit of position commands, rad (.inf = '
         'none). Live.', unit='rad'),
    Spec('servo.position_p', 8.0, 'Position loop gain of the servo, 1/s: the speed demanded '
         'per rad of position error (limited to max_velocity). ' + SAMPLED + ' Live.',
         low=0.0, high=1e6, unit='1/s'),
    Spec('servo.velocity_p', 4.0, 'Velocity loop proportional gain of the servo, N m s/rad. '
         + SAMPLED + ' Live.', low=0.0, high=1e6, unit='N m s/rad'),
    Spec('servo.velocity_i', 20.0, 'Velocity loop integral gain of the servo, N m/rad (with '
         'anti-windup at max_effort). ' + SAMPLED + ' Live.', low=0.0, high=1e6,
         unit='N m/rad'),
    Spec('servo.gravity_feedforward', True, "Add the joint's own gravity torque m g l sin(phi) "
         'to the servo torque. Live.'),
    # Sensor realism.
    Spec('sensor.position_noise', 0.0, 'Standard deviation of Gaussian noise on the published '
         'angle, rad. Live.', low=0.0, high=10.0, unit='rad'),
    Spec('sensor.velocity_noise', 0.0, 'Standard deviation of Gaussian noise on the published '
         'velocity, rad/s. Live.', low=0.0, high=100.0, unit='rad/s'),
    Spec('sensor.resolution', 0.0, 'Encoder resolution in rad per count (0 = exact). Live.',
         low=0.0, high=1.0, unit='rad'),
    Spec('sensor.delay', 0.0, 'Delay of the joint_states measurement in simulated seconds, '
         'rounded to steps of h: the state of round(delay/h) steps ago, stamped when it was '
         'measured. Live.', low=0.0, high=1.0, unit='s'),
    Spec('sensor.seed', 0, 'Seed of the sensor noise.', read_only=True, low=0, high=2**31 - 1,
         unit='1'),
    Spec('effort_offset', 0.0, 'Constant torque in N m added to every torque applied to the '
         "pendulum, commanded or not (a drive's or torque sensor's bias, as a driven fit finds "
         'it): at rest it balances gravity at asin(effort_offset / (m g l)). Not in the '
         'published effort; its work counts as input in the energy balance. Live: applies from '
         'the next step.', low=-1e6, high=1e6, unit='N m'),
    # Disturbance: an external torque pulse on the joint.
    Spec('disturbance.torque', 0.0, 'Torque of the disturbance pulse in N m, added to the '
         "actuator's torque on the pendulum (an external torque: not in the published effort; "
         'its work counts as input in the energy balance). Live.', low=-1e6, high=1e6,
         unit='N m'),
    Spec('disturbance.start', 0.0, 'Start of the disturbance pulse in s of simulated time since '
         'the node started (it goes on through resets), rounded to steps of h. Live.', low=0.0,
         high=1e9, unit='s'),
    Spec('disturbance.duration', 0.0, 'Duration of the disturbance pulse in s, rounded to steps '
         'of h: it acts in the steps k with round(start/h) <= k < round(start/h) + '
         'round(duration/h) (0 = no pulse). Live.', low=0.0, high=1e9, unit='s'),
    Spec('disturbance.pulses', '', "More torque pulses, 'torque start duration; ...' (N m, s, s "
         'of simulated time since the node started, rounded to steps of h as the single '
         "pulse's), e.g. '0.5 1.0 0.2; -0.3 4.0 1.0'; they add to the single pulse and to each "
         "other where they overlap ('' = none). Live.",
         constraints="'' or 'torque start duration' triples separated by ';'"),
    # Feature switches.
    Spec('publish_energy', True, 'Publish the energy (J, true state) on energy. ' + SWITCH,
         read_only=True),
    Spec('publish_energy_terms', False, 'Publish energy_terms/{kinetic,potential,'
         'dissipated_power,residual}. ' + SWITCH, read_only=True),
    Spec('effort_input', True, 'Subscribe to effort_command (std_msgs/Float64, N m) when '
         'command_interface is effort; ignored for the velocity and position interfaces. '
         + SWITCH, read_only=True),
    Spec('joint_commands_input', False, 'Subscribe to joint_commands (sensor_msgs/JointState '
         'matched by joint name, the field of command_interface; topic_based_ros2_control). '
         + SWITCH, read_only=True),
    Spec('array_command_input', False, 'Subscribe to commands (std_msgs/Float64MultiArray of '
         'length 1; forward_command_controller). ' + SWITCH, read_only=True),
    Spec('services', True, 'Offer ~/reset, ~/pause, ~/step and ~/step_periods. ' + SWITCH,
         read_only=True),
    Spec('diagnostics', True, 'Publish /diagnostics about once a second. ' + SWITCH,
         read_only=True),
    Spec('publish_robot_description', False, 'Publish the URDF on robot_description '
         '(transient local). ' + SWITCH, read_only=True),
    Spec('status_line', True, 'Show a live status line on stderr. ' + SWITCH, read_only=True),
    Spec('recording.path', '', "Record to this MCAP file or folder ('' = off). " + SWITCH,
         read_only=True),
    Spec('recording.overwrite', False, 'Replace an existing recording file.', read_only=True),
    # Live view.
    Spec('foxglove_port', 0, 'Serve the joint live to Foxglove (foxglove-sdk WebSocket server) '
         'on this TCP port; 0 = off.', read_only=True, low=0, high=65535,
         constraints='0 (off) or 1024..65535', unit='1'),
    Spec('foxglove_host', '127.0.0.1', 'Address the Foxglove server listens on (loopback '
         "unless set; '0.0.0.0' = every interface).", read_only=True),
)

SPEC_BY_NAME: dict[str, Spec] = {s.name: s for s in SPECS}
PHYSICS = ('m', 'l', 'inertia', 'g', 'gamma', 'n', 'friction')
COMMAND_INPUTS = ('effort_input', 'joint_commands_input', 'array_command_input')
LIVE = frozenset(s.name for s in SPECS if not s.read_only)


def physics(values: Mapping[str, Value]) -> PendulumParams:
    """Return the PendulumParams of a parameter set (raises ModelError)."""
    return PendulumParams(**{k: float(values[k]) for k in PHYSICS})


def check(values: Mapping[str, Value]) -> str | None:
    """Return why the complete parameter set ``values`` is unusable, or None if it is fine."""
    return _checked(values)[0]


def _checked(values: Mapping[str, Value]) -> tuple[str | None, PendulumParams | None]:
    """Return (why ``values`` is unusable or None, its physics if it has any); the body is
    built once per check (a parameter storm validates every set)."""
    try:
        params = physics(values)
        validate_state(float(values['phi0']), float(values['dphi0']), params)
    except ModelError as exc:
        return str(exc), None
    return _check_rest(values, params), params


def check_states(values: Mapping[str, Value], phi0: FloatArray, dphi0: FloatArray
                 ) -> tuple[int, str] | None:
    """Return the first start state that :func:`check` refuses with the rest of ``values``.

    Many episodes of one parameter set that differ only in their start state (φ0, φ'0), as a
    vector environment's episodes drawing their start: the set is checked once with the first
    state, and the others screened over arrays for what :func:`check` asks of a state (the
    core's state bound, :func:`~pendulum_sim.core.model.states_accepted`, and finite energy
    terms, ``check_config``); a state the screen stops is checked by :func:`check` itself,
    which decides and gives the reason.

    Returns
    -------
    tuple of (int, str) or None
        The index of the first state refused and the reason, or None when all are fine.
    """
    def alone(i: int) -> str | None:
        return check({**values, 'phi0': float(phi0[i]), 'dphi0': float(dphi0[i])})

    if phi0.size == 0:
        return None
    reason = alone(0)
    if reason is not None:
        return 0, reason
    if phi0.size == 1:
        return None
    params = physics(values)
    with np.errstate(over='ignore', invalid='ignore'):
        kin = kinetic_energy(params, dphi0)
        pot = potential_energy(params, phi0)
        fine = (states_accepted(phi0, dphi0, params) & np.isfinite(kin) & np.isfinite(pot)
                & np.isfinite(kin + pot) & np.isfinite(dissipated_power(params, dphi0)))
    for i in np.flatnonzero(~fine).tolist():
        reason = alone(i)
        if reason is not None:
            return i, reason
    return None


def joint_name_refusal(name: str) -> str | None:
    """Return why ``name`` cannot name the joint, or None: blank, or a control character.

    A URDF or a log would not show a control character, and a NUL ends a ROS string (rcl
    passes C strings: ``'a\\x00b'`` set through a parameter file arrives as ``'a'``), so the
    package refuses one wherever it takes a name without rclpy.
    """
    if not name.strip():
        return f"joint_name must be a non-empty name, got '{name}'"
    control = next((c for c in name if unicodedata.category(c) == 'Cc'), None)
    if control is not None:
        return (f'joint_name must hold no control characters (a URDF or a log would not show '
                f'them), got {name!r} with {control!r}')
    return None


def _check_rest(values: Mapping[str, Value], params: PendulumParams) -> str | None:
    if values['integrator'] not in METHODS:
        known = ', '.join(sorted(METHODS))
        return f"integrator must be one of {known}, got '{values['integrator']}'"
    reason = joint_name_refusal(str(values['joint_name']))
    if reason is not None:
        return reason
    rtf = float(values['real_time_factor'])
    if rtf == 0.0 and not values['lockstep']:
        return 'real_time_factor must be > 0 unless lockstep is true, got 0.0'
    if values['synchronous'] and not values['lockstep']:
        return 'synchronous needs lockstep: true'
    if values['synchronous'] and not any(values[k] for k in COMMAND_INPUTS):
        return ('synchronous needs a command input to answer each state: set one of '
                + ', '.join(COMMAND_INPUTS) + ' to true')
    if values['sync_timeout_action'] not in ('hold', 'stop'):
        action = values['sync_timeout_action']
        return f"sync_timeout_action must be one of hold, stop, got '{action}'"
    if values['command_interface'] != 'effort' and not (
            values['joint_commands_input'] or values['array_command_input']):
        return (f"command_interface '{values['command_interface']}' takes commands on "
                'joint_commands or commands: set joint_commands_input or array_command_input '
                'to true (effort_command carries N m, effort only)')
    port_reason = check_port(int(values['foxglove_port']))
    if port_reason is not None:
        return port_reason
    host = str(values['foxglove_host'])
    if not host.strip() or host != host.strip():
        return f"foxglove_host must be an address to listen on, got '{host}'"
    for name in ('position_min', 'position_max'):
        if math.isnan(float(values[name])):
            return f'{name} must be a number or an infinity, got nan'
    lo, hi = float(values['position_min']), float(values['position_max'])
    if math.isfinite(lo) != math.isfinite(hi):
        return ('position_min and position_max must be both finite (a revolute joint) or both '
                f'infinite (a continuous joint), got {lo} and {hi}: a URDF joint has no '
                'one-sided limit')
    try:
        check_config(JointConfig.from_values(values, params))
    except (JointError, ModelError) as exc:
        return str(exc)
    return None


def effort_input_active(values: Mapping[str, Value]) -> bool:
    """Return True when the node subscribes to effort_command (effort_input, effort interface)."""
    return bool(values['effort_input']) and values['command_interface'] == 'effort'


def start_epoch_ns(values: Mapping[str, Value], wall_ns: int) -> int:
    """Return the stamp of step 0 (ns): ``start_time``; a negative one starts a real-time run
    at the wall clock ``wall_ns`` and a lockstep run at 0."""
    start = float(values['start_time'])
    return wall_ns if start < 0.0 and not values['lockstep'] else round(max(start, 0) * 1e9)


def joint_config(values: Mapping[str, Value], epoch_ns: int = 0) -> JointConfig:
    """Return the simulated joint's config of a parameter set (raises JointError)."""
    return JointConfig.from_values(values, physics(values), epoch_ns)


def merged(current: Mapping[str, Value], changes: Iterable[tuple[str, Value]]) -> dict[str, Value]:
    """Return ``current`` updated with the (name, value) changes this node owns."""
    out = dict(current)
    for name, value in changes:
        if name in SPEC_BY_NAME:
            out[name] = value
    return out


def refusal(current: Mapping[str, Value], changes: Iterable[tuple[str, Value]],
            joint: SimulatedJoint) -> str | None:
    """Return why a set of live parameter changes is refused, or None to accept it.

    The whole proposed set is checked (cross-parameter rules hold), then the running joint
    checks the new physics against its state.
    """
    proposed = merged(current, changes)
    reason, params = _checked(proposed)
    if reason is None and params is not None:
        try:
            joint.check_params(params)
        except (JointError, PendulumError) as exc:
            reason = str(exc)
    return reason
