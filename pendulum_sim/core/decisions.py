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

from .codegen import define
from .explicit import step_source, step_source_with_n
from .law import SCALAR_ENV, VECTOR_ENV, damping_expression, laws_source, power_source, whole
from .model import smooth_law
from .tableaus import DOP853, Tableau

ENERGY_TOL = 1e-12
"""An explicit step may raise the energy by round-off and by the conservative part of its
truncation error near turning points, where the damping removes almost nothing; anything above
this relative size (of E/I + ω0²) is a defect and the step is redone implicitly."""

CROSS_SRC = '(v1 * v < 0.0) | ((a0 * v < 0.0) & (abs(v) <= h * abs(a0)))'
NEAR_SRC = 'abs(v) < reach * abs(a0)'
REVERSAL_SRC = f'{CROSS_SRC} | ({NEAR_SRC})'
STIFF_SRC = '(abs(v) > v_acc) & (abs(a0) > 0.5 * gamma * ({power}))'
ENERGY_SRC = '0.5 * v * v + 2.0 * w2 * s * s'
ROSE_SRC = 'e1 > e0 + ENERGY_TOL * (e0 + w2)'
"""The fast path's decisions as source text, written once: compiled into the functions below
(which work on floats and numpy arrays: ``sweep`` and the careful path use them) and inlined
as they stand (``&`` and ``|`` take Python's and numba's bools as numpy's, every operand in
parentheses) into the Stepper's generated fast step
(:func:`compile_fast_step`) and the compiled sweep's run (:func:`kernel_source`).
``STIFF_SRC`` holds the damping's |φ'|^n as ``{power}``: :func:`stiff_source` fills it in
with the law's one power rule (``law.power_source``)."""

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
this factor the step is taken by error-controlled substeps instead (:meth:`Engine.stiff`)."""

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


def stiff_source(n: float) -> str:
    """Return the stiff-transient test for the exponent ``n`` as source (:data:`STIFF_SRC`).

    |φ'|^n is the damping law's power (``law.power_source``): multiplications for a whole n,
    ``sqrt`` for 0.5, ``abs(v) ** n`` for every other exponent (one text for all of those).
    """
    return STIFF_SRC.format(power=power_source(n, 'n'))


@functools.lru_cache(maxsize=256)
def _stiff(n: float, vector: bool) -> Any:
    env: dict[str, object] = dict(VECTOR_ENV if vector else SCALAR_ENV)
    return define(f'def f(v, a0, gamma, n, v_acc):\n    return {stiff_source(n)}\n', 'f', env,
                  '<decision>')


def stiff_transient(v: Any, a0: Any, gamma: Any, n: Any, v_acc: Any,
                    text: float | None = None) -> Any:
    """Return where a step starts in a damping-dominated transient too fast for a plain step.

    Above :func:`accuracy_speed` and with the net acceleration at least half the damping
    γ|φ'|^n (the damping is not balanced by gravity and input, as it is in a creep;
    :func:`stiff_source`). ``v`` a float or a numpy array, the others alike or floats; ``n``
    an array of exponents that share one text needs ``text``, one of them (whose text it is).
    """
    return _stiff(n if text is None else text, isinstance(v, np.ndarray))(v, a0, gamma, n,
                                                                         v_acc)


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


@functools.lru_cache(maxsize=256)
def compile_fast_step(tableau: Tableau, n: float, nonsmooth: bool, reach: float, v_acc: float,
                      check_energy: bool, w2: float, gamma: float) -> Any:
    """Compile the Stepper's fast path: one plain step and the fast-path decisions, inlined.

    ``fast(p0, v0, h, ain, e0)`` (ω0² = ``w2`` and γ = ``gamma`` bound in) returns
    ``(φ₁, φ'₁, w, E₁/I)`` when the engine's decisions accept the plain step (E₁/I is NaN
    where the energy check does not apply), and None when the careful path must take it;
    ``e0`` is E/I at the start or NaN if unknown.
    The step is ``explicit.step_source`` and the decisions are the ``*_SRC`` texts above, so
    this is the same code ``sweep`` runs on arrays, without the calls between its parts.
    """
    body = step_source(tableau, damping_expression(n, scalar=True)).splitlines()[1:-1]
    lines = ['def fast(p0, v0, h, ain, e0):', *body,
             '    if not (-INF < p1 < INF and -INF < v1 < INF):', '        return None',
             '    v = v0', '    a0 = a_0']
    if nonsmooth:
        test = REVERSAL_SRC if reach > 0.0 else CROSS_SRC
        lines += [f'    if {test}:', '        return None']
    if math.isfinite(v_acc):
        lines += [f'    if abs(v) > v_acc and {stiff_source(n)}:', '        return None']
    if check_energy:
        lines += ['    if ain != 0.0:', '        return p1, v1, w, NAN',
                  '    if e0 != e0:', '        s = sin(0.5 * p0)',
                  f'        e0 = {ENERGY_SRC}',
                  '    v = v1', '    s = sin(0.5 * p1)', f'    e1 = {ENERGY_SRC}',
                  f'    if {ROSE_SRC}:', '        return None', '    return p1, v1, w, e1']
    else:
        lines += ['    return p1, v1, w, NAN']
    env: dict[str, object] = dict(SCALAR_ENV, n=n, reach=reach, v_acc=v_acc, INF=math.inf,
                                  NAN=math.nan, ENERGY_TOL=ENERGY_TOL, w2=w2, gamma=gamma)
    return define('\n'.join(lines) + '\n', 'fast', env, f'<fast {tableau.name}>')


KERNEL_ARGS = ('P', 'V', 'E', 'K', 'IDX', 'h', 'count', 'AIN', 'W2', 'GAMMA', 'CF', 'NN',
               'LO', 'HI', 'REACH', 'V_ACC', 'CHECK', 'NONSMOOTH', 'COULOMB', 'VMAX', 'base',
               'every', 'total', 'RP', 'RV', 'COUNTS', 'CAREFUL', 'GUARD')
"""The arguments of a compiled sweep run (:func:`kernel_source`), arrays in capitals."""


def record_row(done: int, every: int, total: int, rows: int) -> int:
    """Return the row of the recording that holds the state after step ``done``, or −1.

    Row 0 is the start; a state is recorded every ``every`` steps and after the last step
    ``total`` (in the last of ``rows`` rows); ``every`` = 0 records nothing.
    """
    if every <= 0:
        return -1
    if done % every == 0:
        return done // every
    if done == total:
        return rows - 1
    return -1


def next_record(done: int, every: int, total: int) -> int:
    """Return the first step after ``done`` whose state :func:`record_row` records, or −1.

    The compiled run keeps it beside its step counter, so that a step that records nothing
    costs one comparison (no division).
    """
    if every <= 0 or done >= total:
        return -1
    return min((done // every + 1) * every, total)


@functools.lru_cache(maxsize=256)
def kernel_source(tableau: Tableau, n: float, friction: bool = False) -> str:
    """Return the sweep's run of many steps for one exponent, over arrays, as source text.

    ``kernel(P, V, E, K, IDX, h, count, AIN, W2, GAMMA, CF, NN, LO, HI, REACH, V_ACC, CHECK,
    NONSMOOTH, COULOMB, VMAX, base, every, total, RP, RV, COUNTS, CAREFUL, GUARD)``
    advances every pendulum ``i = IDX[j]`` (in parallel over j where compiled with
    ``prange``), its state ``(P[i], V[i], E[i])`` held in registers, from step ``K[i]`` to
    step ``count`` of size h, under the input ``AIN[0, i]`` (shape (1, N)) or, where ``AIN``
    is a schedule of shape (steps, N), ``AIN[base + k, i]`` in the step after ``base + k``.
    Each step is the plain step of ``explicit.step_source`` where the
    fast-path decisions accept it: the guard's range ``LO[i] <= |φ'| <= HI[i]``, a finite
    result, not a Coulomb pendulum at rest, the reversal test where ``NONSMOOTH[i]``, the
    stiff-transient test and, where ``CHECK[i]``, the energy test (E/I kept in ``E[i]``;
    where the method has a stage for it, :func:`kept_stage`, the sound pre-test
    :data:`ENERGY_KEPT_SRC` first, the energy test only where it cannot decide, and E/I made
    from the state where it is read after steps the pre-test accepted: the same floats); a
    text that serves one special exponent leaves out the tests its pendulums cannot fail.
    A refused step is taken, where ``CAREFUL[i]``, by ``careful_step`` (the careful path,
    ``compiled_careful.py``: Coulomb friction at rest, the near-Coulomb creep, the guard's
    substeps, the reversal split, the fallback, the stiff transient's error-controlled substeps
    (its test's |φ'|^n by ``law.power_formula``, the rule :func:`stiff_source` spells) and the
    energy redo; what it did counted in the row ``COUNTS[i]`` as ``compiled_careful.COUNTERS``
    orders them, ``GUARD`` the guard's ``StabilityGuard.constants``). The run stops at a step
    neither takes (``K[i]`` is then the step ``Engine.careful`` must take) or after a step that
    leaves |φ'| above ``VMAX[i]`` (the run's speed bound; the caller refuses to go on). The state
    after step ``base + k`` is written to the row :func:`record_row` gives of ``RP`` and ``RV``
    (the next such step kept by :func:`next_record`).
    The texts are the ``*_SRC`` above, as in :func:`compile_fast_step`;
    the exponent is read per pendulum (``NN[i]``), so one text serves every exponent whose law
    it spells alike, in one call.
    With ``friction`` the text serves pendulums with a Coulomb friction c_f = ``CF[i]`` beside
    the law: a moving step takes it as the input ``coulomb.moving_input`` of its direction
    (``a_in − copysign(c_f, φ'₀)``, the numpy sweep's floats), and the Coulomb rest and the
    reversal test are kept whatever the exponent (friction makes every law stick and kink at
    φ' = 0); the careful step gets the input a_in itself and c_f. Without it (``CF`` all
    zero) the text is as it was, the friction never read.
    The source also defines ``plain`` and ``branch``, the scalar steps (plain and branch law)
    with the exponent an argument (``explicit.step_source_with_n``), ``laws``, the two laws
    themselves (``law.laws_source``), and ``pair_plain`` and ``pair_branch``, the steps of
    STIFF_PAIR with error estimate (``stiff.stiff_pair``), which ``careful_step`` takes as
    arguments (compiled, as first-class functions: ``jit.first_class_twin`` compiles
    ``careful_step`` once for every text).
    """
    body = step_source(tableau, damping_expression(n, scalar=True)).splitlines()[1:-1]
    stiff = stiff_source(n)
    # A text serves its exponent alone where the law spells it specially (law.power_source):
    # a test that cannot refuse a step of that exponent is left out (Problem: Coulomb only at
    # n = 0, no kink for odd whole n, no stiff transient for n <= 1).
    special = n in (0.0, 0.5) or whole(n)
    tests = []
    if friction or not special or n == 0.0:
        tests += ['            if ok and coulomb and v == 0.0:', '                ok = False']
    if friction or not (special and smooth_law(n)):
        tests += [f'            if ok and nonsmooth and ({REVERSAL_SRC}):',
                  '                ok = False']
    if not special or n > 1.0:
        tests += [f'            if ok and av > v_acc and {stiff}:', '                ok = False']
    pad = '        '
    exact = ['e0 = e', 'v = v1', 's = sin(0.5 * p1)', f'e1 = {ENERGY_SRC}',
             f'if {ROSE_SRC}:', '    ok = False', 'else:', '    e = e1']
    stage = kept_stage(tableau)
    if stage is None:
        energy = [' ' * 16 + line for line in exact]
        renew = [' ' * 20 + line for line in ('v = v1', 's = sin(0.5 * p1)',
                                               f'e = {ENERGY_SRC}')]
        fresh = []
    else:
        # E/I is carried lazily: a step the pre-test accepts leaves it stale, and it is made
        # from (φ₀, φ'₀) by the same formula where it is read (the same float as carried).
        make = ['if stale:', '    v = v0', '    s = sin(0.5 * p0)', f'    e = {ENERGY_SRC}',
                '    stale = False']
        energy = [' ' * 16 + line for line in (
            *energy_kept_source(f'p_{stage}').splitlines(), 'if kept:', '    stale = True',
            'else:', *('    ' + x for x in (*make, *exact)))]
        renew = [' ' * 20 + 'stale = True']
        fresh = [' ' * 8 + line for line in make]
    lines = [*step_source_with_n(tableau, n, False, 'plain').splitlines(),
             *step_source_with_n(tableau, n, True, 'branch').splitlines(),
             *laws_source(n).splitlines(),
             *step_source_with_n(STIFF_PAIR, n, False, 'pair_plain', True).splitlines(),
             *step_source_with_n(STIFF_PAIR, n, True, 'pair_branch', True).splitlines(),
             f'def kernel({", ".join(KERNEL_ARGS)}):',
             '    rows = RP.shape[0]',
             # AIN is (1, N), one input per pendulum, or a schedule (steps, N): row base + k
             # is the input of step base + k + 1 of the stretch.
             '    rs = 1 if AIN.shape[0] > 1 else 0',
             '    for j in prange(IDX.shape[0]):',
             '        i = IDX[j]',
             '        w2 = W2[i]', '        gamma = GAMMA[i]',
             *(['        cf = CF[i]'] if friction else []),
             '        lo = LO[i]', '        hi = HI[i]', '        reach = REACH[i]',
             '        v_acc = V_ACC[i]', '        check = CHECK[i]',
             '        nonsmooth = NONSMOOTH[i]', '        coulomb = COULOMB[i]',
             '        vmax = VMAX[i]', '        n = NN[i]', '        use_careful = CAREFUL[i]',
             '        p0 = P[i]', '        v0 = V[i]', '        e = E[i]', '        k = K[i]',
             '        stale = False',
             '        nxt = next_record(base + k, every, total)',
             '        while k < count:',
             '            a_in = AIN[rs * (base + k), i]',
             pad + ('    ain = a_in if cf == 0.0 else a_in - copysign(cf, v0)' if friction
                    else '    ain = a_in'),
             # Outside the guard's range the run refuses the step before taking it: the
             # careful step then takes its plain step itself where it needs one.
             '            av = abs(v0)', '            known = lo <= av <= hi',
             '            if known:',
             *(pad + '    ' + line for line in body),
             '                v = v0', '                a0 = a_0',
             '                ok = -INF < p1 < INF and -INF < v1 < INF',
             *('    ' + line for line in tests),
             '                if ok and check:', *('    ' + line for line in energy),
             '            else:', '                ok = False', '                p1 = 0.0',
             '                v1 = 0.0', '                w = 0.0', '                a0 = 0.0',
             '            if not ok:',
             '                if not use_careful:', '                    break',
             '                done, p1, v1 = careful_step(',
             '                    plain, branch, laws, pair_plain, pair_branch, p0, v0, h, a_in,',
             '                    w2, gamma, n, ' + ('cf' if friction else '0.0')
             + ', v_acc, reach, check, nonsmooth, coulomb,',
             '                    GUARD, COUNTS[i], known, p1, v1, w, a0, lo, hi)',
             '                if not done:', '                    break',
             '                if check:', *renew,
             '            p0 = p1', '            v0 = v1', '            k += 1',
             '            if base + k == nxt:',
             '                r = record_row(nxt, every, total, rows)',
             '                RP[r, i] = p0', '                RV[r, i] = v0',
             '                nxt = next_record(nxt, every, total)',
             '            if not abs(v0) <= vmax:', '                break',
             *fresh,
             '        P[i] = p0', '        V[i] = v0', '        E[i] = e', '        K[i] = k']
    return '\n'.join(lines) + '\n'


def compile_kernel(tableau: Tableau, n: float, careful_step: Any, friction: bool = False) -> Any:
    """Return the Python function of :func:`kernel_source` (``jit.compile_kernel`` compiles it).

    ``careful_step`` is ``compiled_careful.careful_step``; ``friction`` as for
    :func:`kernel_source`. Run as Python, ``prange`` is
    ``range``: the same steps, one pendulum after another.
    """
    env: dict[str, object] = dict(SCALAR_ENV, INF=math.inf, ENERGY_TOL=ENERGY_TOL,
                                  prange=range, record_row=record_row,
                                  next_record=next_record, careful_step=careful_step)
    return define(kernel_source(tableau, n, friction), 'kernel', env,
                  f'<kernel {tableau.name}>')


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
    'KERNEL_ARGS',
    'NEAR_SRC',
    'REVERSAL_SRC',
    'ROSE_SRC',
    'STIFF_K',
    'STIFF_MAX_TRIALS',
    'STIFF_PAIR',
    'STIFF_SRC',
    'STIFF_TOL',
    'accuracy_speed',
    'ain_bound',
    'ain_bounds',
    'compile_fast_step',
    'compile_kernel',
    'energy_kept',
    'energy_kept_source',
    'energy_rose',
    'kept_stage',
    'kernel_source',
    'next_record',
    'record_row',
    'reference_rate',
    'reversal_suspect',
    'specific_energy',
    'stiff_source',
    'stiff_transient',
]
