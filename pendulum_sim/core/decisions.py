"""The fast path's decisions, written once as source text and compiled for floats and arrays.

A plain explicit step of h is accepted on the fast path when ``|φ'|`` lies in the guard's safe
speed range (``guard.py``), no velocity reversal is suspected (:func:`reversal_suspect`), the
step is not in a damping-dominated transient (:func:`stiff_transient`), energy did not rise
without input (:func:`energy_rose`; the compiled sweep tries the sound pre-test
:func:`energy_kept` first) and the result is finite. The texts below are compiled into
functions that work on floats and numpy arrays (the sweep and the careful path call them) and
inlined into the Stepper's generated fast step (:func:`compile_fast_step`).
"""
from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
import numpy.typing as npt

from .codegen import body_of, define, fill
from .explicit import step_source
from .law import SCALAR_ENV, damping_expression, power_source
from .tableaus import DOP853, Tableau

ENERGY_TOL = 1e-12
"""An explicit step may raise the energy by round-off and by the conservative part of its
truncation error near turning points, where the damping removes almost nothing; anything above
this relative size (of E/I + ω0²) is a defect and the step is redone implicitly."""

CROSS_SRC = '(v1 * v < 0.0) | ((a0 * v < 0.0) & (abs(v) <= h * abs(a0)))'
NEAR_SRC = 'abs(v) < reach * abs(a0)'
REVERSAL_SRC = f'{CROSS_SRC} | ({NEAR_SRC})'
ENERGY_SRC = '0.5 * v * v + 2.0 * w2 * s * s'
ROSE_SRC = 'e1 > e0 + ENERGY_TOL * (e0 + w2)'
"""The fast path's decisions as source text, written once: compiled into the functions below
(which work on floats and numpy arrays: ``sweep`` and the careful path use them) and inlined
as they stand (``&`` and ``|`` take Python's and numba's bools as numpy's, every operand in
parentheses) into the Stepper's generated fast step
(:func:`compile_fast_step`) and the compiled sweep's run (:func:`kernel_source`). The
stiff-transient test is a function (:func:`stiff_transient`), which the generated texts call
(:func:`stiff_source`)."""

ENERGY_KEPT_SRC = """\
k_dl = 0.5 * (p1 - p0)
k_ad = abs(k_dl)
k_dk = 0.5 * (v1 - v0) * (v1 + v0)
k_gap = abs(p0 - {q} + k_dl) + 1e-15 * (abs(p0 - {q}) + k_ad)
k_est = k_dk + 2.0 * w2 * sin({q}) * (k_dl - k_dl * k_dl * k_dl / 6.0)
k_bound = (2.002 * w2 * k_ad * (k_gap + 2e-15 + k_ad * k_ad * k_ad * k_ad / 119.0)
           + 2e-15 * abs(k_dk) + 1e-300)
kept = (w2 >= 0.0) & (k_est + k_bound <= 0.4 * ENERGY_TOL * (0.5 * v0 * v0 + w2))
"""
"""A sound pre-test of :data:`ROSE_SRC` that takes no sine of its own: ``kept`` True proves
that the energy test of the step (φ₀, φ'₀) → (φ₁, φ'₁) says "not rose" (the proof:
:func:`energy_kept`). ``{q}`` is a point whose sine the step has already taken (a stage near
φ₀ + h φ'₀ / 2: :func:`kept_stage`), so compiled code takes that sine once."""


def _expr(args: str, src: str) -> Any:
    env: dict[str, object] = {'ENERGY_TOL': ENERGY_TOL}
    return define(f'def f({args}):\n    return {src}\n', 'f', env, '<decision>')


_REVERSAL = _expr('v, v1, a0, h, reach', REVERSAL_SRC)
_ENERGY = _expr('v, s, w2', ENERGY_SRC)
_ROSE = _expr('e0, e1, w2', ROSE_SRC)


def reversal_suspect(v: Any, v1: Any, a0: Any, h: float, reach: Any = 0.0) -> Any:
    """Return where a step from φ' = ``v`` to ``v1`` may have crossed or come near φ' = 0.

    A reversal shows as a sign change over the step, or, where a stage already crossed and
    spoiled the result, as a deceleration ``a0`` that could stop the pendulum within h; with
    ``reach`` > 0 (graded laws: the window S of :func:`grade_window`) also as a speed below
    S |a0|, i.e. a reversal within about S before or after (:data:`REVERSAL_SRC`).
    """
    return _REVERSAL(v, v1, a0, h, reach)


