"""The careful path's commonest step, written to compile: one guarded step, split at a reversal.

Most steps a sweep's fast path refuses are refused because the velocity reverses inside them
(n = 2, 4, … and non-integer n) or because the guard's speed range is a bound, not the rule.
For those, :meth:`Engine.careful <pendulum_sim.core.engine.Engine.careful>` takes one plain
step (the guard asks for one substep), split at the reversal by
:meth:`SplitSteps.split <pendulum_sim.core.split.SplitSteps.split>`. :func:`careful_step`
takes the same operations in the same order, with the same generated steps (``plain``,
``branch``: ``explicit.step_source`` with the exponent an argument), the same reversal location
(``reversal.locate_on_branch``: the form of ``reversal.LOCATE_SRC`` that calls ``branch``
itself, which numba compiles), the same slope (``model.slope_formula``) and eigenvalues, and the
same decision texts, so the compiled sweep takes it without leaving compiled code
(``decisions.kernel_source``), graded substeps near a reversal (``reversal.graded_mesh``)
included. Everything else (a stiff transient, guard substeps or the fallback, Coulomb and
near-Coulomb friction, n < 1, an energy redo, a non-finite result) it declines, and the sweep
hands the step to ``Engine.careful`` itself; a parity test (``test_sweep_jit.py``) checks that
both give the same floats and counters.
"""
from __future__ import annotations

import math
from typing import Any

from .decisions import ENERGY_TOL
from .law import slope_formula
from .model import _eigs
from .reversal import (
    GRADED_ITERATIONS,
    GRADED_TOL,
    NEWTON_ITERATIONS,
    NEWTON_TOL,
    graded_mesh,
    locate_on_branch,
)

Result = tuple[bool, float, float, int]


def terminal(gamma: float, n: float, force: float) -> float:
    """Return ``guard.terminal_speed`` without its ``except`` (compiled, an overflow is inf)."""
    if gamma <= 0.0 or n == 0.0:
        return math.inf
    return float((force / gamma) ** (1.0 / n))


def one_substep(h: float, w2: float, gamma: float, n: float, p: float, v: float, force: float,
                disk: float, real: float, max_angle: float) -> bool:
    """Return True where ``StabilityGuard.substeps`` gives one substep (n >= 1), else False."""
    top = abs(v) + min(h * force, terminal(gamma, n, force))  # guard.max_speed
    d = slope_formula(gamma, n, top)
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


def careful_step(plain: Any, branch: Any, p: float, v: float, h: float, ain: float, w2: float,
                 gamma: float, n: float, v_acc: float, reach: float, check: bool,
                 nonsmooth: bool, disk: float, real: float, max_angle: float) -> Result:
    """Take ``Engine.careful``'s step of h from (φ, φ') where it is one split plain step.

    For a guarded explicit method and n >= 1 (no Coulomb or near-Coulomb friction); ``reach``
    is ``Problem.reach``. Returns ``(done, φ₁, φ'₁, reversals)``; ``done`` False where the
    step needs more than this (the caller then takes it with ``Engine.careful``).
    """
    p1, v1, _, a0 = plain(p, v, h, ain, w2, gamma, 1.0, n)
    if abs(v) > v_acc:  # decisions.STIFF_SRC: a stiff transient is declined
        pw = abs(v) ** n
        if not pw < math.inf or abs(a0) > 0.5 * gamma * pw:
            return False, p, v, 0
    if not one_substep(h, w2, gamma, n, p, v, abs(ain) + w2, disk, real, max_angle):
        return False, p, v, 0
    turns = 0
    # SplitSteps.micro: decisions.REVERSAL_SRC, then the split or the graded branch run.
    if nonsmooth and ((v1 * v < 0.0) or ((a0 * v < 0.0) and (abs(v) <= h * abs(a0)))
                      or (abs(v) < reach * abs(a0))):
        if v1 * v < 0.0 or (a0 * v < 0.0 and abs(v) <= h * abs(a0)):
            done, p1, v1, turns = split(plain, branch, p, v, h, ain, w2, gamma, n, a0, reach)
        elif reach > 0.0 and a0 != 0.0:
            side = 1.0 if (v > 0.0 or (v == 0.0 and a0 > 0.0)) else -1.0
            x = abs(v) / abs(a0)
            if a0 * v < 0.0:
                lens = graded_mesh(max(x - h, 0.0), x, h, n, reach)
                back = True
            else:
                lens = graded_mesh(x, x + h, h, n, reach)
                back = False
            p1, v1 = branch_run(branch, p, v, lens, back, ain, w2, gamma, side, n)
            done = True
            if not v1 * v >= 0.0:  # the branch reached φ' = 0 after all: split there
                done, p1, v1, turns = split(plain, branch, p, v, h, ain, w2, gamma, n, a0,
                                            reach)
        else:
            done = True
        if not done:
            return False, p, v, 0
    if check and ain == 0.0:
        s = math.sin(0.5 * p)
        e0 = 0.5 * v * v + 2.0 * w2 * s * s
        s = math.sin(0.5 * p1)
        e1 = 0.5 * v1 * v1 + 2.0 * w2 * s * s
        if e1 > e0 + ENERGY_TOL * (e0 + w2):
            return False, p, v, 0
    if not (math.isfinite(p1) and math.isfinite(v1)):
        return False, p, v, 0
    return True, p1, v1, turns


