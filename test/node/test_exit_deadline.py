"""exit_deadline: a process stuck in a C call that keeps the GIL ends with the code it was given.

Each case runs a child Python that blocks in ``pause()`` called through ``ctypes.PyDLL`` (which
keeps the GIL for the whole call, as rclpy's node teardown does): only the deadline can end it.
"""
from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from pendulum_sim.exit_deadline import exit_deadline

pytestmark = pytest.mark.skipif(not sys.platform.startswith('linux'),
                                reason='the deadline is a Linux POSIX timer')

CHILD = textwrap.dedent("""
    import ctypes
    import sys
    from pendulum_sim.exit_deadline import exit_deadline

    def stuck():
        ctypes.PyDLL(None).pause()  # never returns; the GIL stays held

    {body}
""")


def run_child(body: str) -> subprocess.CompletedProcess[str]:
    """Run ``body`` in a child interpreter; its end is bounded by the deadlines it arms."""
    code = CHILD.format(body=textwrap.dedent(body).strip())
    return subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=120)


def test_a_call_that_keeps_the_gil_is_ended_with_the_code_given() -> None:
    done = run_child("""
        print('summary written before the teardown')  # buffered: a pipe is not a tty
        with exit_deadline(7, 0.2) as armed:
            print(f'armed {armed}', file=sys.stderr)
            stuck()
    """)
    assert done.returncode == 7, done.stderr
    # What was printed before the deadline was armed reached the pipe: it was flushed first.
    assert done.stdout == 'summary written before the teardown\n'
    assert 'armed True' in done.stderr


def test_the_code_can_be_zero() -> None:
    done = run_child("""
        with exit_deadline(0, 0.2):
            stuck()
    """)
    assert done.returncode == 0, done.stderr


def test_leaving_the_block_disarms_the_deadline() -> None:
    # The first deadline (code 7) is left in time; only the second (code 3) may end the child.
    done = run_child("""
        with exit_deadline(7, 0.2):
            pass
        try:
            with exit_deadline(5, 0.2):
                raise KeyError('left by an exception')
        except KeyError:
            pass
        with exit_deadline(3, 0.6):
            stuck()
    """)
    assert done.returncode == 3, done.stderr


@pytest.mark.parametrize(('code', 'seconds', 'message'), [
    (256, 1.0, 'exit code must be in 0..255, got 256'),
    (-1, 1.0, 'exit code must be in 0..255, got -1'),
    (0, 0.0, 'deadline must be > 0 s, got 0.0'),
    (0, float('nan'), 'deadline must be > 0 s, got nan'),
])
def test_bad_arguments_are_refused(code: int, seconds: float, message: str) -> None:
    with pytest.raises(ValueError) as info:
        with exit_deadline(code, seconds):
            pass
    assert str(info.value) == message


@pytest.mark.parametrize(('raises', 'code', 'expected'), [
    (False, 0, 0), (False, 2, 2), (True, 0, 1), (True, 2, 2)])
def test_shut_down_ends_a_stuck_teardown_with_the_programs_code(
        raises: bool, code: int, expected: int) -> None:
    # A node whose destruction never returns, as Fast DDS's spinning participant deletion: the
    # process ends with the code given, or 1 when an exception is on its way out of main.
    done = run_child(f"""
        from pendulum_sim.dds import shut_down

        class StuckNode:
            def destroy_node(self):
                stuck()

        try:
            if {raises}:
                raise RuntimeError('a bug in main')
        finally:
            shut_down(StuckNode(), {code}, limit=0.2)
    """)
    assert done.returncode == expected, done.stderr
    assert 'a bug in main' not in done.stderr  # the traceback was never reached
