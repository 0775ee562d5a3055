"""Read a record to identify: a JointState stream of a rosbag2 MCAP file, or a CSV file.

MCAP files of any writer are read with :mod:`pendulum_sim.recording` (its reader and the
per-message decoder); a JointState stream is chosen by ``topic`` and ``joint`` and its samples
stamped by their header stamps (the log times where a writer left the stamp at zero). A CSV file
is read by ``--columns``: the roles of its columns in order (a header row, whatever it says,
is recognised by a cell that is not a number and skipped), or its header names mapped to roles
(``time=t,angle=position``).
"""
from __future__ import annotations

import csv
import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .errors import IdentifyError

if TYPE_CHECKING:   # the loader needs rclpy: imported where a file is read
    from pendulum_sim.recording.loader import Recording

FloatArray = npt.NDArray[np.float64]
JOINT_STATE = 'sensor_msgs/msg/JointState'
ROLES = ('t', 'position', 'velocity', 'effort')
SKIP = '_'


@dataclass(frozen=True)
class Samples:
    """A stream read from a file: times (s), angle (rad), velocity and effort where present.

    ``commands`` holds a command stream read from its own topic (stamps in s, values in N m;
    ``--effort-topic``), ``joint`` the joint's name where the file gives one.
    """

    t: FloatArray
    position: FloatArray
    velocity: FloatArray | None
    effort: FloatArray | None
    source: str
    commands: tuple[FloatArray, FloatArray] | None = None
    joint: str | None = None


@dataclass(frozen=True)
class Columns:
    """What ``--columns`` says of a CSV's columns.

    Either ``roles``, the role of each column in order (``_`` skips one), whatever a header
    row says; or ``names``, each role's column by its header name (the header row required).
    """

    roles: tuple[str, ...] | None = None
    names: tuple[tuple[str, str], ...] | None = None   # (role, header name)

    def text(self) -> str:
        """Return the columns as ``--columns`` spells them."""
        if self.names is not None:
            return ','.join(f'{name}={role}' for role, name in self.names)
        assert self.roles is not None
        return ','.join(self.roles)


def _check_roles(named: list[str], text: str) -> None:
    if len(set(named)) != len(named) or 't' not in named or 'position' not in named:
        raise IdentifyError(f'--columns must name t and position once each (and velocity, '
                            f'effort at most once), got {text!r}')


def parse_columns(text: str) -> Columns:
    """Return what ``--columns`` says: roles in order (``t,_,position``) or by header name.

    ``time=t,angle=position`` maps the header names ``time`` and ``angle`` to the roles t and
    position; columns it does not name are skipped.
    """
    items = tuple(c.strip() for c in text.split(','))
    mapped = ['=' in c for c in items]
    if any(mapped) and not all(mapped):
        raise IdentifyError(f'--columns either names the roles of the columns in order '
                            f'(t,_,position) or maps header names to roles (time=t,'
                            f'angle=position), not both; got {text!r}')
    if not any(mapped):
        for c in items:
            if c not in (*ROLES, SKIP):
                raise IdentifyError(f'--columns names t, position, velocity, effort or _ (a '
                                    f'column to skip), or maps header names to them '
                                    f'(time=t,angle=position); got {c!r}')
        _check_roles([c for c in items if c != SKIP], text)
        return Columns(roles=items)
    pairs = []
    for item in items:
        name, _, role = (part.strip() for part in item.partition('='))
        if not name or role not in ROLES:
            raise IdentifyError(f'--columns maps a header name to a role as NAME=ROLE, the '
                                f'role one of t, position, velocity, effort; got {item!r}')
        pairs.append((role, name))
    _check_roles([role for role, _ in pairs], text)
    names = [name for _, name in pairs]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise IdentifyError(f'--columns maps the header name {twice[0]!r} to two roles; map '
                            f'each column once, got {text!r}')
    return Columns(names=tuple(pairs))


