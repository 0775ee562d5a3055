"""The swing-up benchmark tutorial's shell steps run as written: benchmark, read, your own law,
animate."""
from __future__ import annotations

import re
from pathlib import Path

import yaml
from doc_pages import ROOT, TUTORIALS, blocks, run_steps

PAGE = TUTORIALS / 'swing-up-benchmark.md'


def test_the_tutorial_benchmarks_reads_and_animates(tmp_path: Path) -> None:
    steps = blocks(PAGE, 'bash')
    assert len(steps) == 4
    outputs = run_steps(steps, tmp_path, timeout=900)
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
