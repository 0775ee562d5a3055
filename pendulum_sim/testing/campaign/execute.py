"""Run a campaign's pending episodes on Dask and store each task's rows as it arrives.

By default a local Dask cluster (:mod:`~pendulum_sim.testing.campaign.cluster`, one
single-threaded worker process per core, or ``workers``); with ``scheduler`` an existing
``dask.distributed`` cluster (``Client('tcp://host:8786')``). Episodes are submitted in chunks
(:func:`chunk_size`), one task each, and collected with ``as_completed``: each task runs its
episodes in its worker's episode process (:mod:`~pendulum_sim.testing.campaign.sandbox`), and
its rows are committed to the store in one transaction the moment it ends, so an
interruption loses only the tasks still running. An episode depends on the campaign and its
id only, so the table is the same whichever worker ran what, in whatever order; a worker that
dies mid-task has the task rerun elsewhere by the scheduler, and a task that fails as a whole
is run again one episode per task.
"""
from __future__ import annotations

import functools
import hashlib
import os
import pickle
import re
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from ..errors import CampaignError
from .episode import batched, fault_row, same_batch
from .sandbox import Fault, run_chunk_pickled, run_parts_pickled
from .spec import CampaignSpec, shown
from .store import EpisodeStore

MAX_BATCH = 10_000
MAX_CHUNK = 25



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

    The local cluster (:func:`~pendulum_sim.testing.campaign.cluster.local_cluster`) runs with
    ``cluster.CLUSTER_CONFIG``, without HTTP servers; an
    existing cluster runs with the configuration its processes were started with.

    Raises
    ------
    CampaignError
        If Dask is missing, or ``scheduler`` is not an address or cannot be reached.
    """
    try:
        from distributed import Client
    except ImportError:
        raise CampaignError("campaigns need Dask: pip install 'dask[distributed]'") from None
    if scheduler is not None:
        check_address(scheduler)
        try:
            return Client(scheduler, timeout='20s')
        except ValueError:
            raise CampaignError(f'--scheduler must be an address such as tcp://host:8786, got '
                                f'{shown(scheduler)}') from None
        except (OSError, TimeoutError) as exc:
            raise CampaignError(f'cannot reach the Dask scheduler {scheduler}: {exc}') from None
    from .cluster import local_cluster

    return Client(local_cluster(workers or os.cpu_count() or 1))


_HOST = re.compile(r'^[A-Za-z0-9._\-]+$|^\[?[0-9A-Fa-f:.]+\]?$')


def check_address(address: str) -> None:
    """Refuse ``address`` unless it reads ``[scheme://]host[:port]`` (CampaignError)."""
    from distributed.comm.addressing import parse_address, parse_host_port

    try:
        scheme, location = parse_address(address)
        host, _ = parse_host_port(location, 8786)
    except ValueError:
        host, scheme = '', ''
    if scheme not in ('tcp', 'tls', 'ucx', 'ws', 'wss') or not _HOST.match(str(host)):
        raise CampaignError(f'--scheduler must be an address such as tcp://host:8786, got '
                            f'{shown(address)}')


def run_pending(spec: CampaignSpec, store: EpisodeStore, client: Any,
                progress: bool = True,
                on_row: Callable[[dict[str, Any]], Any] | None = None,
                foxglove_port: int = 0,
                on_submitted: Callable[[], Any] | None = None) -> int:
    """Run the episodes without a stored row on ``client``; return how many ran.

    Each task's rows are stored in one transaction when it ends. A task that fails as a whole
    (its worker died, say) is run again one episode per task; an episode whose own task fails
    so fails with the reason. With ``foxglove_port`` (0 = off) each episode is served live
    while it runs (the caller gives a client of one worker: one server at a time).
    ``on_submitted`` is called once the tasks are submitted, while this process waits for
    them (the command line imports its writers meanwhile).
    """
    return run_pending_all([(spec, store, on_row)], client, progress, foxglove_port,
                           on_submitted)[0]


Job = tuple[CampaignSpec, EpisodeStore, Callable[[dict[str, Any]], Any] | None]


def run_pending_all(jobs: list[Job], client: Any, progress: bool = True,
                    foxglove_port: int = 0,
                    on_submitted: Callable[[], Any] | None = None) -> list[int]:
    """Run the pending episodes of several campaigns on ``client`` at once; return how many
    ran of each.

    Every campaign's tasks are submitted together, so the workers stay busy from the first
    campaign's last task to the next campaign's first (the benchmark's criteria). Campaigns of
    one vectorised law and episode length (:func:`~.episode.same_batch`) run their episodes
    in shared batches, one per worker (:func:`~.sandbox.run_parts`): a batch costs the
    law's call and the sweep's a period whatever its size, so one batch of all the criteria's
    episodes runs each episode far faster than many small ones. Each task's rows go to their
    own campaign's store as it ends (:func:`run_pending` for one campaign).
    """
    from distributed import as_completed

    total = sum(spec.episodes for spec, _, _ in jobs)
    done_before = 0
    passed_before = 0
    tasks: dict[str, list[tuple[int, list[int]]]] = {}   # task key: [(job, episodes)]
    counts = []
    workers = _workers(client)
    pendings = []
    for spec, store, _ in jobs:
        done = store.done()
        done_before += len(done)
        passed_before += store.passed()
        pendings.append([i for i in range(spec.episodes) if i not in done])
        counts.append(len(pendings[-1]))
    groups: dict[tuple[Any, ...], list[int]] = {}
    for j, ((spec, store, _), pending) in enumerate(zip(jobs, pendings, strict=True)):
        if not pending:
            continue
        tag = hashlib.sha1((spec.text + str(store.out.resolve())).encode()).hexdigest()[:12]
        if batched(spec) and not foxglove_port:
            groups.setdefault((*same_batch(spec), spec.episode_timeout), []).append(j)
            continue
        size = chunk_size(len(pending), workers, False)
        for a in range(0, len(pending), size):
            chunk = pending[a:a + size]
            tasks[f'episodes-{chunk[0]}-{chunk[-1]}-{tag}'] = [(j, chunk)]
    for members in groups.values():
        flat = [(j, i) for j in members for i in pendings[j]]
        # One batch per worker for several campaigns: a batch's time is mostly its periods'
        # (the law's call, the sweep's), so twice the episodes cost little more (measured:
        # 1400 swing-up episodes 1.1-1.2x the time of 700); one campaign keeps two per worker.
        size = (chunk_size(len(flat), workers, True) if len(members) == 1 else
                min(MAX_BATCH, -(-len(flat) // max(workers, 1))))
        tag = hashlib.sha1(''.join(jobs[j][0].text + str(jobs[j][1].out.resolve())
                                   for j in members).encode()).hexdigest()[:12]
        count = -(-len(flat) // size)
        for b in range(count):
            # Every count-th episode: each batch holds the same share of each campaign, so
            # the batches take about as long (an episode of one campaign can cost more than
            # another's: pulses, friction), and the last to end is not the slowest one's.
            parts: list[tuple[int, list[int]]] = []
            for j, i in flat[b::count]:
                if not parts or parts[-1][0] != j:
                    parts.append((j, []))
                parts[-1][1].append(i)
            tasks[f'batch-{b}-of-{count}-{tag}'] = parts
    bar = ProgressBar(total, done_before, passed_before, enabled=progress)
    if not tasks:
        bar.close()
        return counts

    def submit(key: str) -> Any:
        parts = tasks[key]
        if len(parts) == 1:
            j, chunk = parts[0]
            spec, store, _ = jobs[j]
            return client.submit(run_chunk_pickled, spec.text, chunk,
                                 str(store.out.resolve()), spec.episode_timeout,
                                 foxglove_port=foxglove_port, pure=False, key=key)
        return client.submit(run_parts_pickled,
                             [(jobs[j][0].text, chunk, str(jobs[j][1].out.resolve()))
                              for j, chunk in parts],
                             jobs[parts[0][0]][0].episode_timeout, pure=False, key=key)

    futures = as_completed([submit(key) for key in list(tasks)])
    if on_submitted is not None:
        on_submitted()
    try:
        for future in futures:
            parts = tasks[future.key]
            try:
                found = pickle.loads(future.result())
                results = [found] if len(parts) == 1 else found
            except Exception as exc:   # the task itself failed: its worker is gone
                if len(parts) > 1 or len(parts[0][1]) > 1:
                    for j, chunk in parts:
                        for i in chunk:
                            tasks[f'{future.key}-alone-{j}-{i}'] = [(j, [i])]
                            futures.add(submit(f'{future.key}-alone-{j}-{i}'))
                    continue
                results = [[Fault(parts[0][1][0], f'worker killed: {type(exc).__name__}')]]
            for (j, _), got in zip(parts, results, strict=True):
                spec, store, on_row = jobs[j]
                rows = [fault_row(spec, r.episode, r.reason) if isinstance(r, Fault) else r
                        for r in got]
                store.write(rows)
                for row in rows:
                    bar.update(bool(row['passed']))
                    if on_row is not None:
                        on_row(row)
    finally:
        bar.close()
    return counts


def chunk_size(pending: int, workers: int, batch: bool) -> int:
    """Return the episodes per task: about two tasks per worker for a batch (eight for scalar
    episodes, which are slower one by one), at most MAX_BATCH in a batch and MAX_CHUNK one by
    one.

    A task runs its episodes together and its rows are stored when it ends: big enough that
    Dask's cost per task is small against it, small enough that the workers stay busy to the
    end and an interruption loses little. A batch costs some time per control period whatever
    its size (the law's call, the sweep's), so a batch of a few thousand episodes runs each
    faster than four smaller ones (``bench/bench_testbench.py``, part (e)).
    """
    per_worker = 2 if batch else 8
    most = MAX_BATCH if batch else MAX_CHUNK
    return max(1, min(most, -(-pending // (per_worker * max(workers, 1)))))


def _workers(client: Any) -> int:
    try:
        return len(client.scheduler_info()['workers'])
    except Exception:   # an unreachable scheduler shows up at the first result
        return 1


def run_campaign(spec: CampaignSpec, out: Path, *, scheduler: str | None = None,
                 workers: int | None = None, resume: bool = False,
                 progress: bool = True, foxglove_port: int = 0,
                 on_submitted: Callable[[], Any] | None = None) -> list[dict[str, Any]]:
    """Run (or continue) the campaign into ``out``; return every row, by episode id.

    The rows this run stored are returned as they were stored, the others as read back from
    the store (the same values: a row's cells are numbers, booleans and strings, which JSON
    keeps as they are). Nothing is written before the folder is checked and the cluster
    reached. With ``foxglove_port`` (0 = off) the episode being run is served live to
    Foxglove; with ``on_submitted``, that is called once the episodes are submitted
    (:func:`run_pending`).
    """
    return run_campaigns([(spec, out, resume)], scheduler=scheduler, workers=workers,
                         progress=progress, foxglove_port=foxglove_port,
                         on_submitted=on_submitted)[0]


def run_campaigns(jobs: list[tuple[CampaignSpec, Path, bool]], *, scheduler: str | None = None,
                  workers: int | None = None, progress: bool = True, foxglove_port: int = 0,
                  on_submitted: Callable[[], Any] | None = None
                  ) -> list[list[dict[str, Any]]]:
    """Run (or continue, where its flag says) each campaign ``(spec, out, resume)`` on one
    cluster, their episodes together (:func:`run_pending_all`); return each one's rows.

    Every folder is checked before anything is written or the cluster started.
    """
    stores = [EpisodeStore(out) for _, out, _ in jobs]
    for (spec, _, resume), store in zip(jobs, stores, strict=True):
        store.check(spec.text, resume)
    busy = any(len(store.done()) < spec.episodes
               for (spec, _, _), store in zip(jobs, stores, strict=True))
    client = make_client(scheduler, workers) if busy else None
    try:
        fresh: list[dict[int, dict[str, Any]]] = [{} for _ in jobs]   # rows stored now
        for (spec, _, resume), store in zip(jobs, stores, strict=True):
            store.create(spec.text, resume)
        if client is not None:
            run_pending_all([(spec, store, functools.partial(_keep, mine))
                             for (spec, _, _), store, mine in zip(jobs, stores, fresh,
                                                                  strict=True)],
                            client, progress, foxglove_port, on_submitted)
        return [store.rows(known=mine) for store, mine in zip(stores, fresh, strict=True)]
    finally:
        for store in stores:
            store.close()
        if client is not None:
            close_client(client, scheduler is None)


def _keep(rows: dict[int, dict[str, Any]], row: dict[str, Any]) -> None:
    """Keep ``row`` by its episode id (the rows a campaign stored in this run)."""
    rows.setdefault(int(row['episode']), row)


def close_client(client: Any, own_cluster: bool) -> None:
    """Close ``client`` (and its local cluster when ``own_cluster``), quietly."""
    import logging

    logging.getLogger('distributed').setLevel(logging.CRITICAL)   # closing mid-task is normal
    cluster = client.cluster if own_cluster else None
    try:
        client.close()
        if cluster is not None:
            cluster.close()
    except Exception:   # a cluster already gone has nothing left to close
        pass
