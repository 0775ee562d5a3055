"""``closed_loop``: a controller against the simulated joint, in-process or over DDS.

The in-process path runs a Python callable ``(t, position, velocity) -> command`` against
:class:`~pendulum_sim.joint.joint.SimulatedJoint` exactly as ``pendulum_node`` runs it in
synchronous lockstep (``synchronous: true``): at the start of each control period the joint is
measured (the state the node publishes, stamped ``epoch + k h``), the controller answers that
state, and the node's synchronous driver and exchange (``pendulum_sim.joint.drivers``,
``pendulum_sim.joint.exchange``, the same objects ``pendulum_node`` runs) apply the answer and
advance the joint to the next period boundary. No rclpy, no DDS. The command-line path
(:mod:`pendulum_sim.testing.ros`) runs the same exchange across processes; for the same law
both give the same trajectory bit for bit (``test/testing/test_testing_loop.py``).

A run of ``periods`` control periods holds the ``periods`` states at the start of each period
(``t``, ``position``, ``velocity``; ``effort`` is the torque applied in the step before each
state, as ``joint_states`` carries it) and ``command``, the controller's answer to each.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pendulum_sim.joint.drivers import WAKE_BUDGET_NS, SyncDriver
from pendulum_sim.joint.errors import JointError
from pendulum_sim.joint.exchange import Gate, SyncExchange
from pendulum_sim.joint.joint import Sample, SimulatedJoint
from pendulum_sim.joint.parameters import joint_config

from .errors import ControllerFailed, TestingError
from .run import ClosedLoopRun, FloatArray
from .scene import Value, epoch_ns, scene_values
from .target import bind_target, substitute_target

__all__ = ['MAX_PERIODS', 'ClosedLoopRun', 'Law', 'answer_reason', 'closed_loop',
           'run_in_process']

Law = Callable[[float, float, float], float]
MAX_PERIODS = 10_000_000


def _check_periods(periods: int) -> int:
    if isinstance(periods, bool) or not isinstance(periods, int) or not (
            1 <= periods <= MAX_PERIODS):
        raise TestingError(f'periods must be an integer in [1, {MAX_PERIODS}], got '
                           f'{periods!r}')
    return periods


def _check_target(target: float | None) -> float | None:
    if target is None:
        return None
    if isinstance(target, bool) or not isinstance(target, (int, float)) or not math.isfinite(
            target):
        raise TestingError(f'target must be a finite number (rad), got {target!r}')
    return float(target)


def closed_loop(controller: Law | Callable[..., float] | Sequence[str], *,
                scene: str = 'controller_test', periods: int,
                overrides: Mapping[str, Any] | None = None, record: str | Path | None = None,
                timeout: float = 120.0, target: float | None = None,
                foxglove_port: int = 0) -> ClosedLoopRun:
    """Run ``controller`` against the joint of ``scene`` for ``periods`` control periods.

    Parameters
    ----------
    controller : callable or list of str
        ``(t, position, velocity) -> command`` run in this process, or a command line (e.g.
        ``['pendulum_pd_controller']``) run in its own process against ``pendulum_node`` in
        synchronous lockstep over DDS, in a namespace of its own.
    scene : str
        A scene name or parameter file (the node's ``--scene``).
    periods : int
        Control periods (``1/publish_rate`` of simulated time each) to run.
    overrides : mapping, optional
        Node parameters (the scene's names) that replace the scene's values.
    record : path, optional
        Write the run to this MCAP file (replaced if it exists).
    timeout : float
        Command-line path: wall-clock seconds the whole run may take.
    target : float, optional
        The reference (rad). A law whose signature has a parameter ``target`` is called with
        it bound (``law(t, position, velocity, target=target)``), a command line gets it where
        an argument holds ``{target}`` (:mod:`pendulum_sim.testing.target`); the run keeps it
        as its ``target``, the default of ``metrics()`` and ``plot()``. None (the default):
        the controller gets no target and the run has none.
    foxglove_port : int
        Serve the run live to Foxglove on this port (the node's ``foxglove_port``: 0 = off,
        or 1024..65535); in this process the run is paced to real time while a client
        watches (:mod:`pendulum_sim.testing.live`).

    Raises
    ------
    TestingError
        For a bad scene, override, ``periods`` or ``target``, or a command line with a
        ``{target}`` placeholder and no ``target``.
    ControllerFailed
        When the controller raises, answers with a non-finite command, cannot be started or
        leaves a state unanswered.
    """
    periods = _check_periods(periods)
    target = _check_target(target)
    if foxglove_port:
        overrides = {**(overrides or {}), 'foxglove_port': foxglove_port}
    values = scene_values(scene, overrides)
    if isinstance(controller, (list, tuple)):
        if not controller or not all(isinstance(a, str) for a in controller):
            raise TestingError(f'a controller command line must be a non-empty list of '
                               f'strings, got {controller!r}')
        from .ros import run_command_line

        return run_command_line(substitute_target(controller, target), values, periods,
                                None if record is None else Path(record), timeout,
                                target=target)
    if not callable(controller):
        raise TestingError(f'controller must be a callable (t, position, velocity) -> '
                           f'command or a command line (list of str), got {controller!r}')
    law = controller if target is None else bind_target(controller, target)
    run = run_in_process(law, values, periods, target)
    if target is not None:
        run = run.with_target(target)
    if record is not None:
        from .record import write_run

        write_run(run, Path(record))
    return run


def run_in_process(law: Law, values: Mapping[str, Value], periods: int,
                   target: float | None = None) -> ClosedLoopRun:
    """Run ``law`` against a :class:`SimulatedJoint` built from ``values`` (no ROS).

    The node's own synchronous driver (:class:`~pendulum_sim.joint.drivers.SyncDriver` with its
    :class:`~pendulum_sim.joint.exchange.SyncExchange`) decides which answer is applied and when
    the joint advances; here the controller is always connected, answers each state at once
    (unstamped, counted as the node counts them) and the steady clock stands still, so no
    timeout fires and every wake finishes its period.
    """

    from .live import LiveLoop

    try:
        joint = SimulatedJoint(joint_config(values, epoch_ns(values)))
    except JointError as exc:
        raise TestingError(str(exc)) from None
    sent: list[Sample] = []
    live = LiveLoop(values, target) if values['foxglove_port'] else None

    def publish(with_clock: bool) -> bool:
        """Send the state as the node's outputs do: one measurement per publication."""
        if joint.failed is not None:
            return False
        sample = joint.sample()
        if sample is not None:
            sent.append(sample)
            if live is not None:   # the node's synchronous counters, as over DDS
                live.offer(joint, sample, driver.counters())
        return sample is not None

    exchange = SyncExchange(Gate(), round(float(values['sync_timeout']) * 1e9), 'hold')
    driver = SyncDriver(joint, exchange, publish, _quiet, 0, _connected, '', clock=_still)
    out = np.full((5, periods), np.nan)
    n = 0
    try:
        driver.wake(0, WAKE_BUDGET_NS)   # the first state
        for _ in range(periods):
            if joint.failed is not None:
                break
            if not sent:   # no state went out (a sensor delay filling): the command holds
                driver.wake(0, WAKE_BUDGET_NS)
                continue
            sample = sent.pop()
            t = sample.stamp_ns / 1e9
            try:
                value = _answer(law, t, sample.position, sample.velocity)
            except ControllerFailed as exc:
                exc.run = _samples(out, n, values, joint.failed)   # the run up to the fault
                raise
            out[:, n] = (t, sample.position, sample.velocity, sample.effort, value)
            n += 1
            driver.command(value, None, 0)   # answers the state, advances, sends the next
    finally:
        if live is not None:
            live.close()
    return _samples(out, n, values, joint.failed)


def _samples(out: FloatArray, n: int, values: Mapping[str, Value],
             failed: str | None) -> ClosedLoopRun:
    """Return the run of the first ``n`` answered states in ``out``."""
    times, position, velocity, effort, command = (np.ascontiguousarray(row[:n]) for row in out)
    return ClosedLoopRun(times, position, velocity, effort, command, parameters=dict(values),
                         failed=failed)


def _quiet(level: str, text: str) -> None:
    """Log nothing: a stopped simulation is reported by ``ClosedLoopRun.failed``."""


def _connected() -> tuple[bool, int]:
    """Return that a controller is connected (one subscriber on the states)."""
    return True, 1


def _still() -> int:
    """Return a steady clock that stands still (no timeout, no wake budget runs out)."""
    return 0


def answer_reason(value: object, t: float) -> ControllerFailed:
    """Return the failure of a controller that answered ``value`` (not a finite number)."""
    if isinstance(value, float):
        return ControllerFailed(f'the controller returned {value} at t = {t:.9g} s; a command '
                                'must be finite')
    if isinstance(value, int) and not isinstance(value, bool):   # too large for a float
        return ControllerFailed(f'law raised OverflowError: the controller returned an int of '
                                f'{len(str(abs(value)))} digits at t = {t:.9g} s, too large '
                                'for a float; a command must be finite')
    shown = repr(value)
    shown = shown if len(shown) <= 60 else shown[:57] + '...'
    return ControllerFailed(f'the controller returned {shown} at t = {t:.9g} s; a command '
                            'is a number')


def _answer(law: Law, t: float, position: float, velocity: float) -> float:
    """Return the controller's finite answer to one state; ControllerFailed if it has none."""
    try:
        raw = law(t, position, velocity)
    except Exception as exc:
        raise ControllerFailed(f'the controller raised {type(exc).__name__}: {exc} at '
                               f't = {t:.9g} s') from exc
    if isinstance(raw, (str, bytes, bytearray)):   # float() would read '0.5'
        raise answer_reason(raw, t)
    try:
        value = float(raw)
    except (TypeError, ValueError, OverflowError):
        raise answer_reason(raw, t) from None
    if not math.isfinite(value):
        raise answer_reason(value, t)
    return value
