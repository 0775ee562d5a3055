"""Every evaluator of the damping law agrees with the one expression of ``core/law.py``.

The law D(φ') = γ φ'|φ'|^(n−1), its branch s γ |φ'|^n, its slope γ n |φ'|^(n−1) and its power
γ |φ'|^(n+1) (Quiroga and Ospina-Henao 2017, eq 15, 18-19, 26) are generated from one rule,
``law.power_source``. Each evaluator the core has (the compiled laws, the parameters' method,
the problem, the reversal's branch acceleration, the generated explicit steps over scalars and
arrays, the compiled steps, the slope and the dissipated power) must return the very float
that rule gives, down to the last bit, over exponents from Coulomb to n = 9 and speeds from 0
through the subnormals to overflow; and the rule itself must be the physics, γ|φ'|^n.
"""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from pendulum_sim.core import PendulumParams
from pendulum_sim.core.codegen import define
from pendulum_sim.core.explicit import compile_step
from pendulum_sim.core.jit import available as jit_available
from pendulum_sim.core.jit import numba_twin
from pendulum_sim.core.law import (
    SCALAR_ENV,
    SLOPE_SOURCE,
    VECTOR_ENV,
    compile_damping,
    compile_power,
    damping_derivative,
    damping_expression,
    power_formula,
    power_source,
    slope_formula,
)
from pendulum_sim.core.model import dissipated_power
from pendulum_sim.core.problem import Problem
from pendulum_sim.core.reversal import branch_accel
from pendulum_sim.core.rosenbrock import compile_rosenbrock
from pendulum_sim.core.tableaus import DOPRI5, RK4, RODAS4

EXPONENTS = (0.0, 0.001, 0.5, 1.0, 1.5, 2.0, 3.0, 5.23, 8.0, 9.0)
TINY = 5e-324
SPEEDS = (0.0, TINY, -TINY, 1e-300, -1e-300, 0.7, -0.7, 3.0, -3.0, 1e300, -1e300)
GAMMA = 0.7
ENV = {'abs': abs, 'sqrt': math.sqrt}


def _value(fn: Callable[[], float], sign: float) -> float:
    """Return fn(), with Python's OverflowError read as the inf compiled code gives."""
    try:
        with np.errstate(all='ignore'):
            return float(fn())
    except OverflowError:
        return math.copysign(math.inf, sign)


def _rule(text: str, vector: bool = False, **names: float) -> float:
    """Evaluate source of the rule with ``names``; an overflow is +inf.

    ``vector`` evaluates it over a one-element array with numpy, whose power differs from the
    C library's pow in the last bit for some arguments: array evaluators are held to that.
    """
    if vector:
        arrays = {k: np.array([x]) if k in 'va' else x for k, x in names.items()}
        return _value(lambda: np.ravel(eval(text, dict(VECTOR_ENV), arrays))[0], 1.0)
    return _value(lambda: eval(text, dict(ENV), dict(names)), 1.0)


def one_expression(n: float, v: float, gamma: float = GAMMA, vector: bool = False) -> float:
    """Return sgn(v) γ |v|^n as the one rule spells it (0 at rest, also for n = 0)."""
    if v == 0.0:
        return 0.0
    text = f'gamma * {power_source(n, "n")}'
    return math.copysign(_rule(text, vector, v=v, n=n, gamma=gamma), v)


def bits(x: float) -> bytes:
    return np.float64(x).tobytes()


def _same(got: float, want: float) -> bool:
    """Return True where two floats are the same (0.0 and -0.0 alike: the law is 0 at rest)."""
    return got == want or bits(got) == bits(want)


