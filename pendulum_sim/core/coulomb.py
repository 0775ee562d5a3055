"""Friction at rest: Coulomb sticking, and the creep of near-Coulomb laws (0 < n < 1).

At rest the net force per unit inertia is F = a_in − ω0² sin φ. Under Coulomb friction (n = 0,
or a friction c_f = f/I beside the power law) the pendulum sticks while |F| <= c, the Coulomb
level c = c_f (+ γ where n = 0) of ``model.coulomb_level``: :func:`rest_direction`, the rest
rule every family takes (the explicit steps by :func:`rest_step`, the adaptive cover
``embedded.cover`` and the implicit steps ``implicit.slide`` directly). While it moves in the
direction s the friction is the constant −s c_f: a step on one side of a reversal is the power
law's step under the input a_in − s c_f (:func:`moving_input`), and the friction's work per
unit inertia is c_f |Δφ| = s c_f (φ₁ − φ₀) (:func:`friction_work`); every family takes these
two.

A law γ φ'|φ'|^(n−1) with 0 < n < 1 has
no static friction, but where it dominates, it holds the pendulum at the creep speed where
damping balances the force, γ v_c^n = |F| (eq 16 with φ'' = 0):

    v_c = (|F| / γ)^(1/n),

reached from near rest within the relaxation time 1/D'(v_c) = v_c / (n |F|) (the inverse slope
of the law there). Where that time is far below the step, the velocity is slaved to the angle
(a singular perturbation: Hairer and Wanner, *Solving ODEs II*, VI.1, the reduced problem) and
:func:`creep` integrates the reduced equation φ' = sgn(F) v_c(φ) instead of the stiff one, whose
slope γ n |φ'|^(n−1) is unbounded at rest and beyond any explicit step. Beside a friction c_f
the creep is that of the force under the moving friction, F − s c_f in the direction s of the
motion (γ v_c^n + c_f = |F|), where the friction does not hold the pendulum (|F| > c_f).

Each decision is one function written to compile (floats and the generated steps and laws in, a
tuple out, no exception on its path: :func:`rest_direction`, :func:`rest_step`,
:func:`creep_state`, :func:`settle_shift`,
:func:`friction_step`, :func:`stuck`): the Stepper's careful path calls them in Python
(``split.py``, ``engine.py``), and the compiled sweep's careful step calls the very same functions
compiled by numba (``careful.py``). :func:`creep` and :func:`creep_speed` are their
forms on a :class:`~pendulum_sim.core.problem.Problem`.
"""
from __future__ import annotations

import math
import types
from math import copysign
from typing import Any

import numpy as np

from .law import VECTOR_ENV, compile_laws
from .model import coulomb_level
from .problem import Problem

CREEP_RELAX = 0.025
"""A step is taken on the creep where the time to settle onto it is at most this part of h.

The settle time counts the relaxation time τ = v_c / (n |F|) once more than the transient
needs (the least deceleration brings φ' to v_c in at most that bound, then φ' − v_c decays as
e^(−t/τ)); with it at most h/40, the transient left at the end of the step is below
e^(−39) ≈ 1e-17 of |φ' − v_c| at its start: below round-off. What the reduced equation leaves
out beyond that is the slow correction τ dv_c/dt to φ' (Hairer and Wanner, VI.1), some 1e-14
rad/s on the creeps of ``bench/bench_worst_law.py`` that h/100 sent to the guard's substeps
(n = 0.3 at γ = 100, n = 0.1 at γ = 10: 50-60 substeps a step before)."""

StepResult = tuple[float, float, float]


def moving_input(ain: Any, sign: Any, cf: Any) -> Any:
    """Return the input a_in − s c_f a motion in the direction ``sign`` feels (c_f = ``cf``).

    ``ain`` itself, to the bit, without friction (c_f = 0): copysign(0, s) + 0.0 is +0.0 for
    either sign, and a_in − (+0.0) is a_in, a zero's sign kept. Without a branch, so that the
    numpy sweep takes the same code over arrays (:data:`moving_inputs`).
    """
    return ain - (copysign(cf, sign) + 0.0)


moving_inputs = types.FunctionType(moving_input.__code__, dict(VECTOR_ENV), 'moving_inputs')
"""``moving_inputs(ain, sign, cf)``: :func:`moving_input`'s code over numpy arrays (numpy's
copysign), the moving input of the numpy sweep's pendulums."""


