"""The generated URDF, checked by independent parsers and by rigid-body engines (MuJoCo,
PyBullet, Pinocchio, Drake).

Issue 9 item 4 and issue 11 item 6: escaped names, full precision, a rigid body's inertia
(I >= m l²), limits, viscous damping γ I where n = 1, a ros2_control block for
topic_based_ros2_control; MuJoCo's joint inertia equals I and its swing matches simulate().
"""
from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from doc_pages import TUTORIALS, blocks

from pendulum_sim.core import ModelError, PendulumParams, simulate
from pendulum_sim.joint.errors import ParameterError
from pendulum_sim.joint.urdf import PLUGIN, default_urdf, pendulum_urdf

REPO_URDF = Path(__file__).resolve().parents[2] / 'urdf' / 'pendulum.urdf'
# A body with I > m l² (MuJoCo needs a positive inertia tensor about the centre of mass).
BODY = PendulumParams(m=0.37, l=0.83, inertia=0.31, g=9.81, gamma=0.7, n=1.0)
# The same pendulum with 1 % more damping: the comparisons with an engine must see it.
MORE_DAMPED = BODY.with_changes(gamma=BODY.gamma * 1.01)
# The bodies whose inertia, gravity torque and damping Pinocchio and Drake are asked for.
MEASURED_BODIES = pytest.mark.parametrize('params', [
    BODY,
    PendulumParams(m=2.0, l=0.25, inertia=0.2, gamma=0.1),
    PendulumParams(m=0.2, l=1.0, inertia=0.2, gamma=1.0),
], ids=['body', 'short-heavy', 'point-mass'])
TEXT_ATTRIBUTES = ('a&b', 'x" type="fixed', "q'<j>", 'spaced name')


def parse(urdf: str) -> ET.Element:
    """Parse with the standard library's XML parser (validity)."""
    return ET.fromstring(urdf)


def one(root: ET.Element, path: str) -> ET.Element:
    """Return the single element at ``path``."""
    found = root.findall(path)
    assert len(found) == 1, f'{len(found)} elements at {path}'
    return found[0]


@pytest.mark.parametrize('name', TEXT_ATTRIBUTES)
def test_names_are_escaped(name: str) -> None:
    """A hostile joint name stays one name attribute, of the joint and of its ros2_control."""
    root = parse(pendulum_urdf(BODY, name))
    joint = one(root, 'joint')
    assert joint.get('name') == name and joint.get('type') == 'continuous'
    assert one(root, 'ros2_control/joint').get('name') == name


def test_xml_cannot_hold_control_characters() -> None:
    """A name with a character XML 1.0 cannot hold is refused, not written."""
    with pytest.raises(ParameterError, match='XML cannot represent'):
        pendulum_urdf(BODY, 'a\x01b')


def test_numbers_are_written_at_full_precision() -> None:
    """Every number reads back as exactly the float it came from."""
    params = PendulumParams(m=0.1234567890123456, l=0.7777777777777777, inertia=0.3141592653589793,
                            gamma=0.123456789012345, n=1.0)
    root = parse(pendulum_urdf(params, max_effort=1.0 / 3.0, max_velocity=2.0 / 3.0))
    inertial = one(root, "link[@name='pendulum_link']/inertial")
    assert float(one(inertial, 'mass').get('value') or '') == params.m
    assert one(inertial, 'origin').get('xyz') == f'0 0 {-params.l!r}'
    i_com = params.inertia - params.m * params.l ** 2
    tensor = one(inertial, 'inertia')
    assert [float(tensor.get(k) or 'nan') for k in ('ixx', 'iyy', 'izz')] == [i_com] * 3
    assert [float(tensor.get(k) or 'nan') for k in ('ixy', 'ixz', 'iyz')] == [0.0] * 3
    limit = one(root, 'joint/limit')
    assert (float(limit.get('effort') or ''), float(limit.get('velocity') or '')) == (
        1.0 / 3.0, 2.0 / 3.0)
    assert float(one(root, 'joint/dynamics').get('damping') or '') == (
        params.gamma * params.inertia)