@pytest.mark.parametrize('n', EXPONENTS)
@pytest.mark.parametrize('v', SPEEDS)
def test_every_law_evaluator_returns_the_one_expression(n: float, v: float) -> None:
    want = one_expression(n, v)
    want_vec = one_expression(n, v, vector=True)
    s = 1.0 if v >= 0.0 else -1.0
    scalar = compile_damping(n)
    vector = compile_damping(n, vector=True)
    branch = compile_damping(n, branch=True)
    spelled = define(f'def law(v, gamma):\n    return {damping_expression(n, scalar=True)}\n',
                     'law', dict(SCALAR_ENV, n=n))  # the scalar spelling the steps are built of
    rk4 = compile_step(RK4, n)
    rk4_vec = compile_step(RK4, n, vector=True)
    got = {
        'compile_damping': _value(lambda: scalar(v, GAMMA, 1.0), s),
        'damping_expression(scalar)': _value(lambda: spelled(v, GAMMA), s),
        'PendulumParams.damping': _value(lambda: PendulumParams(gamma=GAMMA, n=n).damping(v), s),
        'Problem.damping': _value(lambda: Problem(9.8, GAMMA, n).damping(v), s),
        # a₀ = a_in − D(v₀) − ω0² sin φ₀ with a_in = ω0² = 0: the step's own law, negated
        # (h = 0, so that the later stages stay finite however fast v₀ is).
        'rk4 step': -_value(lambda: rk4(0.0, v, 0.0, 0.0, 0.0, GAMMA, 1.0)[3], -s),
    }
    got_vec = {
        'compile_damping(vector)': _value(lambda: vector(np.array([v]), GAMMA, 1.0)[0], s),
        'rk4 step(vector)': -_value(
            lambda: rk4_vec(np.zeros(1), np.array([v]), 0.0, 0.0, 0.0, GAMMA, 1.0)[3][0], -s),
    }
    if v != 0.0:  # the branch of the direction of motion is the law itself
        got['branch law'] = _value(lambda: branch(v, GAMMA, s), s)
        got['branch_accel'] = -_value(lambda: branch_accel(0.0, v, 0.0, s, GAMMA, n, 0.0), -s)
    differ = {k: x for k, x in got.items() if not _same(x, want)}
    differ.update({k: x for k, x in got_vec.items() if not _same(x, want_vec)})
    assert differ == {}, f'one expression gives {want!r} ({want_vec!r} with numpy)'


@pytest.mark.parametrize('n', EXPONENTS)
def test_the_one_expression_is_gamma_times_speed_to_the_n(n: float) -> None:
    """The rule is the law of eq 15: γ sgn(v) |v|^n to a few roundings (pow as reference)."""
    for v in SPEEDS:
        want = 0.0 if v == 0.0 else math.copysign(
            _value(lambda v=v: GAMMA * math.pow(abs(v), n), 1.0), v)  # type: ignore[misc]
        got = one_expression(n, v)
        if abs(want) < 1e-290 or math.isinf(want):  # subnormal or beyond float64: same class
            assert abs(got) < 1e-290 if abs(want) < 1e-290 else got == want
        else:
            assert got == pytest.approx(want, rel=10 * 2.0 ** -52)


def one_slope(n: float, v: float, gamma: float = GAMMA) -> float:
    """Return γ n |v|^(n−1) as the one rule spells it (inf for n < 1 at rest)."""
    if n == 1.0:
        return gamma
    if n == 0.0:
        return 0.0
    if v == 0.0:
        return math.inf if n < 1.0 else 0.0
    return _rule(f'gamma * n * ({power_source(n - 1.0, "(n - 1.0)", "a")})',
                 a=abs(v), n=n, gamma=gamma)


@pytest.mark.parametrize('n', EXPONENTS)
@pytest.mark.parametrize('v', SPEEDS)
def test_the_slope_is_the_one_rule_and_the_derivative_of_the_law(n: float, v: float) -> None:
    want = one_slope(n, v)
    assert _same(damping_derivative(GAMMA, n, v), want)
    assert _same(_value(lambda: slope_formula(GAMMA, n, v), 1.0), want)
    if 1e-3 <= abs(v) <= 10.0:
        # Central difference of the law itself (eq 18-19: d = ∂D/∂φ').
        dv = 1e-4 * abs(v)
        law = compile_damping(n)
        diff = (law(v + dv, GAMMA, 1.0) - law(v - dv, GAMMA, 1.0)) / (2.0 * dv)
        assert want == pytest.approx(diff, rel=1e-6)