def friction_work(cf: float, sign: float, p0: float, p1: float) -> float:
    """Return the friction's work per unit inertia over a motion from φ₀ to φ₁ in one direction.

    c_f |φ₁ − φ₀| as s c_f (φ₁ − φ₀), s = ``sign``: the quadrature of the step itself
    (φ₁ − φ₀ = h Σ bᵢ φ'ᵢ), so the energy balance closes to the method's accuracy.
    """
    return math.copysign(cf, sign) * (p1 - p0)


def rest_direction(p: float, ain: float, w2: float, gamma: float, n: float,
                   cf: float = 0.0) -> float:
    """Return where the pendulum at rest at φ = ``p`` goes: 0.0 (it sticks) or ±1.0.

    The rest rule, the one decision every family takes at rest: it sticks while the force
    F = a_in − ω0² sin φ stays within the Coulomb level, |F| <= c (``model.coulomb_level`` of
    γ, n and the friction ``cf`` = c_f), and otherwise breaks away in the direction of F.
    """
    force = ain - w2 * math.sin(p)
    if abs(force) <= coulomb_level(gamma, n, cf):
        return 0.0
    return 1.0 if force > 0.0 else -1.0


def rest_step(branch: Any, p: float, v: float, h: float, ain: float, w2: float, gamma: float,
              n: float, cf: float = 0.0) -> StepResult:
    """Take a step of h from rest (or within round-off of it, φ' = ``v``) under Coulomb friction.

    The pendulum sticks while |a_in − ω0² sin φ| <= c (:func:`rest_direction`: the Coulomb
    level of γ, n and the friction ``cf`` = c_f); otherwise it breaks away on the branch of
    the law in the direction of the force (``branch(φ, φ', h, a_in, ω0², γ, s, n)``: the
    method's branch step, ``explicit.step_source_with_n``) under :func:`moving_input`, and
    stops again if that step reversed. Returns (φ₁, φ'₁, w), w with the friction's work
    (:func:`friction_work`).
    """
    sign = rest_direction(p, ain, w2, gamma, n, cf)
    if sign == 0.0:
        return p, 0.0, 0.0
    p1, v1, w, _ = branch(p, v, h, moving_input(ain, sign, cf), w2, gamma, sign, n)
    if v1 * sign < 0.0:
        return p, 0.0, 0.0  # the break-away reversed within the step: it stops again
    if cf != 0.0:
        w += friction_work(cf, sign, p, p1)
    return p1, v1, w


TINY = 2.2250738585072014e-308
"""The smallest normal double (``sys.float_info.min``): a creep that moves φ by less in a step
does no work the step counts (:func:`creep_state`)."""


def stuck(coulomb: bool, v: float, v1: float) -> bool:
    """Return True where a step from φ' = ``v`` came to rest under Coulomb friction (a stick)."""
    return coulomb and v1 == 0.0 and v != 0.0


def creep_rate(force: float, gamma: float, n: float) -> float:
    """Return the signed creep velocity sgn(F) (|F|/γ)^(1/n) under the force ``F``."""
    ratio = abs(force) / gamma
    return math.copysign(ratio ** (1.0 / n), force) if ratio > 0.0 else 0.0


def creep_speed(prob: Problem, force: float) -> float:
    """Return :func:`creep_rate` for the pendulum ``prob``."""
    return creep_rate(force, prob.gamma, prob.n)


_NODES = tuple(float(x) for x in np.polynomial.legendre.leggauss(16)[0])
_WEIGHTS = tuple(float(x) for x in np.polynomial.legendre.leggauss(16)[1])


def _quadrature(laws: Any, n: float, a: float, b: float) -> float:
    """Return ∫ from a to b of (u − 1) / (1 − u|u|^(n−1)) du by Gauss-Legendre (16 nodes)."""
    mid, half = 0.5 * (a + b), 0.5 * (b - a)
    total = 0.0
    for k in range(len(_NODES)):
        u = mid + half * _NODES[k]
        den = 1.0 - laws(u, 1.0, 1.0, n)[0]  # u|u|^(n−1): the law at γ = 1 (``law.py``)
        total += _WEIGHTS[k] * ((u - 1.0) / den if den != 0.0 else -1.0 / n)
    return half * total


