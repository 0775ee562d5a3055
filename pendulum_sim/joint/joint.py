"""The simulated joint between two publications, without ROS.

Everything that happens to the pendulum between two messages lives here, in simulated time
(steps of h), so the same inputs give the same outputs whatever the wall clock or the DDS
transport does:

- the command path: non-finite commands refused, limits and saturation, a command delay of
  ``round(command_delay / h)`` steps, a hold of ``command_timeout`` after which the command
  returns to its safe value, and the drive of the velocity and position interfaces (a cascaded
  servo with gravity feed-forward, ``servo.py``);
- the sensor path: a delay of ``round(sensor.delay / h)`` steps, seeded Gaussian noise, encoder
  quantisation;
- the effort offset: a constant torque ``effort_offset`` added to the actuator's torque in
  every step (a drive's or torque sensor's bias, as a driven fit finds it: the model's
  ``τ_off``), commanded or not; like the disturbance below it is not in the effort published,
  and its work counts as input in the energy balance;
- the disturbance: torque pulses added to the actuator's torque, each acting in the steps
  ``k`` with ``round(start / h) <= k < round(start / h) + round(duration / h)`` (step ``k``
  runs from ``k h`` to ``(k + 1) h`` of simulated time since the start, which goes on through
  resets); where pulses overlap their torques add. The pulses are ``disturbance.pulses``
  (``'torque start duration; ...'``, :func:`parse_pulses`) and the single pulse of
  ``disturbance.torque``, ``disturbance.start`` and ``disturbance.duration``. It is an
  external torque: the effort published is the actuator's torque alone (what a joint's torque
  sensor reports), while the energy balance counts the pulses' work as input work (the core
  integrates the sum);
- the stamp grid: step ``k`` is stamped ``epoch + k h``; the step count never goes back, not even
  at a reset, so simulated time (and ``/clock``) is monotonic;
- the values to publish: the measured joint state and the energy terms of the true state.

:class:`SimulatedJoint` is built once from a frozen :class:`JointConfig`; live parameter changes
build a new config and hand it to :meth:`SimulatedJoint.reconfigure`. The ROS node
(``pendulum_node.py``) declares parameters, ticks the joint and publishes what it returns.
Nothing here imports rclpy.
"""
from __future__ import annotations

import functools
import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from pendulum_sim.core import (
    PendulumError,
    PendulumParams,
    Stepper,
    dissipated_power,
    kinetic_energy,
    potential_energy,
)
from pendulum_sim.core.model import speed_limit

from .errors import JointError
from .sensors import SensorModel
from .servo import Servo, ServoGains, loop_refusal

INTERFACES = ('effort', 'velocity', 'position')
# Steps of delay are kept in memory (one entry per step), so a delay is bounded.
MAX_DELAY_STEPS = 1_000_000
NS = 1_000_000_000


def steps_of(name: str, seconds: float, h: float) -> int:
    """Return a duration in whole steps of ``h``: ``round(seconds / h)``.

    The one timing rule of the joint: every duration given in seconds (delays, timeouts, the
    control period) becomes a whole number of steps this way, so it is exact in simulated time.
    """
    if not (math.isfinite(seconds) and seconds >= 0.0):
        raise JointError(f'{name} must be a finite number of seconds >= 0, got {seconds}')
    return round(seconds / h)


def timeout_steps(seconds: float, h: float) -> int:
    """Return the command timeout in steps: 0 only for 0 s (hold for ever), else at least 1."""
    steps = steps_of('command_timeout', seconds, h)
    return max(1, steps) if seconds > 0.0 else 0


MAX_PULSES = 1000


class Pulse(NamedTuple):
    """A disturbance torque pulse: ``torque`` N m in the steps ``start <= k < start + steps``."""

    torque: float
    start_step: int
    steps: int


