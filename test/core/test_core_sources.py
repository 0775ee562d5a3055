"""Generated sources: templates that read as code, and the files written for review are what runs.

Oracles: Python's own parser and compiler (a template with its holes stubbed is a function; every
written file compiles), and the functions the core runs (``codegen.source_of`` gives the text a
function was defined from: the compiled sweep's run, the Stepper's fast step, the laws).
"""
from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from pendulum_sim.core import PendulumParams, Stepper, decisions, kernel
from pendulum_sim.core.careful import careful_step
from pendulum_sim.core.codegen import fill, source_of
from pendulum_sim.core.dirk import damping_formula
from pendulum_sim.core.kernel import compile_kernel
from pendulum_sim.core.law import power_formula, slope_formula
from pendulum_sim.core.methods import METHODS
from pendulum_sim.core.reversal import locate_on_branch, locate_reversal
from pendulum_sim.core.sources import LAW_TEXTS, SWEEP_GAMMA, SWEEP_W2, main

REPO = Path(__file__).resolve().parents[2]

TEMPLATE = """\
def f(x, y):
    z = $first
    if z > 0.0:
        $block
    return z
"""


def test_a_block_hole_takes_lines_at_its_indentation_and_a_line_hole_one_line() -> None:
    got = fill(TEMPLATE, first='x + y', block='z = -z\nif y:\n    z += 1.0')
    assert got == ('def f(x, y):\n    z = x + y\n    if z > 0.0:\n        z = -z\n'
                   '        if y:\n            z += 1.0\n    return z\n')
    assert fill(TEMPLATE, first='x', block='') == (
        'def f(x, y):\n    z = x\n    if z > 0.0:\n    return z\n')


def test_a_template_refuses_a_hole_not_given_a_value_without_a_hole_and_lines_in_a_line(
) -> None:
    with pytest.raises(KeyError, match=re.escape('the template has a hole $block that was not '
                                                 'given')):
        fill(TEMPLATE, first='x')
    with pytest.raises(KeyError, match=re.escape('no hole in the template for extra')):
        fill(TEMPLATE, first='x', block='pass', extra='1')
    with pytest.raises(ValueError, match=re.escape('the hole $first is within a line: its '
                                                   'value must be one line')):
        fill(TEMPLATE, first='x\ny', block='pass')


TEMPLATES = [kernel.KERNEL_TEMPLATE, kernel.TEST_TEMPLATE, kernel.ENERGY_EXACT_TEMPLATE,
             kernel.ENERGY_LAZY_TEMPLATE, kernel.ENERGY_MADE_TEMPLATE,
             kernel.ENERGY_RENEWED_TEMPLATE, decisions.FAST_STEP_TEMPLATE,
             decisions.REFUSE_TEMPLATE, decisions.FAST_ENERGY_TEMPLATE]


@pytest.mark.parametrize('template', TEMPLATES)
def test_each_template_is_python_with_named_holes(template: str) -> None:
    # A block hole stands where a statement stands and a line hole where an expression does:
    # stubbed (pass, a name), the template parses as Python as it is written.
    stubbed = re.sub(r'^(\s*)\$\w+\s*$', r'\1pass', template, flags=re.MULTILINE)
    stubbed = re.sub(r'\$(\w+)', r'\1', stubbed)
    ast.parse(stubbed)
    assert '$' in template


def _stepper_fast(method: str, n: float) -> object:
    """Return the Stepper's compiled fast step for the written pendulum of exponent ``n``."""
    st = Stepper(PendulumParams.from_omega0_sq(SWEEP_W2, SWEEP_GAMMA, n), 0.5, 0.0, 1e-3,
                 method=method)
    return st._fast_fn


def test_the_written_sources_compile_and_are_the_texts_that_run(tmp_path: Path) -> None:
    assert main(['--write', str(tmp_path / 'gen')]) == 0
    files = {p.name: p.read_text(encoding='utf-8') for p in (tmp_path / 'gen').iterdir()}
    for name, text in files.items():
        compile(text, name, 'exec')  # each is Python as written
    explicit = [m for m in METHODS.values() if m.family.fast_path]
    assert len(files) == 3 * len(explicit) * len(LAW_TEXTS) + 2
    for meth in explicit:
        for n in LAW_TEXTS:
            tag = f'n{n:g}'
            for friction, suffix in ((False, ''), (True, '_friction')):
                run = compile_kernel(meth.tableau, n, careful_step, friction)
                assert files[f'kernel_{meth.name}_{tag}{suffix}.py'] == source_of(run)
            assert files[f'fast_{meth.name}_{tag}.py'] == source_of(_stepper_fast(meth.name, n))
    for fn in (slope_formula, power_formula, damping_formula):
        text = source_of(fn)
        assert text is not None and text in files['laws.py']
    for fn in (locate_reversal, locate_on_branch):
        text = source_of(fn)
        assert text is not None and text in files['locate.py']


def test_the_command_writes_the_sources_and_refuses_a_file_for_a_directory(
        tmp_path: Path) -> None:
    env = dict(os.environ, PYTHONPATH=str(REPO))
    out = tmp_path / 'review'
    ok = subprocess.run([sys.executable, '-m', 'pendulum_sim.core.sources', '--write', str(out)],
                        capture_output=True, text=True, env=env, timeout=120, check=False)
    assert ok.returncode == 0, ok.stderr
    assert ok.stdout == f'wrote {len(list(out.iterdir()))} generated sources into {out}\n'
    blocker = tmp_path / 'file'
    blocker.write_text('')
    bad = subprocess.run([sys.executable, '-m', 'pendulum_sim.core.sources', '--write',
                          str(blocker)], capture_output=True, text=True, env=env, timeout=120,
                         check=False)
    assert bad.returncode == 2
    assert bad.stderr == f'sources: --write {blocker} is not a directory\n'
    assert blocker.read_text() == ''
