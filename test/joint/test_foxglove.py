"""The live view without ROS: its parameters, its queue, its server seen by a plain client,
the in-process closed loop served live, and the shipped layout."""
from __future__ import annotations

import json
import re
import socket
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from foxglove_client import SUBPROTOCOLS, FoxgloveClient, connect_when_up, free_port
from scipy.spatial.transform import Rotation

from pendulum_sim.controller.pd_law import PDGains, pd_torque
from pendulum_sim.joint.errors import LiveError
from pendulum_sim.joint.exchange import Gate, SyncExchange
from pendulum_sim.joint.foxglove import (
    SCHEMAS,
    TOPICS,
    DropOldest,
    LiveView,
    layout_path,
)
from pendulum_sim.joint.joint import CommandCounters
from pendulum_sim.joint.parameters import SPECS, check
from pendulum_sim.testing import TestingError, closed_loop
from pendulum_sim.testing.record import EFFORT_COMMAND, JOINT_STATES

DEFAULTS = {s.name: s.default for s in SPECS}


def view(port: int = 0, **kw: Any) -> LiveView:
    return LiveView('127.0.0.1', port, joint_name='j', interface='effort', urdf='<robot/>',
                    parameters={'gamma': 1.0}, **kw)


@pytest.mark.parametrize('port', [0, 1024, 8765, 65535])
def test_foxglove_port_is_0_or_an_unprivileged_port(port: int) -> None:
    assert check({**DEFAULTS, 'foxglove_port': port}) is None


@pytest.mark.parametrize('port', [1, 80, 1023])
def test_a_privileged_foxglove_port_is_refused_with_the_rule(port: int) -> None:
    assert check({**DEFAULTS, 'foxglove_port': port}) == (
        f'foxglove_port must be 0 (off) or in 1024..65535, got {port}')


@pytest.mark.parametrize('host', ['', ' 127.0.0.1'])
def test_a_blank_foxglove_host_is_refused(host: str) -> None:
    assert check({**DEFAULTS, 'foxglove_host': host}) == (
        f"foxglove_host must be an address to listen on, got '{host}'")


def test_a_full_queue_drops_the_oldest_and_counts_it() -> None:
    queue = DropOldest(4)
    for i in range(10):
        queue.put(i)
    assert (queue.take(), queue.dropped) == ([6, 7, 8, 9], 6)
    assert queue.take() == []


def test_a_port_in_use_is_a_live_error_naming_it() -> None:
    with socket.socket() as taken:
        taken.bind(('127.0.0.1', 0))
        taken.listen()
        port = taken.getsockname()[1]
        msg = (f'foxglove_port {port}: cannot listen on 127.0.0.1:{port} (Failed to bind port: '
               'Address already in use (os error 98))')
        with pytest.raises(LiveError, match=re.escape(msg)):
            view(port)


def wait(predicate: Any, what: str, timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f'timed out waiting for {what}')
        time.sleep(0.005)


def test_the_server_takes_the_protocol_under_foxglove_sdk_v1_only() -> None:
    """What the guide says of foxglove-sdk 0.30.3: a handshake offering only the spec's
    foxglove.websocket.v1 gets HTTP 400; offering foxglove.sdk.v1 too, the server picks it."""
    from websockets.exceptions import InvalidStatus
    from websockets.sync.client import connect

    assert SUBPROTOCOLS == ('foxglove.websocket.v1', 'foxglove.sdk.v1')
    with view() as live:
        url = f'ws://127.0.0.1:{live.port}'
        with pytest.raises(InvalidStatus, match=re.escape('HTTP 400')):
            connect(url, subprotocols=['foxglove.websocket.v1'],  # type: ignore[list-item]
                    proxy=None, open_timeout=10.0)
        with connect(url, subprotocols=[*SUBPROTOCOLS],  # type: ignore[list-item]
                     proxy=None, open_timeout=10.0) as ws:
            assert ws.subprotocol == 'foxglove.sdk.v1'
            assert json.loads(ws.recv(timeout=10.0))['op'] == 'serverInfo'


def test_the_view_is_watched_only_while_a_client_subscribes() -> None:
    with view() as live:
        with FoxgloveClient(live.port) as client:
            client.wait_channels(*TOPICS.values())
            assert not live.watching            # connected, subscribed to nothing
            advertised = {c['topic']: c['schemaName'] for c in client.channels.values()}
            assert advertised == {TOPICS[k]: name for k, (name, _) in SCHEMAS.items()}
            assert advertised['/tf'] == 'foxglove.FrameTransforms'
            assert advertised['/log'] == 'foxglove.Log'
            client.subscribe('/robot_description', '/log')
            wait(lambda: live.watching, 'the subscription')
            (_, _, msg), = client.messages(1, '/robot_description')
            assert msg == {'data': '<robot/>'}
            live.log(5_000_000_007, 'warning', 'a line')
            (_, log_time, line), = client.messages(1, '/log')
            assert (log_time, line) == (5_000_000_007, {
                'timestamp': {'sec': 5, 'nsec': 7}, 'level': 3, 'message': 'a line',
                'name': 'pendulum_node', 'file': '', 'line': 0})
        wait(lambda: not live.watching, 'the disconnect')
        assert live.stats()['foxglove_subscriptions'] == 0