def parse_pulses(text: str, h: float) -> tuple[Pulse, ...]:
    """Return the pulses of ``disturbance.pulses``: ``'torque start duration; ...'``.

    Each pulse is three numbers, the torque (N m, finite) and its start and duration (s of
    simulated time, finite and >= 0, rounded to whole steps of ``h`` by :func:`steps_of`),
    separated by spaces or commas; pulses are separated by ``;``. ``''`` is no pulse.

    Raises
    ------
    JointError
        If a pulse is not three such numbers, or there are more than :data:`MAX_PULSES`.
    """
    parts = [p for p in text.split(';') if p.strip()]
    if len(parts) > MAX_PULSES:
        raise JointError(f'disturbance.pulses holds {len(parts)} pulses; at most {MAX_PULSES}')
    pulses = []
    for i, part in enumerate(parts, start=1):
        fields = part.replace(',', ' ').split()
        try:
            torque, start, duration = (float(f) for f in fields)
        except ValueError:
            raise JointError(f"disturbance.pulses: pulse {i} must be three numbers 'torque "
                             f"start duration' (N m, s, s), got {part.strip()!r}") from None
        if not math.isfinite(torque):
            raise JointError(f'disturbance.pulses: pulse {i} torque must be a finite number of '
                             f'N m, got {torque}')
        pulses.append(Pulse(torque, steps_of(f'disturbance.pulses: pulse {i} start', start, h),
                            steps_of(f'disturbance.pulses: pulse {i} duration', duration, h)))
    return tuple(pulses)


def pulses_text(pulses: list[tuple[float, float, float]]) -> str:
    """Return ``disturbance.pulses`` for ``(torque, start, duration)`` triples (N m, s, s)."""
    return '; '.join(' '.join(repr(float(v)) for v in p) for p in pulses)


@dataclass(frozen=True)
class JointConfig:
    """Everything the joint needs, fixed for its lifetime (live changes make a new one)."""

    params: PendulumParams
    h: float
    phi0: float = 0.0
    dphi0: float = 0.0
    method: str = 'rk4'
    guard: bool = True
    period_steps: int = 1
    epoch_ns: int = 0
    max_effort: float = math.inf
    timeout_steps: int = 0
    command_delay_steps: int = 0
    sensor_delay_steps: int = 0
    sensor_seed: int = 0
    position_noise: float = 0.0
    velocity_noise: float = 0.0
    resolution: float = 0.0
    command_interface: str = 'effort'
    servo: ServoGains = field(default_factory=ServoGains)
    max_velocity: float = math.inf
    position_min: float = -math.inf
    position_max: float = math.inf
    disturbance_torque: float = 0.0
    disturbance_start_step: int = 0
    disturbance_steps: int = 0
    effort_offset: float = 0.0
    pulses: tuple[Pulse, ...] = ()

    def __post_init__(self) -> None:
        if not math.isfinite(self.effort_offset):
            raise JointError(f'effort_offset must be a finite number of N m, got '
                             f'{self.effort_offset}')
        if not math.isfinite(self.disturbance_torque):
            raise JointError(f'disturbance.torque must be a finite number of N m, got '
                             f'{self.disturbance_torque}')
        if self.command_interface not in INTERFACES:
            raise JointError(f"command_interface must be one of {', '.join(INTERFACES)}, "
                             f"got '{self.command_interface}'")
        for name in ('command_delay_steps', 'sensor_delay_steps'):
            steps = getattr(self, name)
            if steps > MAX_DELAY_STEPS:
                raise JointError(f'{name[:-6]} is {steps} steps of h = {self.h:g} s; at most '
                                 f'{MAX_DELAY_STEPS} steps are kept')
        if self.command_interface != 'effort':
            reason = loop_refusal(self.servo, self.params.inertia, self.h,
                                  self.command_interface)
            if reason is not None:
                raise JointError(reason)
        if not self.position_min < self.position_max:
            raise JointError(f'position_min must be < position_max, got {self.position_min} '
                             f'and {self.position_max}')

    @classmethod
    def from_values(cls, values: Mapping[str, object], params: PendulumParams,
                    epoch_ns: int = 0) -> JointConfig:
        """Build the config from a node's parameter values (names as the node declares them)."""
        def num(name: str) -> float:
            return float(values[name])  # type: ignore[arg-type]

        h = num('h')
        rate = num('publish_rate')
        lo = num('position_min') if 'position_min' in values else -math.inf
        hi = num('position_max') if 'position_max' in values else math.inf
        return cls(
            params=params, h=h, phi0=num('phi0'), dphi0=num('dphi0'),
            method=str(values['integrator']), guard=bool(values['guard']),
            period_steps=max(1, steps_of('1/publish_rate', 1.0 / rate, h)),
            epoch_ns=epoch_ns, max_effort=num('max_effort'),
            timeout_steps=timeout_steps(num('command_timeout'), h),
            command_delay_steps=steps_of('command_delay', num('command_delay'), h),
            sensor_delay_steps=steps_of('sensor.delay', num('sensor.delay'), h),
            sensor_seed=int(values['sensor.seed']),  # type: ignore[call-overload]
            position_noise=num('sensor.position_noise'),
            velocity_noise=num('sensor.velocity_noise'),
            resolution=num('sensor.resolution'),
            command_interface=str(values.get('command_interface', 'effort')),
            servo=ServoGains(num('servo.position_p'), num('servo.velocity_p'),
                             num('servo.velocity_i'), bool(values['servo.gravity_feedforward'])
                             ) if 'servo.position_p' in values else ServoGains(),
            max_velocity=num('max_velocity') if 'max_velocity' in values else math.inf,
            position_min=lo, position_max=hi,
            disturbance_torque=num('disturbance.torque') if 'disturbance.torque' in values
            else 0.0,
            disturbance_start_step=steps_of('disturbance.start', num('disturbance.start'), h)
            if 'disturbance.start' in values else 0,
            disturbance_steps=steps_of('disturbance.duration', num('disturbance.duration'), h)
            if 'disturbance.duration' in values else 0,
            effort_offset=num('effort_offset') if 'effort_offset' in values else 0.0,
            pulses=parse_pulses(str(values['disturbance.pulses']), h)
            if 'disturbance.pulses' in values else (),
        )

    @property
    def has_position_limits(self) -> bool:
        """Return True when the position command is limited."""
        return math.isfinite(self.position_min) or math.isfinite(self.position_max)

    @functools.cached_property
    def all_pulses(self) -> tuple[Pulse, ...]:
        """Return the pulses that act: ``disturbance.torque``'s, then ``disturbance.pulses``."""
        single = Pulse(self.disturbance_torque, self.disturbance_start_step,
                       self.disturbance_steps)
        return tuple(p for p in (single, *self.pulses) if p.torque != 0.0 and p.steps > 0)

    @property
    def has_disturbance(self) -> bool:
        """Return True when a disturbance pulse acts in some step (a torque for >= 1 step)."""
        return bool(self.all_pulses)

    def disturbance_at(self, step: int) -> float:
        """Return the disturbance torque in step ``step`` (from ``step h`` to ``(step + 1) h``).

        The one rule of the pulses: each pulse's torque in the steps ``k`` with
        ``start_step <= k < start_step + steps``, summed over the pulses (0 where none acts).
        """
        total = 0.0
        for pulse in self.all_pulses:
            if pulse.start_step <= step < pulse.start_step + pulse.steps:
                total += pulse.torque
        return total


