"""bench/record.py keeps what a benchmark prints, with its conditions, and only a good run."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
RECORD = ROOT / 'bench' / 'record.py'


def run_record(script: Path, *args: str) -> subprocess.CompletedProcess[str]:
    """Run the copy of record.py beside ``script`` on it."""
    return subprocess.run([sys.executable, str(script.parent / 'record.py'), str(script), *args],
                          capture_output=True, text=True, timeout=60, check=False)


@pytest.fixture
def bench_script(tmp_path: Path) -> Path:
    """A benchmark script in a scratch copy of bench/, so the real results stay untouched."""
    bench = tmp_path / 'bench'
    bench.mkdir()
    (bench / 'record.py').write_text(RECORD.read_text(encoding='utf-8'), encoding='utf-8')
    script = bench / 'bench_fake.py'
    script.write_text('import sys\nprint("ratio 0.5", sys.argv[1:])\n'
                      'sys.exit(int(sys.argv[1]) if sys.argv[1:] else 0)\n', encoding='utf-8')
    return script


def test_the_figures_are_kept_with_command_date_and_machine(bench_script: Path) -> None:
    done = run_record(bench_script, '0')
    assert done.returncode == 0, done.stderr
    assert "ratio 0.5 ['0']" in done.stdout          # shown as it comes
    text = (bench_script.parent / 'results' / 'bench_fake.txt').read_text(encoding='utf-8')
    lines = text.splitlines()
    assert lines[0] == f'command: python {bench_script} 0'
    assert [line.split(':')[0] for line in lines[1:5]] == ['date', 'machine', 'load', 'python']
    assert lines[-1] == "ratio 0.5 ['0']"


def test_a_failed_run_keeps_the_last_good_file(bench_script: Path) -> None:
    assert run_record(bench_script, '0').returncode == 0
    failed = run_record(bench_script, '3')
    assert failed.returncode == 3
    results = bench_script.parent / 'results'
    assert failed.stderr.strip() == (f'{bench_script} exited 3; output kept in '
                                     f'{results / "bench_fake.txt.part"}')
    assert (results / 'bench_fake.txt').read_text(encoding='utf-8').endswith("['0']\n")
    assert "['3']" in (results / 'bench_fake.txt.part').read_text(encoding='utf-8')
