"""Velocity reversals where the damping is not smooth: locating one, grading steps near it.

Where the law φ'|φ'|^(n−1) is not smooth at φ' = 0 (n even, non-integer, or 0) a step is split
at a reversal, and for non-integer n < 3 the steps within a window of it are graded
(:func:`graded_mesh`) so the method keeps its order. The location (a Hermite guess,
:func:`hermite_root`, then Newton on the partial step's own φ'(θh)) is written once, as the
source text :data:`LOCATE_SRC` with its two evaluations as named fields, and defined in two
forms by ``codegen.define``: :func:`locate_reversal` on Python callables (the explicit family's
split, ``split.py``, and the embedded cover's reversal cut, ``embedded.py``) and
:func:`locate_on_branch` on a generated branch step, which numba compiles for the compiled
careful step (``careful.py``). What follows the location in a split, the Newton run on
a graded run's own φ'(θh) and the landing on φ' = 0 (:func:`graded_landing`, over
:func:`branch_run`), is one function written to compile, which ``split.split_step`` calls in
Python and compiled alike.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from .codegen import define
from .law import compile_damping

GRADE_WINDOW = 1.0
"""Laws graded at reversals: the window, in units of 1/ω0 (1 s without gravity), on either
side of a reversal inside which steps are graded (:func:`graded_mesh`)."""


def grade_window(omega0: float) -> float:
    """Return the time S on either side of a reversal within which steps are graded."""
    return GRADE_WINDOW / omega0 if omega0 > 0.0 else GRADE_WINDOW


def graded_law(n: float) -> bool:
    """Return True where steps next to a reversal need grading: non-integer 0 < n < 3."""
    return 0.0 < n < 3.0 and n != int(n)


HERMITE_ITERATIONS = 60
""":func:`hermite_root`'s iterations at most (Newton safeguarded by bisection)."""


def hermite_root(v0: float, v1: float, dv0: float, dv1: float) -> float:
    """Return θ in (0, 1) where the cubic Hermite interpolant of φ' vanishes.

    ``v0``, ``v1`` are φ' at both ends (opposite signs), ``dv0``, ``dv1`` the derivatives
    h φ''. Newton's method, safeguarded by bisection on the bracket.
    """
    lo, hi = 0.0, 1.0
    flo = v0
    th = v0 / (v0 - v1)
    for _ in range(HERMITE_ITERATIONS):
        t2 = th * th
        t3 = t2 * th
        f = ((2 * t3 - 3 * t2 + 1) * v0 + (t3 - 2 * t2 + th) * dv0
             + (-2 * t3 + 3 * t2) * v1 + (t3 - t2) * dv1)
        if f == 0.0:
            return th
        if (f < 0.0) == (flo < 0.0):
            lo = th
        else:
            hi = th
        df = ((6 * t2 - 6 * th) * v0 + (3 * t2 - 4 * th + 1) * dv0
              + (-6 * t2 + 6 * th) * v1 + (3 * t2 - 2 * th) * dv1)
        nt = th - f / df if df != 0.0 else 0.5 * (lo + hi)
        if not lo < nt < hi:
            nt = 0.5 * (lo + hi)
        if abs(nt - th) <= 1e-15:
            return nt
        th = nt
    return th


def branch_accel(p: float, v: float, ain: float, sign: float, gamma: float, n: float,
                 w2: float) -> float:
    """Return φ'' on the damping branch ``sign``: a_in − s γ |φ'|^n − ω0² sin φ (eq 16).

    The branch law is the generated one (``law.damping_expression``), as in the steps.
    """
    return float(ain - compile_damping(n, True)(v, gamma, sign) - w2 * math.sin(p))


NEWTON_TOL = 1e-14
NEWTON_ITERATIONS = 4
"""The split of a plain step (``split.split_step``, in Python and compiled): Newton on the
partial step's own φ'(θh) until |φ'| <= NEWTON_TOL |φ'₀|, for NEWTON_ITERATIONS at most."""
GRADED_TOL = 1e-13
GRADED_ITERATIONS = 3
"""The same split's Newton on a graded run's own φ'(θh) = 0 (:func:`graded_landing`)."""
CUT_TOL = 1e-15
CUT_ITERATIONS = 8
"""The embedded cover's reversal cut (``embedded.cover``): Newton's tolerance and iterations."""

