"""Generate the pendulum's URDF from its parameters: a simulator-ready joint and link.

One joint (continuous, or revolute with position limits) carries one link whose centre of mass
sits ``l`` below the pivot. The link's inertia about its centre of mass follows from the
parallel-axis theorem, ``I_com = I − m l²``, written as an isotropic tensor (a ball's: ``ixx =
iyy = izz = I_com``, positive definite whenever ``I > m l²``, as MuJoCo requires), so the inertia
about the joint axis is exactly the paper's ``I`` (Quiroga & Ospina-Henao, Eur. J. Phys. 38 (2017)
065005). ``I < m l²`` describes no rigid body (PendulumParams refuses it); ``I = m l²`` (the
paper's point mass) gives the zero tensor, which engines that need a positive one cannot load.

The damping law ``γ I |φ'|^n sgn φ'`` has a URDF equivalent only for ``n = 1``: viscous damping
``<dynamics damping="γ I"/>`` in N m s/rad. For any other ``n`` no ``<dynamics>`` is written and a
comment says why.

The ``<ros2_control>`` block declares the joint for ``topic_based_ros2_control``
(https://github.com/PickNikRobotics/topic_based_ros2_control: plugin
``topic_based_ros2_control/TopicBasedSystem``, hardware parameters ``joint_commands_topic`` and
``joint_states_topic``, see its ``doc/user.md``), so a controller manager drives this node's
``joint_commands`` topic and reads its ``joint_states``. The topics are absolute, in the node's
namespace (``/pendulum`` by default): the plugin's node lives in the controller manager's process,
where relative names would resolve to ``/joint_states``, joint_state_broadcaster's topic. The
state interfaces carry ``initial_value`` (φ0, φ'0, 0 N m): the plugin's ``on_init`` copies them
into its commands, so a position interface commands φ0, not 0, before any controller runs.

Regenerate the shipped ``urdf/pendulum.urdf`` (the default scene) with::

    python -m pendulum_sim.joint.urdf > urdf/pendulum.urdf
"""
from __future__ import annotations

import math
import re
from collections.abc import Mapping
from xml.sax.saxutils import escape

from pendulum_sim.core import PendulumParams

from .errors import ParameterError

INTERFACES = ('effort', 'velocity', 'position')
# The namespace the shipped URDF expects the node in (run it with -r __ns:=/pendulum).
NAMESPACE = '/pendulum'
COMMANDS_TOPIC = f'{NAMESPACE}/joint_commands'
STATES_TOPIC = f'{NAMESPACE}/joint_states'
PLUGIN = 'topic_based_ros2_control/TopicBasedSystem'
# Characters XML 1.0 cannot hold at all, escaped or not.
_NOT_XML = re.compile('[\x00-\x08\x0b\x0c\x0e-\x1f\ufffe\uffff]')


def _num(value: float) -> str:
    """Return ``value`` at full precision (the shortest text that reads back as the same float)."""
    return repr(float(value))


def _attr(text: str, what: str) -> str:
    """Return ``text`` escaped for a double-quoted attribute or element text."""
    if _NOT_XML.search(text):
        raise ParameterError(f'{what} {text!r} holds a character XML cannot represent')
    return escape(text, {'"': '&quot;', "'": '&apos;'})


def _finite(name: str, value: float, *, positive: bool = False) -> float:
    value = float(value)
    if not math.isfinite(value) or value < 0.0 or (positive and value == 0.0):
        need = '> 0' if positive else '>= 0'
        raise ParameterError(f'{name} must be a finite number {need} for the URDF, got {value}')
    return value


def com_inertia(params: PendulumParams) -> float:
    """Return the link's moment of inertia about its centre of mass, ``I − m l²`` (kg m²).

    PendulumParams refuses ``I < m l²`` (the core's parallel-axis rule, within its round-off
    tolerance), so only round-off below 0 is left: that is the point mass, 0.
    """
    return max(params.inertia - params.m * params.l * params.l, 0.0)


def _friction_note(friction: float) -> str:
    """Return ', friction = f N m' for a comment where f > 0 ('' without friction)."""
    return f', friction = {_num(friction)} N m' if friction > 0.0 else ''


