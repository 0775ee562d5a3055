"""The reversal location: one source text, its Python and compiled forms locating alike."""
from __future__ import annotations

import ast
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pendulum_sim.core import careful, engine, reversal, split
from pendulum_sim.core.careful import careful_step
from pendulum_sim.core.explicit import compile_step
from pendulum_sim.core.jit import available, numba_twin
from pendulum_sim.core.kernel import compile_kernel, kernel_source
from pendulum_sim.core.reversal import (
    NEWTON_ITERATIONS,
    NEWTON_TOL,
    branch_accel,
    locate_on_branch,
    locate_reversal,
)
from pendulum_sim.core.tableaus import TABLEAUS


def test_both_forms_are_defined_from_the_one_source_text() -> None:
    # Each form is LOCATE_SRC with its own calls in the two named fields, nothing else.
    for name, fn in (('locate_reversal', locate_reversal), ('locate_on_branch', locate_on_branch)):
        params = reversal.LOCATE_FORMS[name][0]
        assert fn.__name__ == name
        assert fn.__code__.co_filename == f'<{name}>'
        assert fn.__code__.co_varnames[:len(params.split(', '))] == tuple(params.split(', '))
        again = reversal.locate_form(name)
        assert again.__code__ is fn.__code__  # codegen.define: one compile per text


def _closures(branch_fn: Any, p: float, v: float, ain: float, w2: float, gamma: float,
              sign: float, n: float) -> tuple[Any, Any]:
    """Return the closures ``at`` and ``accel`` of ``locate_reversal`` for a branch step."""
    def at(x: float) -> tuple[float, float, float]:
        pa, va, wa, _ = branch_fn(p, v, x, ain, w2, gamma, sign)
        return pa, va, wa

    def accel(pp: float, vv: float) -> float:
        return branch_accel(pp, vv, ain, sign, gamma, n, w2)

    return at, accel


@pytest.mark.parametrize('n', [2.0, 2.5, 3.7, 4.0])
def test_the_branch_form_locates_where_the_closures_do(n: float) -> None:
    # A branch step of h that reverses: both forms must return the same (θ, φ, φ', w) to the
    # bit (with the split's tolerances), and φ' at θh must be ~0.
    branch_fn = compile_step(TABLEAUS['rk4'], n, branch=True)
    branch = compile_kernel(TABLEAUS['rk4'], n, careful_step).__globals__['branch']
    compiled = (numba_twin(locate_on_branch), numba_twin(branch)) if available() else None
    rng = np.random.default_rng(int(10 * n))
    located = 0
    for _ in range(200):
        gamma = float(rng.choice([0.1, 1.0, 30.0]))
        w2 = float(rng.choice([0.0, 9.8, 40.0]))
        h = float(rng.choice([1e-3, 2e-2]))
        ain = float(rng.choice([0.0, 1.7, -3.0]))
        p = float(rng.uniform(-3.0, 3.0))
        v = float(rng.uniform(-0.05, 0.05))
        sign = 1.0 if v > 0.0 else -1.0
        p1, v1, _, a0 = branch_fn(p, v, h, ain, w2, gamma, sign)
        if not v1 * v < 0.0:
            continue

        at, accel = _closures(branch_fn, p, v, ain, w2, gamma, sign, n)
        a1 = accel(p1, v1)
        assert branch(p1, v1, 0.0, ain, w2, gamma, sign, n)[3] == a1
        want = locate_reversal(at, accel, v, v1, a0, a1, h, NEWTON_TOL, NEWTON_ITERATIONS)
        args = (p, v, v1, a0, a1, h, ain, w2, gamma, sign, n, NEWTON_TOL, NEWTON_ITERATIONS)
        assert locate_on_branch(branch, *args) == want
        if compiled is not None:
            assert compiled[0](compiled[1], *args) == want
        th, _, vm, _ = want
        assert 0.0 < th < 1.0
        assert abs(vm) <= 1e-12 * abs(v)
        located += 1
    assert located > 30


def test_the_split_and_its_graded_newton_run_are_written_once() -> None:
    # The Newton run on a graded run's own φ'(θh) after the location is one function,
    # reversal.graded_landing, the only reader of its iteration bound; split.split_step calls
    # it, split.micro_step (the plain step, split at a reversal) calls split_step, and the one
    # careful step calls micro_step (careful.substep under careful.guarded under
    # careful.careful_step), the friction decisions after a reversal being coulomb's
    # (rest_step, creep_state). The careful step settles its result by careful_settle: the
    # Stepper's engine runs it as Python, the compiled sweep's run and the numpy sweep's
    # refused steps (careful_each) compiled. No other form of any of these exists.
    core = Path(reversal.__file__).parent
    users = {f.name for f in core.glob('*.py') if 'GRADED_ITERATIONS' in f.read_text('utf-8')}
    assert users == {'reversal.py'}
    assert {'graded_landing', 'locate_on_branch', 'rest_step',
            'creep_state'} <= set(split.split_step.__code__.co_names)
    assert {'split_step', 'rest_step'} <= set(split.micro_step.__code__.co_names)
    assert careful.micro_step is split.micro_step
    assert 'micro_step' in careful.substep.__code__.co_names
    assert 'substep' in careful.guarded.__code__.co_names
    assert {'friction_step', 'stiff_transient', 'stiff_cover', 'guarded',
            'careful_settle'} <= set(careful.careful_step.__code__.co_names)
    assert 'careful_step' in careful.careful_each.__code__.co_names
    assert {'careful_step', 'careful_settle'} <= set(engine.Engine.careful.__code__.co_names)
    assert 'careful_step(' in kernel_source(TABLEAUS['rk4'], 1.5)


RULES = ('rest_direction', 'rest_step', 'creep_state', 'friction_step', 'moving_input',
         'hermite_root', 'graded_mesh', 'branch_run', 'graded_landing', 'split_step',
         'micro_step', 'reversal_suspect', 'substep_count', 'safe_speed_range',
         'stiff_transient', 'stiff_cover', 'fallback_run', 'redo', 'careful_step')
"""The careful step's rules: rest, reversal (location, graded landing), guard count, safe speed
range, stiff test, moving friction input, fallback, energy redo, and the step itself."""


def test_each_rule_of_the_careful_step_is_defined_once() -> None:
    # Every function the core defines, by name: each rule once, and no array copy of one
    # (the numpy sweep's former masked forms were named by their plurals).
    defined: dict[str, list[str]] = {}
    for path in sorted(Path(reversal.__file__).parent.glob('*.py')):
        for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
            if isinstance(node, ast.FunctionDef):
                defined.setdefault(node.name, []).append(path.name)
    for rule in RULES:
        assert len(defined.get(rule, [])) == 1, (rule, defined.get(rule))
    copies = {'graded_meshes', 'branch_runs', 'hermite_roots', 'locate_on_branches',
              'graded_landings', 'split_steps', 'careful_steps', 'graded_steps'}
    assert not copies & set(defined)
    # The reversal location is one text (LOCATE_SRC) in its two forms, not a definition.
    assert 'locate_on_branch' not in defined and 'locate_reversal' not in defined
