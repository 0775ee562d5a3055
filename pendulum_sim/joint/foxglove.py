"""Serve the joint live to Foxglove: a ``foxglove.websocket.v1`` server, without ROS.

:class:`LiveView` starts a foxglove-sdk WebSocket server and advertises typed JSON channels (a
JSON schema each; the 3D view's on Foxglove's well-known schemas ``foxglove.FrameTransforms``
and ``foxglove.Log``). The tick hands it one :class:`Snapshot` per published state, and only
while a client is subscribed (:attr:`LiveView.watching`, one attribute read otherwise). The
snapshot goes into a bounded queue that drops and counts the oldest when full, as the recorder
does; a thread of its own turns snapshots into messages and logs them, off the tick's path, at
most :data:`MAX_SEND_RATE` states a wall second.

Topic names are those of a node without a namespace where the topic exists on DDS
(``/joint_states``, ``/energy``, ``/robot_description``), so the shipped layout (:data:`LAYOUT`)
opens the live view of any node and this package's MCAP recordings alike.
"""
from __future__ import annotations

import json
import math
import threading
import time
from collections import deque
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple, cast

from pendulum_sim.core import PendulumParams

from .errors import LiveError
from .joint import Sample, SimulatedJoint, energy_terms

if TYPE_CHECKING:
    from foxglove.websocket import ServerListener

QUEUE_SIZE = 256          # snapshots waiting for the sender thread; the oldest goes first
# The sender sends at most this many states per wall second (more than a real-time node's
# publish rate of 1 kHz); faster, e.g. free lockstep, the queue drops the oldest. Its thread
# holds the GIL while it builds messages: unbounded, it would slow the tick it serves.
MAX_SEND_RATE = 2000.0
HISTORY = 50              # log lines kept for a client that subscribes later
SEND_PERIOD = 1.0 / MAX_SEND_RATE
LAYOUT = 'foxglove_layout.json'
PORT_RANGE = (1024, 65535)
LEVELS = {'debug': 1, 'info': 2, 'warning': 3, 'error': 4, 'fatal': 5}

_NUMBER = {'type': 'number'}
_STAMP = {'type': 'object', 'properties': {'sec': {'type': 'integer'},
                                           'nanosec': {'type': 'integer'}}}
_FOXGLOVE_TIME = {'type': 'object', 'properties': {'sec': {'type': 'integer'},
                                                   'nsec': {'type': 'integer'}}}
_VECTOR = {'type': 'object', 'properties': {k: _NUMBER for k in 'xyz'}}
_QUATERNION = {'type': 'object', 'properties': {k: _NUMBER for k in 'xyzw'}}


def _object(**fields: Any) -> dict[str, Any]:
    return {'type': 'object', 'properties': fields}


def _array(item: dict[str, Any]) -> dict[str, Any]:
    return {'type': 'array', 'items': item}


# name: (schema name, JSON schema). The ROS names of the node's topics, as JSON.
SCHEMAS: dict[str, tuple[str, dict[str, Any]]] = {
    'joint_states': ('sensor_msgs/msg/JointState', _object(
        header=_object(stamp=_STAMP, frame_id={'type': 'string'}),
        name=_array({'type': 'string'}), position=_array(_NUMBER), velocity=_array(_NUMBER),
        effort=_array(_NUMBER))),
    'energy': ('std_msgs/msg/Float64', _object(data=_NUMBER)),
    'target': ('std_msgs/msg/Float64', _object(data=_NUMBER)),
    'energy_terms': ('pendulum_sim/EnergyTerms', _object(
        energy=_NUMBER, kinetic=_NUMBER, potential=_NUMBER, dissipated=_NUMBER,
        dissipated_power=_NUMBER, input=_NUMBER, residual=_NUMBER)),
    'command': ('pendulum_sim/Command', _object(
        interface={'type': 'string'}, commanded=_NUMBER, applied=_NUMBER)),
    'physics': ('pendulum_sim/Physics', _object(n=_NUMBER, gamma=_NUMBER, friction=_NUMBER)),
    'counters': ('pendulum_sim/Counters', {'type': 'object',
                                           'additionalProperties': {'type': 'integer'}}),
    'parameters': ('pendulum_sim/Parameters', {'type': 'object'}),
    'robot_description': ('std_msgs/msg/String', _object(data={'type': 'string'})),
    'tf': ('foxglove.FrameTransforms', _object(transforms=_array(_object(
        timestamp=_FOXGLOVE_TIME, parent_frame_id={'type': 'string'},
        child_frame_id={'type': 'string'}, translation=_VECTOR, rotation=_QUATERNION)))),
    'log': ('foxglove.Log', _object(
        timestamp=_FOXGLOVE_TIME, level={'type': 'integer'}, message={'type': 'string'},
        name={'type': 'string'}, file={'type': 'string'}, line={'type': 'integer'})),
}
# The topic of each channel (a server shows one joint: no namespace is needed).
TOPICS = {'joint_states': '/joint_states', 'energy': '/energy', 'target': '/target',
          'energy_terms': '/energy_terms', 'command': '/command', 'physics': '/physics',
          'counters': '/counters', 'parameters': '/parameters',
          'robot_description': '/robot_description', 'tf': '/tf', 'log': '/log'}