LOCATE_SRC = """\
def {name}({params}):
    th = hermite_root(v, v1, h * a0, h * a1)
    pm, vm, wm = {at}
    for _ in range(iterations):
        if abs(vm) <= tol * abs(v):
            break
        acc = {accel}
        if acc == 0.0:
            break
        nth = th - vm / (acc * h)
        if not 0.0 < nth < 1.0:
            break
        th = nth
        pm, vm, wm = {at}
    return th, pm, vm, wm
"""
"""The reversal location, written once: a step of h from φ' = ``v`` to ``v1`` reverses at θh.

The first guess is the root of the cubic Hermite interpolant of φ' (:func:`hermite_root`, end
slopes h ``a0`` and h ``a1``, φ'' on the start's branch); Newton iterations on the partial
step's own φ'(θh) then put θ where the method itself says φ' = 0, until |φ'| <= ``tol`` |v|
or for ``iterations`` at most; a Newton step that leaves (0, 1) ends them. Returns
``(θ, φ, φ', w)`` at θh. The two evaluations are named fields: ``{at}``, the partial step's
(φ, φ', w) at θh, and ``{accel}``, the branch's φ'' at (``pm``, ``vm``); each form in
:data:`LOCATE_FORMS` fills them with calls of its own (:func:`locate_form`).
"""

LOCATE_FORMS: dict[str, tuple[str, str, str]] = {
    'locate_reversal': ('at, accel, v, v1, a0, a1, h, tol, iterations',
                        'at(th * h)', 'accel(pm, vm)'),
    'locate_on_branch': ('branch, p, v, v1, a0, a1, h, ain, w2, gamma, sign, n, tol, iterations',
                         'branch(p, v, th * h, ain, w2, gamma, sign, n)[:3]',
                         'branch(pm, vm, 0.0, ain, w2, gamma, sign, n)[3]'),
}
"""The forms of :data:`LOCATE_SRC`: name → (parameters, the ``at`` call, the ``accel`` call).

``locate_reversal`` takes Python callables (``at(θh)`` → (φ, φ', w), ``accel(φ, φ')`` → φ''),
for the explicit family's split (``split.py``) and the embedded cover's reversal cut
(``embedded.py``). ``locate_on_branch`` calls a generated branch step
``branch(φ, φ', dt, a_in, ω0², γ, s, n)`` → (φ₁, φ'₁, w, φ''₀) itself (its φ'' is the step's
φ''₀ at dt = 0), so numba compiles it for the compiled careful step (``careful.py``),
which cannot pass Python closures.
"""

LocateFn = Callable[..., tuple[float, float, float, float]]


def locate_form(name: str) -> LocateFn:
    """Return the form ``name`` of :data:`LOCATE_FORMS`, defined from :data:`LOCATE_SRC`."""
    params, at, accel = LOCATE_FORMS[name]
    src = LOCATE_SRC.format(name=name, params=params, at=at, accel=accel)
    fn: LocateFn = define(src, name, {'hermite_root': hermite_root, '__name__': __name__},
                          f'<{name}>')
    fn.__doc__ = (f"Return (θ, φ, φ', w) where a step of h from φ' = v to v1 reverses "
                  f'(reversal.LOCATE_SRC, its form {name!r}).')
    return fn


locate_reversal = locate_form('locate_reversal')
"""``locate_reversal(at, accel, v, v1, a0, a1, h, tol, iterations)`` → (θ, φ, φ', w).

The reversal location (:data:`LOCATE_SRC`) on Python callables: ``at(θh)`` returns the partial
step's φ, φ', w, ``accel(φ, φ')`` the branch's φ'' (:func:`branch_accel`).
"""

locate_on_branch = locate_form('locate_on_branch')
"""``locate_on_branch(branch, p, v, v1, a0, a1, h, ain, w2, gamma, sign, n, tol, iterations)``.

The reversal location (:data:`LOCATE_SRC`) on a generated branch step from (``p``, ``v``), its
arguments passed on; numba compiles it (``split.split_step`` in the compiled careful step).
"""