class Sample(NamedTuple):
    """One measurement to publish: stamp (ns), angle, velocity, torque applied."""

    stamp_ns: int
    position: float
    velocity: float
    effort: float


class EnergyTerms(NamedTuple):
    """Energy of the true state, J (eq 23), and the power dissipated by damping, W."""

    energy: float
    kinetic: float
    potential: float
    dissipated_power: float
    residual: float


@dataclass
class CommandCounters:
    """What happened to commands: received, refused, limited, timed out."""

    received: int = 0
    rejected_nonfinite: int = 0
    saturated: int = 0
    limited: int = 0
    timeouts: int = 0


def energy_terms(params: PendulumParams, phi: float, dphi: float,
                 residual: float = 0.0) -> EnergyTerms:
    """Return the energy terms of a state; raise JointError if one is not a finite number."""
    try:
        with np.errstate(over='ignore', invalid='ignore'):
            kin = float(kinetic_energy(params, dphi))
            pot = float(potential_energy(params, phi))
            diss = float(dissipated_power(params, dphi))
    except (OverflowError, ZeroDivisionError, ValueError) as exc:
        raise JointError(f'the state phi = {phi}, dphi = {dphi} has no finite energy '
                         f'({exc})') from None
    terms = EnergyTerms(kin + pot, kin, pot, diss, residual)
    for name, value in zip(EnergyTerms._fields, terms, strict=True):
        if not math.isfinite(value):
            raise JointError(f'the state phi = {phi}, dphi = {dphi} gives a non-finite {name} '
                             f'({value}) with gamma = {params.gamma}, n = {params.n}')
    return terms


