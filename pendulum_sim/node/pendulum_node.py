"""``pendulum_node``: the core's pendulum served as a real-time simulated joint.

The node is a thin adapter: a :class:`~pendulum_sim.core.Stepper` does the physics; the node
decides when to step (``realtime.py``), what a sensor would report (``sensors.py``) and fills
messages. Run it as::

    pendulum_node --scene default
    pendulum_node --ros-args --params-file config/default.yaml
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
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, String
from std_srvs.srv import SetBool, Trigger

from pendulum_sim import __version__
from pendulum_sim.core import PendulumError, Stepper

from . import diagnostics as diag
from .errors import ParameterError
from .parameters import SPEC_BY_NAME, Value, check, declare_all, merged, physics
from .realtime import RateMeter, Schedule, WakeStats
from .sensors import DelayLine, SensorModel
from .serialized import ClockBytes, Float64Bytes, JointStateBytes
from .status import StatusLine, status_text, summary_text
from .urdf import pendulum_urdf

# Reliable, volatile, depth 10: the default profile, which matches both reliable and best-effort
# subscriptions (robot_state_publisher, RViz, Foxglove, plain rclpy defaults).
JOINT_STATE_QOS = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                             reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.VOLATILE)
# Late joiners (RViz, Foxglove) must still get the URDF: transient local, as
# robot_state_publisher publishes robot_description (ros/robot_state_publisher, README.md).
LATCHED_QOS = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
DIAGNOSTICS_PERIOD_NS = 1_000_000_000
# Lockstep as fast as possible: work for this long per wake, then let the executor serve
# commands, parameters and services.
LOCKSTEP_BUDGET_NS = 10_000_000
LOCKSTEP_PERIOD = 1e-3
LOCKSTEP_CHUNK = 64
# At most this much simulated time is caught up in one wake; beyond it the schedule slips
# (counted) instead of freezing the node after a long stall.
CATCH_UP_SECONDS = 0.25
ENERGY_TERMS = ('kinetic', 'potential', 'dissipated_power', 'residual')


def _stamp(ns: int) -> Time:
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


class PendulumNode(Node):
    """Advance a pendulum in real time (or lockstep) and publish it as a joint."""

    def __init__(self, *, status: StatusLine | None = None) -> None:
        super().__init__('pendulum_node')
        self._values: dict[str, Value] = declare_all(self)
        reason = check(self._values)
        if reason is not None:
            raise ParameterError(reason)
        v = self._values
        self._h = float(v['h'])
        h_ns = self._h * 1e9
        # An h of whole nanoseconds keeps every stamp exactly on the grid epoch + k h.
        self._h_ns_int = round(h_ns) if abs(h_ns - round(h_ns)) < 1e-6 else 0
        self._lockstep = bool(v['lockstep'])
        self._joint = str(v['joint_name'])
        self._stepper = Stepper(physics(v), float(v['phi0']), float(v['dphi0']), self._h,
                                str(v['integrator']), guard=bool(v['guard']))
        self._guard_before_reset: dict[str, int] = {}
        self._steps_total = 0
        self._paused = False
        self._failed: str | None = None

        # Effort input: a command holds for round(command_timeout / h) steps (simulated time,
        # counted in steps so the duration is exact), then the torque drops to 0.
        self._command = 0.0
        self._command_step = 0
        self._timeout_steps = round(float(v['command_timeout']) / self._h)
        self._torque = 0.0
        self._cmd_received = 0
        self._cmd_rejected = 0
        self._cmd_saturated = 0
        self._cmd_timeouts = 0

        self._sensor = SensorModel(int(v['sensor.seed']), float(v['sensor.position_noise']),
                                   float(v['sensor.velocity_noise']),
                                   float(v['sensor.resolution']))
        self._delay_ns = round(float(v['sensor.delay']) * 1e9)
        self._delay_line: DelayLine[bytes] = DelayLine()

        start_time = float(v['start_time'])
        self._wall_anchored = start_time < 0.0 and not self._lockstep

        # Entities: only what the scene enables.
        self._js_pub = self.create_publisher(JointState, 'joint_states', JOINT_STATE_QOS)
        self._energy_pub = (self.create_publisher(Float64, 'energy', 10)
                            if v['publish_energy'] else None)
        self._terms_pubs = ([self.create_publisher(Float64, f'energy_terms/{name}', 10)
                             for name in ENERGY_TERMS] if v['publish_energy_terms'] else [])
        self._clock_pub = (self.create_publisher(ClockMsg, '/clock', 10)
                           if self._lockstep else None)
        self._diag_pub = (self.create_publisher(DiagnosticArray, '/diagnostics', 10)
                          if v['diagnostics'] else None)
        self._desc_pub = None
        if v['publish_robot_description']:
            self._desc_pub = self.create_publisher(String, 'robot_description', LATCHED_QOS)
            self._desc_pub.publish(String(data=pendulum_urdf(self._stepper.params,
                                                             self._joint)))
        self._cmd_sub = (self.create_subscription(Float64, 'effort_command', self._on_command,
                                                  10) if v['effort_input'] else None)
        if v['services']:
            self.create_service(Trigger, '~/reset', self._on_reset)
            self.create_service(SetBool, '~/pause', self._on_pause)
        self._recorder: Any = None
        self._recorder_error_logged = False
        if v['recording.path']:
            self._open_recorder(str(v['recording.path']), bool(v['recording.overwrite']))

        # Timing: a steady-clock timer, an absolute schedule and rttest-like measurement.
        # The schedule starts after every entity (and the recorder) exists, so the first wake
        # has no set-up time to catch up.
        now = time.monotonic_ns()
        self._epoch_ns = time.time_ns() if self._wall_anchored else round(
            max(start_time, 0.0) * 1e9)
        rate = float(v['publish_rate'])
        self._k_pub = max(1, round(1.0 / (rate * self._h)))
        period = LOCKSTEP_PERIOD if self._lockstep else 1.0 / rate
        self._period_ns = round(period * 1e9)
        rtf = float(v['real_time_factor'])
        self._schedule = Schedule(self._h, rtf if rtf > 0.0 else 1.0, now)
        self._asap = self._lockstep and rtf == 0.0
        self._wakes = WakeStats(0 if self._asap else self._period_ns)
        self._rate = RateMeter(now)
        self._cap = max(1, math.ceil(CATCH_UP_SECONDS * max(rtf, 1.0) / self._h))
        self._slips = 0
        self._next_report_ns = now + DIAGNOSTICS_PERIOD_NS
        self._last_error = math.nan
        self._max_error = 0.0
        self._status = status if v['status_line'] else None
        self._js_bytes = JointStateBytes(self._joint)
        self._clock_bytes = ClockBytes()
        self._float_bytes = Float64Bytes()
        self._js_topic = self._js_pub.topic_name
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._timer = self.create_timer(period, self._on_wake, clock=self._steady)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._on_parameters_set)
        mode = 'lockstep' if self._lockstep else 'real time'
        self.get_logger().info(
            f'{mode}: h = {self._h:g} s, {v["integrator"]}, publishing at {rate:g} Hz, '
            f'real_time_factor = {rtf:g}, joint {self._joint!r}')

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
        if self._cmd_sub is not None:
            rec.add_channel(self._cmd_sub.topic_name, Float64, 10)
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
    def _stamp_ns(self) -> int:
        steps = self._stepper.steps
        if self._h_ns_int:
            return self._epoch_ns + steps * self._h_ns_int
        return self._epoch_ns + round(steps * self._h * 1e9)

    def _on_wake(self) -> None:
        try:
            self._wake()
        except Exception:
            # Ctrl-C or SIGTERM shut the context down in the middle of this wake (rclpy's
            # signal handler runs on its own thread): publishing then fails; that is the end.
            if self.context.ok():
                raise

    def _wake(self) -> None:
        """Step up to the schedule, publish, and measure this wake (the timer callback)."""
        now = time.monotonic_ns()
        remaining = self._timer.time_until_next_call()
        sched = now if remaining is None else now + remaining - self._period_ns
        wakes = self._wakes
        wakes.wake(sched, now)
        taken = 0
        if not self._paused and self._failed is None:
            if self._asap:
                taken = self._run_until(now + LOCKSTEP_BUDGET_NS)
            else:
                k = self._schedule.due(now) - self._stepper.steps
                if k > self._cap:
                    self._slips += 1
                    taken = self._run(self._cap)
                    self._schedule.rebase(now, self._stepper.steps)
                elif k > 0:
                    taken = self._run(k)
            if taken and not self._lockstep:
                self._publish(now)
        if self._delay_ns and len(self._delay_line):
            for msg in self._delay_line.pop_due(now):
                self._js_pub.publish(msg)
        if now >= self._next_report_ns:
            self._next_report_ns += DIAGNOSTICS_PERIOD_NS * max(
                1, (now - self._next_report_ns) // DIAGNOSTICS_PERIOD_NS + 1)
            self._report(now)
        status = self._status
        if status is not None and status.due(now / 1e9):
            st = self._stepper
            status.show(now / 1e9, status_text(st.t, st.phi, st.energy(), self._rate.total(now),
                                               self._paused))
        wakes.done(sched, time.monotonic_ns(), taken)

    def _run(self, k: int) -> int:
        """Take ``k`` steps; in lockstep publish on every k_pub-th step. Return steps taken."""
        st = self._stepper
        step = st.step
        lockstep = self._lockstep
        k_pub = self._k_pub
        timeout = self._timeout_steps
        done = 0
        tau = self._torque
        try:
            while done < k:
                tau = self._command
                if tau != 0.0 and timeout and st.steps - self._command_step >= timeout:
                    self._command = tau = 0.0
                    self._cmd_timeouts += 1
                step(tau)
                done += 1
                if lockstep and st.steps % k_pub == 0:
                    self._torque = tau
                    self._publish(0)
        except PendulumError as exc:
            self._fail(f'{type(exc).__name__}: {exc}')
        self._torque = tau
        self._after_steps(done)
        return done

    def _run_until(self, deadline_ns: int) -> int:
        """Step as fast as possible until ``deadline_ns`` (lockstep), in chunks of k_pub."""
        done = 0
        k_pub = self._k_pub
        # Chunks of about LOCKSTEP_CHUNK steps between looks at the clock, each ending on a
        # publish step, so /clock ticks land on the k_pub grid.
        chunk = k_pub * max(1, LOCKSTEP_CHUNK // k_pub)
        while self._failed is None:
            done += self._run(chunk - self._stepper.steps % k_pub)
            if time.monotonic_ns() >= deadline_ns:
                break
        return done

    def _after_steps(self, done: int) -> None:
        self._steps_total += done
        self._rate.advance(done * self._h)
        st = self._stepper
        if not (math.isfinite(st.phi) and math.isfinite(st.dphi)):
            self._fail(f'non-finite state phi = {st.phi}, dphi = {st.dphi} at t = {st.t} s')

    def _fail(self, reason: str) -> None:
        if self._failed is None:
            self._failed = reason
            self.get_logger().error(f'simulation stopped: {reason}; call ~/reset to restart')

    # ------------------------------------------------------------------ publishing
    def _publish(self, now_ns: int) -> None:
        st = self._stepper
        if self._failed is not None:
            return
        stamp_ns = self._stamp_ns()
        sec, nanosec = divmod(stamp_ns, 1_000_000_000)
        if self._clock_pub is not None:
            self._clock_pub.publish(self._clock_bytes.pack(sec, nanosec))
        phi, dphi = st.phi, st.dphi
        if not self._sensor.ideal:
            phi, dphi = self._sensor.measure(phi, dphi)
        data = self._js_bytes.pack(sec, nanosec, phi, dphi, self._torque)
        if self._delay_ns:
            self._delay_line.push((now_ns or time.monotonic_ns()) + self._delay_ns, data)
        else:
            self._js_pub.publish(data)
        rec = self._recorder
        if rec is not None:
            self._record(self._js_topic, data, stamp_ns)
        if self._energy_pub is not None:
            e = self._float_bytes.pack(st.energy())
            self._energy_pub.publish(e)
            if rec is not None:
                self._record(self._energy_pub.topic_name, e, stamp_ns)
        if self._terms_pubs:
            p = st.params
            s = math.sin(0.5 * st.phi)
            absv = abs(st.dphi)
            dissipated = p.gamma * p.inertia * (absv if p.n == 0.0 else absv ** (p.n + 1.0))
            values = (0.5 * p.inertia * st.dphi * st.dphi, 2.0 * p.mgl * s * s, dissipated,
                      st.residual)
            pack = self._float_bytes.pack
            for pub, value in zip(self._terms_pubs, values, strict=True):
                pub.publish(pack(value))

    # ------------------------------------------------------------------ inputs
    def _on_command(self, msg: Float64) -> None:
        x = msg.data
        if not math.isfinite(x):
            self._cmd_rejected += 1
            if self._cmd_rejected == 1 or self._cmd_rejected % 1000 == 0:
                self.get_logger().warning(
                    f'rejected non-finite effort command {x} ({self._cmd_rejected} so far)')
            return
        limit = float(self._values['max_effort'])
        tau = min(max(x, -limit), limit)
        if tau != x:
            self._cmd_saturated += 1
        self._command = tau
        self._command_step = self._stepper.steps
        self._cmd_received += 1
        if self._recorder is not None and self._cmd_sub is not None:
            self._record(self._cmd_sub.topic_name, msg, self._stamp_ns())

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        v = self._values
        self._accumulate_guard_stats()
        self._stepper.reset(float(v['phi0']), float(v['dphi0']))
        now = time.monotonic_ns()
        self._schedule.rebase(now, 0)
        if self._wall_anchored:
            self._epoch_ns = time.time_ns()
        self._command = 0.0
        self._torque = 0.0
        self._delay_line.clear()
        was_failed, self._failed = self._failed, None
        response.success = True
        response.message = (f'reset to phi = {v["phi0"]} rad, dphi = {v["dphi0"]} rad/s at '
                             f't = 0' + (f' (was stopped: {was_failed})' if was_failed else ''))
        return response

    def _on_pause(self, request: SetBool.Request, response: SetBool.Response) -> Any:
        now = time.monotonic_ns()
        t = self._stepper.t
        if request.data == self._paused:
            response.success = True
            response.message = f'already {"paused" if self._paused else "running"} at t = {t} s'
            return response
        self._paused = bool(request.data)
        if self._paused:
            self._rate.pause(now)
        else:
            self._rate.resume(now)
            self._schedule.rebase(now, self._stepper.steps)
            if self._wall_anchored and self._h_ns_int:
                # Keep stamps near the wall clock and on the grid of h.
                lag = time.time_ns() - self._stamp_ns()
                self._epoch_ns += round(lag / self._h_ns_int) * self._h_ns_int
        response.success = True
        response.message = f'{"paused" if self._paused else "resumed"} at t = {t} s'
        return response

    # ------------------------------------------------------------------ parameters
    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        proposed = merged(self._values, ((p.name, p.value) for p in params))
        reason = check(proposed)
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
        if names & {'gamma', 'n'}:
            self._stepper.set_params(self._stepper.params.with_changes(
                gamma=float(v['gamma']), n=float(v['n'])))
        if 'real_time_factor' in names:
            rtf = float(v['real_time_factor'])
            self._asap = self._lockstep and rtf == 0.0
            self._schedule.rebase(time.monotonic_ns(), self._stepper.steps,
                                  rtf if rtf > 0.0 else 1.0)
            self._cap = max(1, math.ceil(CATCH_UP_SECONDS * max(rtf, 1.0) / self._h))
        if names & {'sensor.position_noise', 'sensor.velocity_noise', 'sensor.resolution'}:
            self._sensor.position_noise = float(v['sensor.position_noise'])
            self._sensor.velocity_noise = float(v['sensor.velocity_noise'])
            self._sensor.resolution = float(v['sensor.resolution'])
        if 'sensor.delay' in names:
            self._delay_ns = round(float(v['sensor.delay']) * 1e9)
            if not self._delay_ns:
                for msg in self._delay_line.pop_due(2**62):
                    self._js_pub.publish(msg)
        if 'command_timeout' in names:
            self._timeout_steps = round(float(v['command_timeout']) / self._h)
        if 'max_effort' in names:
            limit = float(v['max_effort'])
            self._command = min(max(self._command, -limit), limit)
        if self._recorder is not None:
            event = ParameterEvent(node=self.get_fully_qualified_name())
            event.stamp = _stamp(self._stamp_ns())
            event.changed_parameters = [p.to_parameter_msg() for p in params
                                        if p.name in names]
            self._record('/parameter_events', event, self._stamp_ns())

    # ------------------------------------------------------------------ diagnostics
    def _accumulate_guard_stats(self) -> None:
        for key, value in self._stepper.stats.as_dict().items():
            self._guard_before_reset[key] = self._guard_before_reset.get(key, 0) + int(value)

    def guard_stats(self) -> dict[str, int]:
        """Return the guard's counters over the whole run (across resets)."""
        out = dict(self._guard_before_reset)
        for key, value in self._stepper.stats.as_dict().items():
            out[key] = out.get(key, 0) + int(value)
        return out

    def _estimate_error(self) -> float:
        if self._failed is not None:
            return self._last_error
        try:
            err = self._stepper.local_error_estimate(self._command)
        except PendulumError:
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
        st = self._stepper
        values: dict[str, object] = {
            'sim_time': st.t,
            'steps': self._steps_total,
            'epoch_ns': self._epoch_ns,
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
            'energy': st.energy(),
            'energy_residual': st.residual,
            'local_error_estimate': err,
            'local_error_max': self._max_error,
            'commands_received': self._cmd_received,
            'commands_rejected_nonfinite': self._cmd_rejected,
            'commands_saturated': self._cmd_saturated,
            'command_timeouts': self._cmd_timeouts,
            'torque': self._torque,
        }
        if self._failed is not None:
            level, message = diag.ERROR, f'stopped: {self._failed}'
        elif self._paused:
            level, message = diag.OK, 'paused'
        else:
            level, message = diag.OK, 'running'
        name = f'{self.get_fully_qualified_name()}: simulation'
        array = diag.status_array(_stamp(self._stamp_ns()), name, self._joint, level, message,
                                  values)
        self._diag_pub.publish(array)
        if rec is not None:
            self._record(self._diag_pub.topic_name, array, self._stamp_ns())

    def summary(self) -> dict[str, object]:
        """Return the figures printed at shutdown."""
        now = time.monotonic_ns()
        lat = self._wakes.summary()
        st = self._stepper
        err = self._estimate_error()
        guard = self.guard_stats()
        return {
            'steps': self._steps_total,
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
            'energy-balance residual (J)': st.residual,
            'local error estimate (last / max)': f'{err:.3g} / {self._max_error:.3g}',
            'effort commands received / rejected': f'{self._cmd_received} / '
                                                   f'{self._cmd_rejected}',
            'stopped by': self._failed or '-',
        }

    def close(self) -> None:
        """Print the summary and close the recording (call once, before destroy_node)."""
        if self._status is not None:
            self._status.finish()
        print(summary_text(self.summary()), file=sys.stderr, flush=True)
        rec, self._recorder = self._recorder, None
        if rec is not None:
            try:
                rec.close()
            except Exception as exc:  # report, keep shutting down
                print(f'pendulum_node: closing the recording failed: {exc}', file=sys.stderr)
            if rec.error is not None:
                print(f'pendulum_node: recording error: {rec.error}', file=sys.stderr)
