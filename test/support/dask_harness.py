"""Test fixture helper: a real Dask cluster on 127.0.0.1, started as a user starts one.

A ``dask scheduler`` and ``dask worker`` processes of the venv's ``dask`` command line, each a
process of its own (nothing mocked, no dashboard); every wait polls with a timeout.
"""
from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

BIN = Path(sys.executable).parent


@dataclass(frozen=True)
class DaskCluster:
    """A running cluster: the scheduler's address and the worker processes."""

    address: str
    workers: list[subprocess.Popen[bytes]]


@contextlib.contextmanager
def dask_cluster(folder: Path, workers: int = 2, *, nanny: bool = True,
                 memory_limit: str | None = None,
                 env: Mapping[str, str] | None = None) -> Iterator[DaskCluster]:
    """Start a scheduler and ``workers`` single-threaded workers; end them on leaving.

    Parameters
    ----------
    folder : Path
        Where the scheduler writes its scheduler file.
    workers : int
        How many ``dask worker`` processes to start.
    nanny : bool
        Start each worker under a nanny (Dask's default). Without one the process is the
        worker, so a signal to it is a worker dying.
    memory_limit : str, optional
        The workers' ``--memory-limit`` (Dask's default where None).
    env : Mapping, optional
        The workers' environment (this process's where None).

    Yields
    ------
    DaskCluster
        Once the scheduler has every worker.
    """
    scheduler_file = folder / 'scheduler.json'
    dask = str(BIN / 'dask')
    procs = [subprocess.Popen([dask, 'scheduler', '--host', '127.0.0.1', '--port', '0',
                               '--no-dashboard', '--scheduler-file', str(scheduler_file)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        end = time.monotonic() + 60
        while not scheduler_file.is_file() or not scheduler_file.read_text().strip():
            assert procs[0].poll() is None and time.monotonic() < end, 'no scheduler'
            time.sleep(0.05)
        options = ([] if nanny else ['--no-nanny']) + (
            [] if memory_limit is None else ['--memory-limit', memory_limit])
        for _ in range(workers):
            procs.append(subprocess.Popen(
                [dask, 'worker', '--scheduler-file', str(scheduler_file), '--nthreads', '1',
                 '--host', '127.0.0.1', '--no-dashboard', *options],
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                env=dict(os.environ if env is None else env)))
        address = json.loads(scheduler_file.read_text())['address']
        from distributed import Client

        with Client(address, timeout='30s') as client:
            client.wait_for_workers(workers, timeout=60)
        yield DaskCluster(address, procs[1:])
    finally:   # the workers' episode processes leave when their worker is gone
        for p in reversed(procs):
            p.terminate()
        for p in reversed(procs):
            try:
                p.wait(3)   # a worker closing gracefully may wait on its scheduler: not needed
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


# Run on the workers or the scheduler by reference: importable there from test/support.
def worker_profiling(dask_worker: Any) -> bool:
    """Return True when the worker runs Dask's statistical profiler (its periodic sampling)."""
    return 'profile' in dask_worker.periodic_callbacks


def scheduler_tick(dask_scheduler: Any) -> float:
    """Return the seconds between the scheduler's event-loop health checks."""
    return float(dask_scheduler._tick_interval)


def worker_tick(dask_worker: Any) -> float:
    """Return the seconds between the worker's event-loop health checks."""
    return float(dask_worker._tick_interval)
