"""Episodes in a process of their own, so that a law that exits, hangs or eats memory fails alone.

A Dask task (:func:`run_chunk`; :func:`run_chunk_pickled` returns its rows as one pickle)
hands its episodes to an episode process, a child of the worker started once
(``python -m pendulum_sim.testing.campaign.sandbox``) and kept for the next tasks, so the
campaign file is parsed and the scene read once per worker. The child
sends each finished episode's row as it ends (a batch of a vectorised law sends its rows
together); the worker watches it meanwhile, with
:class:`~pendulum_sim.testing.campaign.watch.LawClock` showing whether the law is in a call.
When the child ends without the rows, the episode it was running fails with the reason and
the child is started again for the rest:

- ``law exited with C`` (``sys.exit(C)``, ``os._exit(C)`` in a call of the law; ``law killed
  by SIGNAL`` for a signal), or ``episode process exited with C`` outside the law;
- ``worker killed: memory``: the child's resident memory passed the worker's memory limit
  (Dask's ``memory_limit``; none, no watch);
- ``law did not answer within N s``: the episode's closed loop ran longer than the campaign's
  ``episode_timeout`` (wall-clock, from the first call of the law to the loop's end), most of
  it in calls of the law (one call that never returns, or many that each take long);
  ``episode did not end within N s`` where most of it was spent outside the law. A batch of a
  vectorised law has the same limit as one episode.

A batch that ends so is run again one episode at a time, so only the faulty episodes fail.
Messages are pickles with an 8-byte length, on the child's stdin and stdout.
"""
from __future__ import annotations

import importlib
import os
import pickle
import select
import signal
import struct
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from typing import IO, Any

from .watch import CLOCK, SIZE, LawClock

POLL_S = 0.02
# What a batch runs with besides the episode module, imported by the episode process at start.
PRELOAD = ('pendulum_sim.core.sweep', 'pendulum_sim.joint.parameters',
           'pendulum_sim.testing.batch')
_HEADER = struct.Struct('<Q')


@dataclass(frozen=True)
class Fault:
    """An episode whose process ended (or was ended) without its row, and why."""

    episode: int
    reason: str


def send(stream: IO[bytes], message: Any) -> None:
    """Write one message (a pickle with its length)."""
    body = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(_HEADER.pack(len(body)) + body)
    stream.flush()


def _read_exactly(fd: int, n: int) -> bytes | None:
    chunks = []
    while n:
        data = os.read(fd, min(n, 1 << 20))
        if not data:
            return None
        chunks.append(data)
        n -= len(data)
    return b''.join(chunks)


def receive(fd: int) -> Any:
    """Return the next message on ``fd``; raise EOFError when the writer is gone."""
    head = _read_exactly(fd, _HEADER.size)
    body = None if head is None else _read_exactly(fd, _HEADER.unpack(head)[0])
    if body is None:
        raise EOFError
    return pickle.loads(body)