def speed_bound(config: JointConfig) -> float:
    """Return the speed no torque may drive the joint past (rad/s): the joint's one rule.

    ``max_velocity``, or the core's state bound for the damping
    (:func:`pendulum_sim.core.model.speed_limit`) where that is lower. :class:`SimulatedJoint`
    limits its torque by it (``_velocity_limited``), and the batched lockstep
    (:mod:`pendulum_sim.joint.lockstep`) hands a joint that could reach it within a period to a
    SimulatedJoint for that period.
    """
    p = config.params
    return min(config.max_velocity, speed_limit(p.gamma, p.n))


def whole_ns(h: float) -> int:
    """Return the step ``h`` in whole nanoseconds, or 0 when it is not a whole number of them."""
    h_ns = h * NS
    return round(h_ns) if abs(h_ns - round(h_ns)) < 1e-6 else 0


def stamp_ns(epoch_ns: int, step: int, h: float) -> int:
    """Return the stamp of step ``step`` (ns): ``epoch + step h``, the joint's stamp grid.

    An exact integer grid where ``h`` is a whole number of nanoseconds, else ``step h``
    rounded to the nanosecond.
    """
    h_int = whole_ns(h)
    if h_int:
        return epoch_ns + step * h_int
    return epoch_ns + round(step * h * NS)


def check_config(config: JointConfig) -> None:
    """Raise JointError if the joint cannot run ``config``: its start state must be publishable.

    Cheap enough for every parameter change (the core validates the rest when the joint is
    built).
    """
    energy_terms(config.params, config.phi0, config.dphi0)


