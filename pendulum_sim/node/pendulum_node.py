"""``pendulum_node``: the core's pendulum served as a simulated ROS 2 joint.

The node is a thin adapter. A :class:`~pendulum_sim.node.joint.SimulatedJoint` (no ROS) holds
everything between two publications: command hold, limits, delays, sensor, stamps, energy. The
node declares parameters, decides *when* the joint advances, and publishes what it returns:

- real time: a steady-clock timer at ``publish_rate`` steps to an absolute schedule
  (``realtime.py``);
- free lockstep (``lockstep: true``): whole control periods as fast as possible (or paced by
  ``real_time_factor``), ``/clock`` after each;
- synchronous lockstep (``synchronous: true``): each control period publishes ``/clock`` and
  ``joint_states``, then waits for the controller's command answering that state.

The command line lives in ``cli.py``.
"""
from __future__ import annotations

import math
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
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray, String, UInt32
from std_srvs.srv import SetBool, Trigger

from pendulum_sim import __version__
from pendulum_sim.core import PendulumError

from . import diagnostics as diag
from .errors import JointError, ParameterError
from .joint import SimulatedJoint
from .parameters import (
    SPEC_BY_NAME,
    Value,
    check,
    declare_all,
    effort_input_active,
    joint_config,
    merged,
    physics,
)
from .realtime import RateMeter, Schedule, WakeStats
from .serialized import ClockBytes, Float64Bytes, JointStateBytes
from .status import StatusLine, status_text, summary_text
from .urdf import urdf_from_values


def _qos(depth: int, reliable: bool = True, latched: bool = False) -> QoSProfile:
    """Return a keep-last profile of ``depth``: reliable or best effort, volatile or latched."""
    return QoSProfile(depth=depth, history=HistoryPolicy.KEEP_LAST,
                      reliability=ReliabilityPolicy.RELIABLE if reliable
                      else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if latched
                      else DurabilityPolicy.VOLATILE)