def test_point_mass_has_a_zero_tensor_and_no_body_below_m_l2() -> None:
    """I = m l² (the paper's point mass): the zero tensor; I < m l² never reaches the URDF."""
    tensor = one(parse(pendulum_urdf(PendulumParams())), 'link/inertial/inertia')
    assert {tensor.get(k) for k in ('ixx', 'iyy', 'izz')} == {'0.0'}
    with pytest.raises(ModelError, match='inertia must be >= m'):
        pendulum_urdf(PendulumParams(m=0.2, l=1.0, inertia=0.1))


def test_limits_and_joint_type() -> None:
    """No position limits: continuous; both: revolute with lower/upper; bad limits refused."""
    root = parse(pendulum_urdf(BODY, lower=-1.5, upper=2.25, max_effort=3.0, max_velocity=4.0))
    joint = one(root, 'joint')
    assert joint.get('type') == 'revolute'
    assert one(joint, 'limit').attrib == {'lower': '-1.5', 'upper': '2.25', 'effort': '3.0',
                                          'velocity': '4.0'}
    infinite = parse(pendulum_urdf(BODY, lower=-math.inf, upper=math.inf))
    assert one(infinite, 'joint').get('type') == 'continuous'
    for bad in ({'lower': 1.0, 'upper': 1.0}, {'max_effort': math.inf},
                {'max_velocity': -1.0}, {'command_interface': 'torque'}):
        with pytest.raises(ParameterError):
            pendulum_urdf(BODY, **bad)


def test_damping_only_where_urdf_has_an_equivalent() -> None:
    """n = 1: <dynamics damping = γ I>; n ≠ 1: no <dynamics>, a comment says why."""
    quadratic = PendulumParams(m=0.2, l=1.0, inertia=0.2, gamma=0.5, n=2.0)
    text = pendulum_urdf(quadratic)
    assert parse(text).find('joint/dynamics') is None
    assert 'gamma = 0.5, n = 2.0 has no URDF equivalent' in text


@pytest.mark.parametrize(('gamma', 'n', 'friction', 'damping', 'coulomb'), [
    (0.7, 1.0, 0.25, 0.7 * 0.31, 0.25),   # viscous: damping γ I, friction f
    (0.5, 0.0, 0.25, 0.0, 0.5 * 0.31 + 0.25),  # dry law: its γ I adds to f
    (0.5, 2.0, 0.25, 0.0, 0.25),  # no URDF law for n = 2: the friction alone
])
def test_dynamics_writes_the_friction(gamma: float, n: float, friction: float, damping: float,
                                      coulomb: float) -> None:
    """<dynamics damping=".." friction=".."/>: the Coulomb torque f beside the law."""
    params = BODY.with_changes(gamma=gamma, n=n, friction=friction)
    dyn = one(parse(pendulum_urdf(params)), 'joint/dynamics')
    assert float(dyn.get('damping', 'nan')) == pytest.approx(damping, rel=1e-15)
    assert float(dyn.get('friction', 'nan')) == pytest.approx(coulomb, rel=1e-15)