def _number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def read_csv(path: Path, columns: Columns, units: str) -> Samples:
    """Read a CSV: its columns by role in order, or by their header names.

    A first row with a cell that is not a number (in a column read) is a header row: skipped
    where ``columns`` gives the roles in order, read for the names where it maps header names
    to roles.
    """
    with path.open(newline='') as fh:
        rows = [r for r in csv.reader(fh) if r and any(cell.strip() for cell in r)]
    if not rows:
        raise IdentifyError(f'{path} is empty; pass a CSV with a sample on each line')
    first = [c.strip() for c in rows[0]]
    read = first   # the cells that tell a header: those of the columns read
    if columns.roles is not None and len(first) == len(columns.roles):
        read = [c for c, role in zip(first, columns.roles, strict=True) if role != SKIP]
    header = None if all(_number(c) for c in read) else tuple(
        c.lstrip('#').strip() if i == 0 else c for i, c in enumerate(first))
    if columns.names is not None:
        if header is None:
            raise IdentifyError(f'{path} has no header row (its first line is numbers) to '
                                f'find the columns {columns.text()!r} by name; pass --columns '
                                f'with the roles of the columns in order (_ for one to skip)')
        roles = [SKIP] * len(header)
        for role, name in columns.names:
            if name not in header:
                raise IdentifyError(f"{path}: --columns names a column {name!r} that the "
                                    f"header {','.join(header)!r} does not have; pass "
                                    f"--columns with the file's header names")
            if header.count(name) > 1:
                raise IdentifyError(f"{path}: the header {','.join(header)!r} has "
                                    f"{header.count(name)} columns named {name!r}; pass "
                                    f"--columns with the roles of the columns in order")
            roles[header.index(name)] = role
        order = tuple(roles)
    else:
        assert columns.roles is not None
        order = columns.roles
        if header is not None and len(header) != len(order):
            raise IdentifyError(f"{path}: the header {','.join(header)!r} has {len(header)} "
                                f"columns but --columns {columns.text()!r} names "
                                f"{len(order)}; pass --columns with a role for each column "
                                f"(_ for one to skip)")
    body = rows[1:] if header is not None else rows
    offset = 2 if header is not None else 1
    if not body:
        raise IdentifyError(f'{path} has a header row and no samples; pass a CSV with samples')
    data = np.full((len(body), len(order)), np.nan)
    for i, row in enumerate(body):
        if len(row) != len(order):
            raise IdentifyError(f'{path}: line {i + offset} has {len(row)} fields, '
                                + (f'the header {len(order)}' if header is not None else
                                   f'--columns names {len(order)}'))
        for j, cell in enumerate(row):
            if order[j] == SKIP:
                continue
            try:
                data[i, j] = float(cell)
            except ValueError:
                raise IdentifyError(f'{path}: line {i + offset}, column {order[j]}: {cell!r} '
                                    f'is not a number') from None
    scale = math.pi / 180.0 if units == 'deg' else 1.0

    def col(role: str, factor: float = 1.0) -> FloatArray | None:
        return data[:, order.index(role)] * factor if role in order else None

    t, pos = col('t'), col('position', scale)
    assert t is not None and pos is not None
    return Samples(t=t, position=pos, velocity=col('velocity', scale), effort=col('effort'),
                   source=f'{path} (CSV, {units})')


def _mcap_file(path: Path) -> Path:
    if path.is_dir():   # a rosbag2 folder: its one .mcap file
        found = sorted(path.glob('*.mcap'))
        if len(found) != 1:
            raise IdentifyError(f'{path} is a folder with {len(found)} .mcap files; pass one '
                                f'.mcap file')
        return found[0]
    return path


COMMAND_TYPES = ('std_msgs/msg/Float64', JOINT_STATE)
"""The types of a command stream ``--effort-topic`` reads: ``effort_command``'s and
``joint_commands``'s."""


def _joint_at(msg: Any, joint: str, log_ns: int) -> tuple[float, int] | None:
    """Return a JointState's stamp (s; its log time where the header has none) and the index
    of ``joint`` in it, or None where the message does not name the joint."""
    if joint not in msg.name:
        return None
    stamp = int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
    return (stamp if stamp else log_ns) * 1e-9, list(msg.name).index(joint)


def _item(values: Any, i: int) -> float:
    """Return ``values[i]``, or NaN where the message's field is shorter (not reported)."""
    return values[i] if len(values) > i else math.nan


def read_commands(rec: Recording, file: Path, topic: str, joint: str) -> tuple[FloatArray,
                                                                           FloatArray]:
    """Return the stamps (s) and values (N m) of the command stream ``topic`` for ``joint``.

    A ``std_msgs/Float64`` stream has no header: its messages are stamped by their log time
    (``pendulum_node`` logs each at the stamp of the state it answers); a JointState stream
    by its header stamps (the log time where a writer left them zero), its value the effort
    field of ``joint``.
    """
    topics = rec.topics
    streams = sorted(name for name, info in topics.items() if info.type in COMMAND_TYPES)
    if topic not in topics or topics[topic].type not in COMMAND_TYPES:
        have = ', '.join(streams) or 'none'
        raise IdentifyError(f'{file} has no command topic {topic!r} (its Float64 and '
                            f'JointState topics: {have}); pass --effort-topic with the topic '
                            f'the joint was commanded on')
    messages = rec.messages(topic)
    stamps, values = [], []
    for log_ns, msg in messages:
        if topics[topic].type == JOINT_STATE:
            at = _joint_at(msg, joint, log_ns)
            if at is None:
                continue
            stamps.append(at[0])
            values.append(_item(msg.effort, at[1]))
        else:
            stamps.append(log_ns * 1e-9)
            values.append(float(msg.data))
    return np.asarray(stamps, dtype=np.float64), np.asarray(values, dtype=np.float64)


