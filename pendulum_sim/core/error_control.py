"""The error control of embedded pairs: the error norm, the acceptance and the step-size factor.

A trial substep of an embedded pair is judged by its scaled error norm (:func:`error_norm`),
accepted where that is at most 1 (:func:`accepted`), and the next trial is ``0.9 err^(−q)``
times the last, q = 1/(p̂ + 1), within [0.2, :data:`MAX_GROWTH`] (:func:`step_factor`; Hairer,
Nørsett and Wanner, *Solving ODEs I*, II.4). Written once, numbers in and numbers out, so that
both loops of trial substeps call them: the adaptive methods' ``embedded.cover`` and the
stiff transient's ``stiff.stiff_cover`` (in Python, and compiled in the compiled sweep).
"""
from __future__ import annotations

import math

MAX_GROWTH = 10.0
"""The largest factor by which a substep may grow after an accepted one (Hairer's facmax)."""

MIN_SHRINK = 0.2
"""The smallest factor by which a rejected substep shrinks (Hairer's facmin)."""

SAFETY = 0.9
"""The safety factor of the step-size rule (Hairer's fac)."""


def min_step(h: float) -> float:
    """Return the smallest substep a cover tries on a step of h (below: it cannot progress)."""
    return 1e-14 * max(1.0, h)


def error_norm(p: float, v: float, p1: float, v1: float, ep: float, ev: float, rtol: float,
               atol: float, vmax: float) -> float:
    """Return the scaled RMS norm of a trial's error estimate (``ep``, ``ev``) from (φ, φ').

    Each component is scaled by ``atol + rtol max(|y₀|, |y₁|)``. A trial that ends beyond the
    speed ``vmax`` a run may reach (``model.run_speed_limit``) has an infinite norm (rejected
    like one that overflows: a loose tolerance scales its error by that speed and would accept
    it); so has a trial whose numbers are not finite (NaN compares false).
    """
    ap, ap1, av, av1 = abs(p), abs(p1), abs(v), abs(v1)
    ep /= atol + rtol * (ap if ap > ap1 else ap1)
    ev /= atol + rtol * (av if av > av1 else av1)
    return math.sqrt(0.5 * (ep * ep + ev * ev)) if av1 <= vmax else math.inf


def accepted(err: float) -> bool:
    """Return True where a trial with the error norm ``err`` is accepted (False for NaN)."""
    return err <= 1.0


def step_factor(err: float, q: float) -> float:
    """Return the factor from the trial substep just judged to the next one.

    After an accepted trial ``0.9 err^(−q)`` at most :data:`MAX_GROWTH` (that for err = 0);
    after a rejected one ``0.9 err^(−q)`` at least :data:`MIN_SHRINK` (that for a norm that is
    not finite). ``q`` is 1/(p̂ + 1), p̂ the order of the error estimate.
    """
    if accepted(err):
        return MAX_GROWTH if err == 0.0 else min(MAX_GROWTH, SAFETY * err ** -q)
    return MIN_SHRINK if not math.isfinite(err) else max(MIN_SHRINK, SAFETY * err ** -q)


__all__ = ['MAX_GROWTH', 'MIN_SHRINK', 'SAFETY', 'accepted', 'error_norm', 'min_step',
           'step_factor']