def settle_shift(laws: Any, n: float, gamma: float, v: float, vc: float, force: float) -> float:
    """Return ∫ (φ' − v_c) dt as φ' settles from ``v`` onto the creep speed ``v_c`` (rad).

    With F fixed over the transient, dφ'/dt = F − γ φ'|φ'|^(n−1) and γ v_c^n = |F|, so with
    u = φ'/v_c the integral is (v_c² / F) ∫ from u₀ to 1 of (u − 1) / (1 − u|u|^(n−1)) du
    (the integrand tends to −1/n at u = 1); Gauss-Legendre quadrature on each side of u = 0,
    where the law has its kink. Where v_c is negligible beside φ' (|φ'| > 1e100 |v_c|: then
    v_c² underflows or the integral overflows in u; or v_c is below the smallest double, as for
    the issue's n = 0.001), the same integral is taken in φ' itself, u = |φ'| from the speed it
    settles at (|v_c|, or 0 where it passes through rest) to |φ'₀|:
    sgn(φ') ∫ (u − sgn(φ') v_c) / (γ u^n − sgn(φ') F) du, whose integrand is finite there.
    ``laws`` is ``law.compile_laws(n)`` (or its compiled form).
    """
    if not abs(v) <= 1e100 * abs(vc):
        s = 1.0 if v > 0.0 else -1.0
        lo = abs(vc) if s * vc > 0.0 else 0.0
        mid, half = 0.5 * (abs(v) + lo), 0.5 * (abs(v) - lo)
        total = 0.0
        for k in range(len(_NODES)):
            u = mid + half * _NODES[k]
            total += _WEIGHTS[k] * (u - s * vc) / (laws(u, gamma, 1.0, n)[0] - s * force)
        return s * half * total
    u0 = v / vc
    if u0 < 0.0:
        integral = _quadrature(laws, n, u0, 0.0) + _quadrature(laws, n, 0.0, 1.0)
    else:
        integral = _quadrature(laws, n, u0, 1.0)
    return vc * vc / force * integral


def _rate_at(x: float, ain: float, w2: float, gamma: float, n: float) -> tuple[float, float]:
    """Return (the creep velocity, the force) at the angle ``x``."""
    f = ain - w2 * math.sin(x)
    return creep_rate(f, gamma, n), f


def creep_state(laws: Any, n: float, gamma: float, w2: float, p: float, v: float, h: float,
                ain: float, cf: float = 0.0) -> tuple[bool, float, float, float]:
    """Advance a near-Coulomb creep by h, beside a friction c_f = ``cf``; return (crept, …).

    Without friction, :func:`bare_creep`. Beside a friction c_f > 0 the pendulum creeps in one
    direction s: that of φ' or, at rest, the rest rule's (:func:`rest_direction`; where it
    sticks nothing creeps). Moving in the direction s the friction is the input
    a_in − s c_f (:func:`moving_input`), so the creep is :func:`bare_creep` under it, where the
    force under it, F − s c_f, drives the motion on (s (F − s c_f) > 0, the creep speed
    (|F − s c_f|/γ)^(1/n) of the force balance γ |φ'|^n + c_f = |F|) and the creep does not turn
    round within the step; its work adds the friction's (:func:`friction_work`). A motion the
    friction decelerates towards a reversal is no creep (the guard's substeps take it).
    """
    if cf == 0.0:
        return bare_creep(laws, n, gamma, w2, p, v, h, ain)
    if v == 0.0:
        s = rest_direction(p, ain, w2, gamma, n, cf)
        if s == 0.0:
            return False, p, v, 0.0
    else:
        s = 1.0 if v > 0.0 else -1.0
    a = moving_input(ain, s, cf)
    if not s * (a - w2 * math.sin(p)) > 0.0:
        return False, p, v, 0.0
    crept, p1, v1, w = bare_creep(laws, n, gamma, w2, p, v, h, a)
    if not crept or v1 * s < 0.0:
        return False, p, v, 0.0
    return True, p1, v1, w + friction_work(cf, s, p, p1)