def branch_run(branch: Any, p: float, v: float, lens: list[float], back: bool, ain: float,
               w2: float, gamma: float, sign: float, n: float) -> tuple[float, float]:
    """Return ``SplitSteps._branch_run``'s (φ, φ') over ``lens`` (in reverse where ``back``)."""
    m = len(lens)
    for k in range(m):
        p, v, _, _ = branch(p, v, lens[m - 1 - k] if back else lens[k], ain, w2, gamma, sign, n)
    return p, v


def split(plain: Any, branch: Any, p: float, v: float, h: float, ain: float, w2: float,
          gamma: float, n: float, a0: float, reach: float) -> tuple[bool, float, float, int]:
    """Return ``SplitSteps.split``'s (done, φ₁, φ'₁, reversals) for n >= 1."""
    sign = 1.0 if v > 0.0 else -1.0
    p1, v1, _, _ = branch(p, v, h, ain, w2, gamma, sign, n)
    if v1 * v > 0.0:  # no kink inside (graded if it is near)
        if reach > 0.0 and a0 != 0.0:
            x = abs(v) / abs(a0)
            lens = graded_mesh(max(x - h, 0.0), x, h, n, reach)
            p1, v1 = branch_run(branch, p, v, lens, True, ain, w2, gamma, sign, n)
        return True, p1, v1, 0
    # The reversal location (reversal.LOCATE_SRC): the Hermite root (end slope: φ'' on the
    # branch at the step's end, reversal.branch_accel), then Newton on the partial step's φ'(θh).
    a1 = branch(p1, v1, 0.0, ain, w2, gamma, sign, n)[3]
    th, pm, vm, _ = locate_on_branch(branch, p, v, v1, a0, a1, h, ain, w2, gamma, sign, n,
                                     NEWTON_TOL, NEWTON_ITERATIONS)
    lens = graded_mesh(0.0, th * h, h, n, reach)
    if len(lens) > 1:
        acc = 0.0
        for _ in range(GRADED_ITERATIONS):
            pm, vm = branch_run(branch, p, v, lens, True, ain, w2, gamma, sign, n)
            acc = branch(pm, vm, 0.0, ain, w2, gamma, sign, n)[3]
            if acc == 0.0 or abs(vm) <= GRADED_TOL * abs(v):
                break
            nth = th - vm / (acc * h)
            if not 0.0 < nth < 1.0:
                break
            th = nth
            lens = graded_mesh(0.0, th * h, h, n, reach)
        if acc != 0.0:
            dt = min(max(-vm / acc, -th * h), (1.0 - th) * h)
            pm += dt * (vm + 0.5 * dt * acc)
            vm = 0.0
            th += dt / h
    rest = (1.0 - th) * h
    after = ain - w2 * math.sin(pm)
    if after == 0.0:
        p2, v2, _, _ = plain(pm, vm, rest, ain, w2, gamma, 1.0, n)
        return True, p2, v2, 1
    side = 1.0 if after > 0.0 else -1.0
    p2, v2 = branch_run(branch, pm, vm, graded_mesh(0.0, rest, h, n, reach), False, ain, w2,
                        gamma, side, n)
    if not (v2 * side >= 0.0 and abs(v2) <= rest * (abs(ain) + w2) * (1.0 + 1e-9)):
        return False, p, v, 0  # the fallback takes the rest of the step
    return True, p2, v2, 1


__all__ = ['branch_run', 'careful_step', 'one_substep', 'split', 'terminal']