STIFF_K = 100.0
"""For n > 1: a plain step's error in a damping-dominated transient, relative to its error on
the smooth oscillation, is about γ⁴ |φ'|^(4n−3) / (n ω_r⁵) (ω_r = max(ω0, 1 s⁻¹)); above
this factor the step is taken by error-controlled substeps instead (``stiff.stiff_cover``)."""

STIFF_TOL = 1.0
"""Local tolerance of the error-controlled substeps: STIFF_TOL (h ω_r)⁴ in rad and rad/s, so
the transient's error falls with h at the method's order while it costs few substeps."""

STIFF_MAX_TRIALS = 2000
"""Trial substeps per step before the error-controlled path hands the step to the guard."""

STIFF_PAIR = DOP853
"""The embedded pair of the error-controlled substeps (``stiff.stiff_cover``): at tolerances
STIFF_TOL (h ω_r)⁴ the order-8 pair needs about a third of the trials of the order-5 one."""


def reference_rate(omega0: float) -> float:
    """Return ω_r = max(ω0, 1 s⁻¹): the rate of the stiff transient's test and tolerance."""
    return max(omega0, 1.0)


def accuracy_speed(gamma: float, n: float, omega0: float) -> float:
    """Return the speed above which a damping-dominated n > 1 transient is error-controlled."""
    if n <= 1.0 or gamma <= 0.0:
        return math.inf
    w_r = reference_rate(omega0)
    log_v = (math.log(STIFF_K * n) + 5.0 * math.log(w_r) - 4.0 * math.log(gamma)) / (
        4.0 * n - 3.0)
    return math.exp(min(log_v, 700.0))


def stiff_transient(speed: Any, a0: Any, gamma: Any, power: Any, v_acc: Any) -> Any:
    """Return where a step starts in a damping-dominated transient too fast for a plain step.

    Above the accuracy speed ``v_acc`` (:func:`accuracy_speed`) and with the net acceleration
    φ''₀ = ``a0`` at least half the damping γ|φ'|^n (the damping is not balanced by gravity and
    input, as it is in a creep). ``speed`` is |φ'| and ``power`` |φ'|^n by the law's power rule
    (``law.power_source`` in generated text, ``law.power_formula`` for a run-time n). The rule,
    written once: floats or numpy arrays, and compiled by numba; the texts of the fast path
    call it only above ``v_acc``, so that the power is not taken below it (:func:`stiff_source`).
    """
    return (speed > v_acc) & (abs(a0) > 0.5 * gamma * power)


def stiff_source(n: float) -> str:
    """Return the call of :func:`stiff_transient` for the exponent ``n`` as generated source.

    Reads ``v``, ``a0``, ``gamma``, ``n``, ``v_acc``; |φ'|^n is the damping law's power
    (``law.power_source``): multiplications for a whole n, ``sqrt`` for 0.5, ``abs(v) ** n``
    for every other exponent (one text for all of those).
    """
    return f'stiff_transient(abs(v), a0, gamma, {power_source(n, "n")}, v_acc)'


def specific_energy(v: Any, sin_half: Any, w2: Any) -> Any:
    """Return E/I = ½ φ'² + 2 ω0² sin²(φ/2) (eq 23 divided by I) from ``sin(φ/2)``."""
    return _ENERGY(v, sin_half, w2)


def energy_rose(e0: Any, e1: Any, w2: Any) -> Any:
    """Return where E/I rose from ``e0`` to ``e1`` by more than ENERGY_TOL of its scale."""
    return _ROSE(e0, e1, w2)


def energy_kept_source(q: str) -> str:
    """Return the pre-test :data:`ENERGY_KEPT_SRC` with the sine's point named ``q``."""
    return ENERGY_KEPT_SRC.format(q=q)


_KEPT = define('def f(p0, v0, p1, v1, q, w2):\n'
               + ''.join(f'    {line}\n' for line in energy_kept_source('q').splitlines())
               + '    return kept\n', 'f', dict(SCALAR_ENV, ENERGY_TOL=ENERGY_TOL),
               '<decision>')


