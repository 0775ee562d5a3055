"""Benchmark MCAP recording: bytes on disk, write() cost, and what it does to a 1 kHz loop.

Run: ``.venv/bin/python bench/bench_recording.py [--seconds S] [--node]``, or
``.venv/bin/python bench/bench_recording.py --load [--minutes M] [--file PATH]`` for part 5 alone.
Prints figures; asserts nothing. Parts:

1. bytes per JointState on disk (``/joint_states`` alone, and per loop tick with every topic the
   node records), for zstd, lz4 and no compression;
2. ``McapRecorder.write`` cost per call (µs) in a loop thread paced at 1 kHz, writer running;
3. a 1 kHz Python loop (sleep to the next tick, measure how late it wakes) with and without a
   recorder taking four messages per tick: wake-latency p50/p99/max and process CPU;
4. with ``--node`` and the node installed: ``pendulum_node`` CPU (and its recording writer
   process's) and its own wake-latency p99 (from /diagnostics) with and without recording;
5. with ``--load``: ``load()`` of an hour-long 1 kHz recording (3.6 M joint_states and 3.6 M
   energy messages, written by ``McapRecorder`` from rclpy-serialized messages as the node's),
   in a fresh process: messages per second, and peak memory (RSS growth and the tracemalloc
   peak, which numpy reports to) against the bytes of the arrays it returns; the per-message
   decoder (``fast=False``) on the first minutes for comparison. ``--file`` keeps the recording
   (and reuses it when it exists).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('ROS_DOMAIN_ID', '39')

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.qos import QoSProfile
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from pendulum_sim.recording import McapRecorder

RATE_HZ = 1000
TOPICS: dict[str, Any] = {'/joint_states': JointState, '/energy': Float64,
                          '/effort_command': Float64, '/diagnostics': DiagnosticArray}


def joint_state(k: int, ns: int) -> JointState:
    """Return the JointState a pendulum node publishes at tick k (a damped swing)."""
    t = k / RATE_HZ
    msg = JointState()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 10**9)
    msg.name = ['pendulum_joint']
    msg.position = [float(np.exp(-0.1 * t) * np.cos(7.0 * t))]
    msg.velocity = [float(-7.0 * np.exp(-0.1 * t) * np.sin(7.0 * t))]
    msg.effort = [0.0]
    return msg


def tick_messages(k: int, ns: int) -> list[tuple[str, Any]]:
    """Return what the node records in one tick (diagnostics once a second)."""
    out: list[tuple[str, Any]] = [('/joint_states', joint_state(k, ns)),
                                  ('/energy', Float64(data=float(np.exp(-0.2 * k / RATE_HZ))))]
    if k % 10 == 0:
        out.append(('/effort_command', Float64(data=0.0)))
    if k % RATE_HZ == 0:
        diag = DiagnosticArray()
        diag.status = [DiagnosticStatus(name='pendulum', values=[
            KeyValue(key=f'key{i}', value=f'{0.001 * k + i:.6f}') for i in range(12)])]
        out.append(('/diagnostics', diag))
    return out


def bytes_on_disk(seconds: float, folder: Path) -> None:
    ticks = int(seconds * RATE_HZ)
    print(f'1. bytes on disk ({seconds:.0f} s at {RATE_HZ} Hz = {ticks} ticks)')
    for compression in ('zstd', 'lz4', 'none'):
        for alone in (True, False):
            path = folder / f'size_{compression}_{alone}.mcap'
            with McapRecorder(path, overwrite=True, compression=compression) as rec:
                for topic, msg_type in TOPICS.items():
                    if not alone or topic == '/joint_states':
                        rec.add_channel(topic, msg_type, QoSProfile(depth=10))
                for k in range(ticks):
                    ns = k * 1_000_000
                    for topic, msg in tick_messages(k, ns):
                        if not alone or topic == '/joint_states':
                            rec.write(topic, msg, ns)
            size = path.stat().st_size
            what = 'per JointState (alone)' if alone else 'per tick (all topics)'
            print(f'   {compression:5s} {what:24s} {size / ticks:7.1f} B   '
                  f'file {size / 1e6:.2f} MB')


def paced_loop(seconds: float, rec: McapRecorder | None) -> dict[str, float]:
    """Run a 1 kHz loop thread; return wake-latency and write-cost percentiles and CPU."""
    ticks = int(seconds * RATE_HZ)
    late = np.zeros(ticks)
    write_us: list[float] = []
    # Build the messages first: the loop measures only waking and recording.
    prepared = [tick_messages(k, k * 1_000_000) for k in range(ticks)]

    def loop() -> None:
        period = 1.0 / RATE_HZ
        start = time.perf_counter()
        for k in range(ticks):
            target = start + k * period
            now = time.perf_counter()
            if now < target:
                time.sleep(target - now)
                now = time.perf_counter()
            late[k] = now - target
            if rec is not None:
                ns = k * 1_000_000
                for topic, msg in prepared[k]:
                    t0 = time.perf_counter_ns()
                    rec.write(topic, msg, ns)
                    write_us.append((time.perf_counter_ns() - t0) / 1e3)

    usage0 = resource.getrusage(resource.RUSAGE_SELF)
    child0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    wall0 = time.perf_counter()
    thread = threading.Thread(target=loop)
    thread.start()
    thread.join()
    if rec is not None:
        rec.close()
    wall = time.perf_counter() - wall0
    usage1 = resource.getrusage(resource.RUSAGE_SELF)
    child1 = resource.getrusage(resource.RUSAGE_CHILDREN)   # the writer, waited for in close()
    cpu = (usage1.ru_utime - usage0.ru_utime + usage1.ru_stime - usage0.ru_stime) / wall
    writer_cpu = (child1.ru_utime - child0.ru_utime + child1.ru_stime - child0.ru_stime) / wall
    result = {'p50_ms': float(np.percentile(late, 50) * 1e3),
              'p99_ms': float(np.percentile(late, 99) * 1e3),
              'max_ms': float(late.max() * 1e3), 'cpu_pct': 100 * cpu,
              'writer_cpu_pct': 100 * writer_cpu}
    if write_us:
        result.update(write_p50_us=float(np.percentile(write_us, 50)),
                      write_p99_us=float(np.percentile(write_us, 99)),
                      write_max_us=float(max(write_us)))
    return result


def loop_with_and_without(seconds: float, folder: Path) -> None:
    print(f'2./3. a {RATE_HZ} Hz Python loop thread for {seconds:.0f} s (wake lateness, '
          'process CPU)')
    rows = []
    for label in ('without recording', 'with recording', 'without recording',
                  'with recording'):
        rec = None
        if label == 'with recording':
            rec = McapRecorder(folder / 'loop.mcap', overwrite=True)
            rec.open()
            for topic, msg_type in TOPICS.items():
                rec.add_channel(topic, msg_type, QoSProfile(depth=10))
        rows.append((label, paced_loop(seconds, rec)))
    for label, r in rows:
        line = (f'   {label:18s} wake p50 {r["p50_ms"]:.3f} ms  p99 {r["p99_ms"]:.3f} ms  '
                f'max {r["max_ms"]:.3f} ms  CPU {r["cpu_pct"]:.0f} %')
        if 'write_p50_us' in r:
            line += f' + writer {r["writer_cpu_pct"]:.0f} %'
            line += (f'  write() p50 {r["write_p50_us"]:.1f} µs  p99 {r["write_p99_us"]:.1f} µs'
                     f'  max {r["write_max_us"]:.0f} µs')
        print(line)


def node_with_and_without(seconds: float, folder: Path) -> None:
    root = Path(__file__).resolve().parents[1]
    node = Path(sys.executable).parent / 'pendulum_node'
    record_yaml = root / 'config' / 'record.yaml'
    default_yaml = root / 'config' / 'default.yaml'
    if not (node.exists() and record_yaml.exists() and default_yaml.exists()):
        print('4. pendulum_node: not installed yet, skipped')
        return
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    print(f'4. pendulum_node at 1 kHz physics and publishing, {seconds:.0f} s per run, default '
          'scene vs record scene (CPU from /proc; wake latency from its /diagnostics: median '
          'of the per-second p99, and the whole-run p99)')
    for label, params in (('without recording', default_yaml), ('with recording', record_yaml),
                          ('without recording', default_yaml), ('with recording', record_yaml)):
        out = folder / 'node.mcap'
        out.unlink(missing_ok=True)
        cmd = [str(node), '--ros-args', '--params-file', str(params), '-p',
               'publish_rate:=1000.0', '-p', 'status_line:=false']
        if params == record_yaml:
            cmd += ['-p', f'recording.path:={out}']
        context = Context()
        rclpy.init(context=context)
        listener = rclpy.create_node('bench_listener', context=context)
        values: dict[str, list[float]] = {}

        def on_diag(msg: DiagnosticArray, values: dict[str, list[float]] = values) -> None:
            for status in msg.status:
                for pair in status.values:
                    try:
                        values.setdefault(pair.key, []).append(float(pair.value))
                    except ValueError:
                        pass

        listener.create_subscription(DiagnosticArray, '/diagnostics', on_diag, 10)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(listener)
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        t0 = time.monotonic()
        while time.monotonic() - t0 < 2.0:   # start-up and discovery
            executor.spin_once(timeout_sec=0.1)
        writers = _children(proc.pid)   # the recording's writer process, if any
        ticks0 = _cpu_ticks(proc.pid)
        writer0 = sum(_cpu_ticks(p) for p in writers)
        values.clear()
        t0 = time.monotonic()
        while time.monotonic() - t0 < seconds:
            executor.spin_once(timeout_sec=0.1)
        hz = os.sysconf('SC_CLK_TCK')
        cpu = (_cpu_ticks(proc.pid) - ticks0) / hz / seconds
        writer_cpu = (sum(_cpu_ticks(p) for p in writers) - writer0) / hz / seconds
        executor.shutdown()
        proc.terminate()
        proc.wait(timeout=20)
        listener.destroy_node()
        rclpy.try_shutdown(context=context)
        p99 = values.get('wake_latency_p99_us', [])
        total = values.get('wake_latency_p99_us_total', [])
        size = (f'  writer process CPU {100 * writer_cpu:.1f} %  file '
                f'{out.stat().st_size / 1e6:.2f} MB' if out.exists() else '')
        if p99:
            median = statistics.median(p99)
            print(f'   {label:18s} CPU {100 * cpu:5.1f} %  wake p99 median {median:6.0f} µs  '
                  f'run p99 {total[-1]:6.0f} µs  ({len(p99)} reports){size}')
        else:
            print(f'   {label:18s} CPU {100 * cpu:5.1f} %  no diagnostics received{size}')


def _cpu_ticks(pid: int) -> int:
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return int(fields[11]) + int(fields[12])   # utime + stime


def _children(pid: int) -> list[int]:
    found = []
    for task in Path(f'/proc/{pid}/task').iterdir():
        found += [int(c) for c in (task / 'children').read_text().split()]
    return found


def synthesize(path: Path, minutes: float) -> None:
    """Record ``minutes`` of 1 kHz joint_states and energy, serialized by rclpy, one by one."""
    from rclpy.serialization import serialize_message
    ticks = round(minutes * 60 * RATE_HZ)
    msg = joint_state(0, 0)
    energy = Float64()
    t0 = time.perf_counter()
    with McapRecorder(path) as rec:
        rec.add_channel('/joint_states', JointState, QoSProfile(depth=10))
        rec.add_channel('/energy', Float64, 10)
        write = rec.write_serialized
        for k in range(ticks):
            ns = 1_700_000_000_000_000_000 + k * 1_000_000
            t = k / RATE_HZ
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 10**9)
            msg.position[0] = math.exp(-0.1 * t) * math.cos(7.0 * t)
            msg.velocity[0] = -7.0 * math.exp(-0.1 * t) * math.sin(7.0 * t)
            energy.data = math.exp(-0.2 * t)
            write('/joint_states', serialize_message(msg), ns)
            write('/energy', serialize_message(energy), ns)
            if k % 20_000 == 0:   # stay within the writer's backlog
                while 2 * k - rec.messages_written > 400_000 and rec.error is None:
                    time.sleep(0.01)
    if rec.error is not None:
        raise SystemExit(f'recording failed: {rec.error}')
    print(f'   synthesized {2 * ticks} messages in {time.perf_counter() - t0:.0f} s: '
          f'{path.stat().st_size / 1e6:.1f} MB')


MEASURE_LOAD = """
import json, resource, sys, time, tracemalloc
import numpy as np
from pendulum_sim.recording import load
path, mode = sys.argv[1], sys.argv[2]
load(sys.argv[3], fast=True)   # a tiny file: the message types are imported and loaded now
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
if mode == 'traced':
    tracemalloc.start()
