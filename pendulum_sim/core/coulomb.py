"""Friction at rest: Coulomb sticking, and the creep of near-Coulomb laws (0 < n < 1).

At rest the net force per unit inertia is F = a_in − ω0² sin φ. Under Coulomb friction (n = 0)
the pendulum sticks while |F| <= γ (:func:`from_rest`). A law γ φ'|φ'|^(n−1) with 0 < n < 1 has
no static friction, but where it dominates, it holds the pendulum at the creep speed where
damping balances the force, γ v_c^n = |F| (eq 16 with φ'' = 0):

    v_c = (|F| / γ)^(1/n),

reached from near rest within the relaxation time 1/D'(v_c) = v_c / (n |F|) (the inverse slope
of the law there). Where that time is far below the step, the velocity is slaved to the angle
(a singular perturbation: Hairer and Wanner, *Solving ODEs II*, VI.1, the reduced problem) and
:func:`creep` integrates the reduced equation φ' = sgn(F) v_c(φ) instead of the stiff one, whose
slope γ n |φ'|^(n−1) is unbounded at rest and beyond any explicit step.
"""
from __future__ import annotations

import math

import numpy as np

from .explicit import StepFn
from .law import compile_damping
from .problem import Problem

CREEP_RELAX = 0.01
"""A step is taken on the creep where the time to settle onto it is at most this part of h."""


def from_rest(prob: Problem, branch: StepFn, p: float, h: float, ain: float,
              v: float = 0.0) -> tuple[float, float, float]:
    """Take a step of h from rest (or within round-off of it) under Coulomb friction.

    The pendulum sticks while |a_in − ω0² sin φ| <= γ; otherwise it breaks away on the branch
    of the law in the direction of the force (``branch``: the method's branch step), and stops
    again if that step reversed.
    """
    force = ain - prob.w2 * math.sin(p)
    if abs(force) <= prob.gamma:
        return p, 0.0, 0.0
    sign = 1.0 if force > 0.0 else -1.0
    p1, v1, w, _ = branch(p, v, h, ain, prob.w2, prob.gamma, sign)
    if v1 * sign < 0.0:
        return p, 0.0, 0.0  # the break-away reversed within the step: it stops again
    return p1, v1, w


def creep_speed(prob: Problem, force: float) -> float:
    """Return the signed creep velocity sgn(F) (|F|/γ)^(1/n) under the force ``F``."""
    ratio = abs(force) / prob.gamma
    return math.copysign(ratio ** (1.0 / prob.n), force) if ratio > 0.0 else 0.0


_NODES, _WEIGHTS = (x.tolist() for x in np.polynomial.legendre.leggauss(16))


def settle_shift(n: float, v: float, vc: float, force: float) -> float:
    """Return ∫ (φ' − v_c) dt as φ' settles from ``v`` onto the creep speed ``v_c`` (rad).

    With F fixed over the transient, dφ'/dt = F − γ φ'|φ'|^(n−1) and γ v_c^n = |F|, so with
    u = φ'/v_c the integral is (v_c² / F) ∫ from u₀ to 1 of (u − 1) / (1 − u|u|^(n−1)) du
    (the integrand tends to −1/n at u = 1); Gauss-Legendre quadrature on each side of u = 0,
    where the law has its kink.
    """
    u0 = v / vc
    law = compile_damping(n)  # u|u|^(n−1): the law at γ = 1 (``law.py``)

    def part(a: float, b: float) -> float:
        mid, half = 0.5 * (a + b), 0.5 * (b - a)
        total = 0.0
        for x, wt in zip(_NODES, _WEIGHTS, strict=True):
            u = mid + half * x
            den = 1.0 - law(u, 1.0, 1.0)
            total += wt * ((u - 1.0) / den if den != 0.0 else -1.0 / n)
        return half * total

    integral = part(u0, 0.0) + part(0.0, 1.0) if u0 < 0.0 else part(u0, 1.0)
    return vc * vc / force * integral


def creep(prob: Problem, p: float, v: float, h: float,
          ain: float) -> tuple[float, float, float] | None:
    """Advance a near-Coulomb creep by h; return (φ₁, φ'₁, w), or None where it does not creep.

    It creeps for 0 < n < 1 and γ > 0 where the creep speed is below 1 rad/s (the damping
    dominates the force: |F| < γ) and the pendulum settles onto it from φ' within CREEP_RELAX h:
    the relaxation time v_c / (n |F|) plus the time to bring φ' to v_c, at most |φ' − v_c| over
    the least deceleration towards it (|F| against the motion, |γ |φ'|^n − |F|| with it).
    The reduced equation φ' = sgn(F) (|F(φ)|/γ)^(1/n) is then taken by one RK4 step; the
    damping balances the force on the creep, so its work per unit inertia is ∫ F φ' dt (the
    same quadrature). Where h v_c is below half an ulp of φ, φ stays and so does v_c.
    """
    n, g, w2 = prob.n, prob.gamma, prob.w2
    if not (0.0 < n < 1.0 and g > 0.0):
        return None
    force = ain - w2 * math.sin(p)
    a = abs(force)
    if a >= g:
        return None
    if a == 0.0:
        return (p, 0.0, 0.0) if v == 0.0 else None  # balanced at rest: no creep speed
    vc = creep_speed(prob, force)
    settle = abs(vc) / (n * a)
    if v != 0.0 and v != vc:
        toward = a if v * force < 0.0 else abs(abs(prob.damping(v)) - a)
        settle += abs(v - vc) / toward if toward > 0.0 else math.inf
    if not settle <= CREEP_RELAX * h:
        return None
    w0 = 0.0
    if v != vc:
        # The lag (or lead) the settling leaves behind, ∫ (φ' − v_c) dt over the transient,
        # and the damping work in it beyond the creep's: F · shift + ½ (φ'² − v_c²).
        shift = settle_shift(n, v, vc, force)
        p += shift
        w0 = force * shift + 0.5 * (v * v - vc * vc)
    if p + h * vc == p:
        return p, vc, w0 + h * vc * force

    def rate(x: float) -> tuple[float, float]:
        f = ain - w2 * math.sin(x)
        return creep_speed(prob, f), f

    k2, f2 = rate(p + 0.5 * h * vc)
    k3, f3 = rate(p + 0.5 * h * k2)
    k4, f4 = rate(p + h * k3)
    p1 = p + h / 6.0 * (vc + 2.0 * (k2 + k3) + k4)
    w = w0 + h / 6.0 * (vc * force + 2.0 * (k2 * f2 + k3 * f3) + k4 * f4)
    v1, _ = rate(p1)
    return p1, v1, w


__all__ = ['CREEP_RELAX', 'creep', 'creep_speed', 'from_rest', 'settle_shift']
