"""A recording whose writer process falls behind stops, and the file says so (issue 20, item 7).

The writer process is really stopped (SIGSTOP) while the recording process writes on: the pipe
and then a small backlog (``max_backlog``) fill up, the recording stops there, and the file holds
every message written before the stop, intact, then the stop event; :func:`load` and the
independent reader (mcap-ros2-support) both see it.
"""
from __future__ import annotations

import os
import re
import signal
from pathlib import Path

import numpy as np
import pytest
from recording_support import read_independently
from std_msgs.msg import Float64

from pendulum_sim.recording import STOPPED_TOPIC, McapRecorder, RecorderError, load
from pendulum_sim.recording.loader import TruncatedRecordingWarning

LIMIT = 64 << 10          # bytes of backlog: far less than the default, so the test is quick
MOST = 1_000_000          # messages: far more than the pipe (1 MiB at most) and LIMIT hold
STEP_NS = 1_000_000


def _recorder_with_writer_stopped(path: Path, **options: int) -> tuple[McapRecorder, int]:
    """Open a recorder of /energy at ``path`` and stop its writer process (SIGSTOP).

    Returns the recorder and the writer's pid (the caller continues it with SIGCONT).
    """
    rec = McapRecorder(path, **options)
    rec.open()
    rec.add_channel('/energy', Float64, 10)
    pid = rec.writer_pid
    assert pid is not None
    os.kill(pid, signal.SIGSTOP)
    return rec, pid


def _record_until_stopped(path: Path) -> tuple[McapRecorder, int]:
    """Record Float64 k at k ms with the writer stopped until the recording stops; return where.

    Returns the recorder (closed) and the index of the first message the recording left out.
    """
    rec, pid = _recorder_with_writer_stopped(path, max_backlog=LIMIT)
    try:
        k = 0
        while rec.error is None:
            assert k < MOST, 'the recording never stopped'
            rec.write('/energy', Float64(data=float(k)), k * STEP_NS)
            k += 1
        cut = k - 1
        for later in range(k, k + 1000):   # everything later is dropped, whole
            rec.write('/energy', Float64(data=float(later)), later * STEP_NS)
        rec.write_reset((k + 1000) * STEP_NS, 'dropped as well')
    finally:
        os.kill(pid, signal.SIGCONT)
    rec.close()
    return rec, cut


def test_a_writer_that_falls_behind_cuts_the_recording_short_and_the_file_says_so(
        tmp_path: Path) -> None:
    path = tmp_path / 'behind.mcap'
    rec, cut = _record_until_stopped(path)
    stop_ns = cut * STEP_NS
    reason = (f'the writer process fell {LIMIT} bytes behind at the message stamped {stop_ns} '
              f'ns; that message and every later one are not recorded')
    assert cut > LIMIT // 27   # the backlog filled: at least LIMIT bytes of 27-byte frames
    assert str(rec.error) == f'recording {path} stopped: {reason}'
    assert rec.messages_written == cut + 1   # every message before the stop, and the stop event

    problem = f'{path} was cut short at {stop_ns} ns (t = {stop_ns / 1e9:.9g} s): {reason}'
    for fast in (True, False):
        with pytest.warns(TruncatedRecordingWarning, match=re.escape(problem)):
            loaded = load(path, fast=fast)
        assert loaded.complete is False
        assert loaded.stopped_ns == stop_ns
        assert loaded.problems == (problem,)
        assert loaded.energy is not None
        np.testing.assert_array_equal(loaded.energy.value, np.arange(cut, dtype=float))
        np.testing.assert_array_equal(loaded.energy.stamp_ns, np.arange(cut) * STEP_NS)
        assert loaded.resets.size == 0
        assert loaded.topics[STOPPED_TOPIC].message_count == 1

    summary, decoded = read_independently(path)
    topics = [channel.topic for _, channel, _, _ in decoded]
    assert topics == ['/energy'] * cut + [STOPPED_TOPIC]
    assert [m.data for _, _, _, m in decoded[:-1]] == [float(k) for k in range(cut)]
    assert [r.log_time for _, _, r, _ in decoded[:-1]] == [k * STEP_NS for k in range(cut)]
    schema, _, record, event = decoded[-1]
    assert (schema.name, record.log_time, event.data) == ('std_msgs/msg/String', stop_ns, reason)
    assert summary.statistics.message_count == cut + 1


def test_a_recording_that_ran_to_its_end_is_complete(tmp_path: Path) -> None:
    path = tmp_path / 'whole.mcap'
    with McapRecorder(path, max_backlog=LIMIT) as rec:
        rec.add_channel('/energy', Float64, 10)
        for k in range(100):
            rec.write('/energy', Float64(data=float(k)), k * STEP_NS)
    assert rec.error is None
    loaded = load(path)
    assert loaded.complete is True and loaded.stopped_ns is None and loaded.problems == ()
    assert STOPPED_TOPIC not in loaded.topics


