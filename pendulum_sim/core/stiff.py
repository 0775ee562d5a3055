"""The stiff transient's error-controlled substeps, written to compile.

A step that starts in a damping-dominated n > 1 transient (``decisions.stiff_transient``) is
covered by error-controlled substeps of the Dormand-Prince 8(5,3) pair (``dop853``) at the
local tolerance STIFF_TOL (h ω_r)⁴ (``decisions.py``): its substeps grow with the transient's
own time scale, so the transient is resolved, not merely kept stable, and its error falls at
order ≥ 4 as h falls. :func:`stiff_cover` is that cover, numbers and generated steps in, a tuple
out (a return code and counts, no exceptions, closures or stats objects), so that the careful
step (``careful.careful_step``) runs it as Python and compiled, the same function. Its trial
loop is the adaptive methods'
(``embedded.cover``) for one step and a law with n > 1 (no Coulomb friction, no output stops,
no trace, no run budget); the decisions the two loops share are one function each
(``error_control.py``: the error norm, the acceptance, the step-size factor), the cut at a
reversal is ``reversal.locate_on_branch`` on the pair's branch step.

Where Python raises inside a trial step (OverflowError for a power beyond float64, ValueError
for the sine of inf), compiled code gives inf or NaN: the trial is rejected either way (its
error norm is not finite). Elsewhere a raise would change Python's path (``Engine.careful``'s
``except``); there the function returns a code instead (:data:`OVERFLOW`: the damping slope at
the start is beyond float64, where the fallback takes the step; :data:`NOT_FINITE`, with
``strict``: the location of a reversal is not finite, where Python may have raised), and the
compiled careful step declines the step.
"""
from __future__ import annotations

import math
from typing import Any

from .decisions import STIFF_MAX_TRIALS, STIFF_PAIR, STIFF_TOL, reference_rate
from .error_control import accepted, error_norm, min_step, step_factor
from .explicit import compile_step_with_n
from .law import damping_derivative
from .model import run_speed_limit
from .reversal import CUT_ITERATIONS, CUT_TOL, locate_on_branch

STIFF_Q = 1.0 / (STIFF_PAIR.error_order + 1)
"""The exponent q of the step-size factor ``0.9 err^(−q)`` for :data:`STIFF_PAIR`."""

TAKEN, TO_GUARD, OVERFLOW, NOT_FINITE = range(4)
"""The codes of :func:`stiff_cover`: the step is covered; the substeps could not cover it (more
than STIFF_MAX_TRIALS trials, or a substep below ``error_control.min_step``: the guard takes
the step from its start); the damping slope at the start overflows; a reversal's location is
not finite (with ``strict``)."""

StiffResult = tuple[int, float, float, float, int, int]
"""``stiff_cover``'s (code, φ₁, φ'₁, w, substeps, reversals)."""


def stiff_pair(n: float) -> tuple[Any, Any]:
    """Return the pair's steps with error estimate for ``n``, the exponent an argument.

    ``(pair_plain, pair_branch)``, each ``step(φ, φ', h, a_in, ω0², γ, s, n)`` →
    (φ₁, φ'₁, w, φ''₀, e_φ, e_φ') (``explicit.step_source_with_n``), as the compiled sweep's
    run defines them (``kernel.kernel_source``).
    """
    return (compile_step_with_n(STIFF_PAIR, n, False, True),
            compile_step_with_n(STIFF_PAIR, n, True, True))


def trial(pair_plain: Any, pair_branch: Any, on_branch: bool, p: float, v: float, h: float,
          ain: float, w2: float, gamma: float, sign: float, n: float, tol: float,
          vmax: float) -> tuple[float, float, float, float, float]:
    """Return one trial substep of h and its error norm: (φ₁, φ'₁, w, φ''₀, err).

    On the branch law ``sign`` where ``on_branch``. A step that raises in Python (a power beyond
    float64, the sine of inf) has the norm inf, the state unchanged; compiled, such a step's
    numbers are inf or NaN and so is its norm (``error_control.error_norm``).
    """
    try:
        if on_branch:
            p1, v1, w, a0, ep, ev = pair_branch(p, v, h, ain, w2, gamma, sign, n)
        else:
            p1, v1, w, a0, ep, ev = pair_plain(p, v, h, ain, w2, gamma, sign, n)
        return p1, v1, w, a0, error_norm(p, v, p1, v1, ep, ev, tol, tol, vmax)
    except Exception:  # OverflowError, ValueError: numba catches no narrower class
        return p, v, 0.0, 0.0, math.inf


