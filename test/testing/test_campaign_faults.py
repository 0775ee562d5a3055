"""A campaign survives its controller: one episode's fault fails that episode alone.

Through ``pendulum_campaign`` as a user runs it, on a real Dask cluster on 127.0.0.1 (``dask
scheduler`` and two ``dask worker`` processes with a memory limit, started here), with the
laws of test/support/campaign_faulty.py misbehaving in the episodes whose target is 0.4.
"""
from __future__ import annotations

import os
import re
import signal
import socket
import sqlite3
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from dask_harness import dask_cluster

from pendulum_sim.testing.campaign.episode import RUN_COLUMNS, run_episode

HERE = Path(__file__).resolve().parents[1] / 'support'
BIN = Path(sys.executable).parent
MEMORY_LIMIT = '600MB'
ENV = {**os.environ, 'PYTHONPATH': os.pathsep.join(
    [str(HERE), *filter(None, [os.environ.get('PYTHONPATH')])])}

CAMPAIGN = """
controller: campaign_faulty:{law}
episodes: 12
periods: 50
target: [0.5, 0.4, 0.6]
"""
TIMED = 3.0
"""The episode_timeout of the campaigns whose law takes too long (the others have the default,
60 s): the closed loop of a healthy episode, from its law's first call, takes well under 1 s."""
HEALTHY = 'pendulum_sim.testing.examples:pd'


def cli(*args: str, timeout: float = 240.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(BIN / 'pendulum_campaign'), *args], capture_output=True,
                          text=True, timeout=timeout, env=ENV)


def rows_of(folder: Path) -> list[dict[str, Any]]:
    """Return the CSV table's rows (cells as text) without the columns of where and when."""
    import csv

    with (folder / 'episodes.csv').open(newline='') as fh:
        return [{k: v for k, v in r.items() if k not in RUN_COLUMNS} for r in csv.DictReader(fh)]