class SimulatedJoint:
    """The pendulum as a joint: commands in, measurements out, all timing in steps of h.

    Parameters
    ----------
    config : JointConfig
        The joint's configuration; :meth:`reconfigure` replaces it (live parameters).
    """

    def __init__(self, config: JointConfig) -> None:
        check_config(config)
        self._config = config
        try:
            self._stepper = Stepper(config.params, config.phi0, config.dphi0, config.h,
                                    config.method, guard=config.guard)
        except PendulumError as exc:
            raise JointError(str(exc)) from None
        self._sensor = SensorModel(config.sensor_seed, config.position_noise,
                                   config.velocity_noise, config.resolution)
        self.counters = CommandCounters()
        self._base_steps = 0       # steps taken before the last reset
        self._target = self._initial_target()  # the command held, in the interface's unit
        self._target_step = 0      # the step at which it took effect
        self._pending: deque[tuple[int, float]] = deque()   # (effective step, command)
        self._history: deque[tuple[int, float, float, float]] = deque()
        self._torque = 0.0
        self._failed: str | None = None
        self._guard_before_reset: dict[str, int] = {}
        self._commanded = False
        self._servo = Servo(config.servo, config.params, config.max_effort,
                            config.max_velocity, config.h)
        self._epoch_ns = config.epoch_ns
        self._vmax = speed_bound(config)
        self._inertia_per_h = config.params.inertia / config.h

    # ------------------------------------------------------------------ state
    @property
    def config(self) -> JointConfig:
        """Return the joint's configuration."""
        return self._config

    @property
    def stepper(self) -> Stepper:
        """Return the core's integrator (read its state; step through the joint)."""
        return self._stepper

    @property
    def steps(self) -> int:
        """Return the steps taken since the start (never decreases, not even at a reset)."""
        return self._base_steps + self._stepper.steps

    @property
    def torque(self) -> float:
        """Return the actuator's torque in the last step, N m (without the disturbance)."""
        return self._torque

    @property
    def target(self) -> float:
        """Return the command held (N m, rad/s or rad by the interface)."""
        return self._target

    @property
    def failed(self) -> str | None:
        """Return why the simulation stopped, or None while it runs."""
        return self._failed

    @property
    def time(self) -> float:
        """Return the simulated time since the start, s (goes on through resets)."""
        return self.steps * self._config.h

    def stamp_ns(self, step: int | None = None) -> int:
        """Return the stamp of step ``step`` (default: now): ``epoch + step h`` in ns."""
        k = self._base_steps + self._stepper.steps if step is None else step
        return stamp_ns(self._epoch_ns, k, self._config.h)

    def energy(self) -> float:
        """Return the energy of the true state now, J (finite, or JointError)."""
        e = self._stepper.energy()
        if not math.isfinite(e):
            st = self._stepper
            raise JointError(f'the state phi = {st.phi}, dphi = {st.dphi} gives a non-finite '
                             f'energy ({e})')
        return e

    def terms(self) -> EnergyTerms:
        """Return the energy terms of the true state now (finite, or JointError)."""
        st = self._stepper
        return energy_terms(st.params, st.phi, st.dphi, st.residual)

    def guard_stats(self) -> dict[str, int]:
        """Return the guard's counters over the whole run (across resets)."""
        out = dict(self._guard_before_reset)
        for key, value in self._stepper.stats.as_dict().items():
            out[key] = out.get(key, 0) + int(value)
        return out

    # ------------------------------------------------------------------ commands
    def command(self, value: float) -> bool:
        """Take a command in the active interface's unit; return False if it was refused.

        Non-finite values are refused and counted. Effort is saturated at ±max_effort, velocity
        at ±max_velocity, position to [position_min, position_max] (each counted). The command
        takes effect ``command_delay_steps`` from now and holds for ``timeout_steps``.
        """
        c = self._config
        if not self.accepts(value):
            return False
        kind = c.command_interface
        if kind == 'effort':
            limited = min(max(value, -c.max_effort), c.max_effort)
            if limited != value:
                self.counters.saturated += 1
        else:
            lo, hi = ((-c.max_velocity, c.max_velocity) if kind == 'velocity'
                      else (c.position_min, c.position_max))
            limited = min(max(value, lo), hi)
            if limited != value:
                self.counters.limited += 1
        self.counters.received += 1
        if c.command_delay_steps:
            self._pending.append((self.steps + c.command_delay_steps, limited))
        else:
            self._set_target(limited, self.steps)
        return True

    def accepts(self, value: float) -> bool:
        """Return True for a usable command value; count a refused (non-finite) one."""
        if math.isfinite(value):
            return True
        self.counters.rejected_nonfinite += 1
        return False

    def _set_target(self, value: float, step: int) -> None:
        self._target = value
        self._target_step = step
        self._commanded = True

    def _initial_target(self) -> float:
        """Return the command held before any arrives: the initial state (φ0, φ'0) or no torque.

        The same values the URDF gives as ``initial_value`` (what topic_based_ros2_control
        commands before a controller does), so the joint starts where it is, at the speed it has.
        """
        c = self._config
        return {'effort': 0.0, 'velocity': c.dphi0, 'position': c.phi0}[c.command_interface]

    def _safe_target(self) -> float:
        """Return what a timed-out command returns to: no torque, no speed, or the same place."""
        return self._target if self._config.command_interface == 'position' else 0.0

    def _torque_for(self, phi: float, dphi: float) -> float:
        c = self._config
        if c.command_interface == 'effort':
            tau = min(max(self._target, -c.max_effort), c.max_effort)
        else:
            tau = self._servo.torque(c.command_interface, self._target, phi, dphi)
        return self._velocity_limited(tau, dphi)

    def _velocity_limited(self, tau: float, dphi: float) -> float:
        """Return ``tau``, limited (counted) so that it drives the joint no faster than the
        speed bound (:func:`speed_bound`): 0 at or past it, and never more than one step of it
        takes to reach it."""
        vmax = self._vmax
        speed = abs(dphi)
        pushing = tau * dphi > 0.0
        if pushing and speed >= vmax:
            self.counters.limited += 1
            return 0.0
        room = vmax - speed if pushing or dphi == 0.0 else vmax + speed
        most = room * self._inertia_per_h
        if abs(tau) > most:
            self.counters.limited += 1
            return math.copysign(most, tau)
        return tau

    # ------------------------------------------------------------------ stepping
    def advance(self, k: int) -> int:
        """Take ``k`` steps (fewer if the simulation fails); return the number taken."""
        if self._failed is not None or k <= 0:
            return 0
        c = self._config
        st = self._stepper
        step = st.step
        timeout = c.timeout_steps
        pending = self._pending
        history = self._history if c.sensor_delay_steps else None
        effort_mode = c.command_interface == 'effort'
        base = self._base_steps
        disturbed = c.has_disturbance
        disturbance_at = c.disturbance_at
        offset = c.effort_offset
        done = 0
        tau = self._torque
        try:
            while done < k:
                if pending or (timeout and self._commanded):
                    now = base + st.steps
                    while pending and pending[0][0] <= now:
                        self._set_target(pending.popleft()[1], now)
                    if timeout and self._commanded and now - self._target_step >= timeout:
                        self._commanded = False
                        self._target = self._safe_target()
                        self.counters.timeouts += 1
                if effort_mode:
                    tau = self._target
                    if tau != 0.0:   # the velocity limit matters only under torque
                        tau = self._velocity_limited(tau, st.dphi)
                else:
                    tau = self._torque_for(st.phi, st.dphi)
                # The one place torque meets the pendulum: the actuator's, the offset's and
                # the disturbance's (the last two on the pendulum, not in the effort).
                if disturbed:
                    step(tau + offset + disturbance_at(base + st.steps))
                elif offset:
                    step(tau + offset)
                else:
                    step(tau)
                done += 1
                if history is not None:
                    history.append((base + st.steps, st.phi, st.dphi, tau))
                    if len(history) > c.sensor_delay_steps + 1:
                        history.popleft()
        except PendulumError as exc:
            self.fail(f'{type(exc).__name__}: {exc}')
        self._torque = tau
        if not (math.isfinite(st.phi) and math.isfinite(st.dphi)):
            self.fail(f'non-finite state phi = {st.phi}, dphi = {st.dphi} at t = {st.t} s')
        return done

    def fail(self, reason: str) -> None:
        """Stop the simulation with ``reason`` (kept until a reset)."""
        if self._failed is None:
            self._failed = reason

    def sample(self) -> Sample | None:
        """Return the measurement to publish now, or None while a sensor delay is filling.

        With a sensor delay of d steps the measurement is the state of d steps ago, stamped with
        the time it was taken (a real delayed sensor's stamp), measured through noise and
        quantisation now.
        """
        d = self._config.sensor_delay_steps
        st = self._stepper
        now = self._base_steps + st.steps
        if d == 0:
            step, phi, dphi, tau = now, st.phi, st.dphi, self._torque
        else:
            want = now - d
            hist = self._history
            # The history holds consecutive steps, the oldest d + 1 steps back at most; it
            # fills again after a reset or a change of the delay.
            if not hist or hist[0][0] > want or want - hist[0][0] >= len(hist):
                return None
            step, phi, dphi, tau = hist[want - hist[0][0]]
        if not self._sensor.ideal:
            phi, dphi = self._sensor.measure(phi, dphi)
        return Sample(self.stamp_ns(step), phi, dphi, tau)

    # ------------------------------------------------------------------ control
    def reset(self) -> str | None:
        """Go back to the initial state; return why it was stopped before, if it was.

        The step count (and so the stamps) goes on: simulated time never goes back.
        """
        c = self._config
        for key, value in self._stepper.stats.as_dict().items():
            self._guard_before_reset[key] = self._guard_before_reset.get(key, 0) + int(value)
        self._base_steps = self.steps
        self._stepper.reset(c.phi0, c.dphi0)
        self._target = self._initial_target()
        self._commanded = False
        self._torque = 0.0
        self._pending.clear()
        self._history.clear()
        self._servo.reset()
        was, self._failed = self._failed, None
        return was

    def check_params(self, params: PendulumParams) -> None:
        """Raise JointError if the current state would have no finite energy under ``params``."""
        st = self._stepper
        try:
            energy_terms(params, st.phi, st.dphi)
        except JointError as exc:
            raise JointError(f'{exc} (the current state; ~/reset first)') from None

    def reconfigure(self, config: JointConfig) -> None:
        """Apply a new config (live parameters): the state, the step count and stamps are kept.

        Damping (γ, n) applies from the next step; a lower ``max_effort`` re-saturates the held
        effort command; sensor settings apply to the next measurement; delays apply to what
        is sampled or commanded from now on.
        """
        check_config(config)
        old = self._config
        fixed = ('h', 'method', 'guard', 'period_steps', 'epoch_ns', 'command_interface',
                 'sensor_seed')
        for name in fixed:
            if getattr(old, name) != getattr(config, name):
                raise JointError(f'{name} is fixed for the joint lifetime')
        if config.params != old.params:
            self._stepper.set_params(config.params)
        if config.sensor_delay_steps != old.sensor_delay_steps:
            self._history.clear()   # its steps were kept for the old delay
        self._config = config
        self._vmax = speed_bound(config)
        servo = self._servo
        servo.gains = config.servo
        servo.max_effort = config.max_effort
        servo.max_velocity = config.max_velocity
        servo.set_params(config.params)
        if config.command_interface == 'effort':
            self._target = min(max(self._target, -config.max_effort), config.max_effort)
        s = self._sensor
        s.position_noise = config.position_noise
        s.velocity_noise = config.velocity_noise
        s.resolution = config.resolution
