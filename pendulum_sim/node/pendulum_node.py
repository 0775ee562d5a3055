"""``pendulum_node``: the core's pendulum served as a simulated ROS 2 joint (wiring only).

The node declares parameters, creates the publishers, subscriptions, services and timer, and hands
each callback to a ROS-free part: ``joint.py`` (the joint), ``drivers.py`` (when it advances, per
mode), ``exchange.py`` (pause, step budget, synchronous answers), ``commands.py`` (decoding),
``outputs.py`` (publishing, recording), ``telemetry.py`` (diagnostics, summary) and
``foxglove.py`` (the live view).
"""
from __future__ import annotations

import sys
import time
from typing import Any

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import ParameterEvent, SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray, String, UInt32
from std_srvs.srv import SetBool, Trigger

from pendulum_sim import __version__
from pendulum_sim.joint import commands, replies
from pendulum_sim.joint.cost import cost_line, estimate_real_time_factor
from pendulum_sim.joint.drivers import WAKE_BUDGET_NS, make_driver, wake_period
from pendulum_sim.joint.exchange import Gate, StepError
from pendulum_sim.joint.foxglove import LiveView
from pendulum_sim.joint.joint import SimulatedJoint
from pendulum_sim.joint.parameters import (
    SPEC_BY_NAME,
    Value,
    check,
    effort_input_active,
    joint_config,
    refusal,
    start_epoch_ns,
)
from pendulum_sim.joint.realtime import WakeStats
from pendulum_sim.joint.status import StatusLine, summary_text
from pendulum_sim.joint.telemetry import Telemetry
from pendulum_sim.joint.urdf import urdf_from_values

from . import diagnostics as diag
from .declare import declare_all
from .errors import ParameterError
from .outputs import Recording, StateOutputs
from .qos import COMMAND_QOS, JOINT_STATE_QOS, LATCHED_QOS, SERVICE_QOS, STEP_QOS, SYNC_COMMAND_QOS

ENERGY_TERMS = ('kinetic', 'potential', 'dissipated_power', 'residual')


def _stamp(ns: int) -> Time:
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