t0 = time.perf_counter()
rec = load(path, fast=mode != 'slow')
seconds = time.perf_counter() - t0
peak = tracemalloc.get_traced_memory()[1] if mode == 'traced' else 0
after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
arrays = 0
for part in (rec.joint_states, rec.energy):
    for value in vars(part).values():
        if isinstance(value, np.ndarray):
            arrays += value.nbytes
count = sum(info.message_count for info in rec.topics.values())
print(json.dumps({'seconds': seconds, 'messages': count, 'arrays': arrays,
                  'rss_growth': (after - before) * 1024, 'traced_peak': peak}))
"""


def measure_load(path: Path, mode: str, warm: Path) -> dict[str, float]:
    """Load in a fresh process (so the memory figures are its own); return the figures.

    ``mode``: ``'fast'``, ``'slow'`` (the per-message decoder) or ``'traced'`` (fast, under
    tracemalloc, which slows Python down: for the memory peak only).
    """
    out = subprocess.run([sys.executable, '-c', MEASURE_LOAD, str(path), mode, str(warm)],
                         capture_output=True, text=True, check=True).stdout
    result: dict[str, float] = json.loads(out)
    return result


def load_figures(minutes: float, keep: Path | None, folder: Path) -> None:
    print(f'5. load() of a {minutes:g}-minute 1 kHz recording (joint_states + energy)')
    warm = folder / 'warm.mcap'
    synthesize(warm, 0.001)
    path = keep or folder / 'long.mcap'
    if not path.exists():
        synthesize(path, minutes)
    for _ in range(2):
        r = measure_load(path, 'fast', warm)
        print(f'   fast path: {r["messages"] / 1e6:.2f} M messages in {r["seconds"]:.2f} s = '
              f'{r["messages"] / r["seconds"] / 1e3:.0f} k messages/s; returned arrays '
              f'{r["arrays"] / 2**20:.0f} MiB, peak RSS growth {r["rss_growth"] / 2**20:.0f} '
              f'MiB = {r["rss_growth"] / r["arrays"]:.2f} x the arrays')
    r = measure_load(path, 'traced', warm)
    print(f'   fast path under tracemalloc: peak {r["traced_peak"] / 2**20:.0f} MiB = '
          f'{r["traced_peak"] / r["arrays"]:.2f} x the arrays')
    short = folder / 'short.mcap'
    short_minutes = min(minutes, 1.0)
    synthesize(short, short_minutes)
    for mode in ('slow', 'fast'):
        r = measure_load(short, mode, warm)
        label = 'fast path' if mode == 'fast' else 'per-message decoder'
        print(f'   {short_minutes:g} min, {label:19s} {r["messages"] / r["seconds"] / 1e3:.0f} k '
              f'messages/s ({r["seconds"]:.2f} s)')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=10.0)
    parser.add_argument('--node', action='store_true', help='also measure pendulum_node')
    parser.add_argument('--load', action='store_true',
                        help='measure load() on a long recording only (part 5)')
    parser.add_argument('--minutes', type=float, default=60.0,
                        help='length of the recording --load reads (default 60)')
    parser.add_argument('--file', type=Path, default=None,
                        help='keep the --load recording here (reused if it exists)')
    args = parser.parse_args()
    print(f'machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, '
          f'Python {platform.python_version()}, {platform.platform()}')
    if args.load:
        with tempfile.TemporaryDirectory() as tmp:
            load_figures(args.minutes, args.file, Path(tmp))
        return
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        bytes_on_disk(60.0, folder)
        loop_with_and_without(args.seconds, folder)
        if args.node:
            node_with_and_without(args.seconds, folder)


if __name__ == '__main__':
    main()
