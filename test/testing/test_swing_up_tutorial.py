"""The swing-up benchmark tutorial's shell steps run as written: benchmark, read, your own law,
animate."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / 'docs' / 'tutorials' / 'swing-up-benchmark.md'


def bash_blocks() -> list[str]:
    """Return the page's ```bash blocks, in order."""
    return re.findall(r'^```bash\n(.*?)^```', PAGE.read_text(encoding='utf-8'), re.S | re.M)


def test_the_tutorial_benchmarks_reads_and_animates(tmp_path: Path) -> None:
    blocks = bash_blocks()
    assert len(blocks) == 4
    env = dict(os.environ)
    env['PATH'] = f'{Path(sys.executable).parent}{os.pathsep}{env["PATH"]}'
    outputs = []
    for block in blocks:
        res = subprocess.run(['bash', '-euo', 'pipefail', '-c', block], cwd=tmp_path, env=env,
                             capture_output=True, text=True, timeout=900, check=False)
        assert res.returncode == 0, f'{block}\n{res.stdout}\n{res.stderr}'
        outputs.append(res.stdout)
    # The table the page shows is the start of the one printed.
    shown = re.search(r'```text\n(.*?)\.\.\.\n```', PAGE.read_text(encoding='utf-8'), re.S)
    assert shown is not None and outputs[0].startswith(shown.group(1))
    doc = yaml.safe_load((tmp_path / 'bench' / 'benchmark.yaml').read_text())
    assert doc['consistency'] == 100.0 and doc['criteria']['roa']['grid'] == 12
    assert outputs[1].split()[:2] == [str(doc['swing_up_time']), str(doc['consistency'])]
    for name in ('benchmark.png', 'roa.png', 'swing_up.gif'):
        assert (tmp_path / 'bench' / name).is_file()
    mine = yaml.safe_load((tmp_path / 'mine' / 'benchmark.yaml').read_text())
    assert mine['consistency'] < 100.0 and 0 < mine['swing_up_time'] < 10   # pumps, no balance
    assert mine['criteria']['nominal']['swung_up'] == 0
    assert (tmp_path / 'pump.gif').stat().st_size > 1000


def test_the_figures_the_page_shows_are_in_the_tree() -> None:
    for name in re.findall(r'\]\(\.\./(_static/[^)]+)\)', PAGE.read_text(encoding='utf-8')):
        assert (ROOT / 'docs' / name).is_file(), name