def urdf_dynamics(params: PendulumParams) -> str:
    """Return the joint's ``<dynamics damping=".." friction=".."/>`` (or why there is none).

    URDF (and Gazebo, MuJoCo's ``damping`` and ``frictionloss``) take a viscous torque
    −damping φ' and a Coulomb torque of level ``friction``: n = 1 writes damping = γ I,
    n = 0 adds its dry friction γ I to ``friction``; another n has no URDF equivalent, so only
    the Coulomb friction is written (where it is > 0), with the law left out named.
    """
    f = params.friction
    if params.n == 1.0:
        return (f'<!-- Viscous damping (n = 1): gamma I = {_num(params.gamma)} * '
                f'{_num(params.inertia)} N m s/rad{_friction_note(f)}. -->\n'
                f'    <dynamics damping="{_num(params.gamma * params.inertia)}" '
                f'friction="{_num(f)}"/>')
    if params.n == 0.0:
        dry = params.gamma * params.inertia + f
        return (f'<!-- Dry friction (n = 0): gamma I = {_num(params.gamma)} * '
                f'{_num(params.inertia)} N m plus the friction {_num(f)} N m. -->\n'
                f'    <dynamics damping="0.0" friction="{_num(dry)}"/>')
    law = (f'the damping torque gamma I |dphi|^n sgn(dphi) with gamma = {_num(params.gamma)}, '
           f'n = {_num(params.n)} has no URDF equivalent (URDF damping is viscous, n = 1)')
    if f > 0.0:
        return (f'<!-- Coulomb friction only: {law}. -->\n'
                f'    <dynamics damping="0.0" friction="{_num(f)}"/>')
    return f'<!-- No <dynamics>: {law}. -->'


def pendulum_urdf(params: PendulumParams, joint_name: str = 'pendulum_joint', *,
                  max_effort: float = 10.0, max_velocity: float = 100.0,
                  lower: float | None = None, upper: float | None = None,
                  command_interface: str = 'effort',
                  joint_commands_topic: str = COMMANDS_TOPIC,
                  joint_states_topic: str = STATES_TOPIC,
                  phi0: float = 0.0, dphi0: float = 0.0) -> str:
    """Return the URDF of a pendulum swinging about the y axis of ``base_link``.

    Parameters
    ----------
    params : PendulumParams
        The physical parameters (m, l, I, γ, n; g is the world's, not the robot's).
    joint_name : str
        The joint's name (any text; escaped).
    max_effort, max_velocity : float
        ``<limit effort=… velocity=…>`` in N m and rad/s (finite, >= 0).
    lower, upper : float, optional
        Position limits in rad: both finite (a revolute joint) or neither (continuous).
    command_interface : str
        The command interface declared in ``<ros2_control>``: effort, velocity or position.
    joint_commands_topic, joint_states_topic : str
        This node's topics, given to topic_based_ros2_control (absolute names).
    phi0, dphi0 : float
        The initial state: ``initial_value`` of the position and velocity state interfaces.

    Returns
    -------
    str
        The URDF document.

    Raises
    ------
    ParameterError
        A non-finite or negative limit, a one-sided position limit, ``lower >= upper``, an
        unknown interface or a name XML cannot hold.
    """
    if command_interface not in INTERFACES:
        raise ParameterError(f"command_interface must be one of {', '.join(INTERFACES)}, got "
                             f"'{command_interface}'")
    if not str(joint_name).strip():
        raise ParameterError(f"joint_name must be a non-empty name, got '{joint_name}'")
    name = _attr(str(joint_name), 'joint_name')
    cmd_topic = _attr(joint_commands_topic, 'joint_commands_topic')
    state_topic = _attr(joint_states_topic, 'joint_states_topic')
    effort = _finite('max_effort', max_effort)
    velocity = _finite('max_velocity', max_velocity)
    has_lower = lower is not None and math.isfinite(lower)
    has_upper = upper is not None and math.isfinite(upper)
    if has_lower != has_upper:
        raise ParameterError(f'position limits must be both finite (revolute) or both absent '
                             f'(continuous), got lower = {lower} and upper = {upper}: a URDF '
                             'joint has no one-sided limit')
    limited = has_lower and has_upper
    for what, value in (('phi0', phi0), ('dphi0', dphi0)):
        if not math.isfinite(value):
            raise ParameterError(f'{what} must be finite for the URDF, got {value}')
    if limited:
        assert lower is not None and upper is not None
        if not lower < upper:
            raise ParameterError(f'position limits need lower < upper, got {lower} and {upper}')
    m, l = params.m, params.l  # noqa: E741 - the paper's symbol
    i_com = com_inertia(params)
    rod = 0.01 * max(l, 0.1)
    bob = 0.05 * max(l, 0.1)

    if limited:
        joint_type = 'revolute'
        limit = (f'<limit lower="{_num(lower)}" upper="{_num(upper)}" '  # type: ignore[arg-type]
                 f'effort="{_num(effort)}" velocity="{_num(velocity)}"/>')
    else:
        joint_type = 'continuous'
        limit = f'<limit effort="{_num(effort)}" velocity="{_num(velocity)}"/>'
    dynamics = urdf_dynamics(params)

    limits_params = {
        'effort': (-effort, effort),
        'velocity': (-velocity, velocity),
        'position': (lower, upper) if limited else (None, None),
    }[command_interface]
    cmd_params = ''.join(
        f'\n        <param name="{key}">{_num(value)}</param>'
        for key, value in zip(('min', 'max'), limits_params, strict=True) if value is not None)
    cmd_close = '\n      </command_interface>' if cmd_params else ''
    cmd_open = f'<command_interface name="{command_interface}"' + ('>' if cmd_params else '/>')

    return f"""<?xml version="1.0"?>
<!-- Generated by pendulum_sim.joint.urdf from m = {_num(m)} kg, l = {_num(l)} m, \
I = {_num(params.inertia)} kg m^2, gamma = {_num(params.gamma)}, n = {_num(params.n)}\
{_friction_note(params.friction)}. -->
<robot name="pendulum">
  <link name="base_link"/>
  <joint name="{name}" type="{joint_type}">
    <parent link="base_link"/>
    <child link="pendulum_link"/>
    <origin xyz="0 0 0" rpy="0 0 0"/>
    <axis xyz="0 1 0"/>
    {limit}
    {dynamics}
  </joint>
  <link name="pendulum_link">
    <inertial>
      <!-- Centre of mass l below the pivot; about it I - m l^2 in every direction, so the
           inertia about the joint axis is I. -->
      <origin xyz="0 0 {_num(-l)}" rpy="0 0 0"/>
      <mass value="{_num(m)}"/>
      <inertia ixx="{_num(i_com)}" ixy="0.0" ixz="0.0" iyy="{_num(i_com)}" iyz="0.0" \
izz="{_num(i_com)}"/>
    </inertial>
    <visual>
      <origin xyz="0 0 {_num(-l / 2)}" rpy="0 0 0"/>
      <geometry><cylinder radius="{_num(rod)}" length="{_num(l)}"/></geometry>
    </visual>
    <visual>
      <origin xyz="0 0 {_num(-l)}" rpy="0 0 0"/>
      <geometry><sphere radius="{_num(bob)}"/></geometry>
    </visual>
  </link>
  <!-- ros2_control through topic_based_ros2_control
       (github.com/PickNikRobotics/topic_based_ros2_control, doc/user.md): it publishes
       sensor_msgs/JointState commands on joint_commands_topic and reads joint_states_topic.
       trigger_joint_command_threshold -1 sends every command (its default 1e-5 skips commands
       whose position equals the measured one, which drops effort and velocity commands).
       initial_value: what the plugin commands before a controller does (the initial state). -->
  <ros2_control name="pendulum" type="system">
    <hardware>
      <plugin>{PLUGIN}</plugin>
      <param name="joint_commands_topic">{cmd_topic}</param>
      <param name="joint_states_topic">{state_topic}</param>
      <param name="trigger_joint_command_threshold">-1</param>
    </hardware>
    <joint name="{name}">
      {cmd_open}{cmd_params}{cmd_close}
      <state_interface name="position">
        <param name="initial_value">{_num(phi0)}</param>
      </state_interface>
      <state_interface name="velocity">
        <param name="initial_value">{_num(dphi0)}</param>
      </state_interface>
      <state_interface name="effort">
        <param name="initial_value">0.0</param>
      </state_interface>
    </joint>
  </ros2_control>
</robot>
"""