PIVOT_FRAME, BOB_FRAME = 'base_link', 'pendulum_link'   # the URDF's links (node/urdf.py)


class Snapshot(NamedTuple):
    """What one published state shows, taken on the tick (plain values, computed later).

    ``position``, ``velocity`` and ``effort`` are the published measurement; ``phi`` and
    ``dphi`` the true state the energy is of.
    """

    stamp_ns: int
    position: float
    velocity: float
    effort: float
    commanded: float
    phi: float
    dphi: float
    dissipated: float
    work_input: float
    residual: float
    params: PendulumParams
    counters: Mapping[str, int]


def snapshot(joint: SimulatedJoint, sample: Sample,
             counters: Mapping[str, int]) -> Snapshot:
    """Return what ``sample``, just published by ``joint``, shows (a copy of ``counters``)."""
    st = joint.stepper
    return Snapshot(sample.stamp_ns, sample.position, sample.velocity, sample.effort,
                    joint.target, st.phi, st.dphi, st.dissipated_work, st.input_work,
                    st.residual, st.params, dict(counters))


def check_port(port: int) -> str | None:
    """Return why ``port`` cannot be ``foxglove_port`` (0 = off), or None."""
    low, high = PORT_RANGE
    if port == 0 or low <= port <= high:
        return None
    return f'foxglove_port must be 0 (off) or in {low}..{high}, got {port}'


def layout_path() -> Path:
    """Return the path of the Foxglove layout shipped with the package."""
    return Path(str(resources.files('pendulum_sim').joinpath(LAYOUT)))


def _stamp(ns: int, nano: str = 'nanosec') -> dict[str, int]:
    sec, rest = divmod(ns, 1_000_000_000)
    return {'sec': sec, nano: rest}


def _finite(x: float) -> float | None:
    """JSON has no nan or infinity: a value that is not finite goes out as null."""
    return x if math.isfinite(x) else None


class DropOldest:
    """A bounded queue for one producer and one consumer: a put into a full queue drops the
    oldest item and counts it (the recorder's rule: the newest state matters most)."""

    def __init__(self, size: int) -> None:
        self._items: deque[Any] = deque(maxlen=size)
        self.dropped = 0

    def put(self, item: Any) -> None:
        """Append ``item``, dropping (and counting) the oldest if the queue is full."""
        items = self._items
        if len(items) == items.maxlen:
            self.dropped += 1
        items.append(item)

    def get(self) -> Any:
        """Remove and return the oldest item, or None if the queue is empty."""
        items = self._items
        return items.popleft() if items else None

    def take(self) -> list[Any]:
        """Remove and return every item, oldest first."""
        out = []
        items = self._items
        while items:
            out.append(items.popleft())
        return out


class _Listener:
    """The server's callbacks: count subscriptions, ask for latched messages again (the
    other callbacks of ``foxglove.websocket.ServerListener`` are optional)."""

    def __init__(self, view: LiveView) -> None:
        self._view = view

    def on_subscribe(self, client: Any, channel: Any) -> None:
        self._view._subscribed(channel.topic, +1)

    def on_unsubscribe(self, client: Any, channel: Any) -> None:
        self._view._subscribed(channel.topic, -1)


