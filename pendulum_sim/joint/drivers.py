"""When the joint advances, per mode, without ROS: real time, free or paced lockstep, synchronous.

A driver is woken by the node's steady-clock timer (and, in synchronous mode, by each command),
advances the :class:`~pendulum_sim.joint.joint.SimulatedJoint` by its mode's rule and calls
``publish`` for each state to send out. Every wake does at most ``budget_ns`` of stepping, in
chunks of :data:`CHUNK_STEPS`, whatever the mode: a long control period is finished by the next
wakes, so services, parameters and signals are served in between.

- :class:`RealTimeDriver`: the steps due on an absolute schedule (``realtime.Schedule``), one
  publication per wake; more than :data:`CATCH_UP_SECONDS` of catching up, or more than a
  wake's work, slips the schedule (counted).
- :class:`LockstepDriver`: whole control periods, each published with ``/clock``: as fast as
  possible (``real_time_factor`` 0) or on the schedule.
- :class:`SyncDriver`: the periods the :class:`~pendulum_sim.joint.exchange.SyncExchange` allows.

Paused, every mode takes the periods of the step budget (:class:`~.exchange.Gate`) and nothing
else. The achieved real-time factor counts the wall time while the gate is open.

Live parameters are taken, not applied: :meth:`Driver.take_parameters` (the node's parameter
callback, after validation) only notes the values and the names that changed; the next wake, or
a reset, applies everything noted since the last one at once (:meth:`Driver.apply_parameters`),
before it steps. However many sets arrive, the joint and the mode are reconfigured at most once
a wake (``reconfigures`` <= ``wakes``), and a set takes effect from the step at which it
arrived (no step is taken between a set and the next wake's apply).
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping

from .exchange import Action, Gate, SyncExchange, Verdict
from .joint import SimulatedJoint
from .parameters import Value, joint_config
from .realtime import RateMeter, Schedule

WAKE_BUDGET_NS = 10_000_000
LOCKSTEP_PERIOD = 1e-3       # free and paced lockstep: the timer's period (s)
SYNC_WATCH_PERIOD = 0.02     # synchronous mode: how often to look for controllers, timeouts (s)
CHUNK_STEPS = 256
CATCH_UP_SECONDS = 0.25
REMIND_AFTER_NS = 20_000_000    # synchronous: /clock again after this long without an answer

# Publish the joint's state now (True: with /clock); return whether a state went out (False
# while a sensor delay fills or once the simulation stopped).
Publish = Callable[[bool], bool]
Log = Callable[[str, str], None]      # (level: 'info' | 'warning' | 'error', text)
Clock = Callable[[], int]             # steady clock, ns


class Driver:
    """What every mode shares: the joint, the gate, the rate meter, the work bound.

    Parameters
    ----------
    joint : SimulatedJoint
        The joint to advance.
    gate : Gate
        Pause and step budget.
    publish : callable
        ``publish(with_clock)``: send the joint's current state; return True if one went out.
    log : callable
        ``log(level, text)``.
    now_ns : int
        Steady-clock time at start.
    clock : callable
        The steady clock (``time.monotonic_ns``; a test passes its own).
    """

    def __init__(self, joint: SimulatedJoint, gate: Gate, publish: Publish, log: Log,
                 now_ns: int, clock: Clock = time.monotonic_ns) -> None:
        self.joint = joint
        self.gate = gate
        self.publish = publish
        self.log = log
        self.clock = clock
        self.rate = RateMeter(now_ns)
        if not gate.open:
            self.rate.pause(now_ns)
        self.slips = 0
        self.parameter_sets = 0     # live parameter sets taken
        self.reconfigures = 0       # times they were applied (at most once a wake)
        self._values: Mapping[str, Value] | None = None
        self._changed: set[str] = set()
        self._failure_logged = False

    # ------------------------------------------------------------------ shared
    def wake(self, now_ns: int, deadline_ns: int) -> int:
        """Advance as the mode says, within ``deadline_ns``; return the steps taken."""
        raise NotImplementedError

    def command(self, value: float, stamp_ns: int | None, now_ns: int) -> int | None:
        """Take a decoded command; return the stamp to record it at, or None if dropped."""
        joint = self.joint
        if not joint.accepts(value):
            return None
        joint.command(value)
        return joint.stamp_ns()

    def pause(self, paused: bool, now_ns: int) -> bool:
        """Pause or resume (``~/pause``), ending any step budget; return False if nothing
        changed."""
        changed = self.gate.pause(paused)
        if changed:
            self.gate_changed(now_ns)
        return changed

    def step(self, periods: int, now_ns: int) -> None:
        """Add control periods to the budget while paused (raise StepError if it cannot)."""
        self.gate.step(periods)
        self.gate_changed(now_ns)

    def gate_changed(self, now_ns: int) -> None:
        """Follow a change of pause or budget: count wall time only while the gate is open."""
        if self.gate.open:
            self.rate.resume(now_ns)
        else:
            self.rate.pause(now_ns)

    def take_parameters(self, values: Mapping[str, Value], names: set[str]) -> None:
        """Note a validated set of live parameters (``names`` changed in ``values``, the
        node's current values) for the next :meth:`apply_parameters`; cheap."""
        self.parameter_sets += 1
        self._values = values
        self._changed |= names

    def apply_parameters(self, now_ns: int) -> bool:
        """Apply every set noted since the last call, at once; return False if none was."""
        values, names = self._values, self._changed
        if values is None or not names:
            return False
        self._changed = set()
        self.reconfigures += 1
        self.reconfigure(values, names, now_ns)
        return True

    def reconfigure(self, values: Mapping[str, Value], names: set[str], now_ns: int) -> None:
        """Apply live parameters (``names`` changed in ``values``) to the joint and the mode."""
        self.joint.reconfigure(joint_config(values, self.joint.config.epoch_ns))

    def after_reset(self, now_ns: int) -> None:
        """Publish the reset state at the reset stamp (no /clock: time did not move)."""
        self._failure_logged = False
        self.publish(False)

    def steps_taken(self, done: int) -> None:
        """Count ``done`` steps in the rate; log a failure of the simulation once."""
        self.rate.advance(done * self.joint.config.h)
        self.check_failed()

    def counters(self) -> Mapping[str, int]:
        """Return the joint's command counters (the live view copies them with each state)."""
        counters: Mapping[str, int] = vars(self.joint.counters)
        return counters

    def check_failed(self) -> None:
        """Log, once, that the simulation stopped (stepping or publishing found it)."""
        failed = self.joint.failed
        if failed is not None and not self._failure_logged:
            self._failure_logged = True
            self.log('error', f'simulation stopped: {failed}; call ~/reset to restart')

    def advance_period(self, deadline_ns: int) -> tuple[int, bool]:
        """Advance towards the end of the current control period within ``deadline_ns``;
        return (steps taken, whether the period ended)."""
        joint = self.joint
        k = joint.config.period_steps
        done = 0
        clock = self.clock
        while joint.failed is None:
            left = k - joint.steps % k
            n = joint.advance(min(left, CHUNK_STEPS))
            done += n
            if n == left:
                return done, True
            if n == 0 or clock() >= deadline_ns:
                break
        return done, False

    def run_periods(self, count: int, deadline_ns: int) -> int:
        """Take up to ``count`` whole periods (through the gate), publishing each with /clock."""
        done = 0
        periods = 0
        gate = self.gate
        while periods < count and gate.open and self.joint.failed is None:
            n, ended = self.advance_period(deadline_ns)
            done += n
            if not ended:
                break
            periods += 1
            gate.period_done()
            self.publish(True)
            if self.clock() >= deadline_ns:
                break
        self.steps_taken(done)
        return done


class RealTimeDriver(Driver):
    """Real time (or lockstep on a schedule): the steps due at the wall time, bounded."""

    def __init__(self, joint: SimulatedJoint, gate: Gate, publish: Publish, log: Log,
                 now_ns: int, rtf: float, lockstep: bool,
                 clock: Clock = time.monotonic_ns) -> None:
        super().__init__(joint, gate, publish, log, now_ns, clock)
        self.lockstep = lockstep
        self.schedule = Schedule(joint.config.h, 1.0, now_ns)
        self.set_rtf(rtf, now_ns)
        self._behind_logged_ns: int | None = None

    def set_rtf(self, rtf: float, now_ns: int) -> None:
        """Use a new real-time factor from now (0 in lockstep: as fast as possible)."""
        self.rtf = rtf
        self.asap = self.lockstep and rtf == 0.0
        self.schedule.rebase(now_ns, self.joint.steps, rtf if rtf > 0.0 else 1.0)
        self.cap = max(1, math.ceil(CATCH_UP_SECONDS * max(rtf, 1.0) / self.joint.config.h))

    def reconfigure(self, values: Mapping[str, Value], names: set[str], now_ns: int) -> None:
        super().reconfigure(values, names, now_ns)
        if 'real_time_factor' in names:
            self.set_rtf(float(values['real_time_factor']), now_ns)

    def rebase(self, now_ns: int) -> None:
        """Restart the schedule now (a reset, a resume)."""
        self.schedule.rebase(now_ns, self.joint.steps)

    def gate_changed(self, now_ns: int) -> None:
        super().gate_changed(now_ns)
        if self.gate.open and not self.gate.paused:
            self.rebase(now_ns)

    def after_reset(self, now_ns: int) -> None:
        self.rebase(now_ns)
        super().after_reset(now_ns)

    def wake(self, now_ns: int, deadline_ns: int) -> int:
        joint = self.joint
        gate = self.gate
        self.apply_parameters(now_ns)
        if joint.failed is not None:
            return 0
        if gate.paused:
            taken = self.run_periods(gate.budget, deadline_ns) if gate.budget else 0
            if not gate.open:
                self.rate.pause(self.clock())
            return taken
        if self.asap:
            return self.run_periods(1 << 62, deadline_ns)
        k = self.schedule.due(now_ns) - joint.steps
        capped = k > self.cap
        if capped:
            k = self.cap
        taken = 0
        if self.lockstep:
            periods = k // joint.config.period_steps
            if periods:
                taken = self.run_periods(periods, deadline_ns)
            k = periods * joint.config.period_steps
        elif k > 0:
            taken = self._run_due(k, deadline_ns)
        if capped or taken < k:
            self.slips += 1
            self._behind(now_ns)
            self.rebase(self.clock())
        return taken

    def _run_due(self, k: int, deadline_ns: int) -> int:
        joint = self.joint
        done = 0
        while done < k and joint.failed is None:
            n = joint.advance(min(CHUNK_STEPS, k - done))
            done += n
            if n == 0 or (done < k and self.clock() >= deadline_ns):
                break
        self.steps_taken(done)
        if done:
            self.publish(False)
        return done

    def _behind(self, now_ns: int) -> None:
        last = self._behind_logged_ns
        if last is None or now_ns - last >= 5_000_000_000:
            self._behind_logged_ns = now_ns
            self.log('warning', f'cannot keep real_time_factor {self.rtf:g}: achieved '
                     f'{self.rate.total(now_ns):.3g} so far; the schedule slips ({self.slips} '
                     'slips so far)')


class SyncDriver(Driver):
    """Synchronous lockstep: publish, wait for the answer, advance one period, publish.

    Parameters
    ----------
    exchange : SyncExchange
        The rules of which command answers which state.
    ready : callable
        ``ready()`` -> (a controller can take part, matched subscribers on the states).
    waiting_text : str
        What the log says while no controller is connected.
    """

    def __init__(self, joint: SimulatedJoint, exchange: SyncExchange, publish: Publish,
                 log: Log, now_ns: int, ready: Callable[[], tuple[bool, int]],
                 waiting_text: str, clock: Clock = time.monotonic_ns,
                 remind: Callable[[int, bool], None] | None = None,
                 remind_state: bool = False) -> None:
        super().__init__(joint, exchange.gate, publish, log, now_ns, clock)
        self.exchange = exchange
        self.remind = remind
        self.remind_state = remind_state
        self.ready = ready
        self._waiting_text = waiting_text
        self._waiting_logged = False
        self._started_logged = False

    def command(self, value: float, stamp_ns: int | None, now_ns: int) -> int | None:
        if not self.joint.accepts(value):
            return None
        ex = self.exchange
        verdict = ex.answer(value, stamp_ns)
        if verdict is not Verdict.ANSWER:
            return None
        aw = ex.awaiting
        assert aw is not None
        stamp = aw.stamp_ns
        self.wake(now_ns, now_ns + WAKE_BUDGET_NS)
        return stamp

    def pause(self, paused: bool, now_ns: int) -> bool:
        changed = self.exchange.pause(paused)
        if changed:
            self.gate_changed(now_ns)
            self.wake(now_ns, now_ns + WAKE_BUDGET_NS)
        return changed

    def step(self, periods: int, now_ns: int) -> None:
        self.exchange.step(periods)
        self.gate_changed(now_ns)
        self.wake(now_ns, now_ns + WAKE_BUDGET_NS)

    def reconfigure(self, values: Mapping[str, Value], names: set[str], now_ns: int) -> None:
        super().reconfigure(values, names, now_ns)
        self.exchange.timeout_ns = round(float(values['sync_timeout']) * 1e9)
        self.exchange.action = str(values['sync_timeout_action'])
        self.exchange.reconfigured()

    def counters(self) -> Mapping[str, int]:
        """Return the joint's command counters and the exchange's (``sync_*`` keys' values)."""
        return {**vars(self.joint.counters), **self.exchange.stats}

    def after_reset(self, now_ns: int) -> None:
        self._failure_logged = False
        if self.exchange.reset():
            self._publish_awaited(now_ns, clock=False, reset=True)

    def _publish_awaited(self, now_ns: int, clock: bool, reset: bool = False) -> None:
        joint = self.joint
        if self.publish(clock):
            self.exchange.published(joint.steps, joint.stamp_ns(), now_ns, reset)
        else:   # nothing to answer: the next period goes on with the last command
            self.exchange.unseen()

    def wake(self, now_ns: int, deadline_ns: int) -> int:
        joint = self.joint
        ex = self.exchange
        self.apply_parameters(now_ns)
        if joint.failed is not None:
            return 0
        ready, subscribers = self.ready()
        action = ex.poll(now_ns, ready, subscribers)
        if self.gate.open:
            self.rate.resume(now_ns)   # a controller connecting may have lifted a stop
        taken = 0
        if action is Action.WAIT:
            if not ready and not ex.started and not self._waiting_logged:
                self._waiting_logged = True
                self.log('info', self._waiting_text)
            aw = ex.awaiting
            if (self.remind is not None and aw is not None and not aw.answered
                    and not ex.stepping and self.gate.open
                    and now_ns - aw.since_ns >= REMIND_AFTER_NS):
                # Best-effort subscribers matched only just now (TopicBasedSystem's states,
                # ros2_control_node's /clock) may have missed them: /clock again, and the
                # state until a first answer when every command input is stamped (a copy
                # answered by an unstamped controller would count as the next state's answer).
                self.remind(aw.stamp_ns, self.remind_state and ex.stats['answered'] == 0)
        elif action is Action.PUBLISH:
            if not self._started_logged:
                self._started_logged = True
                self.log('info', 'synchronous: a controller is connected; stepping')
            self._publish_awaited(now_ns, clock=True)
        elif action is Action.REPUBLISH:
            self.log('info', f'synchronous: publishing the state at t = '
                     f'{joint.time:.9g} s again (it awaits its answer)')
            self._publish_awaited(now_ns, clock=False)
        elif action is Action.STOPPED:
            self.log('error', f'sync_timeout: no command answered the state at t = '
                     f'{joint.time:.9g} s within {ex.timeout_ns / 1e9:.3g} s; paused '
                     '(sync_timeout_action: stop; ~/step, ~/pause false or a controller '
                     'connecting goes on)')
            self.rate.pause(now_ns)
        else:
            if action is Action.HOLD:
                n = ex.stats['timeouts']
                if n == 1 or n % 100 == 0:
                    self.log('warning', f'sync_timeout: no command answered the state at '
                             f't = {joint.time:.9g} s within {ex.timeout_ns / 1e9:.3g} s; '
                             f'holding the last command ({n} timeouts so far)')
            if not ex.stepping:
                value = ex.take()
                if value is not None:
                    joint.command(value)
            taken, ended = self.advance_period(deadline_ns)
            self.steps_taken(taken)
            if ended:
                ex.period_done()
                if joint.failed is None:
                    self._publish_awaited(self.clock(), clock=True)
            if not self.gate.open:
                self.rate.pause(self.clock())
        return taken


def wake_period(values: Mapping[str, Value]) -> tuple[float, bool]:
    """Return the node's timer period (s) for the mode of ``values``, and whether its wakes
    keep a schedule (real time and paced lockstep; not free lockstep or synchronous mode,
    which step as fast as they may), against which the wake statistics are measured."""
    if values['synchronous']:
        return SYNC_WATCH_PERIOD, False
    if values['lockstep']:
        return LOCKSTEP_PERIOD, float(values['real_time_factor']) != 0.0
    return 1.0 / float(values['publish_rate']), True


def make_driver(values: Mapping[str, Value], joint: SimulatedJoint, gate: Gate,
                publish: Publish, log: Log, now_ns: int, ready: Callable[[], tuple[bool, int]],
                waiting_text: str, remind: Callable[[int, bool], None] | None = None,
                remind_state: bool = False) -> Driver:
    """Return the driver of the mode of ``values``: a :class:`SyncDriver` with its exchange
    in synchronous mode (``ready``, ``waiting_text``, ``remind`` and ``remind_state`` are
    its), a :class:`RealTimeDriver` otherwise."""
    if values['synchronous']:
        exchange = SyncExchange(gate, round(float(values['sync_timeout']) * 1e9),
                                str(values['sync_timeout_action']))
        return SyncDriver(joint, exchange, publish, log, now_ns, ready, waiting_text,
                          remind=remind, remind_state=remind_state)
    return RealTimeDriver(joint, gate, publish, log, now_ns, float(values['real_time_factor']),
                          bool(values['lockstep']))