# Reliable, volatile, depth 10: the default profile, which matches both reliable and best-effort
# subscriptions (robot_state_publisher, RViz, Foxglove, plain rclpy defaults).
JOINT_STATE_QOS = _qos(10)
# Commands in real time and free lockstep: a best-effort subscription matches reliable and
# best-effort publishers alike (forward_command_controller publishes reliable; many
# teleoperation tools best effort).
COMMAND_QOS = _qos(10, reliable=False)
# Synchronous mode: every command answers a state, so none may be lost.
SYNC_COMMAND_QOS = _qos(100)
# Late joiners (RViz, Foxglove) must still get the URDF: transient local, as
# robot_state_publisher publishes robot_description (ros/robot_state_publisher, README.md).
LATCHED_QOS = _qos(1, latched=True)
# Services keep many requests: a burst of 100 concurrent ~/reset calls is answered in full
# (the rmw default depth of 10 drops the rest).
SERVICE_QOS = _qos(1000)
DIAGNOSTICS_PERIOD_NS = 1_000_000_000
# Lockstep and real time: work for at most this long per wake, then let the executor serve
# commands, parameters and services.
WAKE_BUDGET_NS = 10_000_000
LOCKSTEP_PERIOD = 1e-3
# Steps between looks at the clock.
CHUNK_STEPS = 256
# Synchronous mode: how often the watchdog looks for controllers and timeouts.
SYNC_WATCH_PERIOD = 0.02
# At most this much simulated time is caught up in one wake; beyond it the schedule slips
# (counted) instead of freezing the node after a long stall.
CATCH_UP_SECONDS = 0.25
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
        self._h = float(v['h'])
        self._lockstep = bool(v['lockstep'])
        self._sync = bool(v['synchronous'])
        self._joint_name = str(v['joint_name'])
        start_time = float(v['start_time'])
        wall_anchored = start_time < 0.0 and not self._lockstep
        epoch_ns = round(max(start_time, 0.0) * 1e9)
        self._joint = SimulatedJoint(joint_config(v, epoch_ns))
        self._paused = bool(v['start_paused'])
        self._step_budget = 0          # control periods still to take while paused
        self._stop_requested = False
        self._interface = str(v['command_interface'])

        # Synchronous-mode bookkeeping: the step whose state waits for its answer.
        self._awaiting: int | None = None
        self._awaiting_since = 0
        self._answered: float | None = None
        self._sync_stats = {'answered': 0, 'timeouts': 0, 'late': 0, 'duplicates': 0,
                            'ahead': 0}
        self._incompatible: dict[str, int] = {}
        self._failure_logged = False
        self._sync_started = False
        self._sync_waiting_logged = False
        self._bad_commands: dict[str, int] = {}

        # Entities: only what the scene enables.
        self._js_pub = self.create_publisher(JointState, 'joint_states', JOINT_STATE_QOS)
        self._energy_pub = (self.create_publisher(Float64, 'energy', 10)
                            if v['publish_energy'] else None)
        self._terms_pubs = ([self.create_publisher(Float64, f'energy_terms/{name}', 10)
                             for name in ENERGY_TERMS] if v['publish_energy_terms'] else [])
        self._clock_pub = (self.create_publisher(ClockMsg, '/clock', 10)
                           if self._lockstep and v['publish_clock'] else None)
        self._diag_pub = (self.create_publisher(DiagnosticArray, '/diagnostics', 10)
                          if v['diagnostics'] else None)
        if v['publish_robot_description']:
            self._desc_pub = self.create_publisher(String, 'robot_description', LATCHED_QOS)
            self._desc_pub.publish(String(data=self._urdf()))
        cmd_qos = SYNC_COMMAND_QOS if self._sync else COMMAND_QOS
        self._cmd_subs: list[Any] = []
        self._cmd_topics: dict[str, str] = {}
        if effort_input_active(v):
            self._cmd_subs.append(self._subscribe(Float64, 'effort_command', self._on_effort,
                                                  cmd_qos))
        if v['joint_commands_input']:
            self._cmd_subs.append(self._subscribe(JointState, 'joint_commands',
                                                  self._on_joint_command, cmd_qos))
        if v['array_command_input']:
            self._cmd_subs.append(self._subscribe(Float64MultiArray, 'commands',
                                                  self._on_array_command, cmd_qos))
        if v['services']:
            self.create_service(Trigger, '~/reset', self._on_reset, qos_profile=SERVICE_QOS)
            self.create_service(SetBool, '~/pause', self._on_pause, qos_profile=SERVICE_QOS)
            self.create_service(Trigger, '~/step', self._on_step_one, qos_profile=SERVICE_QOS)
            self.create_subscription(UInt32, '~/step_periods', self._on_step_periods,
                                     SYNC_COMMAND_QOS)
        self._recorder: Any = None
        self._recorder_error_logged = False
        if v['recording.path']:
            self._open_recorder(str(v['recording.path']), bool(v['recording.overwrite']))

        # Timing: a steady-clock timer, an absolute schedule and rttest-like measurement.
        # The schedule starts after every entity (and the recorder) exists, so the first wake
        # has no set-up time to catch up, and a wall-anchored epoch is read at the same moment.
        if wall_anchored:
            self._joint = SimulatedJoint(joint_config(v, time.time_ns()))
        now = time.monotonic_ns()
        rate = float(v['publish_rate'])
        if self._sync:
            period = SYNC_WATCH_PERIOD
        elif self._lockstep:
            period = LOCKSTEP_PERIOD
        else:
            period = 1.0 / rate
        self._period_ns = round(period * 1e9)
        rtf = float(v['real_time_factor'])
        self._schedule = Schedule(self._h, rtf if rtf > 0.0 else 1.0, now)
        self._asap = self._lockstep and rtf == 0.0
        self._wakes = WakeStats(0 if self._asap else self._period_ns)
        self._rate = RateMeter(now)
        if self._paused:
            self._rate.pause(now)
        self._cap = max(1, math.ceil(CATCH_UP_SECONDS * max(rtf, 1.0) / self._h))
        self._slips = 0
        self._behind_logged_ns = 0
        self._next_report_ns = now + DIAGNOSTICS_PERIOD_NS
        self._last_error = math.nan
        self._max_error = 0.0
        self._status = status if v['status_line'] else None
        self._js_bytes = JointStateBytes(self._joint_name)
        self._last_js: Any = None      # the last joint_states message (synchronous reminders)
        self._clock_bytes = ClockBytes()
        self._float_bytes = Float64Bytes()
        self._js_topic = self._js_pub.topic_name
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._timer = self.create_timer(period, self._on_wake, clock=self._steady)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._on_parameters_set)
        mode = ('synchronous lockstep' if self._sync else 'lockstep' if self._lockstep
                else 'real time')
        self.get_logger().info(
            f'{mode}: h = {self._h:g} s, {v["integrator"]}, control period '
            f'{self._joint.config.period_steps} steps ({rate:g} Hz), real_time_factor = {rtf:g}, '
            f'{self._interface} commands, joint {self._joint_name!r}'
            + (', paused (~/step or ~/pause false to go on)' if self._paused else ''))

    @property
    def stop_requested(self) -> bool:
        """Return True once a signal arrived inside a callback (the main loop then ends)."""
        return self._stop_requested

    def _urdf(self) -> str:
        """Return the URDF of this joint, its ros2_control block naming this node's topics."""
        commands = self.resolve_topic_name('joint_commands')
        return urdf_from_values(self._values, joint_commands_topic=commands,
                                joint_states_topic=self._js_pub.topic_name)

    def _subscribe(self, msg_type: Any, topic: str, callback: Any, qos: QoSProfile) -> Any:
        """Create a command subscription that says when a publisher cannot connect."""
        created: list[Any] = []

        def incompatible(event: Any) -> None:
            name = created[0].topic_name if created else topic
            count = self._incompatible.get(name, 0) + 1
            self._incompatible[name] = count
            if count == 1 or count % 100 == 0:
                kind = getattr(event.last_policy_kind, 'name', str(event.last_policy_kind))
                need = ('reliable (synchronous mode loses no command)' if self._sync
                        else 'a compatible QoS')
                self.get_logger().warning(
                    f'a publisher on {name} cannot connect: its QoS is incompatible '
                    f"({kind.removeprefix('RMW_QOS_POLICY_')}); publish {need} "
                    f'({count} so far)')

        events = SubscriptionEventCallbacks(incompatible_qos=incompatible)
        created.append(self.create_subscription(msg_type, topic, callback, qos,
                                                event_callbacks=events))
        return created[0]

    # ------------------------------------------------------------------ recording
    def _open_recorder(self, path: str, overwrite: bool) -> None:
        try:
            from pendulum_sim.recording import McapRecorder
        except ImportError as exc:
            self.get_logger().error(f'recording is not available ({exc}); not recording')
            return
        meta = {'scene': {k: str(val) for k, val in self._values.items()},
                'pendulum_sim': {'version': __version__}}
        rec = McapRecorder(path, overwrite=overwrite, metadata=meta)
        rec.open()
        rec.add_channel(self._js_pub.topic_name, JointState, JOINT_STATE_QOS)
        if self._energy_pub is not None:
            rec.add_channel(self._energy_pub.topic_name, Float64, 10)
        for sub in self._cmd_subs:
            rec.add_channel(sub.topic_name, sub.msg_type, 10)
        if self._diag_pub is not None:
            rec.add_channel(self._diag_pub.topic_name, DiagnosticArray, 10)
        rec.add_channel('/parameter_events', ParameterEvent, 10)
        self._recorder = rec
        self.get_logger().info(f'recording to {rec.path}')

    def _record(self, topic: str, msg: Any, stamp_ns: int) -> None:
        """Write a message (or its CDR bytes) to the recording; never raise."""
        rec = self._recorder
        if rec is None:
            return
        try:
            if isinstance(msg, bytes):
                rec.write_serialized(topic, msg, stamp_ns)
            else:
                rec.write(topic, msg, stamp_ns)
        except Exception as exc:  # a broken recorder must not stop the joint
            self._recorder_failed(exc)

    def _recorder_failed(self, exc: BaseException) -> None:
        if not self._recorder_error_logged:
            self._recorder_error_logged = True
            self.get_logger().error(f'recording failed, simulation continues: {exc}')

    # ------------------------------------------------------------------ time
    def _on_wake(self) -> None:
        try:
            self._wake()
        except KeyboardInterrupt:
            # Ctrl-C landed inside this callback: end the main loop, no traceback.
            self._stop_requested = True
        except Exception:
            # SIGTERM shut the context down in the middle of this wake (rclpy's signal
            # handler runs on its own thread): publishing then fails; that is the end.
            if self.context.ok():
                raise
            self._stop_requested = True

    def _wake(self) -> None:
        """Step as the mode says, publish, and measure this wake (the timer callback)."""
        now = time.monotonic_ns()
        remaining = self._timer.time_until_next_call()
        sched = now if remaining is None else now + remaining - self._period_ns
        wakes = self._wakes
        wakes.wake(sched, now)
        taken = 0
        joint = self._joint
        if self._sync:
            self._sync_watch(now)
        elif joint.failed is None:
            if self._paused:
                if self._step_budget:
                    taken = self._run_periods(self._step_budget, now + WAKE_BUDGET_NS)
            elif self._asap:
                taken = self._run_periods(1 << 62, now + WAKE_BUDGET_NS)
            else:
                k = self._schedule.due(now) - joint.steps
                capped = k > self._cap
                if capped:
                    k = self._cap
                if self._lockstep:   # paced lockstep: whole periods, /clock on their grid
                    periods = k // joint.config.period_steps
                    if periods:
                        taken = self._run_periods(periods, now + WAKE_BUDGET_NS)
                    k = periods * joint.config.period_steps
                elif k > 0:
                    taken = self._run_due(k, now + WAKE_BUDGET_NS)
                if capped or taken < k:
                    # Not all that was due fits in one wake: slip the schedule, say so.
                    self._slips += 1
                    self._behind(now)
                    self._schedule.rebase(time.monotonic_ns(), joint.steps)
        if now >= self._next_report_ns:
            self._next_report_ns += DIAGNOSTICS_PERIOD_NS * max(
                1, (now - self._next_report_ns) // DIAGNOSTICS_PERIOD_NS + 1)
            self._report(now)
        status = self._status
        if status is not None and status.due(now / 1e9):
            st = joint.stepper
            status.show(now / 1e9, status_text(st.t, st.phi, self._energy_or_nan(),
                                               self._rate.total(now), self._paused))
        wakes.done(sched, time.monotonic_ns(), taken)

    def _behind(self, now: int) -> None:
        """Say (at most every 5 s) that the requested real-time factor cannot be kept."""
        if now - self._behind_logged_ns >= 5_000_000_000:
            self._behind_logged_ns = now
            self.get_logger().warning(
                f'cannot keep real_time_factor {float(self._values["real_time_factor"]):g}: '
                f'achieved {self._rate.total(now):.3g} so far; the schedule slips '
                f'({self._slips} slips so far)')

    def _run_due(self, k: int, deadline_ns: int) -> int:
        """Real time: take up to ``k`` steps within the wake's budget, then publish."""
        joint = self._joint
        done = 0
        while done < k and joint.failed is None:
            n = joint.advance(min(CHUNK_STEPS, k - done))
            done += n
            if n == 0 or (done < k and time.monotonic_ns() >= deadline_ns):
                break
        self._after_steps(done)
        if done:
            self._publish()
        return done

    def _run_periods(self, count: int, deadline_ns: int) -> int:
        """Lockstep: take whole control periods, publishing /clock and the state after each.

        Steps go in chunks so a long period never holds the executor past the wake's budget;
        a period left partial is finished by the next wake.
        """
        joint = self._joint
        k = joint.config.period_steps
        done = 0
        periods = 0
        steps = joint.steps
        while periods < count and joint.failed is None:
            n = joint.advance(min(k - steps % k, CHUNK_STEPS))
            done += n
            steps += n
            if n == 0:
                break
            if steps % k == 0:
                periods += 1
                self._publish()
                if self._paused:
                    self._step_budget -= 1
                    if self._step_budget <= 0:
                        self._step_budget = 0
                        break
            if time.monotonic_ns() >= deadline_ns:
                break
        self._after_steps(done)
        return done

    def _after_steps(self, done: int) -> None:
        self._rate.advance(done * self._h)
        failed = self._joint.failed
        if failed is not None and not self._failure_logged:
            self._failure_logged = True
            self.get_logger().error(f'simulation stopped: {failed}; call ~/reset to restart')

    # ------------------------------------------------------------------ synchronous mode
    def _sync_watch(self, now: int) -> None:
        """Start the exchange once a controller is connected; act on a missing answer."""
        if self._joint.failed is not None:
            return
        if self._awaiting is None:
            if self._paused and not self._step_budget:
                return
            if self._ready():
                if not self._sync_started:
                    self._sync_started = True
                    self.get_logger().info('synchronous: a controller is connected; stepping')
                self._sync_publish()
            elif not self._sync_waiting_logged:
                self._sync_waiting_logged = True
                topics = ', '.join(str(sub.topic_name) for sub in self._cmd_subs)
                self.get_logger().info(
                    f'synchronous: waiting for a controller (a subscriber on '
                    f'{self._js_pub.topic_name} and a reliable publisher on {topics})')
            return
        if self._paused and not self._step_budget:
            return
        if self._answered is not None:
            self._sync_go()
            return
        waited = (now - self._awaiting_since) / 1e9
        if waited < float(self._values['sync_timeout']):
            if waited >= SYNC_WATCH_PERIOD:
                self._sync_remind()
            return
        self._sync_stats['timeouts'] += 1
        count = self._sync_stats['timeouts']
        action = str(self._values['sync_timeout_action'])
        t = self._awaiting * self._h
        if action == 'stop':
            self._pause(True)
            self.get_logger().error(
                f'sync_timeout: no command answered the state at t = {t:.9g} s within '
                f'{waited:.3g} s; paused (sync_timeout_action: stop; ~/step or ~/pause false '
                'to go on)')
            self._awaiting_since = now
            return
        if count == 1 or count % 100 == 0:
            self.get_logger().warning(
                f'sync_timeout: no command answered the state at t = {t:.9g} s within '
                f'{waited:.3g} s; holding the last command ({count} timeouts so far)')
        self._answered = math.nan   # hold: nothing new to apply
        self._sync_go()

    def _sync_remind(self) -> None:
        """Publish the awaited state again (until a first answer) and its /clock.

        Best-effort subscribers matched only just now (TopicBasedSystem's SensorDataQoS state
        subscription, ros2_control_node's ClockQoS /clock) can miss the first state and
        /clock; the manager would then sleep until sync_timeout, or answer without the state.
        Nothing is recorded again.
        """
        assert self._awaiting is not None
        if self._sync_stats['answered'] == 0 and self._last_js is not None:
            self._js_pub.publish(self._last_js)
        if self._clock_pub is not None:
            sec, nanosec = divmod(self._joint.stamp_ns(self._awaiting), 1_000_000_000)
            self._clock_pub.publish(self._clock_bytes.pack(sec, nanosec))

    def _ready(self) -> bool:
        """Return True when joint_states and a command topic have a matched peer."""
        if self._js_pub.get_subscription_count() < 1:
            return False
        return any(sub.get_publisher_count() > 0 for sub in self._cmd_subs) or not (
            self._cmd_subs)

    def _sync_publish(self) -> None:
        """Publish the state at the current step and wait for its answer."""
        self._publish()
        self._awaiting = self._joint.steps
        self._awaiting_since = time.monotonic_ns()
        self._answered = None

    def _sync_answer(self, value: float, stamp_ns: int | None) -> bool:
        """Take a command as the answer to the awaited state; return False if dropped."""
        awaiting = self._awaiting
        if awaiting is None:
            self._sync_stats['ahead'] += 1
            return False
        if stamp_ns is not None:
            want = self._joint.stamp_ns(awaiting)
            if stamp_ns < want:
                self._sync_stats['late'] += 1
                return False
            if stamp_ns > want:
                self._sync_stats['ahead'] += 1
                return False
        if self._answered is not None:
            self._sync_stats['duplicates'] += 1
            return False
        self._answered = value
        self._sync_stats['answered'] += 1
        return True

    def _sync_go(self) -> None:
        """Apply the answer, advance one control period and publish the next state."""
        value = self._answered
        if value is not None and not math.isnan(value):
            self._joint.command(value)
        self._awaiting = None
        self._answered = None
        joint = self._joint
        k = joint.config.period_steps
        n = joint.advance(k - joint.steps % k)
        self._after_steps(n)
        if self._paused:
            self._step_budget = max(0, self._step_budget - 1)
        if joint.failed is None:
            # Paused after N steps, this state waits for its answer until the next ~/step.
            self._sync_publish()

    # ------------------------------------------------------------------ publishing
    def _energy_or_nan(self) -> float:
        try:
            return self._joint.energy()
        except JointError:
            return math.nan

    def _publish(self) -> None:
        joint = self._joint
        if joint.failed is not None:
            return
        stamp_ns = joint.stamp_ns()
        sample = joint.sample()
        rec = self._recorder
        if sample is not None:
            sec, nanosec = divmod(sample.stamp_ns, 1_000_000_000)
            data = self._js_bytes.pack(sec, nanosec, sample.position, sample.velocity,
                                       sample.effort)
            self._js_pub.publish(data)
            self._last_js = data
            if rec is not None:
                self._record(self._js_topic, data, stamp_ns)
        # /clock after the state: a controller manager woken by /clock (ros2_control_node on
        # use_sim_time) finds the state of that time already sent when it reads.
        if self._clock_pub is not None:
            sec, nanosec = divmod(stamp_ns, 1_000_000_000)
            self._clock_pub.publish(self._clock_bytes.pack(sec, nanosec))
        if self._energy_pub is None and not self._terms_pubs:
            return
        try:
            energy = joint.energy()
            terms = joint.terms() if self._terms_pubs else None
        except JointError as exc:
            joint.fail(str(exc))
            self._after_steps(0)
            return
        if self._energy_pub is not None:
            e = self._float_bytes.pack(energy)
            self._energy_pub.publish(e)
            if rec is not None:
                self._record(self._energy_pub.topic_name, e, stamp_ns)
        if terms is not None:
            pack = self._float_bytes.pack
            values = (terms.kinetic, terms.potential, terms.dissipated_power, terms.residual)
            for pub, value in zip(self._terms_pubs, values, strict=True):
                pub.publish(pack(value))

    # ------------------------------------------------------------------ inputs
    def _drop(self, topic: str, reason: str) -> None:
        """Count a command that cannot be applied; log each reason once, then every 1000th."""
        key = f'{topic}: {reason}'
        count = self._bad_commands.get(key, 0) + 1
        self._bad_commands[key] = count
        if count == 1 or count % 1000 == 0:
            self.get_logger().warning(f'dropped a command on {topic}: {reason} '
                                      f'({count} so far)')

    def _take(self, topic: str, msg: Any, value: float, stamp_ns: int | None) -> None:
        """Apply (or, in synchronous mode, answer with) a valid command value."""
        if not self._joint.accepts(value):
            self._drop(topic, f'non-finite value {value}')
            return
        stamp = self._joint.stamp_ns()
        if self._sync:
            if self._awaiting is not None:
                stamp = self._joint.stamp_ns(self._awaiting)
            if not self._sync_answer(value, stamp_ns):
                return
        else:
            self._joint.command(value)
        if self._recorder is not None:
            self._record(topic, msg, stamp)
        if self._sync and (not self._paused or self._step_budget):
            self._sync_go()

    def _on_effort(self, msg: Float64) -> None:
        self._guarded(self._take, self._cmd_topic('effort_command'), msg, msg.data, None)

    def _on_array_command(self, msg: Float64MultiArray) -> None:
        topic = self._cmd_topic('commands')
        if len(msg.data) != 1:
            self._drop(topic, f'expected 1 value (one joint), got {len(msg.data)}')
            return
        self._guarded(self._take, topic, msg, float(msg.data[0]), None)

    def _on_joint_command(self, msg: JointState) -> None:
        topic = self._cmd_topic('joint_commands')
        try:
            i = list(msg.name).index(self._joint_name)
        except ValueError:
            self._drop(topic, f'no joint named {self._joint_name!r} in {list(msg.name)}')
            return
        field = self._interface
        values = getattr(msg, field)
        if len(values) <= i:
            self._drop(topic, f'no {field} for joint {self._joint_name!r} '
                       f'({len(values)} {field} values for {len(msg.name)} names)')
            return
        stamp = msg.header.stamp
        stamp_ns = stamp.sec * 1_000_000_000 + stamp.nanosec
        self._guarded(self._take, topic, msg, float(values[i]), stamp_ns)  # 0 is a stamp

    def _cmd_topic(self, name: str) -> str:
        """Return the resolved name of command topic ``name`` (looked up once)."""
        found = self._cmd_topics.get(name)
        if found is None:
            found = self._cmd_topics[name] = next(
                (str(sub.topic_name) for sub in self._cmd_subs
                 if sub.topic_name.endswith('/' + name)), name)
        return found

    def _guarded(self, fn: Any, *args: Any) -> None:
        try:
            fn(*args)
        except KeyboardInterrupt:
            self._stop_requested = True

    # ------------------------------------------------------------------ services
    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        v = self._values
        joint = self._joint
        was_failed = joint.reset()
        self._failure_logged = False
        now = time.monotonic_ns()
        self._schedule.rebase(now, joint.steps)
        stamp = joint.stamp_ns()
        t = joint.time
        message = (f'reset to phi = {v["phi0"]} rad, dphi = {v["dphi0"]} rad/s at '
                   f't = {t:.9g} s (simulated time goes on)'
                   + (f' (was stopped: {was_failed})' if was_failed else ''))
        rec = self._recorder
        if rec is not None:
            try:
                rec.write_reset(stamp, message)
            except Exception as exc:  # a broken recorder must not stop the joint
                self._recorder_failed(exc)
        response.success = True
        response.message = message
        return response

    def _pause(self, paused: bool) -> None:
        now = time.monotonic_ns()
        self._paused = paused
        if paused:
            self._rate.pause(now)
        else:
            self._rate.resume(now)
            self._schedule.rebase(now, self._joint.steps)
            if self._sync and self._answered is not None:
                self._sync_go()

    def _on_pause(self, request: SetBool.Request, response: SetBool.Response) -> Any:
        t = self._joint.time
        if request.data == self._paused:
            response.success = True
            state = 'paused' if self._paused else 'running'
            response.message = f'already {state} at t = {t:.9g} s'
            return response
        self._step_budget = 0
        self._pause(bool(request.data))
        response.success = True
        response.message = f'{"paused" if self._paused else "resumed"} at t = {t:.9g} s'
        return response

    def _step(self, count: int) -> tuple[bool, str]:
        """Queue ``count`` control periods while paused."""
        if not self._paused:
            return False, 'not paused: ~/step advances a paused simulation (call ~/pause true)'
        if count < 1:
            return False, f'the number of control periods must be >= 1, got {count}'
        self._step_budget += count
        k = self._joint.config.period_steps
        target = (self._joint.steps // k + self._step_budget) * k
        if self._sync and self._answered is not None:
            self._sync_go()
        return True, (f'stepping {count} control period(s) of {k * self._h:g} s to '
                      f't = {target * self._h:.9g} s')

    def _on_step_one(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        response.success, response.message = self._step(1)
        return response

    def _on_step_periods(self, msg: UInt32) -> None:
        ok, message = self._step(int(msg.data))
        if not ok:
            self.get_logger().warning(f'~/step_periods: {message}')

    # ------------------------------------------------------------------ parameters
    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        proposed = merged(self._values, ((p.name, p.value) for p in params))
        reason = check(proposed)
        if reason is None:
            try:
                self._joint.check_params(physics(proposed))
            except (JointError, PendulumError) as exc:
                reason = str(exc)
        if reason is not None:
            return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def _on_parameters_set(self, params: list[Parameter]) -> None:
        names = {p.name for p in params if p.name in SPEC_BY_NAME}
        if not names:
            return
        for p in params:
            if p.name in names:
                self._values[p.name] = p.value
        v = self._values
        joint = self._joint
        joint.reconfigure(joint_config(v, joint.config.epoch_ns))
        if 'real_time_factor' in names:
            rtf = float(v['real_time_factor'])
            self._asap = self._lockstep and rtf == 0.0
            self._schedule.rebase(time.monotonic_ns(), joint.steps, rtf if rtf > 0.0 else 1.0)
            self._cap = max(1, math.ceil(CATCH_UP_SECONDS * max(rtf, 1.0) / self._h))
        if self._recorder is not None:
            stamp = joint.stamp_ns()
            event = ParameterEvent(node=self.get_fully_qualified_name())
            event.stamp = _stamp(stamp)
            event.changed_parameters = [p.to_parameter_msg() for p in params
                                        if p.name in names]
            self._record('/parameter_events', event, stamp)

    # ------------------------------------------------------------------ diagnostics
    def guard_stats(self) -> dict[str, int]:
        """Return the guard's counters over the whole run (across resets)."""
        return self._joint.guard_stats()

    def _estimate_error(self) -> float:
        joint = self._joint
        if joint.failed is not None:
            return self._last_error
        try:
            err = joint.stepper.local_error_estimate(joint.torque)
        except (PendulumError, OverflowError, ZeroDivisionError):
            err = math.nan
        self._last_error = err
        if math.isfinite(err):
            self._max_error = max(self._max_error, err)
        return err

    def _report(self, now: int) -> None:
        err = self._estimate_error()
        rec = self._recorder
        if rec is not None and rec.error is not None:
            self._recorder_failed(rec.error)
        if self._diag_pub is None:
            self._wakes.window()
            self._rate.window(now)
            return
        lat, spw = self._wakes.window()
        total = self._wakes.summary()
        joint = self._joint
        st = joint.stepper
        c = joint.counters
        try:
            terms = joint.terms()
            energy, residual = terms.energy, terms.residual
        except JointError:
            energy = residual = math.nan
        values: dict[str, object] = {
            'sim_time': joint.time,
            'steps': joint.steps,
            'epoch_ns': joint.config.epoch_ns,
            'paused': self._paused,
            'real_time_factor_target': float(self._values['real_time_factor']),
            'real_time_factor_achieved': self._rate.window(now),
            'real_time_factor_total': self._rate.total(now),
            'wake_latency_p50_us': lat.p50_us,
            'wake_latency_p99_us': lat.p99_us,
            'wake_latency_max_us': lat.max_us,
            'wake_latency_p99_us_total': total.p99_us,
            'wake_latency_max_us_total': total.max_us,
            'steps_per_wake': spw,
            'steps_per_wake_max': self._wakes.max_steps,
            'wakes': self._wakes.wakes,
            'overruns': self._wakes.overruns,
            'missed_wakes': self._wakes.missed,
            'schedule_slips': self._slips,
            **{f'guard_{k}': val for k, val in self.guard_stats().items()},
            'energy': energy,
            'energy_residual': residual,
            'local_error_estimate': err,
            'local_error_max': self._max_error,
            'commands_received': c.received,
            'commands_rejected_nonfinite': c.rejected_nonfinite,
            'commands_saturated': c.saturated,
            'commands_limited': c.limited,
            'command_timeouts': c.timeouts,
            'commands_dropped': sum(self._bad_commands.values()),
            **{f'commands_dropped[{k}]': n for k, n in self._bad_commands.items()},
            'torque': joint.torque,
            'phase_time_since_reset': st.t,
        }
        if self._sync:
            values.update({f'sync_{k}': n for k, n in self._sync_stats.items()})
        for topic, n in self._incompatible.items():
            values[f'incompatible_qos[{topic}]'] = n
        if joint.failed is not None:
            level, message = diag.ERROR, f'stopped: {joint.failed}'
        elif self._paused:
            level, message = diag.OK, 'paused'
        else:
            level, message = diag.OK, 'running'
        name = f'{self.get_fully_qualified_name()}: simulation'
        array = diag.status_array(_stamp(joint.stamp_ns()), name, self._joint_name, level,
                                  message, values)
        self._diag_pub.publish(array)
        if rec is not None:
            self._record(self._diag_pub.topic_name, array, joint.stamp_ns())

    def summary(self) -> dict[str, object]:
        """Return the figures printed at shutdown."""
        now = time.monotonic_ns()
        lat = self._wakes.summary()
        joint = self._joint
        err = self._estimate_error()
        guard = self.guard_stats()
        c = joint.counters
        out: dict[str, object] = {
            'steps': joint.steps,
            'simulated time (s)': self._rate.sim_seconds,
            'wall time running (s)': self._rate.running_ns(now) / 1e9,
            'achieved real-time factor': self._rate.total(now),
            'wakes': self._wakes.wakes,
            'wake latency p50/p99/max (us)': f'{lat.p50_us:.0f} / {lat.p99_us:.0f} / '
                                             f'{lat.max_us:.0f}',
            'overruns / missed wakes / slips': f'{self._wakes.overruns} / '
                                               f'{self._wakes.missed} / {self._slips}',
            'guard substeps / fallbacks / reversals': f'{guard.get("substeps", 0)} / '
                                                      f'{guard.get("fallbacks", 0)} / '
                                                      f'{guard.get("reversals", 0)}',
            'guard sticks / energy rejections': f'{guard.get("sticks", 0)} / '
                                                f'{guard.get("energy_rejections", 0)}',
            'energy-balance residual (J)': joint.stepper.residual,
            'local error estimate (last / max)': f'{err:.3g} / {self._max_error:.3g}',
            'commands received / rejected / dropped': f'{c.received} / '
                                                      f'{c.rejected_nonfinite} / '
                                                      f'{sum(self._bad_commands.values())}',
        }
        if self._sync:
            s = self._sync_stats
            out['sync answered / timeouts / late / duplicates'] = (
                f'{s["answered"]} / {s["timeouts"]} / {s["late"]} / {s["duplicates"]}')
        out['stopped by'] = joint.failed or '-'
        return out

    def close(self) -> None:
        """Print the summary and close the recording (call once, before destroy_node)."""
        if self._status is not None:
            self._status.finish()
        try:
            print(summary_text(self.summary()), file=sys.stderr, flush=True)
        except Exception as exc:  # the summary must never hide the shutdown
            print(f'pendulum_node: no summary ({type(exc).__name__}: {exc})', file=sys.stderr)
        rec, self._recorder = self._recorder, None
        if rec is not None:
            try:
                rec.close()
            except Exception as exc:  # report, keep shutting down
                print(f'pendulum_node: closing the recording failed: {exc}', file=sys.stderr)
            if rec.error is not None:
                print(f'pendulum_node: recording error: {rec.error}', file=sys.stderr)
