"""The joint's drive: how velocity and position commands become a torque, without ROS.

A cascaded servo as motor drives build it (an outer position loop giving the speed demand of an
inner velocity loop), with gravity feed-forward from the joint's own model. Every step of h,
from the true state (φ, φ') and the command held, x:

- speed demand: ``v* = x`` (velocity interface) or
  ``v* = clamp(position_p (x − φ), ±max_velocity)`` (position interface);
- velocity loop: ``e = v* − φ'``, ``u = m g l sin φ + velocity_p e + velocity_i z``;
- torque applied: ``τ = clamp(u, ±max_effort)``;
- anti-windup by conditional integration: ``z ← z + h e`` unless the torque is saturated and
  ``e`` would drive it further into saturation (``u ≠ τ`` and ``e (u − τ) > 0``).

The feed-forward ``m g l sin φ`` cancels gravity in ``I φ'' = −m g l sin φ − γ I φ'|φ'|^(n−1) + τ``
(Quiroga & Ospina-Henao, Eur. J. Phys. 38 (2017) 065005, eq 11 with an input torque), so the
velocity loop sees ``I e' = −velocity_p e − velocity_i z + (damping)``: a second-order loop
with natural frequency ``sqrt(velocity_i / I)`` and damping ratio
``velocity_p / (2 sqrt(velocity_i I))`` whose integral removes the damping torque (and dry
friction) in the steady state. At rest on target ``v* = 0`` forces ``φ = x``: the position is
reached exactly, whatever gravity, with the integral holding what the feed-forward does not
cancel.

The defaults (position_p 8 1/s, velocity_p 4 N m s/rad, velocity_i 20 N m/rad) are tuned for the
default body (I = 0.2002 kg m²: velocity loop ζ ≈ 1.0 at ≈ 10 rad/s; position loop 8 1/s, below
it, so a step has no overshoot). For another inertia, scale velocity_p and velocity_i with I.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from pendulum_sim.core import PendulumParams

from .errors import JointError


@dataclass(frozen=True)
class ServoGains:
    """Gains of the joint's cascaded servo (see the module's law).

    Parameters
    ----------
    position_p : float
        Position loop gain, 1/s: the speed demanded per rad of position error.
    velocity_p : float
        Velocity loop proportional gain, N m s/rad.
    velocity_i : float
        Velocity loop integral gain, N m/rad (torque per rad of accumulated speed error).
    gravity_feedforward : bool
        Add ``m g l sin φ`` (the joint's own gravity torque) to the servo torque.
    """

    position_p: float = 8.0
    velocity_p: float = 4.0
    velocity_i: float = 20.0
    gravity_feedforward: bool = True

    def __post_init__(self) -> None:
        for name in ('position_p', 'velocity_p', 'velocity_i'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise JointError(f'servo.{name} must be a finite number >= 0, got {value}')


class Servo:
    """The servo's state (the integral of the speed error) and its law.

    Parameters
    ----------
    gains : ServoGains
        The gains (replace with :attr:`gains`; the integral is kept).
    params : PendulumParams
        The body whose gravity torque is fed forward.
    max_effort : float
        Torque limit, N m.
    max_velocity : float
        Limit of the speed demand of the position loop, rad/s.
    h : float
        The step, s: the integral grows by ``h e`` a step.
    """

    def __init__(self, gains: ServoGains, params: PendulumParams, max_effort: float,
                 max_velocity: float, h: float) -> None:
        self.gains = gains
        self.max_effort = max_effort
        self.max_velocity = max_velocity
        self.h = h
        self.integral = 0.0
        self.set_params(params)

    def set_params(self, params: PendulumParams) -> None:
        """Use the gravity torque of ``params`` (live physics)."""
        self._mgl = params.m * params.g * params.l

    def reset(self) -> None:
        """Forget the integral (a reset of the joint)."""
        self.integral = 0.0

    def demand(self, interface: str, target: float, phi: float) -> float:
        """Return the speed demand v* of a velocity or position command, rad/s."""
        if interface == 'velocity':
            return target
        vmax = self.max_velocity
        return min(max(self.gains.position_p * (target - phi), -vmax), vmax)

    def torque(self, interface: str, target: float, phi: float, dphi: float) -> float:
        """Return the torque of one step and update the integral (anti-windup)."""
        g = self.gains
        e = self.demand(interface, target, phi) - dphi
        u = g.velocity_p * e + g.velocity_i * self.integral
        if g.gravity_feedforward:
            u += self._mgl * math.sin(phi)
        tau = min(max(u, -self.max_effort), self.max_effort)
        if u == tau or e * (u - tau) < 0.0:
            self.integral += self.h * e
        return tau
