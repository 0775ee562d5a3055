"""DDS on 127.0.0.1: UDP sockets of the node, the controller and replay, read through /proc.

The node runs in its own process; its sockets are the UDP entries of /proc/<pid>/net/udp{,6}
whose inodes are among /proc/<pid>/fd. Each test also checks that a probe in another process
still receives joint_states (pub/sub across processes works on the loopback).
"""
from __future__ import annotations

import os
import signal
import sys
from pathlib import Path

import pytest
from node_harness import NodeProcess, Probe
from procfs import sockets
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from pendulum_sim.dds import PROFILE_VARIABLES

pytestmark = [pytest.mark.ros,
              pytest.mark.skipif(not sys.platform.startswith('linux'), reason='reads /proc')]

PROFILE = Path(__file__).resolve().parents[2] / 'config' / 'fastdds_localhost.xml'


def udp_sockets(pid: int) -> list[tuple[str, int]]:
    """Return (local address, port) of every UDP socket process ``pid`` holds."""
    return [(addr, port) for addr, port, _ in sockets(pid, 'udp')]


def is_loopback(addr: str) -> bool:
    """Return True for 127.0.0.1 (or its IPv6 forms)."""
    return addr in ('127.0.0.1', '::ffff:127.0.0.1', '::1')


def rtps_ports(domain: int) -> range:
    """Return the ports RTPS gives a domain (PB = 7400, DG = 250: spec 9.6.1.1)."""
    return range(7400 + 250 * domain, 7400 + 250 * (domain + 1))


def set_environ(env: dict[str, str | None]) -> dict[str, str | None]:
    """Set the variables of ``env`` (remove those it maps to None); return what they were."""
    saved = {k: os.environ.get(k) for k in env}
    for key, value in env.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value
    return saved


def start_and_read(env: dict[str, str | None]) -> tuple[list[tuple[str, int]], str]:
    """Start the node with ``env`` changes; once a probe hears it, return its sockets and log."""
    saved = set_environ(env)
    node = NodeProcess('minimal')
    try:
        node.start()
    finally:
        set_environ(saved)
    try:
        with Probe() as probe:
            got = probe.subscribe(JointState, f'{node.namespace}/joint_states',
                                  qos_profile_sensor_data)
            probe.spin_until(lambda: len(got) >= 5 or not node.alive(), 20.0, 'joint_states')
            assert node.alive(), node.output()
            assert node.proc is not None
            return udp_sockets(node.proc.pid), node.output()
    finally:
        node.__exit__(None, None, None)


def test_rtps_sockets_are_loopback_by_default() -> None:
    """No profile variable set: pendulum_node picks the shipped profile itself (LOCALHOST).

    Every UDP socket is bound to 127.0.0.1, among them those on the domain's RTPS ports (where
    DDS listens); without the profile these are bound to 0.0.0.0.
    """
    sockets, log = start_and_read({var: None for var in PROFILE_VARIABLES})
    domain = int(os.environ['ROS_DOMAIN_ID'])
    listening = [s for s in sockets if s[1] in rtps_ports(domain)]
    assert len(listening) >= 2, (sockets, log)
    # Every socket, the send-only ones too.
    assert [s for s in sockets if not is_loopback(s[0])] == [], sockets


def test_a_profile_the_user_chose_is_kept(tmp_path: Path) -> None:
    """A profile of the user's (here: Fast DDS defaults) wins: RTPS ports on 0.0.0.0 again.

    The control of the test above: the same reading sees non-loopback sockets when they exist.
    """
    own = tmp_path / 'defaults.xml'
    own.write_text('<?xml version="1.0"?>\n<dds xmlns="http://www.eprosima.com/XMLSchemas/'
                   'fastRTPS_Profiles"><profiles/></dds>\n')
    sockets, log = start_and_read({var: str(own) for var in PROFILE_VARIABLES})
    domain = int(os.environ['ROS_DOMAIN_ID'])
    listening = [s for s in sockets if s[1] in rtps_ports(domain)]
    assert listening and not all(is_loopback(addr) for addr, _ in listening), (sockets, log)


