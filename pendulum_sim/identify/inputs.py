"""Read a record to identify: a JointState stream of a rosbag2 MCAP file, or a CSV file.

MCAP files of any writer are read with :mod:`pendulum_sim.recording` (its reader and the
per-message decoder); a JointState stream is chosen by ``topic`` and ``joint`` and its samples
stamped by their header stamps (the log times where a writer left the stamp at zero). A CSV file
has a header row naming its columns, checked against ``columns``.
"""
from __future__ import annotations

import csv
import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from .errors import IdentifyError

FloatArray = npt.NDArray[np.float64]
JOINT_STATE = 'sensor_msgs/msg/JointState'
ROLES = ('t', 'position', 'velocity', 'effort')
SKIP = '_'


@dataclass(frozen=True)
class Samples:
    """A stream read from a file: times (s), angle (rad), velocity and effort where present."""

    t: FloatArray
    position: FloatArray
    velocity: FloatArray | None
    effort: FloatArray | None
    source: str


def parse_columns(text: str) -> tuple[str, ...]:
    """Return the roles of ``--columns`` (t and position required, ``_`` skips a column)."""
    cols = tuple(c.strip() for c in text.split(','))
    for c in cols:
        if c not in (*ROLES, SKIP):
            raise IdentifyError(f'--columns names t, position, velocity, effort or _ (a column '
                                f'to skip), got {c!r}')
    named = [c for c in cols if c != SKIP]
    if len(set(named)) != len(named) or 't' not in named or 'position' not in named:
        raise IdentifyError(f'--columns must name t and position once each (and velocity, '
                            f'effort at most once), got {text!r}')
    return cols


def read_csv(path: Path, columns: tuple[str, ...], units: str) -> Samples:
    """Read a CSV whose header row names ``columns`` in order."""
    with path.open(newline='') as fh:
        rows = [r for r in csv.reader(fh) if r and any(cell.strip() for cell in r)]
    if not rows:
        raise IdentifyError(f'{path} is empty; pass a CSV with a header row and samples')
    header = tuple(c.strip() for c in rows[0])
    if len(header) != len(columns) or any(c != SKIP and h != c for h, c in zip(header, columns,
                                                                                strict=True)):
        raise IdentifyError(f"{path}: header {','.join(header)!r} does not match --columns "
                            f"{','.join(columns)!r}; pass --columns with the file's columns in "
                            f"order (_ for one to skip)")
    data = np.full((len(rows) - 1, len(columns)), np.nan)
    for i, row in enumerate(rows[1:]):
        if len(row) != len(columns):
            raise IdentifyError(f'{path}: line {i + 2} has {len(row)} fields, the header '
                                f'{len(columns)}')
        for j, cell in enumerate(row):
            if columns[j] == SKIP:
                continue
            try:
                data[i, j] = float(cell)
            except ValueError:
                raise IdentifyError(f'{path}: line {i + 2}, column {columns[j]}: {cell!r} is '
                                    f'not a number') from None
    scale = math.pi / 180.0 if units == 'deg' else 1.0

    def col(role: str, factor: float = 1.0) -> FloatArray | None:
        return data[:, columns.index(role)] * factor if role in columns else None

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


def read_mcap(path: Path, topic: str | None, joint: str | None) -> Samples:
    """Read the JointState stream ``topic`` (or the only one) of ``joint`` (or the only one)."""
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
        if joint not in msg.name:
            continue
        i = list(msg.name).index(joint)
        stamp = int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
        t.append((stamp if stamp else log_ns) * 1e-9)
        pos.append(msg.position[i] if len(msg.position) > i else math.nan)
        vel.append(msg.velocity[i] if len(msg.velocity) > i else math.nan)
        eff.append(msg.effort[i] if len(msg.effort) > i else math.nan)
    v, e = np.asarray(vel, dtype=np.float64), np.asarray(eff, dtype=np.float64)
    return Samples(t=np.asarray(t, dtype=np.float64), position=np.asarray(pos, dtype=np.float64),
                   velocity=None if np.all(np.isnan(v)) else v,
                   effort=None if np.all(np.isnan(e)) else e,
                   source=f'{file} (topic {topic}, joint {joint})')


def read_record(path: str | Path, *, topic: str | None = None, joint: str | None = None,
                columns: str = 't,position', units: str = 'rad') -> Samples:
    """Read ``path``: a CSV (by its suffix ``.csv``) or a rosbag2 MCAP file or folder."""
    p = Path(path)
    if not p.exists():
        raise IdentifyError(f'{p} does not exist; pass a .mcap recording or a .csv file')
    if units not in ('deg', 'rad'):
        raise IdentifyError(f'--units must be deg or rad, got {units!r}')
    if p.suffix.lower() == '.csv':
        return read_csv(p, parse_columns(columns), units)
    from pendulum_sim.recording.errors import RecorderError

    try:
        return read_mcap(p, topic, joint)
    except RecorderError as exc:
        raise IdentifyError(f'{exc}; pass a rosbag2 MCAP file or a CSV') from None