@pytest.mark.parametrize('interface', ['effort', 'velocity', 'position'])
def test_ros2_control_block(interface: str) -> None:
    """topic_based_ros2_control: plugin, this node's topics, 3 state and 1 command interface."""
    root = parse(pendulum_urdf(BODY, 'j', command_interface=interface, lower=-1.0, upper=1.0,
                               max_effort=5.0, max_velocity=6.0,
                               joint_commands_topic='/ns/joint_commands', phi0=0.25,
                               dphi0=-0.5))
    block = one(root, 'ros2_control')
    assert block.attrib == {'name': 'pendulum', 'type': 'system'}
    assert one(block, 'hardware/plugin').text == PLUGIN == (
        'topic_based_ros2_control/TopicBasedSystem')
    params = {p.get('name'): p.text for p in block.findall('hardware/param')}
    assert params == {'joint_commands_topic': '/ns/joint_commands',
                      'joint_states_topic': '/pendulum/joint_states',
                      'trigger_joint_command_threshold': '-1'}
    joint = one(block, 'joint')
    assert [s.get('name') for s in joint.findall('state_interface')] == [
        'position', 'velocity', 'effort']
    # The plugin's on_init copies each state interface's initial_value into the command of
    # the same name: the initial state, so a position interface holds φ0 until commanded.
    initial = {s.get('name'): [(p.get('name'), p.text) for p in s.findall('param')]
               for s in joint.findall('state_interface')}
    assert initial == {'position': [('initial_value', '0.25')],
                       'velocity': [('initial_value', '-0.5')],
                       'effort': [('initial_value', '0.0')]}
    command = one(joint, 'command_interface')
    assert command.get('name') == interface
    bounds = {'effort': ['-5.0', '5.0'], 'velocity': ['-6.0', '6.0'],
              'position': ['-1.0', '1.0']}[interface]
    assert [(p.get('name'), p.text) for p in command.findall('param')] == list(
        zip(['min', 'max'], bounds, strict=True))


def test_shipped_urdf_is_the_default_scene() -> None:
    """urdf/pendulum.urdf is what the generator makes of config/default.yaml."""
    assert REPO_URDF.read_text() == default_urdf()


def test_shipped_topics_do_not_collide_with_joint_state_broadcaster() -> None:
    """Absolute topics in /pendulum: not /joint_states, wherever the controller manager runs.

    The plugin's node lives in the controller manager's process (in / by default), where a
    relative name would resolve to /joint_states, joint_state_broadcaster's output.
    """
    root = parse(REPO_URDF.read_text())
    params = {p.get('name'): p.text for p in root.findall('ros2_control/hardware/param')}
    assert params['joint_states_topic'] == '/pendulum/joint_states'
    assert params['joint_commands_topic'] == '/pendulum/joint_commands'
    state = one(root, "ros2_control/joint/state_interface[@name='position']/param")
    assert float(state.text or '') == 0.3    # phi0 of the default scene


@pytest.mark.parametrize(('lower', 'upper'), [(-1.0, None), (None, 2.0), (-1.0, math.inf),
                                              (-math.inf, 0.5)])
def test_a_one_sided_limit_is_refused(lower: float | None, upper: float | None) -> None:
    """URDF has no one-sided limit (continuous: none; revolute: both): refused with why."""
    msg = (f'position limits must be both finite (revolute) or both absent (continuous), got '
           f'lower = {lower} and upper = {upper}: a URDF joint has no one-sided limit')
    with pytest.raises(ParameterError, match=re.escape(msg)):
        pendulum_urdf(BODY, lower=lower, upper=upper)


def test_urdf_parser_py_reads_it() -> None:
    """An independent URDF parser (urdf_parser_py) reads the joint, limits, dynamics, inertia."""
    urdf_parser = pytest.importorskip('urdf_parser_py.urdf')
    robot = urdf_parser.URDF.from_xml_string(pendulum_urdf(BODY, 'a&b', max_effort=2.5,
                                                           max_velocity=7.0))
    (joint,) = robot.joints
    assert (joint.name, joint.type, list(joint.axis)) == ('a&b', 'continuous', [0.0, 1.0, 0.0])
    assert (joint.limit.effort, joint.limit.velocity) == (2.5, 7.0)
    assert joint.dynamics.damping == BODY.gamma * BODY.inertia
    link = robot.link_map['pendulum_link']
    assert link.inertial.mass == BODY.m
    assert link.inertial.inertia.iyy == BODY.inertia - BODY.m * BODY.l ** 2
    assert list(link.inertial.origin.xyz) == [0.0, 0.0, -BODY.l]


