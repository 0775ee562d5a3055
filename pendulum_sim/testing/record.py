"""A closed-loop run to and from MCAP, in the layout ``pendulum_node`` records.

An in-process run is written as the node writes a synchronous run: ``/joint_states`` and
``/effort_command`` with the state's stamp as log time, and the parameters as the ``scene``
metadata record; a ``closed_loop`` record keeps the reference when it is known. Reading goes
through :func:`pendulum_sim.recording.load`, so a run recorded by the node and one written here
load the same way. Both need rclpy (for the CDR serialization), imported here only.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from pendulum_sim.joint.parameters import joint_name_refusal

from .errors import TestingError
from .run import ClosedLoopRun
from .scene import Value

JOINT_STATES = '/joint_states'
EFFORT_COMMAND = '/effort_command'


def write_run(run: ClosedLoopRun, path: Path, joint_name: str | None = None) -> Path:
    """Write ``run`` to the MCAP file ``path`` (replaced if it exists); return the path."""
    from builtin_interfaces.msg import Time
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64

    from pendulum_sim.recording import McapRecorder

    name = joint_name or str(run.parameters.get('joint_name', 'pendulum_joint'))
    reason = joint_name_refusal(name)   # a NUL would end the name in the recorded message
    if reason is not None:
        raise TestingError(reason)
    meta = {'scene': {k: str(v) for k, v in run.parameters.items()}}
    if run.target is not None:
        meta['closed_loop'] = {'target': repr(run.target)}
    with McapRecorder(path, overwrite=True, metadata=meta) as rec:
        rec.add_channel(JOINT_STATES, JointState)
        rec.add_channel(EFFORT_COMMAND, Float64)
        for i in range(run.t.size):
            stamp = round(run.t[i] * 1e9)
            sec, nanosec = divmod(stamp, 1_000_000_000)
            msg = JointState(name=[name], position=[float(run.position[i])],
                             velocity=[float(run.velocity[i])],
                             effort=[float(run.effort[i])])
            msg.header.stamp = Time(sec=sec, nanosec=nanosec)
            rec.write(JOINT_STATES, msg, stamp)
            rec.write(EFFORT_COMMAND, Float64(data=float(run.command[i])), stamp)
    return path


def _value(text: str) -> Value:
    """Return a metadata string as the bool, int, float or str it was written from."""
    if text in ('True', 'False'):
        return text == 'True'
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def load_run(path: str | Path, periods: int | None = None) -> ClosedLoopRun:
    """Return the closed-loop run recorded in ``path`` (by the node or by :func:`write_run`).

    Each state is paired with the command answering it (recorded at the state's stamp); the
    run is the states that have an answer, at most ``periods`` of them.

    Raises
    ------
    TestingError
        If the file cannot be read or holds no joint states or no effort commands.
    """
    from pendulum_sim.recording import RecorderError, load

    try:
        rec = load(path)
    except RecorderError as exc:
        raise TestingError(str(exc)) from None
    js, cmd = rec.joint_states, rec.effort_command
    if js is None or cmd is None or js.t.size == 0 or cmd.t.size == 0:
        raise TestingError(f'{path} holds no closed loop: it needs joint_states and '
                           'effort_command messages')
    answers = dict(zip(cmd.stamp_ns.tolist(), cmd.value.tolist(), strict=True))
    n = 0
    while n < js.t.size and int(js.stamp_ns[n]) in answers and (periods is None or
                                                                n < periods):
        n += 1
    stamps = js.stamp_ns[:n]
    params = {k: _value(v) for k, v in rec.scene.items()}
    target_text = rec.metadata.get('closed_loop', {}).get('target')
    target = float(target_text) if target_text is not None else None
    def column(a: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(np.asarray(a, dtype=np.float64).reshape(js.t.size, -1)[:n, 0])
    return ClosedLoopRun(
        t=stamps / 1e9, position=column(js.position), velocity=column(js.velocity),
        effort=column(js.effort),
        command=np.array([answers[int(s)] for s in stamps], dtype=np.float64),
        parameters=params, target=target if target is None or math.isfinite(target) else None)