def bare_creep(laws: Any, n: float, gamma: float, w2: float, p: float, v: float, h: float,
               ain: float) -> tuple[bool, float, float, float]:
    """Advance a near-Coulomb creep by h without friction beside it; return (crept, φ₁, φ'₁, w).

    ``crept`` is False (and the state unchanged) where the pendulum does not creep. It creeps
    for 0 < n < 1 and γ > 0 where the creep speed is below 1 rad/s (the damping dominates the
    force: |F| < γ) and the pendulum settles onto it from φ' within CREEP_RELAX h: the
    relaxation time v_c / (n |F|) plus the time to bring φ' to v_c, at most |φ' − v_c| over
    the least deceleration towards it (|F| against the motion, |γ |φ'|^n − |F|| with it).
    The reduced equation φ' = sgn(F) (|F(φ)|/γ)^(1/n) is then taken by one RK4 step; the
    damping balances the force on the creep, so its work per unit inertia is ∫ F φ' dt (the
    same quadrature). Where h v_c is below half an ulp of φ, φ stays and so does v_c; where it
    is below the smallest normal double (:data:`TINY`), the creep's work is taken as 0.
    ``laws`` is ``law.compile_laws(n)`` (or its compiled form).
    """
    if not (0.0 < n < 1.0 and gamma > 0.0):
        return False, p, v, 0.0
    force = ain - w2 * math.sin(p)
    a = abs(force)
    if a >= gamma:
        return False, p, v, 0.0
    if a == 0.0:  # balanced at rest: no creep speed
        return (True, p, 0.0, 0.0) if v == 0.0 else (False, p, v, 0.0)
    vc = creep_rate(force, gamma, n)
    settle = abs(vc) / (n * a)
    if v != 0.0 and v != vc:
        toward = a if v * force < 0.0 else abs(abs(laws(v, gamma, 1.0, n)[0]) - a)
        settle += abs(v - vc) / toward if toward > 0.0 else math.inf
    if not settle <= CREEP_RELAX * h:
        return False, p, v, 0.0
    w0 = 0.0
    if v != vc:
        # The lag (or lead) the settling leaves behind, ∫ (φ' − v_c) dt over the transient,
        # and the damping work in it beyond the creep's: F · shift + ½ (φ'² − v_c²).
        shift = settle_shift(laws, n, gamma, v, vc, force)
        p += shift
        w0 = force * shift + 0.5 * (v * v - vc * vc)
    if abs(vc) < TINY / h:
        # h v_c is below the smallest normal double: φ stays, and the creep's work h v_c F,
        # below TINY |F|, is taken as 0 (no arithmetic on subnormal numbers, which costs
        # some hundred cycles an operation on x86).
        return True, p, vc, w0
    if p + h * vc == p:
        return True, p, vc, w0 + h * vc * force
    k2, f2 = _rate_at(p + 0.5 * h * vc, ain, w2, gamma, n)
    k3, f3 = _rate_at(p + 0.5 * h * k2, ain, w2, gamma, n)
    k4, f4 = _rate_at(p + h * k3, ain, w2, gamma, n)
    p1 = p + h / 6.0 * (vc + 2.0 * (k2 + k3) + k4)
    w = w0 + h / 6.0 * (vc * force + 2.0 * (k2 * f2 + k3 * f3) + k4 * f4)
    v1 = _rate_at(p1, ain, w2, gamma, n)[0]
    return True, p1, v1, w


def friction_step(branch: Any, laws: Any, p: float, v: float, h: float, ain: float, w2: float,
                  gamma: float, n: float, coulomb: bool, creeps: bool,
                  cf: float = 0.0) -> tuple[bool, float, float, float]:
    """Take the careful path's step where friction holds the pendulum: (taken, φ₁, φ'₁, w).

    Under Coulomb friction at rest, :func:`rest_step` (stick or break away); where a
    near-Coulomb law may creep (``creeps``: guarded explicit steps), :func:`creep_state` (beside
    the friction ``cf`` too).
    ``taken`` is False (the state unchanged) where neither applies: the step is then the
    guard's. ``Engine.careful`` calls it first, in Python, and the compiled sweep's careful
    step (``careful.py``) compiled. ``cf`` is the friction c_f beside the law.
    """
    if coulomb and v == 0.0:
        p1, v1, w = rest_step(branch, p, 0.0, h, ain, w2, gamma, n, cf)
        return True, p1, v1, w
    if creeps:
        return creep_state(laws, n, gamma, w2, p, v, h, ain, cf)
    return False, p, v, 0.0


def creep(prob: Problem, p: float, v: float, h: float, ain: float) -> StepResult | None:
    """Return :func:`creep_state`'s (φ₁, φ'₁, w) for ``prob``, or None where it does not creep."""
    crept, p1, v1, w = creep_state(compile_laws(prob.n), prob.n, prob.gamma, prob.w2, p, v, h,
                                   ain, prob.friction)
    return (p1, v1, w) if crept else None


__all__ = ['CREEP_RELAX', 'TINY', 'bare_creep', 'creep', 'creep_rate', 'creep_speed',
           'creep_state', 'friction_step', 'friction_work', 'moving_input', 'moving_inputs',
           'rest_direction', 'rest_step', 'settle_shift', 'stuck']