# ---------------------------------------------------------------- MuJoCo as the oracle
def mujoco_model(urdf: str) -> Any:
    """Load a URDF into MuJoCo (visuals discarded, as its URDF import requires meshes for them)."""
    mujoco = pytest.importorskip('mujoco')
    tagged = urdf.replace('<robot name="pendulum">', '<robot name="pendulum">\n  <mujoco>'
                          '<compiler discardvisual="true"/></mujoco>', 1)
    return mujoco.MjModel.from_xml_string(tagged)


def joint_inertia(model: Any, phi: float = 0.0) -> float:
    """Return MuJoCo's joint-space inertia (its mass matrix, 1x1) at angle ``phi``."""
    import mujoco

    data = mujoco.MjData(model)
    data.qpos[0] = phi
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    return float(full[0, 0])


@pytest.mark.parametrize('params', [
    BODY,
    PendulumParams(m=2.0, l=0.25, inertia=0.2, gamma=0.1),
    PendulumParams(m=0.2, l=1.0, inertia=0.2000001, gamma=1.0),
], ids=['body', 'short-heavy', 'near-point-mass'])
def test_mujoco_joint_inertia_is_i(params: PendulumParams) -> None:
    """MuJoCo's inertia about the joint axis equals I (1e-12 relative), at any angle."""
    model = mujoco_model(pendulum_urdf(params, 'hinge'))
    assert model.njnt == 1 and model.nv == 1
    for phi in (0.0, 1.0, -2.5):
        assert joint_inertia(model, phi) == pytest.approx(params.inertia, rel=1e-12, abs=0.0)
    assert model.dof_damping[0] == params.gamma * params.inertia


def mujoco_swing(model: Any, g: float, phi0: float, t_end: float, h: float) -> np.ndarray:
    """Swing the loaded frictionless model from rest (``mujoco_run``); return φ at every step."""
    assert model.dof_armature[0] == 0.0 and model.dof_frictionloss[0] == 0.0
    return mujoco_run(model, g, phi0, t_end, h)[0]


def test_mujoco_swing_matches_simulate() -> None:
    """n = 1, no torque, φ0 = 0.5 rad: MuJoCo (RK4, h = 1e-4 s) follows simulate() to 1e-6 rad."""
    h, t_end, phi0 = 1e-4, 3.0, 0.5
    model = mujoco_model(pendulum_urdf(BODY))
    theirs = mujoco_swing(model, BODY.g, phi0, t_end, h)
    ours = simulate(BODY, phi0, 0.0, t_end, h, 'rk4')
    assert len(ours.phi) == len(theirs)
    assert np.max(np.abs(ours.phi - theirs)) < 1e-6
    # The swing is a real one: it decays (γ = 0.7 s⁻¹) and crosses zero several times.
    assert np.count_nonzero(np.diff(np.sign(theirs)) != 0) >= 2
    assert 0.1 < np.max(np.abs(theirs[-10000:])) < 0.8 * phi0


def test_mujoco_notices_a_different_pendulum() -> None:
    """The comparison can fail: 1% more damping in the URDF moves the swing far beyond 1e-6."""
    h, t_end, phi0 = 1e-4, 3.0, 0.5
    theirs = mujoco_swing(mujoco_model(pendulum_urdf(MORE_DAMPED)), BODY.g, phi0, t_end, h)
    ours = simulate(BODY, phi0, 0.0, t_end, h, 'rk4')
    assert np.max(np.abs(ours.phi - theirs)) > 1e-4


def mujoco_run(model: Any, g: float, phi0: float, t_end: float,
               h: float) -> tuple[np.ndarray, np.ndarray]:
    """Swing the loaded model freely from rest under gravity ``g`` with MuJoCo's RK4; return
    (φ, φ') at every step (from t = 0)."""
    import mujoco

    model.opt.gravity[:] = (0.0, 0.0, -g)
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    model.opt.timestep = h
    data = mujoco.MjData(model)
    data.qpos[0] = phi0
    steps = round(t_end / h)
    phi, dphi = np.empty(steps + 1), np.empty(steps + 1)
    phi[0], dphi[0] = phi0, 0.0
    for k in range(steps):
        mujoco.mj_step(model, data)
        phi[k + 1], dphi[k + 1] = data.qpos[0], data.qvel[0]
    return phi, dphi


