"""The compiled sweep's disk cache (``jit_cache.py``): compiled once, loaded by later processes.

Each test runs real processes of the venv's Python on a cache directory of its own
(``PENDULUM_SIM_JIT_CACHE``) and reads what numba reports: every compile raises numba's
``numba:compile`` event, a load from the disk cache none. Oracle of the numbers: the first
process's sweep, to the bit (the same machine code, compiled or loaded). One law text (n = 2),
its serial and parallel runs: the first process pays one cold compile (some 30 s here).
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from pendulum_sim.core.careful import careful_step
from pendulum_sim.core.jit import available
from pendulum_sim.core.jit_cache import (
    ENV_VAR,
    JitCacheWarning,
    cache_dir,
    compiling,
    kernel_module,
    module_file,
    write_atomic,
)
from pendulum_sim.core.kernel import compile_kernel
from pendulum_sim.core.tableaus import TABLEAUS

pytestmark = pytest.mark.skipif(not available(), reason='numba is not installed (jit extra)')

SCRIPT = """\
import json, sys
import numpy as np
from numba.core import event
from pendulum_sim.core import jit_cache
from pendulum_sim.core.sweep import sweep
floats = []
with event.install_recorder('numba:compile') as rec:
    for size in (1, 600):  # the serial run, then the parallel one (compiled_sweep.PARALLEL_MIN)
        res = sweep(9.8, np.linspace(0.5, 30.0, size), 2.0, np.linspace(-2.0, 3.0, size),
                    np.linspace(-6.0, 6.0, size), 0.02, 1e-3, jit=True)
        floats += [x.hex() for x in (*res.phi.tolist(), *res.dphi.tolist())]
        floats += [str(int(res.substeps.sum())), str(int(res.reversals.sum()))]
print(json.dumps({'floats': floats, 'compiles': len(rec.buffer),
                  'events': dict(jit_cache.EVENTS)}))
"""


def run_process(cache: Path) -> tuple[dict[str, Any], str]:
    """Run :data:`SCRIPT` in a new process on the cache ``cache``; return its report, stderr."""
    env = dict(os.environ, **{ENV_VAR: str(cache)})
    out = subprocess.run([sys.executable, '-c', SCRIPT], capture_output=True, text=True,
                         env=env, check=True, timeout=900)
    return json.loads(out.stdout.strip().splitlines()[-1]), out.stderr


@pytest.fixture(scope='module')
def first(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    """A cache filled by a first process, and that process's report."""
    cache = tmp_path_factory.mktemp('jit')
    report, _ = run_process(cache)
    return cache, report


def test_the_first_process_compiles_and_a_second_one_loads_it_all(
        first: tuple[Path, dict[str, Any]]) -> None:
    cache, one = first
    assert one['compiles'] > 0
    assert one['events'].get('hits', 0) == 0 and one['events']['misses'] > 0
    two, err = run_process(cache)
    assert two['compiles'] == 0, err
    assert two['events'].get('misses', 0) == 0 and two['events']['hits'] > 0
    assert two['floats'] == one['floats']
    assert int(one['floats'][-1]) + int(one['floats'][-2]) > 0  # careful steps were taken


