"""DDS on 127.0.0.1: the node's UDP sockets, read from outside through /proc (issue 11 item 15).

The node runs in its own process; its sockets are the UDP entries of /proc/<pid>/net/udp{,6}
whose inodes are among /proc/<pid>/fd. Each test also checks that a probe in another process
still receives joint_states (pub/sub across processes works on the loopback).
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest
from node_harness import NodeProcess, Probe
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import JointState

from pendulum_sim.dds import PROFILE_VARIABLES

pytestmark = [pytest.mark.ros,
              pytest.mark.skipif(not sys.platform.startswith('linux'), reason='reads /proc')]

PROFILE = Path(__file__).resolve().parents[1] / 'config' / 'fastdds_localhost.xml'


def udp_sockets(pid: int) -> list[tuple[str, int]]:
    """Return (local address, port) of every UDP socket process ``pid`` holds."""
    inodes = set()
    for fd in os.listdir(f'/proc/{pid}/fd'):
        try:
            target = os.readlink(f'/proc/{pid}/fd/{fd}')
        except OSError:  # closed meanwhile
            continue
        if target.startswith('socket:['):
            inodes.add(target[8:-1])
    found = []
    for table in ('udp', 'udp6'):
        with open(f'/proc/{pid}/net/{table}') as fh:
            next(fh)
            for line in fh:
                fields = line.split()
                if fields[9] not in inodes:
                    continue
                hex_addr, hex_port = fields[1].split(':')
                raw = bytes.fromhex(hex_addr)
                # The kernel prints addresses as 32-bit words in host (little-endian) order.
                addr = b''.join(raw[i:i + 4][::-1] for i in range(0, len(raw), 4))
                if table == 'udp':
                    text = '.'.join(str(b) for b in addr)
                elif addr[:12] == b'\0' * 10 + b'\xff\xff':
                    text = '::ffff:' + '.'.join(str(b) for b in addr[12:])
                else:
                    text = addr.hex(':', 2)
                found.append((text, int(hex_port, 16)))
    return found


def is_loopback(addr: str) -> bool:
    """Return True for 127.0.0.1 (or its IPv6 forms)."""
    return addr in ('127.0.0.1', '::ffff:127.0.0.1', '0000:0000:0000:0000:0000:0000:0000:0001')


def rtps_ports(domain: int) -> range:
    """Return the ports RTPS gives a domain (PB = 7400, DG = 250: spec 9.6.1.1)."""
    return range(7400 + 250 * domain, 7400 + 250 * (domain + 1))


def start_and_read(env: dict[str, str | None]) -> tuple[list[tuple[str, int]], str]:
    """Start the node with ``env`` changes; once a probe hears it, return its sockets and log."""
    saved = {k: os.environ.get(k) for k in env}
    for key, value in env.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value
    node = NodeProcess('minimal')
    try:
        node.start()
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
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

    Every socket on the domain's RTPS ports (where DDS listens) is bound to 127.0.0.1; without
    the profile these are bound to 0.0.0.0.
    """
    sockets, log = start_and_read({var: None for var in PROFILE_VARIABLES})
    domain = int(os.environ['ROS_DOMAIN_ID'])
    listening = [s for s in sockets if s[1] in rtps_ports(domain)]
    assert len(listening) >= 2, (sockets, log)
    assert all(is_loopback(addr) for addr, _ in listening), sockets


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


@pytest.mark.xfail(strict=True, reason='rmw_fastrtps 8.4 (Jazzy) adds its own UDPv4 transport '
                   'without an interface list when ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST; its '
                   'send-only sockets bind 0.0.0.0 and the host address (rmw_fastrtps_shared_cpp '
                   'participant.cpp)')
def test_every_socket_is_loopback_in_localhost_range() -> None:
    """LOCALHOST and the profile: every UDP socket of the node on 127.0.0.1 (not yet)."""
    sockets, _ = start_and_read({var: str(PROFILE) for var in PROFILE_VARIABLES})
    assert [s for s in sockets if not is_loopback(s[0])] == [], sockets