class LiveView:
    """A Foxglove WebSocket server showing one joint; a context manager.

    Parameters
    ----------
    host, port : str, int
        Where to listen (``port`` in 1024..65535, checked by the caller's parameters).
    joint_name : str
        The joint's name in ``joint_states``.
    interface : str
        The command interface (what ``commanded`` is: N m, rad/s or rad).
    urdf : str
        The URDF sent on ``robot_description`` to each client that subscribes.
    parameters : mapping
        The parameter set sent on ``parameters`` (:meth:`parameters` replaces it).
    topics : mapping, optional
        Topic names replacing those of :data:`TOPICS`.
    target : float, optional
        The reference of a closed-loop run (rad), sent on ``target`` with each state.
    queue_size : int
        Snapshots the queue holds before the oldest is dropped (counted in :attr:`dropped`).

    Raises
    ------
    LiveError
        When foxglove-sdk is not installed or the server cannot listen there.
    """

    def __init__(self, host: str, port: int, *, joint_name: str, interface: str, urdf: str,
                 parameters: Mapping[str, object], topics: Mapping[str, str] | None = None,
                 target: float | None = None, queue_size: int = QUEUE_SIZE) -> None:
        try:
            import foxglove
        except ImportError as exc:
            raise LiveError(f'foxglove_port {port} needs the foxglove-sdk package ({exc}); '
                            "install pendulum_sim with the 'foxglove' extra") from None
        self.watching = False       # a client is subscribed to some channel: snapshots wanted
        self.sent = 0               # snapshots turned into messages
        self._joint = joint_name
        self._target = target
        self._interface = interface
        self._urdf = urdf
        self._parameters = self._jsonable(parameters)
        self._topics = {**TOPICS, **(topics or {})}
        self._queue = DropOldest(queue_size)
        self._lock = threading.Lock()
        self._subscriptions: dict[str, int] = {}
        self._latched: set[str] = set()
        self._logs: deque[tuple[int, str, str]] = deque(maxlen=queue_size)
        self._history: deque[tuple[int, str, str]] = deque(maxlen=HISTORY)
        self._wake = threading.Event()
        self._stopping = False
        self._context = foxglove.Context()
        self._channels: dict[str, Any] = {}
        for name, (schema_name, schema) in SCHEMAS.items():
            self._channels[name] = foxglove.Channel(
                self._topics[name], message_encoding='json', context=self._context,
                schema=foxglove.Schema(name=schema_name, encoding='jsonschema',
                                       data=json.dumps(schema).encode()))
        try:
            self._server = foxglove.start_server(
                name='pendulum_sim', host=host, port=port, context=self._context,
                server_listener=cast('ServerListener', _Listener(self)))
        except RuntimeError as exc:
            reason = str(exc).removeprefix('FoxgloveError: ')
            raise LiveError(f'foxglove_port {port}: cannot listen on {host}:{port} '
                            f'({reason})') from None
        self.host, self.port = host, int(self._server.port)
        self.url = f'ws://{host}:{self.port}'
        self._thread = threading.Thread(target=self._run, name='foxglove', daemon=True)
        self._thread.start()

    @classmethod
    def of(cls, values: Mapping[str, object], urdf: str,
           target: float | None = None) -> LiveView:
        """Return the live view that the node parameters ``values`` ask for (``foxglove_host``,
        ``foxglove_port``, ``joint_name``, ``command_interface``), showing ``urdf``."""
        return cls(str(values['foxglove_host']), int(str(values['foxglove_port'])),
                   joint_name=str(values['joint_name']),
                   interface=str(values['command_interface']), urdf=urdf,
                   parameters=values, target=target)

    @property
    def dropped(self) -> int:
        """Return how many snapshots a full queue dropped (the oldest first)."""
        return self._queue.dropped

    # ------------------------------------------------------------------ the tick's side
    def offer(self, snapshot: Snapshot) -> None:
        """Queue a snapshot for the sender (the caller looked at :attr:`watching`); cheap."""
        self._queue.put(snapshot)
        if not self._wake.is_set():   # set: the sender clears it before it takes the queue
            self._wake.set()          # (Event.set takes a lock: not once per state)

    def log(self, stamp_ns: int, level: str, text: str) -> None:
        """Send a line of the node's log on ``log``; the last lines are kept and sent again to
        each client that subscribes (the start lines come before any client)."""
        line = (stamp_ns, level, text)
        self._history.append(line)
        if self.watching:
            self._logs.append(line)
            self._wake.set()

    def parameters(self, values: Mapping[str, object]) -> None:
        """Replace the parameter set sent on ``parameters`` and send it again."""
        self._parameters = self._jsonable(values)
        self._resend('parameters')

    def stats(self) -> dict[str, int]:
        """Return the live view's counters (the node's diagnostics)."""
        with self._lock:
            subscriptions = sum(self._subscriptions.values())
        return {'foxglove_subscriptions': subscriptions, 'foxglove_sent': self.sent,
                'foxglove_dropped': self.dropped}

    # ------------------------------------------------------------------ the server's side
    def _subscribed(self, topic: str, change: int) -> None:
        with self._lock:
            count = self._subscriptions[topic] = self._subscriptions.get(topic, 0) + change
            if count <= 0:
                del self._subscriptions[topic]
            self.watching = bool(self._subscriptions)
        if change > 0:
            if topic == self._topics['log']:
                self._logs.extend(self._history)
                self._wake.set()
            for name in ('robot_description', 'parameters'):
                if topic == self._topics[name]:
                    self._resend(name)

    def _resend(self, name: str) -> None:
        with self._lock:
            self._latched.add(name)
        self._wake.set()

    @staticmethod
    def _jsonable(values: Mapping[str, object]) -> dict[str, object]:
        return {k: _finite(v) if isinstance(v, float) else v for k, v in values.items()}

    def _run(self) -> None:
        """The sender thread: turn queued snapshots and log lines into messages."""
        last = 0.0
        while True:
            self._wake.wait()
            self._wake.clear()
            stopping = self._stopping   # what was queued before close() still goes out
            with self._lock:
                latched, self._latched = self._latched, set()
            for name in sorted(latched):
                data = self._urdf if name == 'robot_description' else None
                self._channels[name].log({'data': data} if data is not None
                                         else self._parameters)
            while self._logs:
                self._send_log(*self._logs.popleft())
            while (snap := self._queue.get()) is not None:
                due = last + SEND_PERIOD
                now = time.monotonic()
                if due > now:   # at most MAX_SEND_RATE states a second: the GIL is shared
                    time.sleep(due - now)
                last = max(due, now)
                try:
                    self._send(snap)
                except Exception as exc:  # a broken message must not end the sender
                    self._send_log(0, 'error', f'foxglove: a state was not sent ({exc})')
                self.sent += 1
            if stopping:
                return

    def _send_log(self, stamp_ns: int, level: str, text: str) -> None:
        self._channels['log'].log({
            'timestamp': _stamp(stamp_ns, 'nsec'), 'level': LEVELS.get(level, 2),
            'message': text, 'name': 'pendulum_node', 'file': '', 'line': 0},
            log_time=stamp_ns)

    def _send(self, s: Snapshot) -> None:
        ch, t = self._channels, s.stamp_ns
        ch['joint_states'].log({
            'header': {'stamp': _stamp(t), 'frame_id': ''}, 'name': [self._joint],
            'position': [s.position], 'velocity': [s.velocity], 'effort': [s.effort]},
            log_time=t)
        half = s.position / 2.0   # about the joint's y axis (node/urdf.py)
        ch['tf'].log({'transforms': [{
            'timestamp': _stamp(t, 'nsec'), 'parent_frame_id': PIVOT_FRAME,
            'child_frame_id': BOB_FRAME, 'translation': {'x': 0.0, 'y': 0.0, 'z': 0.0},
            'rotation': {'x': 0.0, 'y': math.sin(half), 'z': 0.0, 'w': math.cos(half)}}]},
            log_time=t)
        ch['command'].log({'interface': self._interface, 'commanded': _finite(s.commanded),
                           'applied': _finite(s.effort)}, log_time=t)
        ch['physics'].log({'n': s.params.n, 'gamma': s.params.gamma,
                           'friction': s.params.friction}, log_time=t)
        if self._target is not None:
            ch['target'].log({'data': self._target}, log_time=t)
        ch['counters'].log(dict(s.counters, foxglove_dropped=self.dropped), log_time=t)
        try:
            terms = energy_terms(s.params, s.phi, s.dphi, s.residual)
        except ValueError:   # JointError: no finite energy (the joint stops on its own)
            return
        ch['energy'].log({'data': terms.energy}, log_time=t)
        ch['energy_terms'].log({
            'energy': terms.energy, 'kinetic': terms.kinetic, 'potential': terms.potential,
            'dissipated': _finite(s.dissipated), 'dissipated_power': terms.dissipated_power,
            'input': _finite(s.work_input), 'residual': terms.residual}, log_time=t)

    # ------------------------------------------------------------------ lifetime
    def close(self) -> None:
        """Stop the sender and the server (idempotent)."""
        if self._stopping:
            return
        self._stopping = True
        self._wake.set()
        self._thread.join(timeout=5.0)
        self._server.stop()

    def __enter__(self) -> LiveView:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

