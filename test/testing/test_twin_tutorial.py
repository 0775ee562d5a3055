"""The twin tutorial's shell steps run as written, and print what the page shows.

Each ``pendulum_twin`` step's output is held to the ```text block after it: the metrics, their
verdicts (inside the spread or not) and the fit in % as the page prints them.
"""
from __future__ import annotations

from pathlib import Path

import yaml
from doc_pages import TUTORIALS, blocks, run_steps

PAGE = TUTORIALS / 'twin.md'


def verdicts(text: str) -> tuple[str, list[tuple[str, str]]]:
    """Return the fit line and each metric row's (name, inside) of a printed report."""
    lines = text.splitlines()
    rows = [line.split() for line in lines[2:] if line.split()[:1] and
            line.split()[0] in ('rise_time', 'settling_time', 'overshoot', 'iae', 'max_effort')]
    return lines[0], [(r[0], r[-1]) for r in rows]


def test_the_tutorial_records_identifies_and_checks_the_twin(tmp_path: Path) -> None:
    steps, shown = blocks(PAGE, 'bash'), blocks(PAGE, 'text')
    assert (len(steps), len(shown)) == (4, 2)
    printed = [out for step, out in zip(steps, run_steps(steps, tmp_path), strict=True)
               if 'pendulum_twin' in step]
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
