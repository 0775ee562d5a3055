"""One generic explicit Runge-Kutta step, compiled from a tableau for the pendulum's vector field.

A method is data (``tableaus.py``); this module turns a tableau and a damping law into a plain
Python function with the stages unrolled and zero coefficients dropped, so that the same data
gives both the reference semantics and a step fast enough for a 1 kHz real-time loop
(no per-step loops over arrays, no attribute look-ups).

The compiled step advances ``(φ, φ')`` by ``h`` under a constant input acceleration ``a_in = τ/I``
and returns ``(φ₁, φ'₁, w, a₀)``: the new state, the work done by damping per unit inertia
``w = h Σ bᵢ vᵢ Dᵢ`` (the same quadrature as the state, so the energy balance closes to the
method's own accuracy), and the acceleration at the start ``a₀`` (kept for reversal location).
"""
from __future__ import annotations

import math
from collections.abc import Callable

from .tableaus import Tableau

StepFn = Callable[[float, float, float, float], tuple[float, float, float, float]]
ErrStepFn = Callable[[float, float, float, float],
                     tuple[float, float, float, float, float, float]]
DampingFn = Callable[[float], float]


def damping_expression(n: float) -> str:
    """Return Python source for D(v) = γ v|v|^(n−1) specialised for the exponent ``n``.

    Integer exponents use multiplications (a power call costs as much as a whole stage); the
    expression reads the names ``v`` and ``gamma``. For n = 0 the value at v = 0 is 0: sticking
    is decided by the caller, never by this expression.
    """
    if n == 0.0:
        return '(gamma if v > 0.0 else (-gamma if v < 0.0 else 0.0))'
    if n == 1.0:
        return 'gamma * v'
    if n == int(n) and n <= 8:
        k = int(n)
        prod = ' * '.join(['v'] * k) if k % 2 == 1 else ' * '.join(['v'] * (k - 1)) + ' * abs(v)'
        return f'gamma * {prod}'
    return 'copysign(gamma * abs(v) ** n, v)'


def compile_damping(gamma: float, n: float) -> DampingFn:
    """Return D(v) = γ v|v|^(n−1) as a compiled function (D(0) = 0 for every n)."""
    src = f'def damping(v):\n    return {damping_expression(n)}\n'
    env: dict[str, object] = {'gamma': gamma, 'n': n, 'copysign': math.copysign}
    exec(src, env)
    return env['damping']  # type: ignore[return-value]


def _num(x: float) -> str:
    return repr(float(x))


def _stage_source(tableau: Tableau, damping: str, with_error: bool) -> str:
    s = tableau.stages
    A, B = tableau.A, tableau.B
    lines = ['def step(p0, v0, h, ain):']
    for i in range(s):
        if i == 0:
            lines.append('    p_0 = p0; v_0 = v0')
        else:
            dp = ' + '.join(f'{_num(A[i, j])} * v_{j}' for j in range(i) if A[i, j] != 0.0)
            dv = ' + '.join(f'{_num(A[i, j])} * a_{j}' for j in range(i) if A[i, j] != 0.0)
            lines.append(f'    p_{i} = p0 + h * ({dp or "0.0"})')
            lines.append(f'    v_{i} = v0 + h * ({dv or "0.0"})')
        used = B[i] != 0.0 or i == 0 or any(A[k, i] != 0.0 for k in range(i + 1, s))
        used = used or (with_error and tableau.E is not None and tableau.E[i] != 0.0)
        if not used:
            continue
        lines.append(f'    v = v_{i}')
        lines.append(f'    d_{i} = {damping}')
        lines.append(f'    a_{i} = ain - d_{i} - w2 * sin(p_{i})')
    nz = [i for i in range(s) if B[i] != 0.0]
    lines.append('    p1 = p0 + h * (' + ' + '.join(f'{_num(B[i])} * v_{i}' for i in nz) + ')')
    lines.append('    v1 = v0 + h * (' + ' + '.join(f'{_num(B[i])} * a_{i}' for i in nz) + ')')
    lines.append('    w = h * (' + ' + '.join(f'{_num(B[i])} * v_{i} * d_{i}' for i in nz) + ')')
    if with_error:
        assert tableau.E is not None
        ne = [i for i in range(s) if tableau.E[i] != 0.0]
        ep = ' + '.join(f'{_num(tableau.E[i])} * v_{i}' for i in ne)
        ev = ' + '.join(f'{_num(tableau.E[i])} * a_{i}' for i in ne)
        lines.append(f'    return p1, v1, w, a_0, h * ({ep}), h * ({ev})')
    else:
        lines.append('    return p1, v1, w, a_0')
    return '\n'.join(lines) + '\n'


def compile_step(tableau: Tableau, omega0_sq: float, gamma: float, n: float,
                 damping: DampingFn | None = None) -> StepFn:
    """Compile one explicit step of ``tableau`` for the pendulum with these parameters.

    ``damping`` overrides the damping law (used for Coulomb break-away, where the friction
    keeps one sign over the step); otherwise the law is specialised for ``n``.
    """
    return _compile(tableau, omega0_sq, gamma, n, damping, with_error=False)  # type: ignore


def compile_error_step(tableau: Tableau, omega0_sq: float, gamma: float, n: float,
                       damping: DampingFn | None = None) -> ErrStepFn:
    """Compile an embedded-pair step that also returns the local error estimate (eφ, eφ')."""
    if tableau.E is None:
        raise ValueError(f'{tableau.name} has no embedded error estimate')
    return _compile(tableau, omega0_sq, gamma, n, damping, with_error=True)  # type: ignore


def _compile(tableau: Tableau, omega0_sq: float, gamma: float, n: float,
             damping: DampingFn | None, with_error: bool) -> object:
    if not tableau.explicit:
        raise ValueError(f'{tableau.name} is not an explicit method')
    expr = 'dmp(v)' if damping is not None else damping_expression(n)
    src = _stage_source(tableau, expr, with_error)
    env: dict[str, object] = {
        'sin': math.sin, 'copysign': math.copysign, 'w2': omega0_sq, 'gamma': gamma, 'n': n,
        'dmp': damping,
    }
    exec(compile(src, f'<{tableau.name} step>', 'exec'), env)
    return env['step']