class PendulumNode(Node):
    """Advance a simulated joint in real time, free lockstep or synchronous lockstep."""

    def __init__(self, *, status: StatusLine | None = None) -> None:
        super().__init__('pendulum_node')
        self._values: dict[str, Value] = declare_all(self)
        reason = check(self._values)
        if reason is not None:
            raise ParameterError(reason)
        v = self._values
        lockstep, self._sync = bool(v['lockstep']), bool(v['synchronous'])
        self._joint_name = str(v['joint_name'])
        self._interface = str(v['command_interface'])
        self._incompatible: dict[str, int] = {}
        self._drops = commands.Drops()
        self._refused_steps = commands.Drops()
        self._stop_requested = False

        # Entities: only what the scene enables.
        self._js_pub = self.create_publisher(JointState, 'joint_states', JOINT_STATE_QOS)
        energy = self.create_publisher(Float64, 'energy', 10) if v['publish_energy'] else None
        terms = ([self.create_publisher(Float64, f'energy_terms/{name}', 10)
                  for name in ENERGY_TERMS] if v['publish_energy_terms'] else [])
        clock = (self.create_publisher(ClockMsg, '/clock', 10)
                 if lockstep and v['publish_clock'] else None)
        self._diag_pub = (self.create_publisher(DiagnosticArray, '/diagnostics', 10)
                          if v['diagnostics'] else None)
        if v['publish_robot_description']:
            self._desc_pub = self.create_publisher(String, 'robot_description', LATCHED_QOS)
            self._desc_pub.publish(String(data=self._urdf()))
        cmd_qos = SYNC_COMMAND_QOS if self._sync else COMMAND_QOS
        self._cmd_subs: list[Any] = []
        for enabled, msg_type, topic, callback in (
                (effort_input_active(v), Float64, 'effort_command', self._on_effort),
                (v['joint_commands_input'], JointState, 'joint_commands', self._on_joint_command),
                (v['array_command_input'], Float64MultiArray, 'commands', self._on_array)):
            if enabled:
                self._cmd_subs.append(self._subscribe(msg_type, topic, callback, cmd_qos))
        self._topics = {str(s.topic_name).rsplit('/', 1)[-1]: str(s.topic_name)
                        for s in self._cmd_subs}
        if v['services']:
            self.create_service(Trigger, '~/reset', self._on_reset, qos_profile=SERVICE_QOS)
            self.create_service(SetBool, '~/pause', self._on_pause, qos_profile=SERVICE_QOS)
            self.create_service(Trigger, '~/step', self._on_step_one, qos_profile=SERVICE_QOS)
            self.create_subscription(UInt32, '~/step_periods', self._on_step_periods,
                                     STEP_QOS)
        # The live view before the recording: a port in use stops the start with nothing open.
        self._live = LiveView.of(v, self._urdf()) if v['foxglove_port'] else None
        self._recording = Recording(None, self._log)
        if v['recording.path']:
            channels: list[tuple[str, Any, Any]] = [
                (self._js_pub.topic_name, JointState, JOINT_STATE_QOS)]
            channels += [(pub.topic_name, t, 10) for pub, t in (
                (energy, Float64), (self._diag_pub, DiagnosticArray)) if pub is not None]
            channels += [(s.topic_name, s.msg_type, 10) for s in self._cmd_subs]
            self._recording.open(str(v['recording.path']), bool(v['recording.overwrite']),
                                 {'scene': {k: str(x) for k, x in v.items()},
                                  'pendulum_sim': {'version': __version__}}, channels)

        # What the configured law's steps cost, by a trial of a joint of the same config
        # (before the joint's epoch and schedule start: the trial delays no wake).
        rtf = float(v['real_time_factor'])
        cost = cost_line(estimate_real_time_factor(joint_config(v)), rtf,
                         not self._sync and rtf > 0.0)
        # The joint and its driver start after every entity (and the recorder) exists, so the
        # first wake has no set-up time to catch up; a wall-anchored epoch is read now.
        self._joint = joint = SimulatedJoint(joint_config(v, start_epoch_ns(v, time.time_ns())))
        self._gate = gate = Gate(bool(v['start_paused']))
        self._outputs = StateOutputs(joint, self._joint_name, self._js_pub, clock, energy,
                                     terms, self._recording, self._live)
        now = time.monotonic_ns()
        self._driver = make_driver(
            v, joint, gate, self._outputs, self._log, now, self._ready,
            f'synchronous: waiting for a controller (a subscriber on {self._js_pub.topic_name}'
            f" and a reliable publisher on {', '.join(self._topics.values())})",
            remind=self._outputs.remind, remind_state=set(self._topics) == {'joint_commands'})
        self._outputs.live_counters = self._driver.counters
        period, scheduled = wake_period(v)
        self._period_ns = round(period * 1e9)
        self._wakes = WakeStats(self._period_ns if scheduled else 0)
        self._telemetry = Telemetry(joint, self._driver, gate, self._drops, self._wakes,
                                    self._incompatible, float(v['real_time_factor']), now)
        self._telemetry.live = self._live
        self._status = status if v['status_line'] else None
        self._timer = self.create_timer(period, self._on_wake,
                                        clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._on_parameters_set)
        self._log('info', self._telemetry.start_text(v))
        self._log(*cost)
        if self._live is not None:
            self._log('info', f'foxglove: serving the joint on {self._live.url}')

    @property
    def stop_requested(self) -> bool:
        """Return True once a signal arrived inside a callback (the main loop then ends)."""
        return self._stop_requested

    def _log(self, level: str, text: str) -> None:
        logger = self.get_logger()   # rclpy ties a severity to each call site: one per level
        if level == 'error':
            logger.error(text)
        elif level == 'warning':
            logger.warning(text)
        else:
            logger.info(text)
        if self._live is not None:   # stamp 0 before the joint exists
            self._live.log(self._joint.stamp_ns() if hasattr(self, '_joint') else 0, level, text)

    def _urdf(self) -> str:
        """Return the URDF of this joint, its ros2_control block naming this node's topics."""
        return urdf_from_values(self._values,
                                joint_commands_topic=self.resolve_topic_name('joint_commands'),
                                joint_states_topic=self._js_pub.topic_name)

    def _subscribe(self, msg_type: Any, topic: str, callback: Any, qos: QoSProfile) -> Any:
        """Create a command subscription that says when a publisher cannot connect."""
        created: list[Any] = []

        def incompatible(event: Any) -> None:
            name = created[0].topic_name if created else topic
            count = self._incompatible[name] = self._incompatible.get(name, 0) + 1
            kind = getattr(event.last_policy_kind, 'name', str(event.last_policy_kind))
            line = commands.incompatible_line(name, kind, self._sync, count)
            if line is not None:
                self._log('warning', line)

        events = SubscriptionEventCallbacks(incompatible_qos=incompatible)
        created.append(self.create_subscription(msg_type, topic, callback, qos,
                                                event_callbacks=events))
        return created[0]

    def _ready(self) -> tuple[bool, int]:
        """Return whether a controller can take part, and the subscribers on joint_states."""
        subscribers = self._js_pub.get_subscription_count()
        ready = subscribers >= 1 and any(s.get_publisher_count() > 0 for s in self._cmd_subs)
        return ready, subscribers

    # ------------------------------------------------------------------ callbacks
    def _guarded(self, fn: Any, *args: Any) -> Any:
        """Run a callback; a signal or a shut-down context inside it ends the main loop."""
        try:
            return fn(*args)
        except KeyboardInterrupt:
            self._stop_requested = True
        except Exception:
            if self.context.ok():
                raise
            self._stop_requested = True   # the context went down under a publish
        return None

    def _on_wake(self) -> None:
        self._guarded(self._wake, None)

    def _tick_first(self) -> None:
        """Serve the tick now if a wake is due (on a schedule: real time, paced lockstep).

        The executor takes events in order, so the timer's event can wait behind a queue of
        parameter sets; each set first serves a due wake, and the timer's event, once it comes,
        finds that wake served.
        """
        sched = self._wakes.overdue(time.monotonic_ns())
        if sched is not None:
            self._guarded(self._wake, sched)

    def _wake(self, sched: int | None) -> None:
        """Advance as the mode says, report, and measure this wake (the timer callback, or
        a due wake served early with its scheduled time ``sched``)."""
        now = time.monotonic_ns()
        if sched is None:
            remaining = self._timer.time_until_next_call()
            sched = now if remaining is None else now + remaining - self._period_ns
            if self._wakes.taken(sched):
                return   # served early, ahead of the parameter sets queued before this event
        self._wakes.wake(sched, now)
        self._outputs.refresh()
        taken = self._driver.wake(now, now + WAKE_BUDGET_NS)
        self._driver.check_failed()
        if self._telemetry.report_due(now):
            self._report(now)
        status = self._status
        if status is not None and status.due(now / 1e9):
            status.show(now / 1e9, self._telemetry.status(now))
        self._wakes.done(sched, time.monotonic_ns(), taken)

    def _command(self, name: str, msg: Any, decoded: commands.Decoded) -> None:
        topic = self._topics[name]
        if decoded.reason:
            line = self._drops.drop(topic, decoded.reason, decoded.detail)
            if line is not None:
                self._log('warning', line)
            return
        stamp = self._driver.command(decoded.value, decoded.stamp_ns, time.monotonic_ns())
        if stamp is not None and self._recording.recorder is not None:
            self._recording.write(topic, msg, stamp)

    def _on_effort(self, msg: Float64) -> None:
        self._guarded(self._command, 'effort_command', msg, commands.Decoded(msg.data, None))

    def _on_array(self, msg: Float64MultiArray) -> None:
        self._guarded(self._command, 'commands', msg, commands.from_array(msg.data))

    def _on_joint_command(self, msg: JointState) -> None:
        s = msg.header.stamp
        decoded = commands.from_joint_state(self._joint_name, self._interface, msg.name,
                                            getattr(msg, self._interface), s.sec, s.nanosec)
        self._guarded(self._command, 'joint_commands', msg, decoded)

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        self._driver.apply_parameters(time.monotonic_ns())   # a new phi0 counts from here
        was_failed = self._joint.reset()
        response.success = True
        response.message = replies.reset_reply(self._values, self._joint.time, was_failed)
        self._recording.reset(self._joint.stamp_ns(), response.message)
        self._guarded(self._driver.after_reset, time.monotonic_ns())
        return response

    def _on_pause(self, request: SetBool.Request, response: SetBool.Response) -> Any:
        t, paused = self._joint.time, bool(request.data)
        changed = self._guarded(self._driver.pause, paused, time.monotonic_ns())
        response.success = True
        response.message = replies.pause_reply(paused, bool(changed), t)
        return response

    def _step(self, count: int) -> str:
        """Queue ``count`` control periods while paused; raise StepError if it cannot."""
        text = replies.step_reply(self._joint, self._gate.budget, count)
        self._guarded(self._driver.step, count, time.monotonic_ns())
        return text

    def _on_step_one(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        try:
            response.success, response.message = True, self._step(1)
        except StepError as exc:
            response.success, response.message = False, str(exc)
        return response

    def _on_step_periods(self, msg: UInt32) -> None:
        try:
            self._step(int(msg.data))
        except StepError as exc:
            line = self._refused_steps.drop('~/step_periods', str(exc))
            if line is not None:   # the first of each reason, then every 1000th
                self._log('warning', line.replace('dropped a command on ', ''))

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        self._tick_first()
        reason = refusal(self._values, ((p.name, p.value) for p in params), self._joint)
        return SetParametersResult(successful=reason is None, reason=reason or '')

    def _on_parameters_set(self, params: list[Parameter]) -> None:
        names = {p.name for p in params if p.name in SPEC_BY_NAME}
        if not names:
            return
        for p in params:
            if p.name in names:
                self._values[p.name] = p.value
        self._driver.take_parameters(self._values, names)   # applied by the next wake, once
        self._telemetry.rtf_target = float(self._values['real_time_factor'])
        if self._live is not None:
            self._live.parameters(self._values)
        if self._recording.recorder is not None:
            stamp = self._joint.stamp_ns()
            event = ParameterEvent(node=self.get_fully_qualified_name(), stamp=_stamp(stamp))
            event.changed_parameters = [p.to_parameter_msg() for p in params if p.name in names]
            self._recording.write('/parameter_events', event, stamp)

    # ------------------------------------------------------------------ reports
    def _report(self, now: int) -> None:
        self._recording.check()
        if self._diag_pub is None:
            self._telemetry.window(now)
            return
        values = self._telemetry.values(now)
        level, message = self._telemetry.level()
        array = diag.status_array(_stamp(self._joint.stamp_ns()),
                                  f'{self.get_fully_qualified_name()}: simulation',
                                  self._joint_name, getattr(diag, level), message, values)
        self._diag_pub.publish(array)
        self._recording.write(self._diag_pub.topic_name, array, self._joint.stamp_ns())

    def summary(self) -> dict[str, object]:
        """Return the figures printed at shutdown."""
        return self._telemetry.summary(time.monotonic_ns())

    def close(self) -> None:
        """Print the summary and close the recording (call once, before destroy_node)."""
        if self._status is not None:
            self._status.finish()
        try:
            print(summary_text(self.summary()), file=sys.stderr, flush=True)
        except Exception as exc:  # the summary must never hide the shutdown
            print(f'pendulum_node: no summary ({type(exc).__name__}: {exc})', file=sys.stderr)
        self._recording.close()
        if self._live is not None:
            self._live.close()