def test_an_unreadable_cache_file_is_compiled_anew(first: tuple[Path, dict[str, Any]]) -> None:
    # A truncated index and a garbled data file of numba's, a half-written module file: the
    # process compiles what they held (nothing else), gets the same floats, rewrites them.
    cache, one = first
    (tag,) = cache.iterdir()
    index = next((tag / 'serial').glob('*.nbi'))
    index.write_bytes(index.read_bytes()[:20])
    data = next((tag / 'functions').glob('*plain*.nbc'))
    data.write_bytes(b'not a pickle')
    (module,) = tag.glob('k_*.py')
    text = module.read_text()
    module.write_text(text[:len(text) // 2])
    two, err = run_process(cache)
    assert two['compiles'] > 0
    assert two['events']['unreadable'] == 2, err
    assert two['floats'] == one['floats']
    assert module.read_text() == text
    three, _ = run_process(cache)
    assert three['compiles'] == 0 and three['floats'] == one['floats']


def test_a_cache_that_cannot_be_written_compiles_in_memory_with_one_warning(
        tmp_path: Path, first: tuple[Path, dict[str, Any]]) -> None:
    _, one = first
    blocker = tmp_path / 'a_file'
    blocker.write_text('')
    report, err = run_process(blocker / 'jit')  # a directory below a file: never writable
    assert report['events'] == {'unwritable': 1}
    assert report['compiles'] > 0 and report['floats'] == one['floats']
    lines = [line for line in err.splitlines() if 'JitCacheWarning' in line]
    assert len(lines) == 1, err
    assert f'the jit cache {blocker / "jit"}' in lines[0]
    assert 'is not writable' in lines[0] and f'set {ENV_VAR}' in lines[0]


def test_a_module_file_is_named_by_its_text_and_rewritten_whole(tmp_path: Path) -> None:
    path = module_file(tmp_path, 'x = 1\n')
    assert path.read_text() == 'x = 1\n' and path.name.startswith('k_')
    assert module_file(tmp_path, 'x = 2\n') != path
    write_atomic(path, 'x = ')  # half a file under the text's name
    assert module_file(tmp_path, 'x = 1\n') == path and path.read_text() == 'x = 1\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [path.name, module_file(tmp_path, 'x = 2\n').name])  # no temporary files left


def test_a_cache_directory_removed_under_a_process_leaves_the_run_in_memory(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # The directory was writable when first used, then removed and a file put in its place:
    # the run's module file cannot be written, so the run is compiled in memory (None here),
    # after the warning, not a crash.
    monkeypatch.setenv(ENV_VAR, str(tmp_path / 'jit'))
    directory = cache_dir()
    assert directory is not None and directory.is_dir()
    shutil.rmtree(tmp_path / 'jit')
    (tmp_path / 'jit').write_text('')
    fn = compile_kernel(TABLEAUS['rk4'], 2.0, careful_step)
    with pytest.warns(JitCacheWarning, match=f'the jit cache {directory} is not writable'):
        assert kernel_module(fn) is None


def test_compiling_calls_back_once_where_numba_compiles_and_not_where_it_loads() -> None:
    # numba raises its compile event on a cache miss only: a new function compiles (one call,
    # however many functions compile in the block), one compiled already does not.
    import numba

    calls: list[bool] = []
    first_fn = numba.njit(lambda x: x + 1.0)
    with compiling(calls.append):
        assert first_fn(1.0) == 2.0 and first_fn(2.0) == 3.0
        assert numba.njit(lambda x: 2.0 * x)(1.5) == 3.0
    assert calls == [cache_dir() is not None]
    with compiling(calls.append):
        assert first_fn(3.0) == 4.0
    assert len(calls) == 1


def identify(csv: Path, out: Path, cache: Path) -> subprocess.CompletedProcess[str]:
    """Run ``pendulum_identify`` on ``csv`` (quadratic drag only) with the jit cache ``cache``."""
    env = dict(os.environ, **{ENV_VAR: str(cache)})
    script = Path(sys.executable).parent / 'pendulum_identify'
    return subprocess.run([str(script), str(csv), '--out', str(out), '--models', 'quadratic'],
                          capture_output=True, text=True, env=env, check=False, timeout=900)


@pytest.mark.slow
def test_pendulum_identify_says_when_it_compiles_and_only_then(tmp_path: Path) -> None:
    # A first run on a fresh cache compiles (one cold compile of the n = 2 law) and says so on
    # its progress line; a second run on that cache loads it all and says nothing of it.
    import numpy as np

    from pendulum_sim.core import PendulumParams, simulate
    from pendulum_sim.identify.cli import COMPILING

    run = simulate(PendulumParams.from_omega0_sq(9.8, 0.2, 2.0), 0.9, 0.0, 6.0, 1e-3)
    csv = tmp_path / 'swing.csv'
    np.savetxt(csv, np.c_[run.t[::20], run.phi[::20]], delimiter=',', header='t,position',
               comments='')
    cache = tmp_path / 'jit'
    cold = identify(csv, tmp_path / 'cold', cache)
    assert cold.returncode == 0, cold.stderr
    assert f'fitting quadratic (1/1): {COMPILING}' in cold.stderr
    warm = identify(csv, tmp_path / 'warm', cache)
    assert warm.returncode == 0, warm.stderr
    assert 'fitting quadratic (1/1)' in warm.stderr and 'compiling' not in warm.stderr
