"""Ctrl-C and SIGTERM while the synchronous loop runs: exit 0, nothing on stderr but the end.

Each run starts ``pendulum_node --scene controller_test`` and ``pendulum_pd_controller`` in a
namespace of their own, waits until the node says the loop is stepping and the controller has
answered, then sends the same signal to both at once. Runs go in small concurrent batches; every
wait is on a condition.
"""
from __future__ import annotations

import os
import re
import signal
import time

import pytest
from controller_probe import Controller
from node_harness import NodeProcess

pytestmark = [pytest.mark.ros, pytest.mark.slow]

RUNS = int(os.environ.get('PENDULUM_SIGNAL_RUNS', '50'))
BATCH = 5
BAD = re.compile(r'FATAL|Traceback|Aborted|terminate called|core dumped|Exception in')


def wait_for(predicate: object, timeout: float, what: str) -> None:
    end = time.monotonic() + timeout
    while not predicate():  # type: ignore[operator]
        if time.monotonic() > end:
            raise AssertionError(f'timed out after {timeout} s waiting for {what}')
        time.sleep(0.02)


def test_signals_end_the_running_loop_cleanly() -> None:
    results: list[tuple[int, str, int, str, int]] = []
    for first in range(0, RUNS, BATCH):
        runs = []
        for i in range(first, min(first + BATCH, RUNS)):
            node = NodeProcess('controller_test').start()
            ctrl = Controller(namespace=node.namespace).start()
            runs.append((i, node, ctrl))
        try:
            for _, node, ctrl in runs:
                wait_for(lambda n=node: 'a controller is connected; stepping' in n.output(),
                         60.0, 'the loop to run')
                wait_for(lambda c=ctrl: re.search(r'effort_command reaches [1-9]',
                                                  c.output()) is not None, 60.0,
                         'the controller to answer')
            for i, node, ctrl in runs:
                sig = signal.SIGINT if i % 2 == 0 else signal.SIGTERM
                node.proc.send_signal(sig)  # type: ignore[union-attr]
                ctrl.proc.send_signal(sig)  # type: ignore[union-attr]
            for i, node, ctrl in runs:
                n_code, c_code = node.wait(10.0), ctrl.wait(10.0)
                results.append((i, node.output(), n_code, ctrl.output(), c_code))
        finally:
            for _, node, ctrl in runs:
                for p in (node, ctrl):
                    if p.alive():
                        p.proc.kill()  # type: ignore[union-attr]
                        p.proc.wait()  # type: ignore[union-attr]
                    p.__exit__()
    bad = [(i, n_out, n_code, c_out, c_code) for i, n_out, n_code, c_out, c_code in results
           if n_code != 0 or c_code != 0 or BAD.search(n_out) or BAD.search(c_out)]
    assert not bad, bad[0]
    assert len(results) == RUNS
    assert all('pendulum_node summary:' in n for _, n, _, _, _ in results)
    assert all('answered' in c for _, _, _, c, _ in results)