def one_power(n: float, v: float, gamma_i: float, vector: bool = False) -> float:
    """Return γ I |v|^(n+1) as the one rule spells it."""
    text = f'gamma * {power_source(n + 1.0, "(n + 1.0)")}'
    return _rule(text, vector, v=v, n=n, gamma=gamma_i)


@pytest.mark.parametrize('n', EXPONENTS)
@pytest.mark.parametrize('v', SPEEDS)
def test_dissipated_power_is_the_one_rule_and_speed_times_the_law(n: float, v: float) -> None:
    params = PendulumParams(gamma=GAMMA, n=n)
    gi = GAMMA * params.inertia
    want = one_power(n, v, gi)
    assert _same(_value(lambda: dissipated_power(params, v), 1.0), want)
    got = _value(lambda: compile_power(n)(np.array([v]), gi)[0], 1.0)
    assert _same(got, one_power(n, v, gi, vector=True))
    # eq 26: the power is φ' times the damping torque I D(φ'), never negative.
    assert want >= 0.0
    torque = params.inertia * one_expression(n, v)
    if 1e-150 < abs(v) < 1e20:
        assert want == pytest.approx(v * torque, rel=10 * 2.0 ** -52)


@pytest.mark.skipif(not jit_available(), reason='numba is not installed (jit extra)')
@pytest.mark.parametrize('n', EXPONENTS)
def test_compiled_steps_and_slope_evaluate_the_one_expression(n: float) -> None:
    """The numba-compiled embedded step, Rosenbrock step and slope give the same floats."""
    import numba

    from pendulum_sim.core.jit import compile_step as jit_step

    dopri = jit_step(compile_step(DOPRI5, n, with_error=True))
    slope = numba.njit(slope_formula)
    rodas_py = compile_rosenbrock(RODAS4, n)
    rodas = jit_step(rodas_py)
    for v in SPEEDS:
        s = 1.0 if v >= 0.0 else -1.0
        assert _same(-dopri(0.0, v, 0.0, 0.0, 0.0, GAMMA, 1.0)[3], one_expression(n, v))
        assert _same(slope(GAMMA, n, v), one_slope(n, v))
        if abs(v) < 1e100:  # the Rosenbrock step uses the slope in its matrix
            want = _value(lambda v=v: rodas_py(0.1, v, 1e-3, 0.0, 9.8, GAMMA, 1.0)[1], s)
            got = rodas(0.1, v, 1e-3, 0.0, 9.8, GAMMA, 1.0)[1]
            assert _same(got, want) or (math.isnan(got) and math.isnan(want))


def test_the_slope_source_spells_each_special_exponent_by_the_rule() -> None:
    """n = 1.5 reads a sqrt, n = 2 … 9 multiplications, others one power of a name."""
    assert 'if n == 1.5:\n        return float(gamma * n * (sqrt(a)))' in SLOPE_SOURCE
    assert 'if n == 4.0:\n        return float(gamma * n * (a * a * a))' in SLOPE_SOURCE
    assert SLOPE_SOURCE.count('**') == 1
    assert SLOPE_SOURCE.endswith('    return float(gamma * n * (a ** (n - 1.0)))\n')


@pytest.mark.parametrize('n', (*EXPONENTS, 4.0, 6.0, 7.0))
@pytest.mark.parametrize('v', SPEEDS)
def test_the_run_time_power_is_the_one_rule(n: float, v: float) -> None:
    # power_formula(a, n) is |φ'|^n for an exponent known only at run time (code compiled once
    # for all exponents): the float power_source spells for that n, a product for whole n.
    a = abs(v)
    want = _rule(power_source(n, 'n', 'a'), a=a, n=n)
    assert _same(_value(lambda: power_formula(a, n), 1.0), want)
    if jit_available() and v == 3.0:
        assert _same(numba_twin(power_formula)(a, n), want)