def test_mujoco_frictionloss_shows_the_same_stick_slip() -> None:
    """URDF friction → MuJoCo frictionloss: the same slip, the same stick (time and angle).

    Sliding, MuJoCo's frictionloss is the constant torque f against the motion, as here: the
    first half-swing agrees to 1e-9 rad (both RK4 at h = 1e-4 s). At a reversal MuJoCo solves
    the friction as a soft constraint (its default solref time constant 0.02 s), so its turning
    points and its stick differ a little: a constraint force within f leaves a slow creep,
    not an exact rest. Hence the stick time (|φ'| below 1e-3 rad/s for good in MuJoCo, exactly
    0 here) within 0.05 s and the rest angle within 2e-3 rad (the creep's 2.4e-4 rad/s
    moves MuJoCo's by 5e-4 rad from its stick to 6 s; the static band |m g l sin φ| <= f is
    ±0.034 rad wide, so the bound tells a rest within it from a swing), and MuJoCo's angle
    inside the band.
    """
    h, t_end, phi0 = 1e-4, 6.0, 0.5
    params = BODY.with_changes(friction=0.1)
    model = mujoco_model(pendulum_urdf(params))
    assert model.dof_frictionloss[0] == 0.1 and model.dof_damping[0] == BODY.gamma * 0.31
    phi_mj, dphi_mj = mujoco_run(model, BODY.g, phi0, t_end, h)
    ours = simulate(params, phi0, 0.0, t_end, h, 'rk4')
    first = round(0.9 / h)  # before the first reversal (half a period of 2.0 s)
    assert np.all(ours.dphi[1:first] < 0.0)
    assert np.max(np.abs(ours.phi[:first] - phi_mj[:first])) < 1e-9

    def stick_time(dphi: np.ndarray, tol: float) -> float:
        return float((np.flatnonzero(np.abs(dphi) > tol)[-1] + 1) * h)

    t_ours, t_mj = stick_time(ours.dphi, 0.0), stick_time(dphi_mj, 1e-3)
    assert 1.0 < t_ours < 5.5 and ours.dphi[-1] == 0.0
    assert abs(t_ours - t_mj) < 0.05
    band = math.asin(0.1 / (BODY.m * BODY.g * BODY.l))
    assert abs(ours.phi[-1]) <= band and abs(phi_mj[-1]) <= band
    assert abs(ours.phi[-1] - phi_mj[-1]) < 2e-3
    # The comparison can fail: without the friction MuJoCo still swings where ours rests.
    free, _ = mujoco_run(mujoco_model(pendulum_urdf(BODY)), BODY.g, phi0, t_end, h)
    assert np.max(np.abs(free[-round(2.0 / h):])) > 3 * abs(ours.phi[-1])


@pytest.mark.ros
def test_live_robot_description_loads_in_mujoco() -> None:
    """The live node's robot_description (default scene): MuJoCo reads I, m, γ I from it.

    It is the generator's URDF of the node's parameters, naming the node's resolved topics.
    """
    from node_harness import NodeProcess, Probe
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    from pendulum_sim.joint.scenes import find_scene, read_params_file
    from pendulum_sim.joint.urdf import urdf_from_values

    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    overrides = {'joint_name': 'swing&sway', 'max_effort': 3.5}
    with NodeProcess('default', overrides) as node, Probe() as probe:
        got = probe.subscribe(String, f'{node.namespace}/robot_description', latched)
        probe.spin_until(lambda: len(got) >= 1 or not node.alive(), 20.0, 'robot_description')
        assert node.alive(), node.output()
        urdf = got.msgs[0].data
    values = {**read_params_file(find_scene('default')), **overrides}
    assert urdf == urdf_from_values(values,
                                    joint_commands_topic=f'{node.namespace}/joint_commands',
                                    joint_states_topic=f'{node.namespace}/joint_states')
    assert one(parse(urdf), 'joint').get('name') == 'swing&sway'
    model = mujoco_model(urdf)
    inertia, gamma = float(values['inertia']), float(values['gamma'])
    assert joint_inertia(model) == pytest.approx(inertia, rel=1e-12, abs=0.0)
    assert model.body_mass[-1] == float(values['m'])
    assert model.dof_damping[0] == gamma * inertia