def energy_kept(p0: float, v0: float, p1: float, v1: float, q: float, w2: float) -> bool:
    """Return True where the step (φ₀, φ'₀) → (φ₁, φ'₁) surely passes the energy test.

    True proves that :func:`energy_rose` of ``e0`` and ``e1``, E/I of the two states by
    :func:`specific_energy` (with the C library's sine), is False; False proves nothing (the
    energy test then decides). It takes the sine of ``q`` alone, any point (the compiled sweep
    passes a stage of the step near φ₀ + h φ'₀ / 2, whose sine the step took), and is
    :data:`ENERGY_KEPT_SRC`; it holds for ω0² = ``w2`` >= 0 only (False otherwise).

    Notes
    -----
    With δ = (φ₁ − φ₀)/2 and m = φ₀ + δ, exactly cos φ₀ − cos φ₁ = 2 sin m sin δ (the
    sum-to-product identity), so the change of E/I = ½ φ'² + ω0² (1 − cos φ) (eq 23 over I) is

        ΔE = ½ (φ'₁ − φ'₀)(φ'₁ + φ'₀) + 2 ω0² sin m sin δ.

    The test estimates it as ``k_est`` = ½ (φ'₁ − φ'₀)(φ'₁ + φ'₀) + 2 ω0² sin q (δ − δ³/6)
    and bounds the difference by ``k_bound``: |sin m − sin q| <= |m − q|, |sin δ − (δ − δ³/6)|
    <= |δ|⁵/120 (alternating Taylor series), |sin δ| <= |δ|; the rounding of every operation
    (relative 2⁻⁵³ each, eight or so along each term, a sine within one unit in the last place,
    all below 2e-15 relative; the factor 2.002 and 1/119 for 1/120 cover the rounding of the
    bound itself) and underflow (below 1e-300 in all). So ΔE <= k_est + k_bound. With
    T = ENERGY_TOL (E₀ + ω0²) and ½ φ'₀² <= E₀, accepting means ΔE <= 0.41 T. The floats
    ``e0`` and ``e1`` are E₀ and E₁ within a relative δ_E of about 1e-15 (sums of non-negative
    terms), and the threshold e0 + ENERGY_TOL (e0 + ω0²) is within 3 δ_E of its exact value;
    ``e1`` > threshold would need E₁ − E₀ > T (1 − 4 δ_E) − 2 δ_E E₀, which is above 0.41 T
    for any δ_E <= 2.5e-13 (then 2 δ_E E₀ <= 0.5 T): the margin also holds for an ``e0``
    carried from another sine (numpy's, at the start of a run).
    """
    return bool(_KEPT(p0, v0, p1, v1, q, w2))


def kept_stage(tableau: Tableau) -> int | None:
    """Return the stage whose point the pre-test :func:`energy_kept` takes, or None.

    A stage at c = ½ whose sine the step takes, the one nearest the midpoint m = φ₀ + δ to
    second order (Σⱼ aᵢⱼ cⱼ nearest ¼: the classic RK4's third stage, |m − q| = O(h³));
    None for a method without one (Euler): its sweep takes the energy test as it stands.
    """
    A, C = tableau.A, tableau.C
    cands = [i for i in range(1, tableau.stages) if C[i] == 0.5]
    if not cands:
        return None
    return min(cands, key=lambda i: (abs(float(A[i] @ C) - 0.25), i))


FAST_STEP_TEMPLATE = """\
def fast(p0, v0, h, ain, e0):
    $plain_step
    if not (-INF < p1 < INF and -INF < v1 < INF):
        return None
    v = v0
    a0 = a_0
    $reversal_test
    $stiff_test
    $energy_test
"""
"""The Stepper's fast step (:func:`compile_fast_step`): the plain step, then the decisions."""

REFUSE_TEMPLATE = """\
if $test:
    return None
"""
"""A decision of :data:`FAST_STEP_TEMPLATE` that refuses the step."""

FAST_ENERGY_TEMPLATE = """\
if ain != 0.0:
    return p1, v1, w, NAN
if e0 != e0:
    s = sin(0.5 * p0)
    e0 = $energy
v = v1
s = sin(0.5 * p1)
e1 = $energy
if $rose:
    return None
return p1, v1, w, e1
"""
"""The energy test of :data:`FAST_STEP_TEMPLATE` (without input), E/I returned for the next."""


