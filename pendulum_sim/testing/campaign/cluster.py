"""The local Dask cluster of a campaign: no HTTP server, and Ctrl-C for the campaign alone.

Dask's scheduler and workers each start an HTTP server (the dashboard and its health and
metrics pages) even with the dashboard off; the scheduler's asks for port 8787 and warns
("Port 8787 is already in use") when another cluster holds it. A campaign reads none of those
pages, so its local cluster's scheduler and workers start none (:class:`QuietScheduler`,
:class:`QuietWorker`). Its processes are started with SIGINT ignored (they inherit it, and
Python keeps an inherited SIG_IGN), so Ctrl-C in the terminal interrupts the campaign's own
process, which closes the cluster, and no worker prints a traceback. Each worker starts its
episode process (:mod:`~pendulum_sim.testing.campaign.sandbox`) as it starts, so the first
episodes find it ready.
"""
from __future__ import annotations

import signal
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import dask
from distributed import LocalCluster, Nanny, Scheduler, Worker

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


class QuietScheduler(Scheduler):
    """A Dask scheduler without an HTTP server."""

    def start_http_server(self, *args: Any, **kwargs: Any) -> None:
        """Start nothing (a campaign reads no dashboard)."""


class QuietWorker(Worker):
    """A Dask worker without an HTTP server, whose episode process starts with it."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        from .sandbox import memory_limit_of, prestart

        prestart(memory_limit_of(self))

    def start_http_server(self, *args: Any, **kwargs: Any) -> None:
        """Start nothing (a campaign reads no dashboard)."""


class QuietNanny(Nanny):
    """A Dask nanny whose worker is a :class:`QuietWorker`."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **{**kwargs, 'worker_class': QuietWorker})


class QuietCluster(LocalCluster):
    """A ``LocalCluster`` of a :class:`QuietScheduler` and :class:`QuietNanny` processes."""

    async def _start(self) -> None:
        self.scheduler_spec = {**self.scheduler_spec, 'cls': QuietScheduler}
        await super()._start()  # type: ignore[no-untyped-call]


@contextmanager
def sigint_ignored() -> Iterator[None]:
    """Ignore SIGINT in this process meanwhile (the processes it starts inherit that)."""
    before = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, before)


def local_cluster(workers: int) -> Any:
    """Start the campaign's local cluster of ``workers`` single-threaded worker processes."""
    with dask.config.set(CLUSTER_CONFIG), sigint_ignored():
        return QuietCluster(  # type: ignore[no-untyped-call]
            n_workers=workers, threads_per_worker=1, processes=True,
                            host='127.0.0.1', dashboard_address=None, silence_logs=50,
                            worker_class=QuietNanny)