# ---------------------------------------------------------------- PyBullet, measured
def pybullet_swing(urdf_path: Path, flags: int, link_damping: float | None,
                   h: float = 1e-4, t_end: float = 3.0, phi0: float = 0.5) -> np.ndarray:
    """Swing the loaded URDF freely in PyBullet (no motor); return φ at every step."""
    import pybullet as pb

    cid = pb.connect(pb.DIRECT)
    try:
        body = pb.loadURDF(str(urdf_path), useFixedBase=True, flags=flags, physicsClientId=cid)
        pb.setGravity(0, 0, -BODY.g, physicsClientId=cid)
        pb.setTimeStep(h, physicsClientId=cid)
        # PyBullet drives every joint with a velocity motor by default: switch it off.
        pb.setJointMotorControl2(body, 0, pb.VELOCITY_CONTROL, force=0, physicsClientId=cid)
        if link_damping is not None:
            pb.changeDynamics(body, 0, linearDamping=link_damping, angularDamping=link_damping,
                              physicsClientId=cid)
        pb.resetJointState(body, 0, phi0, physicsClientId=cid)
        out = [phi0]
        for _ in range(round(t_end / h)):
            pb.stepSimulation(physicsClientId=cid)
            out.append(pb.getJointState(body, 0, physicsClientId=cid)[0])
        return np.array(out)
    finally:
        pb.disconnect(cid)


def test_pybullet_needs_the_inertia_flag_and_no_link_damping(tmp_path: Path) -> None:
    """PyBullet replaces the URDF's inertia unless URDF_USE_INERTIA_FROM_FILE is passed, and
    adds a link damping of 0.04 by default; with the flag and that damping at 0 the free swing
    follows simulate() (to its semi-implicit Euler error)."""
    pb = pytest.importorskip('pybullet')
    path = tmp_path / 'pendulum.urdf'
    path.write_text(pendulum_urdf(BODY, 'hinge'))

    def joint_inertia_pb(flags: int) -> float:
        cid = pb.connect(pb.DIRECT)
        try:
            body = pb.loadURDF(str(path), useFixedBase=True, flags=flags, physicsClientId=cid)
            assert pb.getJointInfo(body, 0, physicsClientId=cid)[6] == pytest.approx(
                BODY.gamma * BODY.inertia, rel=1e-12)      # <dynamics damping> is read
            return float(pb.calculateMassMatrix(body, [0.0], physicsClientId=cid)[0][0])
        finally:
            pb.disconnect(cid)

    assert joint_inertia_pb(pb.URDF_USE_INERTIA_FROM_FILE) == pytest.approx(BODY.inertia,
                                                                            rel=1e-12)
    assert abs(joint_inertia_pb(0) - BODY.inertia) > 0.01 * BODY.inertia
    flag = pb.URDF_USE_INERTIA_FROM_FILE
    default = pybullet_swing(path, flag, None)
    # The default link damping is 0.04: setting 0.04 changes nothing (to the round-off of its
    # single-precision copy), 0.039 or 0.041 change the swing 1e6 times more.
    assert np.max(np.abs(default - pybullet_swing(path, flag, 0.04))) < 1e-8
    for other in (0.039, 0.041):
        assert np.max(np.abs(default - pybullet_swing(path, flag, other))) > 1e-4
    ours = simulate(BODY, 0.5, 0.0, 3.0, 1e-4, 'rk4').phi
    assert np.max(np.abs(pybullet_swing(path, flag, 0.0) - ours)) < 2e-4
    assert np.max(np.abs(default - ours)) > 1e-2


