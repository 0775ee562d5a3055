"""PD control with gravity compensation for the pendulum joint, and a settle detector; no ROS.

The joint is ``I φ'' = −m g l sin φ − γ I φ'|φ'|^(n−1) + τ`` (Quiroga & Ospina-Henao,
Eur. J. Phys. 38 (2017) 065005, eq 11 with an input torque τ). The law

    τ = m g l sin φ + Kp · wrap(φ_ref − φ) − Kd · φ',     clipped to [−τ_max, τ_max]

cancels the gravity torque with its first term (with Kp = Kd = 0 it holds any angle at rest, and
with the true m g l the only equilibrium of the closed loop is φ = φ_ref, so there is no static
error to integrate away), and leaves ``I e'' = −Kp e − (Kd + damping) e'`` for the error
e = φ − φ_ref: a damped oscillator for any Kp, Kd ≥ 0 (the textbook computed-torque / PD plus
gravity compensation scheme, e.g. Spong, Hutchinson & Vidyasagar, *Robot Modeling and Control*,
ch. 8). The angle error is wrapped to [−π, π] so that the controller turns the short way round.

Everything here is a pure function of its arguments: no clock, no state but the settle
detectors', which are driven by the simulated time stamps of the states they are given.

Two measures of "settled" are kept apart here, and the controller's log names both:
:class:`SettleDetector` is the controller's own rule (angle and velocity errors within
absolute tolerances, held for a time: a verdict it can give while running), and
:class:`StepSettling` follows the test bench's ``settling_time`` (python-control's
``step_info``: the time after which the angle stays within 2 % of the step around the target).
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from pendulum_sim.core.analysis import SETTLING_THRESHOLD, outside_settling_band

from .errors import ControllerError


def wrap_angle(x: float) -> float:
    """Return ``x`` wrapped to [−π, π] (the angle in that range equal to x modulo 2π)."""
    return math.remainder(x, math.tau)


def _finite(name: str, value: float) -> None:
    if not math.isfinite(value):
        raise ControllerError(f'{name} must be finite, got {value!r}')


def _nonnegative(name: str, value: float) -> None:
    _finite(name, value)
    if value < 0.0:
        raise ControllerError(f'{name} must be >= 0, got {value!r}')


def _positive(name: str, value: float) -> None:
    _finite(name, value)
    if value <= 0.0:
        raise ControllerError(f'{name} must be > 0, got {value!r}')


@dataclass(frozen=True)
class PDGains:
    """Gains, target and limit of the law; validated when built.

    Parameters
    ----------
    kp : float
        Proportional gain in N·m/rad (>= 0).
    kd : float
        Derivative gain in N·m·s/rad (>= 0).
    target : float
        Reference angle φ_ref in rad (finite; φ = 0 hangs straight down).
    mgl : float
        Gravity torque amplitude m g l in N·m (>= 0; 0 switches the compensation off).
    max_effort : float
        The torque is clipped to [−max_effort, max_effort] N·m (> 0).
    """

    kp: float = 4.0
    kd: float = 1.0
    target: float = 0.5
    mgl: float = 0.2 * 9.8 * 1.0
    max_effort: float = 5.0

    def __post_init__(self) -> None:
        _nonnegative('kp', self.kp)
        _nonnegative('kd', self.kd)
        _finite('target', self.target)
        _nonnegative('mgl', self.mgl)
        _positive('max_effort', self.max_effort)


def pd_torque(gains: PDGains, phi: float, dphi: float) -> float:
    """Return the clipped torque τ in N·m for the measured angle ``phi`` and rate ``dphi``.

    Raises
    ------
    ControllerError
        If ``phi`` or ``dphi`` is not finite (no torque is better than a NaN command).
    """
    if not (math.isfinite(phi) and math.isfinite(dphi)):
        raise ControllerError(f'state must be finite, got phi = {phi!r}, dphi = {dphi!r}')
    tau = (gains.mgl * math.sin(phi) + gains.kp * wrap_angle(gains.target - phi)
           - gains.kd * dphi)
    return min(max(tau, -gains.max_effort), gains.max_effort)


class SettleEvent(enum.Enum):
    """What a state told the settle detector."""

    NONE = 'none'
    SETTLED = 'settled'         # the first state at which the hold time has been met
    LEFT = 'left'               # after settling, far outside the band: detection starts over
    RESTARTED = 'restarted'     # simulated time went back (a reset): detection starts over


# After settling, a state this many times outside a tolerance (a reset, a push, a new target)
# starts the detection over; leaving the band by less (sensor noise at the band's edge) does
# not, so a noisy loop is not reported as settling again and again.
REARM_FACTOR = 10.0


@dataclass(frozen=True)
class SettleLimits:
    """When the loop counts as settled.

    Parameters
    ----------
    position : float
        |wrap(φ − φ_ref)| must stay below this, in rad (> 0).
    velocity : float
        |φ'| must stay below this, in rad/s (> 0).
    hold : float
        ... for this long in simulated time, in s (>= 0).
    """

    position: float = 0.01
    velocity: float = 0.01
    hold: float = 0.5

    def __post_init__(self) -> None:
        _positive('settle_position_tolerance', self.position)
        _positive('settle_velocity_tolerance', self.velocity)
        _nonnegative('settle_hold', self.hold)


class SettleDetector:
    """Tell, from states and their simulated time stamps, when the loop has settled.

    The loop has settled at stamp t when every state from stamp t − hold to t was within the
    limits (the stamps, not the wall clock, measure the hold, so the verdict is the same at any
    real-time factor). It is reported once; a state :data:`REARM_FACTOR` times outside a limit
    after that, or a stamp earlier than the previous one, starts the detection over.
    """

    def __init__(self, limits: SettleLimits) -> None:
        self.limits = limits
        self._hold_ns = round(limits.hold * 1e9)
        self._last_ns: int | None = None
        self.inside_since_ns: int | None = None
        self.settled_at_ns: int | None = None

    def update(self, stamp_ns: int, error: float, dphi: float) -> SettleEvent:
        """Take the state at ``stamp_ns`` with position error ``error`` and rate ``dphi``."""
        event = SettleEvent.NONE
        if self._last_ns is not None and stamp_ns < self._last_ns:
            self.inside_since_ns = None
            self.settled_at_ns = None
            event = SettleEvent.RESTARTED
        self._last_ns = stamp_ns
        lim = self.limits
        if self.settled_at_ns is not None and (abs(error) > REARM_FACTOR * lim.position
                                               or abs(dphi) > REARM_FACTOR * lim.velocity):
            self.inside_since_ns = None
            self.settled_at_ns = None
            return SettleEvent.LEFT
        if abs(error) < lim.position and abs(dphi) < lim.velocity:
            if self.inside_since_ns is None:
                self.inside_since_ns = stamp_ns
            if (self.settled_at_ns is None
                    and stamp_ns - self.inside_since_ns >= self._hold_ns):
                self.settled_at_ns = stamp_ns
                return SettleEvent.SETTLED
        else:
            self.inside_since_ns = None
        return event


class StepSettling:
    """Follow, state by state, the test bench's settling time of the step in progress.

    The step runs from the angle φ₀ of the first state (of the first after :meth:`restart`)
    to the target. A state is inside the settling band when
    ``|(φ − φ₀)/(φ_ref − φ₀) − 1| < 2 %``, the rule of
    :func:`pendulum_sim.core.analysis.outside_settling_band` applied to the same numbers, so
    ``since_ns``, the stamp of the first state of the current stretch inside the band, is the
    ``settling_time`` that ``run.metrics(target)`` gives for the run so far: the run's, if the
    angle stays in the band to its end.
    """

    def __init__(self) -> None:
        self.start: float | None = None
        self.target: float | None = None
        self.since_ns: int | None = None
        self._last_ns: int | None = None

    def restart(self) -> None:
        """Start a new step at the next state (after a reset or a change of target)."""
        self.start = None
        self.since_ns = None

    def update(self, stamp_ns: int, phi: float, target: float) -> None:
        """Take the state at ``stamp_ns`` with angle ``phi`` (rad) towards ``target`` (rad).

        A stamp earlier than the last one (simulated time went back: a reset) starts a new
        step at this state.
        """
        if self._last_ns is not None and stamp_ns < self._last_ns:
            self.restart()
        self._last_ns = stamp_ns
        if self.start is None:
            self.start = phi
        self.target = target
        if target == self.start:
            self.since_ns = None   # a step of zero size has no settling time
            return
        outside = outside_settling_band(np.array([phi - self.start]),
                                        np.array([target - self.start]))
        if bool(outside[0]):
            self.since_ns = None
        elif self.since_ns is None:
            self.since_ns = stamp_ns

    def text(self) -> str:
        """Return the settling time so far in words, naming its definition."""
        if self.start is None or self.target is None:
            return 'no step-response settling time: no state yet'
        step = f'the step from {self.start:.6g} rad to {self.target:g} rad'
        if self.target == self.start:
            return f'no step-response settling time: {step} has zero size'
        band = f'{100 * SETTLING_THRESHOLD:g} % of {step}'
        if self.since_ns is None:
            return f'no step-response settling time yet: the angle is not within {band}'
        return (f'step-response settling time t = {self.since_ns / 1e9:.3f} s so far (within '
                f'{band} since; the settling_time of python-control step_info, as '
                'pendulum_sim.testing measures it)')