@pytest.fixture(scope='module')
def cluster(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """Start ``dask scheduler`` and two single-threaded ``dask worker`` processes (memory limit
    :data:`MEMORY_LIMIT`, test/ on their PYTHONPATH); yield the scheduler's address."""
    with dask_cluster(tmp_path_factory.mktemp('dask'), memory_limit=MEMORY_LIMIT,
                      env=ENV) as running:
        yield running.address


@pytest.mark.parametrize(('law', 'reason'), [
    ('overflow', 'law raised OverflowError: the controller returned an int of 401 digits at '
     't = 0.11 s, too large for a float; a command must be finite'),
    ('exits', 'law exited with 3'),
    ('hard_exit', 'law exited with 4'),
    ('batch_exit', 'law exited with 4'),   # a batch: each episode alone says which one
    ('leaks', "worker killed: memory (the episode process passed the worker's memory limit "
     'of 572 MiB)'),
    ('hangs', 'law did not answer within 3 s'),
    # Every call answered within the limit, the episode not: 40 calls of 0.3 s (before: the
    # limit held each call alone, and the episode ran its 12 s to a row that passed).
    ('slow', 'law did not answer within 3 s'),
    ('text', "the controller returned '0.5' at t = 0.11 s; a command is a number"),
])
def test_one_episodes_fault_fails_that_episode_alone(tmp_path: Path, cluster: str, law: str,
                                                     reason: str) -> None:
    path = tmp_path / 'campaign.yaml'
    text = CAMPAIGN.format(law=law) + (f'episode_timeout: {TIMED}\n' if law in (
        'hangs', 'slow') else '')   # else the default: the memory limit stops the leak
    path.write_text(text)
    out = tmp_path / 'out'
    proc = cli(str(path), '--out', str(out), '--scheduler', cluster, '--no-progress')
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr == f'12 episodes, 8 passed; wrote {out / "summary.md"}\n'
    rows = rows_of(out)
    assert [int(r['episode']) for r in rows] == list(range(12))
    healthy = CAMPAIGN.format(law='x').replace('campaign_faulty:x', HEALTHY if 'batch' not in
                                               law else HEALTHY + '_batch')
    for r in rows:
        if r['target'] == '0.4':
            assert (r['passed'], r['reason']) == ('false', reason)
        else:   # every other episode is stored, the same as under a law without the fault
            expected = run_episode(healthy, int(r['episode']), None)
            assert r == {k: rows_of_cell(v) for k, v in expected.items()
                         if k not in RUN_COLUMNS}
    # A fault the law made in this process (its answer) keeps its run up to the fault.
    kept = sorted(p.name for p in (out / 'failures').glob('*.mcap')) if (
        out / 'failures').is_dir() else []
    assert kept == ([f'episode-{i:06d}.mcap' for i in (1, 4, 7, 10)]
                    if law in ('overflow', 'text') else [])


def test_an_episode_slow_outside_its_law_fails_with_the_time_it_had(tmp_path: Path) -> None:
    # The limit is the whole episode's; here the simulation, not the law (the example PD
    # law, microseconds a call), takes most of it.
    from pendulum_sim.testing.campaign.sandbox import Fault, run_chunk

    text = (f'controller: {HEALTHY}\nepisodes: 2\nperiods: 100000\ntarget: 0.5\n'
            'episode_timeout: 0.2\n')
    got = run_chunk(text, [0, 1], None, 0.2)
    assert got == [Fault(0, 'episode did not end within 0.2 s'),
                   Fault(1, 'episode did not end within 0.2 s')]


def rows_of_cell(value: Any) -> str:
    """Return a value as the CSV table writes it."""
    from pendulum_sim.testing.campaign.summary import _cell

    return _cell(value)


def _held_port() -> socket.socket:
    """Hold Dask's dashboard port (8787) as another campaign's cluster would."""
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind(('127.0.0.1', 8787))
    except OSError:   # something holds it already: so much the better
        sock.close()
        return socket.socket()
    sock.listen()
    return sock


def test_ctrl_c_prints_one_line_and_the_cluster_starts_no_http_server(tmp_path: Path) -> None:
    path = tmp_path / 'campaign.yaml'
    # Minutes of episodes: the campaign is still running when the signal lands, however
    # loaded the machine (with 200 it had once finished between the first chunk and Ctrl-C).
    path.write_text(f'controller: {HEALTHY}\nepisodes: 5000\nperiods: 3000\ntarget: 0.5\n')
    out = tmp_path / 'out'
    with _held_port():
        proc = subprocess.Popen([str(BIN / 'pendulum_campaign'), str(path), '--out', str(out),
                                 '--workers', '2', '--no-progress'], start_new_session=True,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                env=ENV)
        end = time.monotonic() + 120
        while not _stored(out):   # the cluster runs and a chunk is in
            assert proc.poll() is None and time.monotonic() < end, proc.communicate()
            time.sleep(0.05)
        os.killpg(proc.pid, signal.SIGINT)   # as Ctrl-C in a terminal: the whole group
        _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130
    assert err == ('\npendulum_campaign: interrupted; the finished episodes are kept, '
                   '--resume continues\n')


def _stored(folder: Path) -> int:
    if not (folder / 'episodes.sqlite').is_file():
        return 0
    db = sqlite3.connect(f'file:{folder / "episodes.sqlite"}?mode=ro', uri=True, timeout=30)
    try:
        return int(db.execute('SELECT count(*) FROM episodes').fetchone()[0])
    except sqlite3.OperationalError:
        return 0
    finally:
        db.close()


def test_the_local_cluster_has_no_http_server() -> None:
    from pendulum_sim.testing.campaign.execute import close_client, make_client

    client = make_client(None, 1)
    try:
        info = client.scheduler_info()
        assert info['services'] == {}
        assert [w['services'] for w in info['workers'].values()] == [{}]
    finally:
        close_client(client, True)


def test_a_rerun_of_a_faulted_episode_reproduces_its_reason(tmp_path: Path,
                                                           cluster: str) -> None:
    path = tmp_path / 'campaign.yaml'
    path.write_text(CAMPAIGN.format(law='hard_exit').replace('episodes: 12', 'episodes: 3'))
    out = tmp_path / 'out'
    assert cli(str(path), '--out', str(out), '--scheduler', cluster,
               '--no-progress').returncode == 1
    again = cli('--rerun', str(out), '1')
    assert (again.returncode, again.stdout) == (
        0, 'episode 1 reproduced bit for bit (failed: law exited with 4)\n')
    assert re.fullmatch(r'', again.stderr)
