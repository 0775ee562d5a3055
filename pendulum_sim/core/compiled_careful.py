"""The careful path's one-substep steps, written to compile: friction at rest, the split.

Most steps a sweep's fast path refuses are refused because the velocity reverses inside them
(n = 2, 4, … and non-integer n), because friction holds the pendulum near rest (Coulomb
sticking and break-away, n = 0; the creep of a near-Coulomb law, 0 < n < 1) or because the
guard's speed range is a bound, not the rule. For those,
:meth:`Engine.careful <pendulum_sim.core.engine.Engine.careful>` takes the step from rest
(``coulomb.friction_step``) or one plain step (the guard asks for one substep), split at the
reversal (``split.split_step``). :func:`careful_step` takes the same operations in the same
order: it calls the very functions the engine calls, written to compile (``friction_step``,
``split_step`` with ``reversal.locate_on_branch`` and ``reversal.graded_landing``), with the
same generated steps (``plain``, ``branch``: ``explicit.step_source_with_n``) and laws
(``laws``: ``law.laws_source``), and mirrors the guard's one-substep decision
(:func:`one_substep`, the stiffness speed of ``guard.stiffness_speed`` included for n < 1) and
the micro step's decision texts, so the compiled sweep takes these steps without leaving
compiled code (``decisions.kernel_source``), for every exponent n >= 0. Everything else (a stiff
transient, guard substeps or the fallback, an energy redo, a non-finite result) it declines,
and the sweep hands the step to ``Engine.careful`` itself; a parity test
(``test_sweep_jit.py``) checks that both give the same floats and counters.
"""
from __future__ import annotations

import math
from typing import Any

from .coulomb import friction_step, stuck
from .decisions import ENERGY_TOL
from .law import slope_formula
from .model import _eigs
from .reversal import branch_run, graded_mesh
from .split import split_step

Result = tuple[bool, float, float, int, int]
"""``careful_step``'s (done, φ₁, φ'₁, reversals, sticks)."""


def terminal(gamma: float, n: float, force: float) -> float:
    """Return ``guard.terminal_speed`` without its ``except`` (compiled, an overflow is inf)."""
    if gamma <= 0.0 or n == 0.0:
        return math.inf
    return float((force / gamma) ** (1.0 / n))


def one_substep(h: float, w2: float, gamma: float, n: float, p: float, v: float, force: float,
                force_now: float, disk: float, real: float, max_angle: float) -> bool:
    """Return True where ``StabilityGuard.substeps`` gives one substep, else False.

    ``force`` is |a_in| + ω0², ``force_now`` |a_in − ω0² sin φ| (the creep's scale for n < 1,
    ``guard.stiffness_speed``).
    """
    top = abs(v) + min(h * force, terminal(gamma, n, force))  # guard.max_speed
    if n >= 1.0:
        speed = top
    else:
        speed = max(abs(v), min(0.5 * h * force_now, terminal(gamma, n, force_now)))
    d = slope_formula(gamma, n, speed)
    if not math.isfinite(d):
        return False
    if not max(1, math.ceil(h * top / max_angle)) == 1:
        return False
    c = w2 * math.cos(p)
    lam1, lam2 = _eigs(d, c)
    big = -1.0  # the largest |λ| with Re λ < 0
    real_only = True
    for lam in (lam1, lam2):
        if lam.real < 0.0:
            big = max(big, abs(lam))
            real_only = real_only and lam.imag == 0.0
    if big < 0.0 or big * h <= disk:
        return True
    if real_only and math.isfinite(real):
        return max(1, math.ceil(big * h / real)) == 1
    return False  # StabilityGuard._search: declined


