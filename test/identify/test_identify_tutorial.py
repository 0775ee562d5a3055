"""The identification tutorial's shell steps run as written: record, identify, campaign."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import yaml

from pendulum_sim.joint.scenes import read_params_file

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / 'docs' / 'tutorials' / 'identify.md'


def bash_blocks() -> list[str]:
    """Return the page's ```bash blocks, in order."""
    return re.findall(r'^```bash\n(.*?)^```', PAGE.read_text(encoding='utf-8'), re.S | re.M)


def test_the_tutorial_records_identifies_and_runs_a_campaign(tmp_path: Path) -> None:
    blocks = bash_blocks()
    assert len(blocks) == 4
    env = dict(os.environ)
    env['PATH'] = f'{Path(sys.executable).parent}{os.pathsep}{env["PATH"]}'
    for block in blocks:
        res = subprocess.run(['bash', '-euo', 'pipefail', '-c', block], cwd=tmp_path, env=env,
                             capture_output=True, text=True, timeout=600, check=False)
        assert res.returncode == 0, f'{block}\n{res.stdout}\n{res.stderr}'
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