def branch_run(branch: Any, p: float, v: float, lens: list[float], back: bool, ain: float,
               w2: float, gamma: float, sign: float, n: float) -> tuple[float, float, float]:
    """Return (φ, φ', w) after branch steps of the lengths ``lens`` (in reverse where ``back``).

    ``branch(φ, φ', dt, a_in, ω0², γ, s, n)`` is the generated branch step with the exponent an
    argument (``explicit.step_source_with_n``); ``w`` sums the steps' damping work.
    """
    m = len(lens)
    w = 0.0
    for k in range(m):
        p, v, wi, _ = branch(p, v, lens[m - 1 - k] if back else lens[k], ain, w2, gamma, sign,
                             n)
        w += wi
    return p, v, w


def graded_landing(branch: Any, laws: Any, p: float, v: float, th: float, pm: float,
                   vm: float, wm: float, h: float, ain: float, w2: float, gamma: float,
                   sign: float, n: float, reach: float) -> tuple[float, float, float, float]:
    """Return the reversal at θh of a step from (φ, φ') = (``p``, ``v``) as graded steps see it.

    ``(th, pm, vm, wm)`` is the location by one partial step (:data:`LOCATE_SRC`); where the
    first side is graded (:func:`graded_mesh`), Newton iterations on the graded run's own
    φ'(θh) = 0 move θ (its θ differs from the single step's by the single step's O(h^(n+1))
    error; GRADED_TOL, GRADED_ITERATIONS), and a last Newton step in time lands the run on
    φ' = 0 exactly, its damping work on the branch law (``laws``: ``law.compile_laws(n)`` or
    its compiled form). Returns (θ, φ, φ', w) at the reversal. Written to compile: the split
    of ``split.split_step`` calls it in Python and compiled alike.
    """
    lens = graded_mesh(0.0, th * h, h, n, reach)
    if len(lens) > 1:
        acc = 0.0
        for _ in range(GRADED_ITERATIONS):
            pm, vm, wm = branch_run(branch, p, v, lens, True, ain, w2, gamma, sign, n)
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
            wm += dt * vm * laws(vm, gamma, sign, n)[1]
            vm = 0.0
            th += dt / h
    return th, pm, vm, wm


def graded_mesh(x_a: float, x_b: float, h: float, n: float, window: float) -> list[float]:
    """Return substep lengths covering distances [x_a, x_b] (s) from a velocity reversal.

    On either side of a reversal the damping branch s γ |φ'|^n with φ' ∝ t is only as smooth
    as t^n, so a plain step at distance x from it has a local error h^5 x^(n−4), which summed
    over the steps near the reversal is O(h^(n+1)): for non-integer n < 3 that lowers RK4's
    order. Substeps of δ(x) = h (x/S)^α with α = 1 − (n+1)/5 inside the window S (and h
    beyond) make every substep's error h^5 S^(n−4), so the order is kept for about
    (5/(n+1) − 1) S/h extra substeps per side (the classic graded mesh for a t^n singularity;
    e.g. Brunner, *Collocation Methods for Volterra Integral and Related Functional Equations*,
    2004, section 2.4). The lengths are listed from x_a outwards.
    """
    length = x_b - x_a
    if not graded_law(n) or length <= 0.0 or x_a >= window:
        return [length]
    alpha = 1.0 - (n + 1.0) / 5.0
    first = window * (h / window) ** (1.0 / (1.0 - alpha))  # δ(x) = x at the reversal
    lens: list[float] = []
    x = x_a
    while x < x_b:
        d = h if x >= window else max(first, h * (x / window) ** alpha)
        d = min(d, x_b - x)
        if x_b - x - d < 1e-3 * d:
            d = x_b - x
        lens.append(d)
        x += d
    lens[-1] += length - sum(lens)  # land on the end exactly
    return lens


__all__ = [
    'CUT_ITERATIONS',
    'CUT_TOL',
    'GRADED_ITERATIONS',
    'GRADED_TOL',
    'GRADE_WINDOW',
    'HERMITE_ITERATIONS',
    'LOCATE_FORMS',
    'LOCATE_SRC',
    'NEWTON_ITERATIONS',
    'NEWTON_TOL',
    'LocateFn',
    'branch_accel',
    'branch_run',
    'grade_window',
    'graded_landing',
    'graded_law',
    'graded_mesh',
    'hermite_root',
    'locate_form',
    'locate_on_branch',
    'locate_reversal',
]