class Sandbox:
    """One episode process and what the worker watches it with."""

    def __init__(self, memory_limit: int | None) -> None:
        self.memory_limit = memory_limit
        self._fd = os.memfd_create('pendulum-law-clock')
        os.ftruncate(self._fd, SIZE)
        self.clock = LawClock(self._fd)
        self.proc = subprocess.Popen(
            [sys.executable, '-m', 'pendulum_sim.testing.campaign.sandbox', str(self._fd)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, pass_fds=(self._fd,))
        import psutil  # type: ignore[import-untyped]

        self._ps = psutil.Process(self.proc.pid)

    def close(self) -> None:
        """End the episode process (it leaves when its input closes) and release the clock."""
        if self.proc.poll() is None:
            try:
                assert self.proc.stdin is not None
                self.proc.stdin.close()
                self.proc.wait(5)
            except (OSError, subprocess.TimeoutExpired):
                self.proc.kill()
                self.proc.wait()
        self.clock.close()
        os.close(self._fd)

    def _kill(self) -> None:
        self.proc.kill()
        self.proc.wait()

    def _why_ended(self, in_law: bool) -> str:
        code = self.proc.wait()
        who = 'law' if in_law else 'episode process'
        if code < 0:
            try:
                name = signal.Signals(-code).name
            except ValueError:
                name = f'signal {-code}'
            return f'{who} killed by {name}'
        return f'{who} exited with {code}'

    def next(self, timeout: float) -> Any:
        """Return the child's next message, or the reason (a str) it ended without one."""
        assert self.proc.stdout is not None
        fd = self.proc.stdout.fileno()
        while True:
            ready, _, _ = select.select([fd], [], [], POLL_S)
            if ready:
                in_law = self.clock.since() > 0.0
                try:
                    return ('message', receive(fd))
                except EOFError:
                    return ('ended', self._why_ended(in_law or self.clock.since() > 0.0))
            began, now = self.clock.episode_since(), time.monotonic()
            if began > 0.0 and now - began > timeout:
                law = self.clock.law_time(now) > 0.5 * (now - began)   # most of it the law's
                self._kill()
                return ('ended', f'law did not answer within {timeout:g} s' if law else
                        f'episode did not end within {timeout:g} s')
            if self.memory_limit is not None:
                try:
                    rss = self._ps.memory_info().rss
                except Exception:   # it has just ended: the next select says how
                    continue
                if rss > self.memory_limit:
                    self._kill()
                    return ('ended', f'worker killed: memory (the episode process passed the '
                            f"worker's memory limit of {self.memory_limit / 2**20:.0f} MiB)")

    def run(self, text: str, episodes: list[int], out: str | None, timeout: float,
            foxglove_port: int = 0) -> tuple[list[dict[str, Any]], Fault | None]:
        """Run ``episodes`` in the child; return the rows it sent and the fault that ended it.

        After a fault the child is gone (:attr:`alive` is False); the rows before it are kept.
        With ``foxglove_port`` (0 = off) the child serves each episode live while it runs.
        """
        assert self.proc.stdin is not None
        try:
            send(self.proc.stdin, (text, episodes, out, foxglove_port))
        except OSError:
            pass   # it is gone: the next message says why
        rows: list[dict[str, Any]] = []
        batch = False
        while True:
            kind, message = self.next(timeout)
            if kind == 'ended':
                left = [i for i in episodes if i not in {r['episode'] for r in rows}]
                # In a batch every episode was in the law's call: which one is not known.
                unknown = not left or (batch and len(left) > 1)
                return rows, Fault(-1 if unknown else left[0], str(message))
            if message is None:
                return rows, None
            if message == 'batch':
                batch = True
            else:
                rows.extend(message)

    def run_parts(self, parts: list[tuple[str, list[int], str | None]],
                  timeout: float) -> list[list[dict[str, Any]]] | None:
        """Run several campaigns' episodes as one batch in the child; return each one's rows,
        or None when the child ended without them (it is gone then)."""
        assert self.proc.stdin is not None
        try:
            send(self.proc.stdin, (parts, None, None, 0))
        except OSError:
            pass   # it is gone: the next message says so
        found: list[list[dict[str, Any]]] | None = None
        while True:
            kind, message = self.next(timeout)
            if kind == 'ended':
                return None
            if message is None:
                return found
            if message != 'batch':
                found = message

    @property
    def alive(self) -> bool:
        """Return True while the episode process runs."""
        return self.proc.poll() is None


_BOXES = threading.local()
_SPARE: list[Sandbox] = []   # started with the worker, before its first task
_SPARE_LOCK = threading.Lock()


def prestart(memory_limit: int | None) -> None:
    """Start an episode process now, for the first task of this process to take.

    The campaign's local cluster starts one with each worker, so the process and its imports
    are ready when the first episodes arrive instead of after.
    """
    with _SPARE_LOCK:
        if not _SPARE:
            _SPARE.append(Sandbox(memory_limit))


def sandbox(memory_limit: int | None) -> Sandbox:
    """Return this thread's episode process, started (again) if it is not running."""
    box: Sandbox | None = getattr(_BOXES, 'box', None)
    if box is None or not box.alive or box.memory_limit != memory_limit:
        if box is not None:
            box.close()
        with _SPARE_LOCK:
            spare = _SPARE.pop() if _SPARE else None
        if spare is not None and (not spare.alive or spare.memory_limit != memory_limit):
            spare.close()
            spare = None
        box = spare if spare is not None else Sandbox(memory_limit)
        _BOXES.box = box
    return box


def worker_memory_limit() -> int | None:
    """Return the memory limit (bytes) of the Dask worker this runs in (None: none, no worker)."""
    try:
        from distributed import get_worker

        return memory_limit_of(get_worker())
    except (ImportError, ValueError, AttributeError):
        return None


def memory_limit_of(worker: Any) -> int | None:
    """Return the memory limit (bytes) of the Dask ``worker`` (None: none)."""
    limit = worker.memory_manager.memory_limit
    return int(limit) if limit else None


def run_chunk(text: str, episodes: list[int], out: str | None, timeout: float,
              memory_limit: int | None = None,
              foxglove_port: int = 0) -> list[dict[str, Any] | Fault]:
    """Run ``episodes`` in this thread's episode process; return a row or a Fault for each.

    A batch that faults is run again one episode at a time. ``memory_limit`` (bytes) is the
    Dask worker's own when None and this runs in a worker. With ``foxglove_port`` (0 = off)
    each episode run one by one is served live to Foxglove from the episode process while it
    runs (one server at a time, so one worker).
    """
    limit = memory_limit if memory_limit is not None else worker_memory_limit()
    rows, fault = sandbox(limit).run(text, episodes, out, timeout, foxglove_port)
    if fault is None:
        return list(rows)
    done = {r['episode'] for r in rows}
    left = [i for i in episodes if i not in done]
    results: list[dict[str, Any] | Fault] = list(rows)
    if fault.episode < 0:   # a batch faulted: each episode alone says which one did
        for i in left:
            results.extend(run_chunk(text, [i], out, timeout, limit, foxglove_port))
        return results
    results.append(fault)
    rest = [i for i in left if i != fault.episode]
    if rest:
        results.extend(run_chunk(text, rest, out, timeout, limit, foxglove_port))
    return results


def run_parts(parts: list[tuple[str, list[int], str | None]], timeout: float,
              memory_limit: int | None = None) -> list[list[dict[str, Any] | Fault]]:
    """Run several campaigns' episodes (one vectorised law) as one batch in this thread's
    episode process; return each campaign's rows (or Faults).

    A batch that faults is run again campaign by campaign (:func:`run_chunk`, which runs a
    faulting batch again one episode at a time), so only the faulty episodes fail.
    """
    limit = memory_limit if memory_limit is not None else worker_memory_limit()
    found = sandbox(limit).run_parts(parts, timeout)
    if found is not None:
        return [list(rows) for rows in found]
    return [run_chunk(text, episodes, out, timeout, limit) for text, episodes, out in parts]


def run_parts_pickled(parts: list[tuple[str, list[int], str | None]], timeout: float) -> bytes:
    """Return what :func:`run_parts` returns as one pickle: a Dask task of several campaigns."""
    return pickle.dumps(run_parts(parts, timeout), protocol=pickle.HIGHEST_PROTOCOL)


def run_chunk_pickled(text: str, episodes: list[int], out: str | None, timeout: float,
                      foxglove_port: int = 0) -> bytes:
    """Return what :func:`run_chunk` returns as one pickle: the Dask task of a campaign.

    Dask serialises a task's list of rows element by element, about a fifth of a second for
    the 5000 rows of a batch; as one pickle they take a hundredth.
    """
    return pickle.dumps(run_chunk(text, episodes, out, timeout, foxglove_port=foxglove_port),
                        protocol=pickle.HIGHEST_PROTOCOL)


def _orphan_guard(parent: int) -> None:
    """End this process when the worker that started it is gone (a law may be stuck)."""
    while True:
        time.sleep(1.0)
        if os.getppid() != parent:
            os._exit(70)


def main() -> None:
    """Serve chunks until the worker is gone; leave without a word when it is."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # Ctrl-C is the campaign's to handle
    CLOCK.append(LawClock(int(sys.argv[1])))
    threading.Thread(target=_orphan_guard, args=(os.getppid(),), daemon=True).start()
    stdin = sys.stdin.buffer.fileno()
    stdout = os.fdopen(os.dup(1), 'wb')   # the messages' own descriptor, and what a law
    os.dup2(2, 1)                         # prints (print, C code) goes to stderr
    sys.stdout = sys.stderr
    try:
        serve(stdin, stdout)
    except (EOFError, OSError):   # the worker closed the pipes (it ends, or was killed)
        pass
    sys.stderr.flush()
    os._exit(0)   # nothing left to flush into a pipe nobody reads


def serve(stdin: int, stdout: IO[bytes]) -> None:
    """Read (text, episodes, out, foxglove_port), send each finished episode's rows, then
    None; repeat. A list of (text, episodes, out) in place of the text is several campaigns'
    batch: their rows go out together, one list per campaign.

    Each episode's end is marked on the law's clock before its row goes out, also where its
    closed loop did not (``watch.loop_done``), so no limit runs between episodes.
    """
    from .episode import (
        batched,
        cached_spec,
        fault_row,
        run_episode,
        run_episodes,
        run_episodes_parts,
    )

    for module in PRELOAD:   # imported while no episode waits for them
        importlib.import_module(module)
    clock = CLOCK[0] if CLOCK else None

    while True:
        text, episodes, out, foxglove_port = receive(stdin)
        if isinstance(text, list):   # several campaigns' episodes in one batch
            send(stdout, 'batch')
            parts = run_episodes_parts(text)   # a fault ends the process: run part by part
            if clock is not None:
                clock.end_episode()
            send(stdout, parts)
            send(stdout, None)
            continue
        spec = cached_spec(text)
        if batched(spec):
            send(stdout, 'batch')
            try:
                rows = run_episodes(text, episodes, out)
            except Exception as exc:
                if len(episodes) != 1:
                    raise
                rows = [fault_row(spec, episodes[0], f'the episode raised {type(exc).__name__}:'
                                  f' {exc}'.splitlines()[0])]
            if clock is not None:
                clock.end_episode()
            send(stdout, rows)
        else:
            for i in episodes:
                try:
                    row = run_episode(text, i, out, foxglove_port)
                except Exception as exc:   # a defect outside the law: this episode's alone
                    row = fault_row(spec, i, f'the episode raised {type(exc).__name__}: '
                                    f'{exc}'.splitlines()[0])
                if clock is not None:
                    clock.end_episode()
                send(stdout, [row])
        send(stdout, None)


if __name__ == '__main__':
    main()
