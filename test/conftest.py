"""Shared test set-up: keep DDS on this machine, in a domain of this test run's own."""
from __future__ import annotations

import os
import random
import signal
import sys
from collections.abc import Generator
from pathlib import Path

import pytest

# The helpers every test folder shares (harnesses, stand-ins, laws run by name in other
# processes) live in test/support/ and import by their module name.
sys.path.insert(0, str(Path(__file__).resolve().parent / 'support'))

from procfs import descendants  # test/support is on the path from here

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(1, 100)))
os.environ.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
# Fast DDS sockets on 127.0.0.1 only, for the node, the probes and every other process.
LOOPBACK_PROFILE = str(Path(__file__).resolve().parents[1] / 'config' / 'fastdds_localhost.xml')
os.environ.setdefault('FASTRTPS_DEFAULT_PROFILES_FILE', LOOPBACK_PROFILE)
os.environ.setdefault('FASTDDS_DEFAULT_PROFILES_FILE', LOOPBACK_PROFILE)

# A run started in the background by a shell without job control (`make test &` in a script)
# inherits SIGINT ignored, and so would every process the tests start, which then could not be
# stopped with Ctrl-C as the tests do. A handler here makes them start with SIGINT at its
# default, as from a terminal (exec resets a handled signal, not an ignored one).
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item: pytest.Item) -> Generator[None, object, object]:
    """Kill what a failing test started and left running, so its fault stays in that test.

    A test that fails while a process it started still runs (a replay looping on the domain's
    topics, a campaign's episode processes) would otherwise go on publishing to, and loading,
    the tests after it.
    """
    before = descendants(os.getpid())
    try:
        return (yield)
    except BaseException:
        for pid in descendants(os.getpid()) - before:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        raise