def careful_step(plain: Any, branch: Any, laws: Any, p: float, v: float, h: float, ain: float,
                 w2: float, gamma: float, n: float, v_acc: float, reach: float, check: bool,
                 nonsmooth: bool, coulomb: bool, disk: float, real: float,
                 max_angle: float) -> Result:
    """Take ``Engine.careful``'s step of h from (φ, φ') where it is one step without a redo.

    For a guarded explicit method; ``reach`` is ``Problem.reach``. Returns
    ``(done, φ₁, φ'₁, reversals, sticks)``; ``done`` False where the step needs more than this
    (the caller then takes it with ``Engine.careful``).
    """
    # Friction holds the pendulum (Engine.careful's first branch): Coulomb sticking or
    # break-away, the near-Coulomb creep (guarded: creep_state decides on n and γ).
    held, p1, v1, _ = friction_step(branch, laws, p, v, h, ain, w2, gamma, n, coulomb, True)
    if held:
        return settled(p, v, p1, v1, 0, check, ain, w2, coulomb)
    p1, v1, _, a0 = plain(p, v, h, ain, w2, gamma, 1.0, n)
    if abs(v) > v_acc:  # decisions.STIFF_SRC: a stiff transient is declined
        pw = abs(v) ** n
        if not pw < math.inf or abs(a0) > 0.5 * gamma * pw:
            return False, p, v, 0, 0
    if not one_substep(h, w2, gamma, n, p, v, abs(ain) + w2, abs(ain - w2 * math.sin(p)), disk,
                       real, max_angle):
        return False, p, v, 0, 0
    turns = 0
    # SplitSteps.micro: decisions.REVERSAL_SRC, then the split or the graded branch run.
    if nonsmooth and ((v1 * v < 0.0) or ((a0 * v < 0.0) and (abs(v) <= h * abs(a0)))
                      or (abs(v) < reach * abs(a0))):
        done = True
        if v1 * v < 0.0 or (a0 * v < 0.0 and abs(v) <= h * abs(a0)):
            done, p1, v1, _, turns, _, _, _, _ = split_step(plain, branch, laws, p, v, h, ain,
                                                            w2, gamma, n, a0, reach, coulomb)
        elif reach > 0.0 and a0 != 0.0:
            side = 1.0 if (v > 0.0 or (v == 0.0 and a0 > 0.0)) else -1.0
            x = abs(v) / abs(a0)
            if a0 * v < 0.0:
                lens = graded_mesh(max(x - h, 0.0), x, h, n, reach)
                back = True
            else:
                lens = graded_mesh(x, x + h, h, n, reach)
                back = False
            p1, v1, _ = branch_run(branch, p, v, lens, back, ain, w2, gamma, side, n)
            if not v1 * v >= 0.0:  # the branch reached φ' = 0 after all: split there
                done, p1, v1, _, turns, _, _, _, _ = split_step(
                    plain, branch, laws, p, v, h, ain, w2, gamma, n, a0, reach, coulomb)
        if not done:
            return False, p, v, 0, 0
    return settled(p, v, p1, v1, turns, check, ain, w2, coulomb)


def settled(p: float, v: float, p1: float, v1: float, turns: int, check: bool, ain: float,
            w2: float, coulomb: bool) -> Result:
    """Return the step's result, or decline it where energy rose or it is not finite.

    The end of ``Engine.careful``: the energy check (its redo is declined), a non-finite state
    (its fallback is declined), a Coulomb stick counted (``coulomb.stuck``).
    """
    if check and ain == 0.0:
        s = math.sin(0.5 * p)
        e0 = 0.5 * v * v + 2.0 * w2 * s * s
        s = math.sin(0.5 * p1)
        e1 = 0.5 * v1 * v1 + 2.0 * w2 * s * s
        if e1 > e0 + ENERGY_TOL * (e0 + w2):
            return False, p, v, 0, 0
    if not (math.isfinite(p1) and math.isfinite(v1)):
        return False, p, v, 0, 0
    return True, p1, v1, turns, 1 if stuck(coulomb, v, v1) else 0


__all__ = ['Result', 'branch_run', 'careful_step', 'one_substep', 'settled', 'terminal']