def urdf_from_values(values: Mapping[str, object], *,
                     joint_commands_topic: str = COMMANDS_TOPIC,
                     joint_states_topic: str = STATES_TOPIC) -> str:
    """Return the URDF of a node parameter set (names as the node declares them).

    Missing names take the declared defaults (``pendulum_sim.joint.parameters.SPECS``); the
    topics are the node's resolved topic names for the ``<ros2_control>`` block.
    """
    from .parameters import SPEC_BY_NAME

    full: dict[str, object] = {name: spec.default for name, spec in SPEC_BY_NAME.items()}
    full.update(values)

    def num(name: str) -> float:
        return float(full[name])  # type: ignore[arg-type]

    params = PendulumParams(**{k: num(k) for k in ('m', 'l', 'inertia', 'g', 'gamma', 'n',
                                                   'friction')})
    lower = num('position_min') if 'position_min' in full else None
    upper = num('position_max') if 'position_max' in full else None
    return pendulum_urdf(params, str(full['joint_name']), max_effort=num('max_effort'),
                         max_velocity=num('max_velocity') if 'max_velocity' in full else 100.0,
                         lower=lower, upper=upper,
                         command_interface=str(full.get('command_interface', 'effort')),
                         joint_commands_topic=joint_commands_topic,
                         joint_states_topic=joint_states_topic,
                         phi0=num('phi0'), dphi0=num('dphi0'))


def default_urdf() -> str:
    """Return the URDF of the default scene (what ``urdf/pendulum.urdf`` holds)."""
    from .scenes import find_scene, read_params_file

    return urdf_from_values(read_params_file(find_scene('default')))


if __name__ == '__main__':  # regenerate urdf/pendulum.urdf: python -m pendulum_sim.joint.urdf
    print(default_urdf(), end='')