@pytest.mark.parametrize('bad', [0, -1, 1.5, True, '64'])
def test_max_backlog_must_be_a_whole_number_of_bytes(tmp_path: Path, bad: object) -> None:
    with pytest.raises(RecorderError, match=re.escape(
            f'max_backlog must be an integer >= 1 byte, got {bad!r}')):
        McapRecorder(tmp_path / 'x.mcap', max_backlog=bad)  # type: ignore[arg-type]


def test_closing_while_the_writer_is_stopped_with_frames_not_handed_over_says_cut_short(
        tmp_path: Path) -> None:
    """close() returns at once on a stopped writer; continued, it finishes the file by itself,
    and since the CLOSE frame (and more) never reached it the file says it was cut short."""
    path = tmp_path / 'stopped_at_close.mcap'
    # The default backlog: nothing is dropped before close().
    rec, pid = _recorder_with_writer_stopped(path)
    try:
        k = 0
        while not rec._backlog:   # the pipe is full: what follows waits here
            assert k < MOST, 'the pipe never filled'
            rec.write('/energy', Float64(data=float(k)), k * STEP_NS)
            k += 1
        total = k + 1000
        for later in range(k, total):
            rec.write('/energy', Float64(data=float(later)), later * STEP_NS)
        rec.close()   # the writer is stopped: close() hands over what it can and returns
    finally:
        os.kill(pid, signal.SIGCONT)
    assert rec.error is not None
    assert re.fullmatch(re.escape(f'recording {path}: the writer process (pid {pid}) is '
                                  'stopped; it finalises the file when it runs again; ')
                        + r'[1-9][0-9]* ' + re.escape(
                            'bytes were not handed over, so the file ends earlier and says it '
                            'was cut short'), str(rec.error))
    assert rec._process is not None
    rec._process.wait(timeout=60)   # continued, the writer finalises the file and exits
    assert rec._process.returncode == 0

    summary, decoded = read_independently(path)
    topics = [channel.topic for _, channel, _, _ in decoded]
    kept = len(topics) - 1
    assert 0 < kept < total
    assert topics == ['/energy'] * kept + [STOPPED_TOPIC]
    assert [m.data for _, _, _, m in decoded[:-1]] == [float(k) for k in range(kept)]
    last_ns = (kept - 1) * STEP_NS
    reason = (f'the writer process saw its input end without CLOSE (the recording process was '
              f'killed, or closed the recording while the writer process was stopped, with '
              f'frames not handed over) after the message stamped {last_ns} ns; nothing later '
              f'is recorded')
    schema, _, record, event = decoded[-1]
    assert (schema.name, record.log_time, event.data) == ('std_msgs/msg/String', last_ns, reason)
    assert summary.statistics.message_count == kept + 1

    problem = f'{path} was cut short at {last_ns} ns (t = {last_ns / 1e9:.9g} s): {reason}'
    for fast in (True, False):
        with pytest.warns(TruncatedRecordingWarning, match=re.escape(problem)):
            loaded = load(path, fast=fast)
        assert loaded.complete is False and loaded.stopped_ns == last_ns
        assert loaded.problems == (problem,)
        assert loaded.energy is not None
        np.testing.assert_array_equal(loaded.energy.value, np.arange(kept, dtype=float))


def test_closing_while_the_writer_is_stopped_with_everything_handed_over_is_complete(
        tmp_path: Path) -> None:
    """A stopped writer that was handed every frame, CLOSE included, ends the file whole."""
    path = tmp_path / 'handed_over.mcap'
    rec, pid = _recorder_with_writer_stopped(path)
    try:
        for k in range(100):   # far less than the pipe holds
            rec.write('/energy', Float64(data=float(k)), k * STEP_NS)
        rec.close()
    finally:
        os.kill(pid, signal.SIGCONT)
    assert str(rec.error) == (f'recording {path}: the writer process (pid {pid}) is stopped; '
                              'it finalises the file when it runs again')
    assert rec._process is not None
    rec._process.wait(timeout=60)
    loaded = load(path)
    assert loaded.complete is True and loaded.stopped_ns is None and loaded.problems == ()
    assert loaded.energy is not None
    np.testing.assert_array_equal(loaded.energy.value, np.arange(100, dtype=float))


def test_the_stop_event_is_the_cdr_rclpy_writes() -> None:
    """The writer process builds the stop event's CDR itself (it never imports rclpy)."""
    from rclpy.serialization import serialize_message
    from std_msgs.msg import String

    from pendulum_sim.recording.sink import cdr_string
    for text in ('', 'a', 'abcd', 'stopped at 5 ns', 'é ∞ \U0001F600'):
        assert cdr_string(text) == serialize_message(String(data=text))
