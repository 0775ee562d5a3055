"""A documentation page's fenced blocks, and its shell steps run as a reader runs them."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
TUTORIALS = ROOT / 'docs' / 'tutorials'


def blocks(page: Path, kind: str) -> list[str]:
    """Return the page's fenced blocks of ``kind`` (``bash``, ``text``, ``yaml``...), in order."""
    return re.findall(rf'^```{kind}\n(.*?)^```', page.read_text(encoding='utf-8'), re.S | re.M)


def run_shell(script: str, cwd: Path, timeout: float = 600) -> subprocess.CompletedProcess[str]:
    """Run ``script`` with ``bash -euo pipefail`` in ``cwd``, this Python's commands on PATH.

    Return the finished process (its output captured as text), whatever its exit status.
    """
    env = dict(os.environ)
    env['PATH'] = f'{Path(sys.executable).parent}{os.pathsep}{env["PATH"]}'
    return subprocess.run(['bash', '-euo', 'pipefail', '-c', script], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=timeout, check=False)


def run_steps(steps: list[str], cwd: Path, timeout: float = 600) -> list[str]:
    """Run each step as ``run_shell`` does, in order; each must succeed. Return their stdout."""
    printed = []
    for step in steps:
        res = run_shell(step, cwd, timeout)
        assert res.returncode == 0, f'{step}\n{res.stdout}\n{res.stderr}'
        printed.append(res.stdout)
    return printed