def test_a_closed_loop_served_live_sends_the_states_of_the_run() -> None:
    port = free_port()
    gains = PDGains(kp=4.0, kd=1.0, target=0.5)
    watched = threading.Event()

    def law(t: float, x: float, v: float) -> float:
        watched.wait(30.0)   # the first answer waits for the client: nothing goes unseen
        return pd_torque(gains, x, v)

    runs: list[Any] = []
    worker = threading.Thread(target=lambda: runs.append(closed_loop(
        law, periods=60, target=0.5, overrides={'friction': 0.25}, foxglove_port=port)))
    worker.start()
    try:
        with connect_when_up(port, 30.0) as client:
            client.subscribe('/joint_states', '/tf', '/target', '/energy_terms',
                             '/counters', '/physics', '/robot_description')
            # The URDF is sent when a subscription arrives: the server has them all now.
            client.messages(1, '/robot_description')
            watched.set()
            got = client.messages(59, '/joint_states')
    finally:
        watched.set()
        worker.join(60.0)
    run = runs[0]
    by_topic: dict[str, list[Any]] = {}
    for topic, log_time, msg in got:
        by_topic.setdefault(topic, []).append((log_time, msg))
    # The states from the first the client watched (the first state, at t = 0, goes out as the
    # server starts: the client may subscribe before or after it) are the run's, exactly.
    first = [round(t * 1e9) for t in run.t].index(by_topic['/joint_states'][0][0])
    assert first <= 1
    states = by_topic['/joint_states'][:59]
    assert [t for t, _ in states] == [round(t * 1e9) for t in run.t[first:first + 59]]
    assert [m['position'][0] for _, m in states] == list(run.position[first:first + 59])
    assert [m['velocity'][0] for _, m in states] == list(run.velocity[first:first + 59])
    assert [m['effort'][0] for _, m in states] == list(run.effort[first:first + 59])
    assert {m['data'] for _, m in by_topic['/target']} == {0.5}
    # The live physics: the scene's n and γ and the friction the run was given.
    assert {(m['n'], m['gamma'], m['friction']) for _, m in by_topic['/physics']} == {
        (run.parameters['n'], run.parameters['gamma'], 0.25)}
    # The counters of the node's synchronous mode: the joint's and the exchange's, each state
    # answered once (the in-process controller answers every state).
    counters = [m for _, m in by_topic['/counters']]
    assert set(counters[-1]) == (set(vars(CommandCounters())) | set(SyncExchange(
        Gate(), 1, 'hold').stats) | {'foxglove_dropped'})
    # State k of the run goes out after the answers to the k before it.
    answered = [c['answered'] for c in counters]   # the last state's may not be read yet
    assert answered == list(range(first, first + len(answered))) and len(answered) >= 58
    assert {c['timeouts'] for c in counters} == {0}
    # The 3D view: the bob's frame turned by the angle about the joint's y axis (the URDF's).
    for (_, state), (_, tf) in zip(states, by_topic['/tf'], strict=False):
        (frame,) = tf['transforms']
        assert (frame['parent_frame_id'], frame['child_frame_id']) == (
            'base_link', 'pendulum_link')
        q = frame['rotation']
        expected = Rotation.from_rotvec([0.0, state['position'][0], 0.0]).as_quat()
        np.testing.assert_allclose([q['x'], q['y'], q['z'], q['w']], expected, atol=1e-15)
    for _, terms in by_topic['/energy_terms']:
        assert terms['energy'] == pytest.approx(terms['kinetic'] + terms['potential'],
                                                rel=1e-15, abs=1e-15)


def test_closed_loop_refuses_a_privileged_foxglove_port() -> None:
    msg = 'foxglove_port must be 0 (off) or in 1024..65535, got 80'
    with pytest.raises(TestingError, match=re.escape(msg)):
        closed_loop(lambda t, x, v: 0.0, periods=1, foxglove_port=80)


def topics_in(node: Any) -> set[str]:
    """Return the topics of every message path and topic field in a layout's panels."""
    found: set[str] = set()
    if isinstance(node, dict):
        for key, value in node.items():
            if key in ('value', 'topicPath', 'topic', 'topicToRender') and isinstance(value,
                                                                                     str):
                found.add(re.match(r'/[^.]*', value).group(0))  # type: ignore[union-attr]
            elif key == 'topics' and isinstance(value, dict):   # the 3D panel's topics
                found |= set(value)
            else:
                found |= topics_in(value)
    elif isinstance(node, list):
        for item in node:
            found |= topics_in(item)
    return found


def test_the_shipped_layout_shows_topics_of_the_live_view_or_the_recordings() -> None:
    doc = json.loads(layout_path().read_text())
    panels = doc['configById']
    recorded = {JOINT_STATES, EFFORT_COMMAND, '/energy', '/parameter_events', '/diagnostics'}
    used = topics_in(panels)
    assert used <= set(TOPICS.values()) | recorded, used - set(TOPICS.values()) - recorded
    # Each panel the layout places exists, and each one configured is placed.
    placed = set(re.findall(r'"([A-Za-z0-9]+![a-z0-9]+)"', json.dumps(doc['layout'])))
    assert placed == set(panels)
    assert {'/joint_states', '/energy', '/robot_description', '/tf'} <= used
    kinds = {name.split('!')[0] for name in panels}
    assert {'Plot', '3D', 'RawMessages'} <= kinds