def test_the_tutorial_shows_the_shipped_ros2_control_block() -> None:
    """docs/tutorials/ros2-control.md's <ros2_control> example is the shipped URDF's block."""
    (example,) = [b for b in blocks(TUTORIALS / 'ros2-control.md', 'xml')
                  if '<ros2_control' in b]

    def summary(block: ET.Element) -> object:
        joint = one(block, 'joint')
        return (block.attrib, one(block, 'hardware/plugin').text,
                {p.get('name'): p.text for p in block.findall('hardware/param')},
                joint.get('name'),
                [(c.get('name'), [(p.get('name'), p.text) for p in c.findall('param')])
                 for c in joint.findall('command_interface')],
                [(s.get('name'), [(p.get('name'), p.text) for p in s.findall('param')])
                 for s in joint.findall('state_interface')])

    assert summary(parse(example)) == summary(one(parse(REPO_URDF.read_text()), 'ros2_control'))


# ---------------------------------------------------------------- Pinocchio, measured
ANGLES = (0.0, 0.4, 1.0, -2.5, 3.0)


def pinocchio_model(urdf: str, g: float) -> tuple[Any, Any]:
    """Build a Pinocchio model from URDF text, gravity ``g`` along -z; return (model, data)."""
    pin = pytest.importorskip('pinocchio')
    model = pin.buildModelFromXML(urdf)
    model.gravity.linear = np.array([0.0, 0.0, -g])
    return model, model.createData()


def configuration(phi: float) -> np.ndarray:
    """Pinocchio's configuration of a continuous joint at angle ``phi``: (cos φ, sin φ)."""
    return np.array([math.cos(phi), math.sin(phi)])


@MEASURED_BODIES
def test_pinocchio_inertia_gravity_and_damping(params: PendulumParams) -> None:
    """Pinocchio: crba is I (1e-12), the gravity torque m g l sin φ, model.damping γ I."""
    import pinocchio as pin

    model, data = pinocchio_model(pendulum_urdf(params, 'hinge'), params.g)
    assert (model.njoints, model.nq, model.nv) == (2, 2, 1)     # universe + the continuous joint
    assert model.names[1] == 'hinge'
    zero = np.zeros(1)
    for phi in ANGLES:
        q = configuration(phi)
        inertia = pin.crba(model, data, q)
        assert inertia.shape == (1, 1)
        assert inertia[0, 0] == pytest.approx(params.inertia, rel=1e-12, abs=0.0)
        # The torque that holds the pendulum still: m g l sin φ (eq 11: I ω0² sin φ).
        expected = params.m * params.g * params.l * math.sin(phi)
        gravity = pin.computeGeneralizedGravity(model, data, q)
        assert gravity[0] == pytest.approx(expected, rel=1e-12, abs=1e-15)
        assert pin.rnea(model, data, q, zero, zero)[0] == pytest.approx(expected, rel=1e-12,
                                                                         abs=1e-15)
    assert model.damping[0] == params.gamma * params.inertia


def pinocchio_field(urdf: str, g: float) -> Callable[[np.ndarray], np.ndarray]:
    """Return (φ, φ') -> (φ', φ'') from Pinocchio's aba, the URDF's damping as joint torque."""
    import pinocchio as pin

    model, data = pinocchio_model(urdf, g)
    damping = float(model.damping[0])

    def field(x: np.ndarray) -> np.ndarray:
        v = np.array([x[1]])
        return np.array([x[1], pin.aba(model, data, configuration(x[0]), v, -damping * v)[0]])

    return field


def rk4_swing(field: Callable[[np.ndarray], np.ndarray], phi0: float, t_end: float,
              h: float) -> np.ndarray:
    """Integrate an engine's vector field from rest at ``phi0`` with classic RK4; return φ."""
    steps = round(t_end / h)
    out = np.empty(steps + 1)
    x = np.array([phi0, 0.0])
    out[0] = x[0]
    for k in range(steps):
        k1 = field(x)
        k2 = field(x + h / 2 * k1)
        k3 = field(x + h / 2 * k2)
        k4 = field(x + h * k3)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        out[k + 1] = x[0]
    return out