def read_mcap(path: Path, topic: str | None, joint: str | None,
              effort_topic: str | None = None) -> Samples:
    """Read the JointState stream ``topic`` (or the only one) of ``joint`` (or the only one).

    With ``effort_topic`` the command stream on that topic is read as well
    (:func:`read_commands`).
    """
    from pendulum_sim.recording.errors import RecorderError
    from pendulum_sim.recording.loader import load

    file = _mcap_file(path)
    if file.stat().st_size == 0:
        raise IdentifyError(f'{file} is empty (0 bytes); pass a recording')
    try:
        with warnings.catch_warnings():
            warnings.simplefilter('ignore')
            rec = load(file)
    except RecorderError as exc:
        raise IdentifyError(f'{exc}; pass a rosbag2 MCAP file or a CSV') from None
    if not rec.complete:
        why = rec.problems[0] if rec.problems else 'it was not closed'
        raise IdentifyError(f'{file} is truncated ({why}); pass a recording that was closed')
    streams = sorted(name for name, info in rec.topics.items() if info.type == JOINT_STATE)
    if not streams:
        have = ', '.join(sorted(rec.topics)) or 'none'
        raise IdentifyError(f'{file} has no {JOINT_STATE} topic (its topics: {have}); pass a '
                            f'recording of joint states')
    if topic is None:
        own = [s for s in streams if s.rsplit('/', 1)[-1] == 'joint_states']
        if len(streams) > 1 and len(own) != 1:
            raise IdentifyError(f'{file} has {len(streams)} JointState topics '
                                f'({", ".join(streams)}); pass --topic')
        topic = own[0] if own else streams[0]
    elif topic not in streams:
        raise IdentifyError(f'{file} has no JointState topic {topic!r}; pass --topic with one '
                            f'of {", ".join(streams)}')
    messages = rec.messages(topic)
    if not messages:
        raise IdentifyError(f'{file}: topic {topic} has no messages; pass a recording with '
                            f'joint states in it')
    names: list[str] = []
    for _, msg in messages:
        names.extend(n for n in msg.name if n not in names)
    if joint is None:
        if len(names) != 1:
            raise IdentifyError(f'{file}: {topic} carries the joints {", ".join(names)}; pass '
                                f'--joint')
        joint = names[0]
    elif joint not in names:
        raise IdentifyError(f'{file}: joint {joint!r} is not in the messages of {topic} (they '
                            f'name {", ".join(names) or "no joint"}); pass --joint with one of '
                            f'them')
    t, pos, vel, eff = [], [], [], []
    for log_ns, msg in messages:
        at = _joint_at(msg, joint, log_ns)
        if at is None:
            continue
        t.append(at[0])
        pos.append(_item(msg.position, at[1]))
        vel.append(_item(msg.velocity, at[1]))
        eff.append(_item(msg.effort, at[1]))
    v, e = np.asarray(vel, dtype=np.float64), np.asarray(eff, dtype=np.float64)
    commands = None if effort_topic is None else read_commands(rec, file, effort_topic, joint)
    return Samples(t=np.asarray(t, dtype=np.float64), position=np.asarray(pos, dtype=np.float64),
                   velocity=None if np.all(np.isnan(v)) else v,
                   effort=None if np.all(np.isnan(e)) else e,
                   source=f'{file} (topic {topic}, joint {joint})', commands=commands,
                   joint=joint)


def read_record(path: str | Path, *, topic: str | None = None, joint: str | None = None,
                columns: str = 't,position', units: str = 'rad',
                effort_topic: str | None = None) -> Samples:
    """Read ``path``: a CSV (by its suffix ``.csv``) or a rosbag2 MCAP file or folder.

    ``effort_topic`` names a command stream of an MCAP file to read the effort from
    (:func:`read_commands`); a CSV has its effort in a column.
    """
    p = Path(path)
    if not p.exists():
        raise IdentifyError(f'{p} does not exist; pass a .mcap recording or a .csv file')
    if units not in ('deg', 'rad'):
        raise IdentifyError(f'--units must be deg or rad, got {units!r}')
    if p.suffix.lower() == '.csv':
        if effort_topic is not None:
            raise IdentifyError(f'{p} is a CSV: its effort is a column (--columns ...,effort), '
                                f'not a topic; drop --effort-topic')
        return read_csv(p, parse_columns(columns), units)
    from pendulum_sim.recording.errors import RecorderError

    try:
        return read_mcap(p, topic, joint, effort_topic)
    except RecorderError as exc:
        raise IdentifyError(f'{exc}; pass a rosbag2 MCAP file or a CSV') from None