def test_the_profile_alone_binds_every_socket_to_loopback() -> None:
    """With the profile doing discovery itself, every UDP socket of the node is 127.0.0.1.

    ROS_AUTOMATIC_DISCOVERY_RANGE=SYSTEM_DEFAULT leaves the transports to the profile (which
    announces to 127.0.0.1 only, like LOCALHOST); the probe, in LOCALHOST, still hears it.
    """
    sockets, log = start_and_read({'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SYSTEM_DEFAULT',
                                   **{var: str(PROFILE) for var in PROFILE_VARIABLES}})
    assert sockets, log
    assert [s for s in sockets if not is_loopback(s[0])] == [], sockets


def test_every_socket_is_loopback_in_localhost_range() -> None:
    """LOCALHOST and the shipped profile chosen explicitly: every UDP socket on 127.0.0.1.

    The profile does LOCALHOST's discovery itself, so the node runs it under SYSTEM_DEFAULT,
    where rmw_fastrtps adds no UDPv4 transport of its own (whose send-only sockets would bind
    0.0.0.0 and the host address).
    """
    sockets, log = start_and_read({var: str(PROFILE) for var in PROFILE_VARIABLES})
    assert sockets, log
    assert [s for s in sockets if not is_loopback(s[0])] == [], sockets


def without_profile_variables() -> dict[str, str]:
    """Return this environment without the Fast DDS profile variables (LOCALHOST kept)."""
    return {k: v for k, v in os.environ.items() if k not in PROFILE_VARIABLES}


def test_the_controller_binds_every_socket_to_loopback() -> None:
    """pendulum_pd_controller, no profile variable set: every UDP socket on 127.0.0.1."""
    from controller_probe import RELIABLE, Controller

    ctl = Controller()
    saved = os.environ.copy()
    os.environ.clear()
    os.environ.update(without_profile_variables())
    try:
        ctl.start()
    finally:
        os.environ.clear()
        os.environ.update(saved)
    with ctl, Probe() as probe:
        pub = probe.node.create_publisher(JointState, f'{ctl.namespace}/joint_states', RELIABLE)
        probe.spin_until(lambda: pub.get_subscription_count() >= 1 or not ctl.alive(), 30.0,
                         "the controller's joint_states subscription")
        assert ctl.alive(), ctl.output()
        assert ctl.proc is not None
        sockets = udp_sockets(ctl.proc.pid)
    assert sockets, ctl.output()
    assert [s for s in sockets if not is_loopback(s[0])] == [], sockets


def test_replay_binds_every_socket_to_loopback(tmp_path: Path) -> None:
    """pendulum_replay, no profile variable set: every UDP socket on 127.0.0.1."""
    import subprocess

    from recording_support import record, scripted_messages

    path = tmp_path / 'run.mcap'
    record(path, scripted_messages(50, period_ns=2_000_000, t0_ns=0), chunk_size=4096)
    replay = Path(sys.executable).parent / 'pendulum_replay'
    proc = subprocess.Popen([str(replay), str(path), '--loop', '--topics', '/energy'],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            env=without_profile_variables())
    try:
        with Probe() as probe:
            got = probe.subscribe(Float64, '/energy')
            probe.spin_until(lambda: len(got) >= 3 or proc.poll() is not None, 30.0,
                             'replayed energy')
            assert proc.poll() is None
            sockets = udp_sockets(proc.pid)
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=10)
    assert sockets
    assert [s for s in sockets if not is_loopback(s[0])] == [], sockets


def test_the_environment_rule() -> None:
    """LOCALHOST: the shipped profile, run as SYSTEM_DEFAULT; another range or profile: kept."""
    from pendulum_sim.dds import use_loopback_profile

    env = {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}
    shipped = use_loopback_profile(env)
    assert shipped is not None and shipped.read_bytes() == PROFILE.read_bytes()
    assert env == {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SYSTEM_DEFAULT',
                   **{var: str(shipped) for var in PROFILE_VARIABLES}}
    chosen = {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST', PROFILE_VARIABLES[0]: str(PROFILE)}
    assert use_loopback_profile(chosen) is not None
    assert chosen['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'SYSTEM_DEFAULT'
    for kept in ({'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SUBNET'}, {},
                 {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST',
                  PROFILE_VARIABLES[0]: '/elsewhere/profile.xml'}):
        before = dict(kept)
        assert use_loopback_profile(kept) is None
        assert kept == before
