"""A plain client of the ``foxglove.websocket.v1`` protocol, written from its specification
(github.com/foxglove/ws-protocol, docs/spec.md) on the ``websockets`` package: it is not
foxglove-sdk, so a test of the server through it checks the protocol as a viewer speaks it.

foxglove-sdk's server (0.30.3) accepts the protocol only under its current subprotocol name,
``foxglove.sdk.v1``: a handshake offering ``foxglove.websocket.v1`` alone gets HTTP 400
(test_foxglove checks it). The messages this client uses (serverInfo, advertise, subscribe,
binary message data) are those of ``foxglove.websocket.v1``; the client offers both names.
"""
from __future__ import annotations

import json
import socket
import struct
import time
from typing import Any

from websockets.sync.client import ClientConnection, connect

SUBPROTOCOLS = ('foxglove.websocket.v1', 'foxglove.sdk.v1')
MESSAGE_DATA = 0x01


def free_port() -> int:
    """Return a TCP port free on 127.0.0.1 now (the kernel's pick, >= 1024)."""
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return int(s.getsockname()[1])


def connect_when_up(port: int, timeout: float = 60.0) -> FoxgloveClient:
    """Return a client of the server on ``port`` once it listens (within ``timeout`` s)."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            return FoxgloveClient(port)
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.01)


class FoxgloveClient:
    """Connect, read the advertised channels, subscribe by topic, read messages."""

    def __init__(self, port: int, host: str = '127.0.0.1', timeout: float = 10.0) -> None:
        self.ws: ClientConnection = connect(
            f'ws://{host}:{port}', subprotocols=[*SUBPROTOCOLS],  # type: ignore[list-item]
            open_timeout=timeout, max_size=None, proxy=None,
            max_queue=None,   # read on while nobody reads: a close is answered at once
            legacy=True)      # the connection itself (this class closes it)
        self.timeout = timeout
        self.server_info: dict[str, Any] = {}
        self.channels: dict[str, dict[str, Any]] = {}     # topic -> advertised channel
        self._by_sub: dict[int, str] = {}
        self._next_sub = 1

    def __enter__(self) -> FoxgloveClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Close the connection."""
        self.ws.close()

    def _take(self, frame: str | bytes) -> tuple[str, int, Any] | None:
        """Handle one frame; return (topic, log time, decoded JSON) of a message."""
        if isinstance(frame, str):
            op = json.loads(frame)
            if op.get('op') == 'serverInfo':
                self.server_info = op
            elif op.get('op') == 'advertise':
                for ch in op['channels']:
                    self.channels[ch['topic']] = ch
            elif op.get('op') == 'unadvertise':
                self.channels = {t: c for t, c in self.channels.items()
                                 if c['id'] not in op['channelIds']}
            return None
        if frame[0] != MESSAGE_DATA:
            return None
        sub, log_time = struct.unpack_from('<IQ', frame, 1)
        return self._by_sub[sub], log_time, json.loads(frame[13:])

    def wait_channels(self, *topics: str) -> None:
        """Read frames until every topic is advertised."""
        deadline = time.monotonic() + self.timeout
        while not all(t in self.channels for t in topics):
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError(f'not advertised within {self.timeout} s: '
                                   f'{sorted(set(topics) - set(self.channels))}; got '
                                   f'{sorted(self.channels)}')
            self._take(self.ws.recv(timeout=left))

    def subscribe(self, *topics: str) -> None:
        """Subscribe to these advertised topics."""
        self.wait_channels(*topics)
        subs = []
        for topic in topics:
            sub = self._next_sub
            self._next_sub += 1
            self._by_sub[sub] = topic
            subs.append({'id': sub, 'channelId': self.channels[topic]['id']})
        self.ws.send(json.dumps({'op': 'subscribe', 'subscriptions': subs}))

    def messages(self, count: int, topic: str | None = None) -> list[tuple[str, int, Any]]:
        """Read until ``count`` messages (of ``topic``, if given) came; return them all."""
        out: list[tuple[str, int, Any]] = []
        deadline = time.monotonic() + self.timeout
        while sum(1 for m in out if topic is None or m[0] == topic) < count:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError(f'{len(out)} messages within {self.timeout} s, wanted '
                                   f'{count} of {topic or "any topic"}')
            got = self._take(self.ws.recv(timeout=left))
            if got is not None:
                out.append(got)
        return out
