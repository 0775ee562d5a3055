"""The command-line path of ``closed_loop``: the controller and ``pendulum_node`` over DDS.

Three processes per run, all in one namespace of the run's own (``/closed_loop_<hex>``, with
``/clock`` remapped into it), so runs at the same time in the same ROS domain never meet:

1. ``pendulum_node`` with the run's parameters (synchronous lockstep, started paused, recording
   to MCAP);
2. the controller, the given command line with ``--ros-args -r __ns:=...`` appended;
3. :mod:`pendulum_sim.testing.driver`, which steps the node ``periods`` control periods and
   waits for the last state.

Then the controller and the node get SIGINT (the node closes the recording), and the run is
read back from the MCAP. Every wait is on a condition (a process's exit), bounded by
``timeout``.
"""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import uuid
from collections.abc import Mapping
from pathlib import Path
from typing import IO

import yaml

from pendulum_sim.joint.joint import SimulatedJoint
from pendulum_sim.joint.parameters import SPEC_BY_NAME, joint_config

from .errors import ControllerFailed, TestingError
from .run import ClosedLoopRun
from .scene import Value, epoch_ns

POLL = 0.02
STOP_TIMEOUT = 20.0


def node_command() -> list[str]:
    """Return the command that starts ``pendulum_node`` (the venv's script if installed)."""
    script = Path(sys.executable).parent / 'pendulum_node'
    if script.is_file():
        return [str(script)]
    return [sys.executable, '-m', 'pendulum_sim.node.cli']


def _params_file(values: Mapping[str, Value], path: Path) -> None:
    """Write the values that differ from the node's defaults as a ROS 2 parameter file."""

    changed = {k: v for k, v in values.items() if SPEC_BY_NAME[k].default != v}
    path.write_text(yaml.safe_dump({'/**': {'ros__parameters': changed}}))


class _Proc:
    """A child process with its output in a temporary file."""

    def __init__(self, name: str, cmd: list[str]) -> None:
        self.name = name
        self.log: IO[str] = tempfile.TemporaryFile(mode='w+')
        try:
            self.proc = subprocess.Popen(cmd, stdout=self.log, stderr=subprocess.STDOUT,
                                         text=True, env=dict(os.environ),
                                         start_new_session=True)
        except OSError as exc:
            self.log.close()
            raise ControllerFailed(f'cannot start the {name} {cmd[0]!r}: '
                                   f'{exc.strerror or exc}') from None

    def output(self) -> str:
        self.log.flush()
        self.log.seek(0)
        return self.log.read()

    def stop(self) -> int:
        """Ask the process to end (SIGINT), kill it after STOP_TIMEOUT; return its code."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(STOP_TIMEOUT)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        return self.proc.returncode

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        self.log.close()


def _tail(text: str, lines: int = 15) -> str:
    return '\n'.join(text.strip().splitlines()[-lines:])


def run_command_line(cmd: list[str], values: Mapping[str, Value], periods: int,
                     record: Path | None, timeout: float,
                     target: float | None = None) -> ClosedLoopRun:
    """Run the controller command line ``cmd`` against the node; return the recorded run.

    ``target`` is the run's reference, kept in the returned run (the node's recording does not
    hold it).
    """

    from .record import load_run

    if shutil.which(cmd[0]) is None and not Path(cmd[0]).is_file():
        raise ControllerFailed(f'cannot start the controller {cmd[0]!r}: no such executable')
    config = joint_config(values, epoch_ns(values))
    last_stamp = SimulatedJoint(config).stamp_ns(periods * config.period_steps)
    ns = f'/closed_loop_{uuid.uuid4().hex[:12]}'
    ros = ['--ros-args', '-r', f'__ns:={ns}', '-r', f'/clock:={ns}/clock']
    with tempfile.TemporaryDirectory(prefix='closed_loop_') as tmp:
        path = (record or Path(tmp) / 'run.mcap').resolve()
        params = dict(values)
        params['recording.path'] = str(path)
        params['recording.overwrite'] = True
        params_file = Path(tmp) / 'params.yaml'
        _params_file(params, params_file)
        procs: list[_Proc] = []
        try:
            node = _Proc('node', [*node_command(), *ros, '--params-file', str(params_file)])
            procs.append(node)
            ctrl = _Proc('controller', [*cmd, *ros])
            procs.append(ctrl)
            driver = _Proc('driver', [sys.executable, '-m', 'pendulum_sim.testing.driver', ns,
                                      str(periods), str(last_stamp)])
            procs.append(driver)
            end = time.monotonic() + timeout
            while driver.proc.poll() is None:
                for p in (node, ctrl):
                    if p.proc.poll() is not None:
                        raise ControllerFailed(
                            f'the {p.name} exited with code {p.proc.returncode} before the '
                            f'{periods} periods were run:\n{_tail(p.output())}')
                if time.monotonic() > end:
                    raise ControllerFailed(
                        f'the run of {periods} periods did not end within {timeout:g} s; '
                        f'controller output:\n{_tail(ctrl.output())}\nnode output:\n'
                        f'{_tail(node.output())}')
                time.sleep(POLL)
            if driver.proc.returncode != 0:
                raise TestingError(f'the driver failed:\n{_tail(driver.output())}')
            ctrl.stop()
            code = node.stop()
            if code != 0:
                raise TestingError(f'pendulum_node exited with code {code}:\n'
                                   f'{_tail(node.output())}')
            node_log = node.output()
        finally:
            for p in procs:
                p.close()
        run = load_run(path, periods)
        if run.t.size < periods:
            missing = run.t.size * config.period_steps * config.h
            raise ControllerFailed(
                f'the controller did not answer the state at t = {missing:.9g} s (synchronous '
                f'mode holds the last command after sync_timeout); node output:\n'
                f'{_tail(node_log)}')
        return ClosedLoopRun(run.t, run.position, run.velocity, run.effort, run.command,
                             parameters=dict(values), failed=None, target=target)
