"""pendulum_node says at start what its configured law's steps cost: the node in its own process.

The node measures a short trial of the joint's own stepping (``joint/cost.py``) and logs the
expected real-time factor; where the stepping cannot keep the configured pace it warns. The
tests read the node's log; the warning is asked for at a pace no step of any law can keep
(real_time_factor 10000 at h = 1 ms: 0.1 us a step, below one Python call), the absence of one
at a pace the median law keeps hundreds of times over.
"""
from __future__ import annotations

import re
import signal

import pytest
from node_harness import NodeProcess, Probe

pytestmark = pytest.mark.ros

LINE = (r'\[(?P<level>INFO|WARN)\] \[[0-9.]+\] \[[^\]]*pendulum_node\]: expected real-time '
        r'factor (?P<rtf>[0-9.e+]+)(?P<below> is below real_time_factor = (?P<pace>[0-9.e+]+))?:'
        r' a step of h = 0\.001 s costs (?P<us>[0-9.]+) us of CPU time \(measured over '
        r'(?P<steps>\d+) steps from the initial state\)')


def start_lines(params: dict[str, object]) -> re.Match[str]:
    """Start the paper's node with ``params``; return the match of its cost line."""
    with NodeProcess('paper', {'status_line': False, **params}) as node, Probe() as probe:
        probe.spin_until(lambda: re.search(LINE, node.output()) is not None, 30.0,
                         'the cost line')
        assert node.stop(signal.SIGINT) == 0
        out = node.output()
    match = re.search(LINE, out)
    assert match is not None, out
    assert 'Traceback' not in out, out
    # It follows the start line, once.
    assert out.index('real time: h = 0.001 s') < match.start()
    assert len(re.findall('expected real-time factor', out)) == 1
    return match


def test_the_node_logs_its_laws_expected_real_time_factor_at_start() -> None:
    match = start_lines({})
    assert match['level'] == 'INFO' and match['below'] is None
    # The factor is h over the measured cost of a step, as logged: to 3 digits, and to 0.1 us.
    rtf, us = float(match['rtf']), float(match['us'])
    assert abs(rtf * us - 1e3) <= 1e3 * (0.005 + 0.05 / us) * 1.01
    assert 0 < int(match['steps']) <= 500


def test_the_node_warns_where_its_law_cannot_keep_the_configured_pace() -> None:
    match = start_lines({'real_time_factor': 10000.0})
    assert match['level'] == 'WARN' and float(match['pace']) == 10000.0
    assert float(match['rtf']) < 10000.0
