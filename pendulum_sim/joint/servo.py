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

The loop is sampled: the torque is computed from the state at the start of each step of h and
held over it. On the linearised loop (gravity cancelled, no damping, no saturation; the joint
stepped exactly, as RK4 steps ``I φ'' = τ`` with τ held) one step maps (φ, φ', z) by
``φ ← φ + h φ' + h² τ / (2 I)``, ``φ' ← φ' + h τ / I``, ``z ← z + h e``. With
``a = h velocity_p / I``, ``b = h² velocity_i / I`` and ``p = h position_p`` its characteristic
polynomial is

- velocity interface: ``λ² − (2 − a) λ + (1 − a + b)``;
- position interface: ``λ³ + (a p + 2 a − 6)/2 λ² + (b p + 2 b − 4 a + 6)/2 λ
  − ((a − b)(p − 2) + 2)/2``.

:func:`loop_refusal` accepts gains whose polynomial has every root inside the unit circle
(Jury's test), a root at 1 being allowed where a gain is 0 (a state not fed back: no
correction, no growth); beyond that the sampled loop grows without bound, whatever the
continuous loop would do (position_p >= 2/h, velocity_p >= 2 I/h + h velocity_i/2, or
velocity_i >= velocity_p/h, among others). The limit it states for a gain is the largest value
that keeps the loop stable with the other gains as set (bisection on the same test).

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


UNITS = {'position_p': '1/s', 'velocity_p': 'N m s/rad', 'velocity_i': 'N m/rad'}


def _deflate(c: list[float]) -> list[float]:
    """Return the monic polynomial ``c`` (descending) divided by (λ − 1), a root of it."""
    out = [c[0]]
    for x in c[1:-1]:
        out.append(x + out[-1])
    return out


def _jury(c: list[float]) -> bool:
    """Return True if the monic polynomial ``c`` (descending, degree <= 3) has every root
    strictly inside the unit circle (Jury's conditions)."""
    if len(c) == 1:
        return True
    if len(c) == 2:
        return abs(c[1]) < 1.0
    if len(c) == 3:
        _, c1, c0 = c
        return abs(c0) < 1.0 and 1.0 + c1 + c0 > 0.0 and 1.0 - c1 + c0 > 0.0
    _, a2, a1, a0 = c
    return (1.0 + a2 + a1 + a0 > 0.0 and 1.0 - a2 + a1 - a0 > 0.0 and abs(a0) < 1.0
            and abs(a0 * a0 - 1.0) > abs(a0 * a2 - a1))


def characteristic(gains: ServoGains, inertia: float, h: float,
                   interface: str) -> list[float]:
    """Return the characteristic polynomial of the sampled servo loop (monic, descending)."""
    a = h * gains.velocity_p / inertia
    b = h * h * gains.velocity_i / inertia
    if interface == 'velocity':
        return [1.0, a - 2.0, 1.0 - a + b]
    p = h * gains.position_p
    return [1.0, (a * p + 2.0 * a - 6.0) / 2.0, (b * p + 2.0 * b - 4.0 * a + 6.0) / 2.0,
            -((a - b) * (p - 2.0) + 2.0) / 2.0]


def _roots_at_one(gains: ServoGains, inertia: float, h: float, interface: str) -> int:
    """Return how many roots the loop's polynomial has at exactly 1 (gains of 0), from its
    value and derivatives at 1 (sums of products of gains >= 0: zero only when exactly so)."""
    a = h * gains.velocity_p / inertia
    b = h * h * gains.velocity_i / inertia
    at_one: tuple[float, ...]
    if interface == 'velocity':
        at_one = (b, a)                  # P(1), P'(1) when P(1) = 0
    else:
        p = h * gains.position_p
        at_one = (b * p, a * p + b * (p / 2.0 + 1.0), a * (p + 2.0) / 2.0)
    count = 0
    for value in at_one:
        if value != 0.0:
            break
        count += 1
    return count


def loop_stable(gains: ServoGains, inertia: float, h: float, interface: str) -> bool:
    """Return True if the sampled servo loop does not grow (see the module's loop)."""
    c = characteristic(gains, inertia, h, interface)
    for _ in range(_roots_at_one(gains, inertia, h, interface)):
        c = _deflate(c)   # a state not fed back (a gain of 0): no correction, no growth
    return _jury(c)


GRID: tuple[float, ...] = (0.0, *(1e-9 * 1.5 ** k for k in range(225)))   # to ~1e30


def gain_range(name: str, gains: ServoGains, inertia: float, h: float,
               interface: str) -> tuple[float, float] | None:
    """Return the range (low, high) of the ``name`` gain keeping the sampled loop stable with
    the other gains as set, nearest to its value; None if no value does.

    Found on a geometric grid (ratio 1.5) and refined at both ends by bisection; ``low`` is 0
    when 0 is stable, ``high`` inf when no grid value is too large.
    """
    def stable(value: float) -> bool:
        values = {'position_p': gains.position_p, 'velocity_p': gains.velocity_p,
                  'velocity_i': gains.velocity_i, name: value}
        trial = ServoGains(values['position_p'], values['velocity_p'], values['velocity_i'],
                           gains.gravity_feedforward)
        return loop_stable(trial, inertia, h, interface)

    flags = [stable(v) for v in GRID]
    if not any(flags):
        return None
    value = getattr(gains, name)
    here = min(range(len(GRID)), key=lambda k: (not flags[k], abs(GRID[k] - value)))
    first = last = here
    while first > 0 and flags[first - 1]:
        first -= 1
    while last + 1 < len(GRID) and flags[last + 1]:
        last += 1

    def edge(good: float, bad: float) -> float:
        for _ in range(200):
            mid = 0.5 * (good + bad)
            if mid in (good, bad):
                break
            if stable(mid):
                good = mid
            else:
                bad = mid
        return good

    low = 0.0 if first == 0 else edge(GRID[first], GRID[first - 1])
    high = math.inf if last + 1 == len(GRID) else edge(GRID[last], GRID[last + 1])
    return low, high


def loop_refusal(gains: ServoGains, inertia: float, h: float, interface: str) -> str | None:
    """Return why the servo gains make the sampled loop grow without bound, or None.

    Names the first gain (velocity_p, velocity_i, position_p) outside a stable range with the
    other gains as set, its value and the limit it crosses.
    """
    if interface not in ('velocity', 'position') or loop_stable(gains, inertia, h, interface):
        return None
    names = ('velocity_p', 'velocity_i') if interface == 'velocity' else (
        'velocity_p', 'velocity_i', 'position_p')
    where = (f'the {interface} servo unstable at h = {h:g} s (its loop is sampled every step, '
             f'inertia {inertia:g} kg m^2)')
    for name in names:
        bounds = gain_range(name, gains, inertia, h, interface)
        value = getattr(gains, name)
        unit = UNITS[name]
        if bounds is None:
            continue
        if value >= bounds[1]:
            return (f'servo.{name} {value:g} {unit} makes {where}: it must be below '
                    f'{bounds[1]:.6g} {unit} with the other gains as set')
        if value <= bounds[0]:
            return (f'servo.{name} {value:g} {unit} makes {where}: it must be above '
                    f'{bounds[0]:.6g} {unit} with the other gains as set')
    position = f'position_p {gains.position_p:g} 1/s, ' if interface == 'position' else ''
    return (f'the servo gains {position}velocity_p {gains.velocity_p:g} N m s/rad, velocity_i '
            f'{gains.velocity_i:g} N m/rad make {where} together')


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