CAMPAIGN = """controller: pendulum_sim.testing.examples:pd
episodes: 2
periods: 5
target: 0.5
"""


@pytest.mark.parametrize(('args', 'msg'), [
    (['--foxglove-port', '80'],
     '--foxglove-port: foxglove_port must be 0 (off) or in 1024..65535, got 80'),
    (['--foxglove-port', '8765', '--workers', '2'],
     '--foxglove-port serves one episode at a time: it needs the local cluster with '
     '--workers 1'),
    (['--foxglove-port', '8765', '--scheduler', 'tcp://127.0.0.1:8786'],
     '--foxglove-port serves one episode at a time: it needs the local cluster with '
     '--workers 1'),
])
def test_pendulum_campaign_refuses_a_live_view_it_cannot_serve(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], msg: str) -> None:
    from pendulum_sim.testing.campaign.cli import main

    path = tmp_path / 'campaign.yaml'
    path.write_text(CAMPAIGN)
    assert main([str(path), '--out', str(tmp_path / 'out'), '--no-progress', *args]) == 2
    assert capsys.readouterr().err == f'pendulum_campaign: error: {msg}\n'
    assert not (tmp_path / 'out').exists()


def test_pendulum_campaign_refuses_a_port_in_use_before_any_episode(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from pendulum_sim.testing.campaign.cli import main

    path = tmp_path / 'campaign.yaml'
    path.write_text(CAMPAIGN)
    with socket.socket() as taken:
        taken.bind(('127.0.0.1', 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert main([str(path), '--out', str(tmp_path / 'out'), '--no-progress',
                     '--foxglove-port', str(port)]) == 2
    assert capsys.readouterr().err == (
        f'pendulum_campaign: error: --foxglove-port: cannot listen on 127.0.0.1:{port} '
        '(Address already in use)\n')
    assert not (tmp_path / 'out').exists()


def test_a_campaign_episode_is_served_live_while_it_runs() -> None:
    import live_laws

    from pendulum_sim.testing.campaign.episode import run_episode

    port = free_port()
    rows: list[dict[str, Any]] = []
    text = CAMPAIGN.replace('pendulum_sim.testing.examples:pd', 'live_laws:gated_pd').replace(
        'periods: 5', 'periods: 50')
    live_laws.GATE.clear()
    worker = threading.Thread(target=lambda: rows.append(run_episode(text, 0, None, port)))
    worker.start()
    try:
        with connect_when_up(port, 30.0) as client:
            client.subscribe('/joint_states', '/robot_description', '/target')
            client.messages(1, '/robot_description')   # the server has the subscriptions
            live_laws.GATE.set()
            got = client.messages(49, '/joint_states')
    finally:
        live_laws.GATE.set()
        worker.join(60.0)
    (row,) = rows
    assert row['episode'] == 0 and row['reason'] == '', row
    assert {m['data'] for topic, _, m in got if topic == '/target'} == {0.5}


def test_pendulum_campaign_serves_the_episode_its_episode_process_runs(tmp_path: Path) -> None:
    """Through the command line: a local cluster of one worker runs each episode in its episode
    process, which serves it live on --foxglove-port while it runs."""
    import os
    import subprocess
    import sys

    here = Path(__file__).resolve().parents[1] / 'support'
    gate = tmp_path / 'gate'
    env = {**os.environ, 'PENDULUM_LIVE_GATE': str(gate), 'PYTHONPATH': os.pathsep.join(
        [str(here), *filter(None, [os.environ.get('PYTHONPATH')])])}
    path = tmp_path / 'campaign.yaml'
    path.write_text(CAMPAIGN.replace('pendulum_sim.testing.examples:pd', 'live_laws:file_gated_pd')
                    .replace('periods: 5', 'periods: 50'))
    port = free_port()
    proc = subprocess.Popen(
        [str(Path(sys.executable).parent / 'pendulum_campaign'), str(path), '--out',
         str(tmp_path / 'out'), '--no-progress', '--foxglove-port', str(port)],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        with connect_when_up(port) as client:   # episode 0's server, in its episode process
            client.subscribe('/joint_states', '/robot_description', '/target')
            client.messages(1, '/robot_description')   # the server has the subscriptions
            gate.touch()
            got = client.messages(49, '/joint_states')
        _, err = proc.communicate(timeout=120.0)
    finally:
        gate.touch()
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, err
    assert '2 episodes, 2 passed' in err
    states = [m for topic, _, m in got if topic == '/joint_states']
    stamps = [s['header']['stamp']['sec'] * 10**9 + s['header']['stamp']['nanosec']
              for s in states]
    assert stamps == sorted(stamps) and len(set(stamps)) == len(stamps) >= 49
    assert {m['data'] for topic, _, m in got if topic == '/target'} == {0.5}