@functools.lru_cache(maxsize=256)
def fast_step_source(tableau: Tableau, n: float, nonsmooth: bool, reach: float, v_acc: float,
                     check_energy: bool) -> str:
    """Return the text of :func:`compile_fast_step`: :data:`FAST_STEP_TEMPLATE` filled.

    The plain step of ``explicit.step_source`` inlined, the reversal test where the law is not
    smooth (:data:`REVERSAL_SRC`, or the crossing test alone without grading), the
    stiff-transient test where a transient can be stiff (:func:`stiff_source`, above
    ``v_acc`` only) and the energy test where it applies (:data:`FAST_ENERGY_TEMPLATE`).
    """
    reversal = ''
    if nonsmooth:
        reversal = fill(REFUSE_TEMPLATE, test=REVERSAL_SRC if reach > 0.0 else CROSS_SRC)
    stiff = ''
    if math.isfinite(v_acc):
        stiff = fill(REFUSE_TEMPLATE, test=f'abs(v) > v_acc and {stiff_source(n)}')
    energy = (fill(FAST_ENERGY_TEMPLATE, energy=ENERGY_SRC, rose=ROSE_SRC) if check_energy
              else 'return p1, v1, w, NAN')
    return fill(FAST_STEP_TEMPLATE,
                plain_step=body_of(step_source(tableau, damping_expression(n, scalar=True))),
                reversal_test=reversal, stiff_test=stiff, energy_test=energy)


@functools.lru_cache(maxsize=256)
def compile_fast_step(tableau: Tableau, n: float, nonsmooth: bool, reach: float, v_acc: float,
                      check_energy: bool, w2: float, gamma: float) -> Any:
    """Compile the Stepper's fast path: one plain step and the fast-path decisions, inlined.

    ``fast(p0, v0, h, ain, e0)`` (ω0² = ``w2`` and γ = ``gamma`` bound in) returns
    ``(φ₁, φ'₁, w, E₁/I)`` when the engine's decisions accept the plain step (E₁/I is NaN
    where the energy check does not apply), and None when the careful path must take it;
    ``e0`` is E/I at the start or NaN if unknown. The text is :func:`fast_step_source`: the
    step is ``explicit.step_source`` and the decisions are the texts above, so this is the same
    code ``sweep`` runs on arrays, without the calls between its parts.
    """
    env: dict[str, object] = dict(SCALAR_ENV, n=n, reach=reach, v_acc=v_acc, INF=math.inf,
                                  NAN=math.nan, ENERGY_TOL=ENERGY_TOL, w2=w2, gamma=gamma,
                                  stiff_transient=stiff_transient)
    return define(fast_step_source(tableau, n, nonsmooth, reach, v_acc, check_energy), 'fast',
                  env, f'<fast {tableau.name}>')


def ain_bound(ain: float) -> float:
    """Return the power of two just above |a_in| (0 for 0): the torque octave of a fast range."""
    a = abs(ain)
    return 0.0 if a == 0.0 else 2.0 ** math.frexp(a)[1]


def ain_bounds(ain: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Return :func:`ain_bound` element-wise: the same floats (frexp and 2**e are exact)."""
    a = np.abs(ain)
    return np.where(a == 0.0, 0.0, np.ldexp(1.0, np.frexp(a)[1]))


__all__ = [
    'CROSS_SRC',
    'ENERGY_KEPT_SRC',
    'ENERGY_SRC',
    'ENERGY_TOL',
    'FAST_ENERGY_TEMPLATE',
    'FAST_STEP_TEMPLATE',
    'NEAR_SRC',
    'REFUSE_TEMPLATE',
    'REVERSAL_SRC',
    'ROSE_SRC',
    'STIFF_K',
    'STIFF_MAX_TRIALS',
    'STIFF_PAIR',
    'STIFF_TOL',
    'accuracy_speed',
    'ain_bound',
    'ain_bounds',
    'compile_fast_step',
    'energy_kept',
    'energy_kept_source',
    'energy_rose',
    'fast_step_source',
    'kept_stage',
    'reference_rate',
    'reversal_suspect',
    'specific_energy',
    'stiff_source',
    'stiff_transient',
]
