"""The twin tutorial's shell steps run as written, and print what the page shows.

Each ``pendulum_twin`` step's output is held to the ```text block after it: the metrics, their
verdicts (inside the spread or not) and the fit in % as the page prints them.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / 'docs' / 'tutorials' / 'twin.md'


def blocks(kind: str) -> list[str]:
    """Return the page's fenced blocks of ``kind`` (bash, text), in order."""
    return re.findall(rf'^```{kind}\n(.*?)^```', PAGE.read_text(encoding='utf-8'), re.S | re.M)


def verdicts(text: str) -> tuple[str, list[tuple[str, str]]]:
    """Return the fit line and each metric row's (name, inside) of a printed report."""
    lines = text.splitlines()
    rows = [line.split() for line in lines[2:] if line.split()[:1] and
            line.split()[0] in ('rise_time', 'settling_time', 'overshoot', 'iae', 'max_effort')]
    return lines[0], [(r[0], r[-1]) for r in rows]


def test_the_tutorial_records_identifies_and_checks_the_twin(tmp_path: Path) -> None:
    steps, shown = blocks('bash'), blocks('text')
    assert (len(steps), len(shown)) == (4, 2)
    env = dict(os.environ)
    env['PATH'] = f'{Path(sys.executable).parent}{os.pathsep}{env["PATH"]}'
    printed = []
    for step in steps:
        res = subprocess.run(['bash', '-euo', 'pipefail', '-c', step], cwd=tmp_path, env=env,
                             capture_output=True, text=True, timeout=600, check=False)
        assert res.returncode == 0, f'{step}\n{res.stdout}\n{res.stderr}'
        if 'pendulum_twin' in step:
            printed.append(res.stdout)
    assert len(printed) == 2
    for out, page in zip(printed, shown, strict=True):
        assert verdicts(out) == verdicts(page), out
        assert out.splitlines()[-2] == page.splitlines()[-2]   # the spread's line
    # Without the sensor the twin misses the settling; with it every metric is inside.
    assert [v for _, v in verdicts(printed[0])[1]] == ['yes', 'NO', 'NO', 'NO', 'yes']
    assert [v for _, v in verdicts(printed[1])[1]] == ['yes'] * 5
    report = yaml.safe_load((tmp_path / 'twin_sensor' / 'twin.yaml').read_text())
    assert report['campaign']['episodes'] == 40 and report['campaign']['failed'] == 0
    assert sorted(p.name for p in (tmp_path / 'twin').iterdir()) == [
        'twin.csv', 'twin.png', 'twin.yaml']
