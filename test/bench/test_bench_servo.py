"""The servo bench's figures meet issue 17's thresholds, and its figure is written."""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

BENCH = Path(__file__).resolve().parents[2] / 'bench' / 'bench_servo.py'


def bench() -> ModuleType:
    spec = importlib.util.spec_from_file_location('bench_servo', BENCH)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules['bench_servo'] = module
    spec.loader.exec_module(module)
    return module


def test_tracking_thresholds() -> None:
    b = bench()
    responses = b.track()
    assert responses['velocity 1.0'].worst_after(1.0) <= 0.01
    for x in b.POSITION_TARGETS:
        r = responses[f'position {x:g}']
        assert r.worst_after(2.0) <= 1e-3
        assert r.overshoot(0.3) <= 1e-3
    assert max(abs(t) for r in responses.values() for t in r.tau) <= 5.0


def test_the_bench_prints_and_draws(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip('matplotlib')
    b = bench()
    png = tmp_path / 'servo.png'
    monkeypatch.setattr(sys, 'argv', ['bench_servo.py', '--png', str(png)])
    b.main()
    out = capsys.readouterr().out
    assert 'MISSED' not in out and out.count('met') == 4
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
