"""The identification tutorial's shell steps run as written: record, identify, campaign."""
from __future__ import annotations

from pathlib import Path

import yaml
from doc_pages import TUTORIALS, blocks, run_steps

from pendulum_sim.joint.scenes import read_params_file

PAGE = TUTORIALS / 'identify.md'


def test_the_tutorial_records_identifies_and_runs_a_campaign(tmp_path: Path) -> None:
    steps = blocks(PAGE, 'bash')
    assert len(steps) == 4
    run_steps(steps, tmp_path)
    scene = read_params_file(tmp_path / 'fit' / 'fit.yaml')
    assert scene['n'] == 2.0   # the free_swing scene's law won
    spec = yaml.safe_load((tmp_path / 'campaign.yaml').read_text())
    assert spec['parameters']['gamma']['distribution'] == 'normal'
    assert (tmp_path / 'results' / 'summary.md').is_file()
    assert len((tmp_path / 'results' / 'episodes.csv').read_text().splitlines()) == 9
    # Under control: the driven joint, its offset and dead time, validated on another record.
    driven = yaml.safe_load((tmp_path / 'driven' / 'fit.yaml').read_text())['/**'][
        'ros__parameters']
    assert {'inertia', 'effort_offset', 'command_delay'} <= set(driven)
    assert abs(driven['inertia'] - 0.2002) < 0.02
    assert (tmp_path / 'driven' / 'validation.csv').is_file()
    assert (tmp_path / 'driven' / 'validate.png').is_file()
