"""Run a campaign's pending episodes on Dask and store each row as it arrives.

By default a local Dask cluster (``LocalCluster``, one single-threaded worker process per core,
or ``workers``); with ``scheduler`` an existing ``dask.distributed`` cluster
(``Client('tcp://host:8786')``). Episodes are submitted in chunks (:func:`chunk_size`) with
``Client.map`` and collected with ``as_completed``: each chunk's rows are written to the store
the moment it arrives, so an interruption loses only the episodes still running. An episode
depends on the campaign and its id only, so the table is the same whichever worker ran what,
in whatever order; a worker that dies mid-chunk has the chunk rerun elsewhere by the scheduler.
"""
from __future__ import annotations

import hashlib
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from ..errors import CampaignError
from ..vector import is_vectorised
from .episode import run_chunk
from .spec import CampaignSpec, load_controller
from .store import EpisodeStore

MAX_BATCH = 10_000
MAX_CHUNK = 25

# Dask settings of the local cluster (``dask.config``, https://docs.dask.org/en/stable/
# configuration.html; for ``dask scheduler`` and ``dask worker`` processes started by hand, the
# same keys as environment variables, DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED=False and
# DASK_DISTRIBUTED__ADMIN__TICK__INTERVAL=200ms, or in a YAML file under ~/.config/dask/).
# Both are periodic callbacks of the event loops that a campaign does not use and that take
# the GIL from the pure-Python episode loop each time: the workers' statistical profiler,
# which samples the running task's stack every 10 ms for the dashboard's profile page
# (distributed's "Diagnosing Performance: Statistical Profiling"), and the event-loop health
# check of every server (scheduler, nanny, worker), every 20 ms by default, which warns when
# a loop was blocked for over ``distributed.admin.tick.limit`` (3 s); it still does at 200 ms.
# bench/bench_testbench.py, part (d), runs this and Dask's default configuration.
CLUSTER_CONFIG: dict[str, Any] = {'distributed.worker.profile.enabled': False,
                                  'distributed.admin.tick.interval': '200ms'}


class ProgressBar:
    """One line on stderr: episodes done, pass rate, ETA (redrawn in place)."""

    def __init__(self, total: int, done: int, passed: int, stream: IO[str] | None = None,
                 enabled: bool = True) -> None:
        self.total = total
        self.done = done
        self.passed = passed
        self.start_done = done
        self.start = time.perf_counter()
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled
        self._last = 0.0

    def line(self) -> str:
        """Return the progress line."""
        width = 30
        filled = round(width * self.done / self.total)
        rate = 100.0 * self.passed / self.done if self.done else 0.0
        new = self.done - self.start_done
        elapsed = time.perf_counter() - self.start
        eta = f'{elapsed / new * (self.total - self.done):.0f} s' if new else '?'
        return (f'[{"#" * filled}{"." * (width - filled)}] {self.done}/{self.total} episodes, '
                f'pass rate {rate:.1f} %, ETA {eta}')

    def update(self, passed: bool) -> None:
        """Count one more finished episode and redraw (at most 10 times a second)."""
        self.done += 1
        self.passed += int(passed)
        now = time.perf_counter()
        if self.enabled and (now - self._last > 0.1 or self.done == self.total):
            self._last = now
            print('\r' + self.line(), end='', file=self.stream, flush=True)

    def close(self) -> None:
        """End the line."""
        if self.enabled:
            print('\r' + self.line(), file=self.stream, flush=True)


def make_client(scheduler: str | None, workers: int | None) -> Any:
    """Return a Dask client: to ``scheduler``, or to a new local cluster of ``workers``.

    The local cluster runs with :data:`CLUSTER_CONFIG`; an existing cluster runs with the
    configuration its processes were started with.
    """
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise CampaignError("campaigns need Dask: pip install 'dask[distributed]'") from None
    if scheduler is not None:
        try:
            return Client(scheduler, timeout='20s')
        except (OSError, TimeoutError) as exc:
            raise CampaignError(f'cannot reach the Dask scheduler {scheduler}: {exc}') from None
    import dask

    n = workers or os.cpu_count() or 1
    with dask.config.set(CLUSTER_CONFIG):   # each worker's nanny hands it this configuration
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=40)
    return Client(cluster)


def run_pending(spec: CampaignSpec, store: EpisodeStore, client: Any,
                progress: bool = True,
                on_row: Callable[[dict[str, Any]], None] | None = None,
                foxglove_port: int = 0) -> int:
    """Run the episodes without a stored row on ``client``; return how many ran (each served
    live on ``foxglove_port`` while it runs, if not 0)."""
    from distributed import as_completed

    done = store.done()
    pending = [i for i in range(spec.episodes) if i not in done]
    passed = sum(1 for i in done if store.read(i)['passed'])
    bar = ProgressBar(spec.episodes, len(done), passed, enabled=progress)
    if not pending:
        bar.close()
        return 0
    out = str(store.out.resolve())
    tag = hashlib.sha1((spec.text + out).encode()).hexdigest()[:12]
    size = chunk_size(len(pending), _workers(client), batched(spec))
    chunks = [pending[a:a + size] for a in range(0, len(pending), size)]
    futures = client.map(run_chunk, [spec.text] * len(chunks), chunks, [out] * len(chunks),
                         [foxglove_port] * len(chunks),
                         key=[f'episodes-{c[0]}-{c[-1]}-{tag}' for c in chunks], pure=False)
    try:
        for future in as_completed(futures):
            for row in future.result():
                store.write(row)
                bar.update(bool(row['passed']))
                if on_row is not None:
                    on_row(row)
    finally:
        bar.close()
    return len(pending)


def batched(spec: CampaignSpec) -> bool:
    """Return True when the campaign's law is declared vectorised (episodes run in batches)."""
    return not spec.is_command_line and is_vectorised(load_controller(str(spec.controller)))


def chunk_size(pending: int, workers: int, batch: bool) -> int:
    """Return the episodes per task: about four tasks per worker (eight for scalar episodes,
    which are slower one by one), at most MAX_BATCH in a batch and MAX_CHUNK one by one.

    A task runs its episodes together and its rows are stored when it ends: big enough that
    Dask's cost per task is small against it, small enough that the workers stay busy to the
    end and an interruption loses little.
    """
    per_worker = 4 if batch else 8
    most = MAX_BATCH if batch else MAX_CHUNK
    return max(1, min(most, -(-pending // (per_worker * max(workers, 1)))))


def _workers(client: Any) -> int:
    try:
        return len(client.scheduler_info()['workers'])
    except Exception:   # an unreachable scheduler shows up at the first result
        return 1


def run_campaign(spec: CampaignSpec, out: Path, *, scheduler: str | None = None,
                 workers: int | None = None, resume: bool = False,
                 progress: bool = True, foxglove_port: int = 0) -> list[dict[str, Any]]:
    """Run (or continue) the campaign into ``out``; return every row, by episode id."""
    store = EpisodeStore(out)
    store.create(spec.text, resume)
    if len(store.done()) < spec.episodes:
        client = make_client(scheduler, workers)
        try:
            run_pending(spec, store, client, progress, foxglove_port=foxglove_port)
        finally:
            cluster = client.cluster if scheduler is None else None
            client.close()
            if cluster is not None:
                cluster.close()
    return store.rows()