# ---------------------------------------------------------------- Drake, measured
def drake_plant(urdf: str, g: float) -> tuple[Any, Any, Any]:
    """Load URDF text into a continuous Drake MultibodyPlant, base_link welded to the world.

    Return (plant, context, joint). Drake gives an unattached root link a floating joint, so
    the weld is what a fixed-base pendulum needs (PyBullet's useFixedBase).
    """
    pytest.importorskip('pydrake')
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant

    plant = MultibodyPlant(time_step=0.0)
    Parser(plant).AddModelsFromString(urdf, 'urdf')
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName('base_link'))
    plant.mutable_gravity_field().set_gravity_vector(np.array([0.0, 0.0, -g]))
    plant.Finalize()
    (joint,) = [plant.get_joint(i) for i in plant.GetJointIndices()
                if plant.get_joint(i).num_velocities() == 1]
    return plant, plant.CreateDefaultContext(), joint


@MEASURED_BODIES
def test_drake_inertia_gravity_and_damping(params: PendulumParams) -> None:
    """Drake: mass matrix I (1e-12), gravity force -m g l sin φ, joint damping γ I."""
    plant, context, joint = drake_plant(pendulum_urdf(params, 'hinge'), params.g)
    assert (plant.num_positions(), plant.num_velocities()) == (1, 1)
    assert joint.name() == 'hinge'
    for phi in ANGLES:
        plant.SetPositions(context, [phi])
        inertia = plant.CalcMassMatrix(context)
        assert inertia.shape == (1, 1)
        assert inertia[0, 0] == pytest.approx(params.inertia, rel=1e-12, abs=0.0)
        # Drake returns the generalized force gravity applies: minus the holding torque.
        expected = -params.m * params.g * params.l * math.sin(phi)
        assert plant.CalcGravityGeneralizedForces(context)[0] == pytest.approx(
            expected, rel=1e-12, abs=1e-15)
    assert joint.default_damping() == params.gamma * params.inertia


def drake_field(urdf: str, g: float) -> Callable[[np.ndarray], np.ndarray]:
    """Return (φ, φ') -> (φ', φ'') from Drake's CalcTimeDerivatives (its joint damping)."""
    plant, context, _ = drake_plant(urdf, g)
    derivatives = plant.AllocateTimeDerivatives()

    def field(x: np.ndarray) -> np.ndarray:
        plant.SetPositionsAndVelocities(context, x)
        plant.CalcTimeDerivatives(context, derivatives)
        return np.asarray(derivatives.get_vector().CopyToVector())

    return field


@pytest.mark.parametrize('engine', ['pinocchio', 'drake'])
def test_engine_swing_matches_simulate(engine: str) -> None:
    """n = 1, φ0 = 0.5 rad: RK4 over the engine's own dynamics (h = 1e-3 s) follows simulate()
    to 1e-12 rad.

    Pinocchio's aba takes the joint torque as an input (the URDF's damping is applied as
    -model.damping φ'); Drake applies the URDF's joint damping itself. 1 % more damping in the
    URDF is seen (> 1e-4 rad).
    """
    pytest.importorskip('pinocchio' if engine == 'pinocchio' else 'pydrake')
    make_field = pinocchio_field if engine == 'pinocchio' else drake_field
    h, t_end, phi0 = 1e-3, 3.0, 0.5
    ours = simulate(BODY, phi0, 0.0, t_end, h, 'rk4').phi
    theirs = rk4_swing(make_field(pendulum_urdf(BODY), BODY.g), phi0, t_end, h)
    assert len(ours) == len(theirs)
    assert np.max(np.abs(ours - theirs)) < 1e-12
    assert np.count_nonzero(np.diff(np.sign(theirs)) != 0) >= 2
    moved = rk4_swing(make_field(pendulum_urdf(MORE_DAMPED), BODY.g), phi0, t_end, h)
    assert np.max(np.abs(ours - moved)) > 1e-4