def stiff_cover(pair_plain: Any, pair_branch: Any, p: float, v: float, h: float, ain: float,
                w2: float, gamma: float, n: float, nonsmooth: bool,
                strict: bool) -> StiffResult:
    """Cover a step of h from (φ, φ') in a damping-dominated n > 1 transient.

    Substeps of the pair (:func:`stiff_pair`) at the tolerance STIFF_TOL (h ω_r)⁴ in φ and φ'
    (ω_r: ``decisions.reference_rate``), the first trial min(h, 1/d) (d the damping slope at
    the start, ``law.damping_derivative``), every trial after the first counted as a substep; where
    ``nonsmooth`` an accepted substep that crosses φ' = 0 is cut at the reversal
    (``reversal.locate_on_branch``, CUT_TOL, CUT_ITERATIONS) and the next trial starts small.
    Returns ``(code, φ₁, φ'₁, w, substeps, reversals)`` (:data:`TAKEN` … :data:`NOT_FINITE`);
    the counts are those of the trials taken whatever the code.
    """
    subs = turns = 0
    d = damping_derivative(gamma, n, v)
    if not d < math.inf:
        return OVERFLOW, p, v, 0.0, subs, turns
    tol = STIFF_TOL * (h * reference_rate(math.sqrt(w2))) ** 4.0
    hh = min(h, 1.0 / d) if d > 0.0 else h
    vmax = run_speed_limit(gamma, n, w2)
    trials = 0
    done = w_total = 0.0
    while done < h:
        trials += 1
        if trials > 1:
            subs += 1
        if STIFF_MAX_TRIALS < trials:
            return TO_GUARD, p, v, w_total, subs, turns
        last = hh >= h - done
        step_h = h - done if last else hh
        sign = 1.0 if v > 0.0 else -1.0
        on_branch = nonsmooth and v != 0.0
        p1, v1, w, a0, err = trial(pair_plain, pair_branch, on_branch, p, v, step_h, ain, w2,
                                   gamma, sign, n, tol, vmax)
        if accepted(err):
            if nonsmooth and v1 * v < 0.0:
                # Cut at the reversal: the branch continuation's φ'(θ step_h) = 0.
                a1 = pair_branch(p1, v1, 0.0, ain, w2, gamma, sign, n)[3]
                th, pm, vm, wm = locate_on_branch(pair_branch, p, v, v1, a0, a1, step_h, ain,
                                                  w2, gamma, sign, n, CUT_TOL, CUT_ITERATIONS)
                if strict and not (math.isfinite(th) and math.isfinite(pm)
                                   and math.isfinite(vm) and math.isfinite(wm)):
                    return NOT_FINITE, p, v, w_total, subs, turns
                turns += 1
                p, v = pm, 0.0
                w_total += wm
                done += th * step_h
                hh = max(th * step_h, 1e-6 * h)
                continue
            done = h if last else done + step_h
            p, v = p1, v1
            w_total += w
            factor = step_factor(err, STIFF_Q)
            hh = step_h * factor if not last else max(hh, step_h * factor)
        else:
            hh = step_h * step_factor(err, STIFF_Q)
            if hh < min_step(h):
                return TO_GUARD, p, v, w_total, subs, turns
    return TAKEN, p, v, w_total, subs, turns


__all__ = ['NOT_FINITE', 'OVERFLOW', 'STIFF_Q', 'TAKEN', 'TO_GUARD',
           'StiffResult', 'stiff_cover', 'stiff_pair', 'trial']
