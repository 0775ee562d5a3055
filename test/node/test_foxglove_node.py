"""pendulum_node's live view, seen by a real Foxglove WebSocket client in this process.

The node runs in its own process over real DDS; the client (``foxglove_client``, on the
``websockets`` package) speaks the protocol from its specification. What it receives is compared
with what a DDS probe receives; the listening socket is read from /proc.
"""
from __future__ import annotations

import socket
import sys
import time

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from foxglove_client import FoxgloveClient, free_port
from node_harness import NodeProcess, Probe, stamp_ns
from procfs import TCP_LISTEN, rss_kib, sockets
from sensor_msgs.msg import JointState

from pendulum_sim.node.diagnostics import values_of

pytestmark = [pytest.mark.ros,
              pytest.mark.skipif(not sys.platform.startswith('linux'), reason='reads /proc')]

MOVING = {'phi0': 1.0, 'sensor.position_noise': 0.01, 'sensor.velocity_noise': 0.01,
          'status_line': False}
WARM_UP = 50


def listening(pid: int) -> list[tuple[str, int]]:
    """Return (address, port) of every TCP socket process ``pid`` listens on (IPv4 and 6)."""
    return [(addr, port) for addr, port, state in sockets(pid, 'tcp') if state == TCP_LISTEN]


def wait_listening(node: NodeProcess, port: int, timeout: float = 30.0) -> list[tuple[str, int]]:
    """Wait until the node listens on ``port``; return its listening sockets."""
    assert node.proc is not None
    deadline = time.monotonic() + timeout
    while True:
        assert node.alive(), node.output()
        found = listening(node.proc.pid)
        if any(p == port for _, p in found):
            return found
        if time.monotonic() > deadline:
            raise AssertionError(f'not listening on {port} after {timeout} s: {found}\n'
                                 f'{node.output()}')
        time.sleep(0.05)


def test_the_joint_states_a_client_receives_are_those_on_dds_with_the_same_stamps() -> None:
    port = free_port()
    with NodeProcess('default', {**MOVING, 'foxglove_port': port}) as node, Probe() as probe:
        dds: dict[int, tuple[float, float, float]] = {}

        def on_state(msg: JointState) -> None:
            dds[stamp_ns(msg)] = (msg.position[0], msg.velocity[0], msg.effort[0])

        probe.subscribe(JointState, f'{node.namespace}/joint_states', 100, on_state)
        probe.spin_until(lambda: len(dds) >= 5, 30.0, 'joint_states on DDS')
        wait_listening(node, port)
        topic = '/joint_states'   # whatever the node's namespace: one joint per server
        with FoxgloveClient(port) as client:
            client.subscribe(topic)
            got = client.messages(50, topic)
            assert client.ws.subprotocol == 'foxglove.sdk.v1'
            schema = client.channels[topic]
            assert (schema['encoding'], schema['schemaName'], schema['schemaEncoding']) == (
                'json', 'sensor_msgs/msg/JointState', 'jsonschema')
        live = {}
        for _topic, log_time, msg in got:
            stamp = msg['header']['stamp']
            ns = stamp['sec'] * 1_000_000_000 + stamp['nanosec']
            assert log_time == ns
            assert msg['name'] == ['pendulum_joint']
            live[ns] = (msg['position'][0], msg['velocity'][0], msg['effort'][0])
        probe.spin_until(lambda: max(dds) >= max(live), 30.0, 'DDS to catch up')
    # joint_states is best effort: a sample may be lost on DDS, never changed.
    common = sorted(set(live) & set(dds))
    assert len(common) >= 0.9 * len(live), (len(common), len(live))
    assert [live[s] for s in common] == [dds[s] for s in common]
    assert len({v[0] for v in live.values()}) == len(live)   # noisy: every sample its own


def test_a_hundred_reconnects_leave_the_node_ticking_with_bounded_memory() -> None:
    port = free_port()
    with NodeProcess('default', {**MOVING, 'foxglove_port': port}) as node, Probe() as probe:
        diags = probe.subscribe(DiagnosticArray, '/diagnostics')
        wait_listening(node, port)
        assert node.proc is not None
        pid = node.proc.pid
        topic = '/joint_states'
        rss = []
        # The first connections warm the server's allocations up (about 4 MiB), then 100
        # more are measured.
        for i in range(WARM_UP + 100):
            if i in (WARM_UP, WARM_UP + 99):
                rss.append(rss_kib(pid))
            with FoxgloveClient(port) as client:
                client.subscribe(topic, '/robot_description', '/tf')
                client.messages(1, topic)
        last: dict[str, str] = {}

        def settled() -> bool:
            for msg in diags.msgs:
                if msg.status and msg.status[0].name.startswith(node.fqn):
                    last.update(values_of(msg))
            diags.clear()
            return last.get('foxglove_subscriptions') == '0' and int(last['foxglove_sent']) > 0
        probe.spin_until(settled, 30.0, 'diagnostics with no subscription left')
        steps = int(last['steps'])
        probe.spin_until(lambda: settled() and int(last['steps']) > steps, 30.0,
                         'the node to keep stepping')
        assert node.alive(), node.output()
    # Measured: about 1.5 KiB per connection after the warm-up (allocator noise); a leak of
    # 20 KiB per connection would show 2 MiB.
    assert rss[1] - rss[0] < 2048, rss


def test_a_port_in_use_is_one_line_and_exit_2() -> None:
    with socket.socket() as taken:
        taken.bind(('127.0.0.1', 0))
        taken.listen()
        port = taken.getsockname()[1]
        with NodeProcess('default', {'foxglove_port': port}) as node:
            assert node.wait(30.0) == 2
            out = node.output()
    assert out.strip().splitlines() == [
        f'pendulum_node: foxglove_port {port}: cannot listen on 127.0.0.1:{port} (Failed to '
        'bind port: Address already in use (os error 98))'], out


@pytest.mark.parametrize(('host', 'bound'), [(None, '127.0.0.1'), ('127.0.0.2', '127.0.0.2')])
def test_the_server_listens_on_loopback_unless_foxglove_host_says_otherwise(
        host: str | None, bound: str) -> None:
    port = free_port()
    params = {'foxglove_port': port, 'status_line': False}
    if host is not None:
        params['foxglove_host'] = host
    with NodeProcess('default', params) as node:
        found = wait_listening(node, port)
        with FoxgloveClient(port, host=bound) as client:
            client.subscribe('/log')   # the lines logged before any client, sent again
            lines = [m['message'] for _, _, m in client.messages(3, '/log')]
    assert lines[2] == f'foxglove: serving the joint on ws://{bound}:{port}', lines
    assert lines[0].startswith('real time: h = 0.001 s, rk4'), lines
    assert lines[1].startswith('expected real-time factor '), lines   # the law's cost
    # The server's is the node's only listening socket, on that address alone.
    assert found == [(bound, port)]


def test_no_server_listens_when_foxglove_port_is_0() -> None:
    with NodeProcess('default', {'status_line': False}) as node, Probe() as probe:
        states = probe.subscribe(JointState, f'{node.namespace}/joint_states')
        probe.spin_until(lambda: len(states) >= 3, 30.0, 'joint_states')
        assert node.proc is not None
        assert listening(node.proc.pid) == []
