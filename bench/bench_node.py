"""Benchmark pendulum_node: the cost of a tick, and the node beside the first release's.

Phase 0 (default), the tick and the comparison:

- the per-tick cost breakdown of this node at 1 kHz (one step of h = 1 ms per tick), measured in
  this process on the node's own parts: stepping (the core's RK4 step), joint bookkeeping
  (``SimulatedJoint.advance`` and ``sample`` beyond the step, stamps, energy), serialization
  (the CDR templates of joint_states, /clock and energy), publish (rclpy ``publish`` of the
  bytes, no subscriber) and executor (one timer wake of the EventsExecutor);
- this node and the first release's (a checkout of commit e07fe85, ``--first``) run the same
  scenes interleaved, each in its own process: the paper scene at 1 kHz (CPU share of one
  core from /proc, start-up excluded) and free lockstep (``--scene lockstep``, the summary's
  achieved real-time factor), with nothing subscribed and with this process subscribed to
  joint_states and /clock (the node skips publications nobody receives, so both are shown).

Then the Foxglove live view (``foxglove_port``, issue 27): the same two figures (1 kHz CPU,
free-lockstep rate) with the server off, on without a client and on with one client reading
every channel, interleaved (``--only-live`` runs only this).

Phase 1, real time (1 kHz physics, 1 kHz publishing by default): the publish period seen by the
subscriber, the stamp-to-receive age, the drift of simulated against wall time over the run,
the node's CPU (from /proc/<pid>/stat) and its own wake latency (from /diagnostics).
Phase 2, lockstep as fast as possible, joint_states every 1 ms of simulated time: the real-time
factor, from /clock as received and from the node's diagnostics.

    .venv/bin/python bench/bench_node.py --duration 60

Targets (issue 3): drift <= h, wake latency p99 <= 0.3 ms, node CPU <= 25 % of one core,
lockstep >= 50x real time. Timings are figures to read, not assertions.
"""
from __future__ import annotations

import argparse
import os
import platform
import random
import sys
import textwrap
import time
from pathlib import Path
from typing import Any

import numpy as np

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(40, 49)))
os.environ.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'test' / 'support'))

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from node_harness import NodeProcess, Probe, stamp_ns, unique_namespace
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from pendulum_sim.node.diagnostics import values_of

CLK_TCK = os.sysconf('SC_CLK_TCK')


def cpu_seconds(pid: int) -> float:
    """Return user + system CPU time of process ``pid`` in s, from /proc/<pid>/stat."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK


def machine() -> str:
    """Return a one-line description of this machine."""
    model = 'unknown CPU'
    for line in Path('/proc/cpuinfo').read_text().splitlines():
        if line.startswith('model name'):
            model = line.split(':', 1)[1].strip()
            break
    return (f'{model}, {os.cpu_count()} cores, Linux {platform.release()}, '
            f'Python {platform.python_version()}')


def pct(values: np.ndarray, q: float) -> float:
    """Return the q-th percentile."""
    return float(np.percentile(values, q))


def node_args(args: argparse.Namespace) -> list[str]:
    """Return the node's own command-line options for this run."""
    return ['--executor', args.executor, '--rt-priority', str(args.rt_priority)]


def wait_for_node(probe: Probe, states: Any, what: str) -> None:
    """Spin until messages flow."""
    probe.spin_until(lambda: len(states) >= 10, 30.0, what)


def real_time_phase(args: argparse.Namespace) -> dict[str, Any]:
    """Run the node in real time and measure it from this process."""
    params = {'publish_rate': args.rate, 'h': args.h, 'status_line': False}
    out: dict[str, Any] = {}
    with NodeProcess('paper', params, extra_args=node_args(args)) as node, \
            Probe('bench', executor='events') as probe:
        stamps: list[int] = []
        recv: list[int] = []

        def on_state(msg: JointState) -> None:
            recv.append(time.time_ns())
            stamps.append(stamp_ns(msg))

        states = probe.subscribe(JointState, f'{node.namespace}/joint_states', 100, on_state)
        diags = probe.subscribe(DiagnosticArray, '/diagnostics', 10)
        wait_for_node(probe, states, 'joint_states')
        probe.spin_for(args.warmup)
        stamps.clear()
        recv.clear()
        n_diag = len(diags)
        assert node.proc is not None
        pid = node.proc.pid
        cpu0, wall0 = cpu_seconds(pid), time.monotonic()
        probe.spin_for(args.duration)
        cpu1, wall1 = cpu_seconds(pid), time.monotonic()
        reports = [values_of(a) for a in diags.msgs[n_diag:]
                   if a.status and a.status[0].name.startswith(node.fqn)]
        node.stop()
        summary = node.output().split('pendulum_node summary:')[-1]
    s = np.array(stamps, dtype=np.int64)
    r = np.array(recv, dtype=np.int64)
    period_ms = np.diff(r) / 1e6
    age_ms = (r - s) / 1e6
    t = (r - r[0]) / 1e9
    # Drift: how the offset between simulated and wall time moves over the run. The age of a
    # message mixes that offset with the step lag (< h), wake latency and transport delay,
    # which only ever add; so the offset is tracked by the smallest age in each 1 s window,
    # and the drift is the trend of those minima.
    window = np.floor(t).astype(np.int64)
    edges = np.flatnonzero(np.diff(window)) + 1
    minima = np.array([a.min() for a in np.split(age_ms, edges)])
    centers = np.array([c.mean() for c in np.split(t, edges)])
    slope, _ = np.polyfit(centers, minima, 1)
    edge = max(1, len(minima) // 10)
    out.update(
        received=len(s), expected=int(args.rate * args.duration),
        period_p50=pct(period_ms, 50), period_p99=pct(period_ms, 99),
        period_max=float(period_ms.max()),
        age_p50=pct(age_ms, 50), age_p99=pct(age_ms, 99), age_max=float(age_ms.max()),
        drift_fit_ms=float(-slope * t[-1]),
        drift_ends_ms=float(np.median(minima[:edge]) - np.median(minima[-edge:])),
        offset_spread_ms=float(minima.max() - minima.min()),
        cpu_percent=100.0 * (cpu1 - cpu0) / (wall1 - wall0),
        wake_p99_windows=[float(x['wake_latency_p99_us']) for x in reports],
        wake_p50_windows=[float(x['wake_latency_p50_us']) for x in reports],
        overruns=reports[-1]['overruns'] if reports else '?',
        missed=reports[-1]['missed_wakes'] if reports else '?',
        rtf_total=reports[-1]['real_time_factor_total'] if reports else '?',
        wake_p99_total=reports[-1]['wake_latency_p99_us_total'] if reports else '?',
        summary=summary.strip())
    return out


def lockstep_phase(args: argparse.Namespace, clock_subscriber: bool) -> dict[str, Any]:
    """Run lockstep as fast as possible; measure the real-time factor.

    Without a /clock subscriber the factor comes from the node's diagnostics (1 Hz, nothing
    else subscribed); with one, from the /clock ticks as this process receives them.
    """
    params = {'status_line': False, 'h': 1e-3, 'publish_rate': 1000.0}
    best_effort = QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT)
    namespace = unique_namespace()
    clock_topic = f'{namespace}/clock'  # remapped, so no other run in the domain interferes
    node = NodeProcess('lockstep', params, namespace=namespace, remap={'/clock': clock_topic},
                       extra_args=node_args(args))
    with node, Probe('bench_lockstep', executor='events') as probe:
        ticks: list[tuple[int, int]] = []

        def on_clock(msg: Clock) -> None:
            ticks.append((time.monotonic_ns(), msg.clock.sec * 1_000_000_000 + msg.clock.nanosec))

        diags = probe.subscribe(DiagnosticArray, '/diagnostics', 10)

        def reports() -> list[dict[str, str]]:
            return [values_of(a) for a in diags.msgs
                    if a.status and a.status[0].name.startswith(node.fqn)]

        if clock_subscriber:
            probe.subscribe(Clock, clock_topic, best_effort, on_clock)
            probe.spin_until(lambda: len(ticks) >= 10, 30.0, '/clock')
        else:
            probe.spin_until(lambda: len(reports()) >= 1, 30.0, 'diagnostics')
        probe.spin_for(1.0)
        n0, r0 = len(ticks), len(reports())
        probe.spin_for(args.lockstep_duration)
        window = ticks[n0:]
        rtf_node = [float(x['real_time_factor_achieved']) for x in reports()[r0:]]
        node.stop()
    out: dict[str, Any] = {'rtf_node': rtf_node}
    if window:
        (w0, c0), (w1, c1) = window[0], window[-1]
        out['rtf_clock'] = (c1 - c0) / (w1 - w0)
    return out


def print_real_time(args: argparse.Namespace, rt: dict[str, Any]) -> None:
    """Print the figures of the real-time phase."""
    h_ms = args.h * 1e3
    p99w = np.array(rt['wake_p99_windows'])
    print(f'\nreal time: h = {h_ms:g} ms, publish {args.rate:g} Hz, {args.duration:g} s '
          f'measured after {args.warmup:g} s warm-up')
    print(f'  received {rt["received"]} of ~{rt["expected"]} joint_states')
    print(f'  publish period at the subscriber p50/p99/max: {rt["period_p50"]:.3f} / '
          f'{rt["period_p99"]:.3f} / {rt["period_max"]:.3f} ms')
    print(f'  stamp-to-receive age p50/p99/max: {rt["age_p50"]:.3f} / {rt["age_p99"]:.3f} / '
          f'{rt["age_max"]:.3f} ms (step lag < h + wake latency + transport)')
    print(f'  smallest age per 1 s window: spread {rt["offset_spread_ms"]:.4f} ms over the run')
    for key, label in (('drift_fit_ms', 'trend of the per-window minimum age'),
                       ('drift_ends_ms', 'first vs last 10 % of windows')):
        ok = 'ok' if abs(rt[key]) <= h_ms else 'MISSED'
        print(f'  sim-vs-wall drift over the run ({label}): {rt[key]:+.4f} ms  '
              f'[target |drift| <= h = {h_ms:g} ms: {ok}]')
    ok = 'ok' if rt['cpu_percent'] <= 25.0 else 'MISSED'
    print(f'  node CPU: {rt["cpu_percent"]:.1f} % of one core  [target <= 25 %: {ok}]')
    if p99w.size:
        ok = 'ok' if np.median(p99w) <= 300.0 else 'MISSED'
        print(f'  wake latency p99 per 1 s window (node diagnostics): median {np.median(p99w):.0f}'
              f' us, worst {p99w.max():.0f} us; p50 median '
              f'{np.median(rt["wake_p50_windows"]):.0f} us  [target p99 <= 300 us: {ok}]')
    print(f'  whole run (incl. start-up): wake latency p99 {rt["wake_p99_total"]} us, overruns '
          f'{rt["overruns"]}, missed wakes {rt["missed"]}, achieved RTF {rt["rtf_total"]}')
    lines = [line.strip() for line in rt['summary'].splitlines()]
    print('\n  node shutdown summary:\n' + textwrap.indent('\n'.join(lines), '    '))


def per_tick(n: int) -> dict[str, float]:
    """Return the cost of one 1 kHz tick's parts in us (mean over ``n`` ticks)."""
    from rclpy.context import Context
    from rclpy.experimental import EventsExecutor
    from std_msgs.msg import Float64

    from pendulum_sim.core import PendulumParams, Stepper
    from pendulum_sim.joint.joint import JointConfig, SimulatedJoint
    from pendulum_sim.node.serialized import ClockBytes, Float64Bytes, JointStateBytes

    params = PendulumParams(gamma=1.0, n=1.0)
    clock = time.perf_counter
    st = Stepper(params, 2.0, 0.0, 1e-3, 'rk4', guard=True)
    t0 = clock()
    for _ in range(n):
        st.step(0.0)
    stepping = (clock() - t0) / n
    joint = SimulatedJoint(JointConfig(params=params, h=1e-3, phi0=2.0))
    t0 = clock()
    for _ in range(n):
        joint.advance(1)
        joint.sample()
        joint.stamp_ns()
        joint.energy()
    bookkeeping = (clock() - t0) / n - stepping
    js, ck, f64 = JointStateBytes('pendulum_joint'), ClockBytes(), Float64Bytes()
    t0 = clock()
    for k in range(n):
        data = js.pack(k, k, 0.1, 0.2, 0.0)
        tick = ck.pack(k, k)
        energy = f64.pack(0.5)
    serialization = (clock() - t0) / n
    context = Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node(f'bench_tick_{os.getpid()}', context=context)
        pubs = [node.create_publisher(t, f'bench_tick/{name}', 10)
                for t, name in ((JointState, 'joint_states'), (Clock, 'clock'),
                                (Float64, 'energy'))]
        t0 = clock()
        for _ in range(n):
            pubs[0].publish(data)
            pubs[1].publish(tick)
            pubs[2].publish(energy)
        publish = (clock() - t0) / n
        wakes = [0]

        def on_timer() -> None:
            wakes[0] += 1

        node.create_timer(1e-4, on_timer)
        executor = EventsExecutor(context=context)
        executor.add_node(node)
        t0 = time.process_time()
        while wakes[0] < n:
            executor.spin_once(timeout_sec=0.1)
        wake = (time.process_time() - t0) / wakes[0]
        executor.remove_node(node)
        executor.shutdown()
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
    return {'stepping': stepping * 1e6, 'joint bookkeeping': bookkeeping * 1e6,
            'serialization': serialization * 1e6, 'publish': publish * 1e6,
            'executor (one timer wake)': wake * 1e6}


def node_cmd(first: Path | None) -> tuple[list[str], dict[str, str]]:
    """Return the command starting a node (this one, or the first release's) and its env."""
    env = dict(os.environ)
    if first is None:
        return [sys.executable, '-m', 'pendulum_sim.node.cli'], env
    env['PYTHONPATH'] = str(first)
    code = ('import sys; from pendulum_sim.node.pendulum_node import main; '
            "sys.argv[0] = 'pendulum_node'; sys.exit(main())")
    return [sys.executable, '-c', code], env


class LiveClient:
    """A Foxglove client in a thread of this process, subscribed to every channel of a node's
    live view, reading (and counting) until stopped."""

    def __init__(self, port: int) -> None:
        import threading

        self.port = port
        self.received = 0
        self.error: BaseException | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        from foxglove_client import connect_when_up

        try:
            with connect_when_up(self.port, 30.0) as client:
                client.wait_channels('/tf', '/log')
                client.subscribe(*client.channels)
                while not self._stop.is_set():
                    self.received += len(client.messages(1))
        except BaseException as exc:  # reported by stop()
            self.error = exc

    def stop(self) -> int:
        """Stop reading; return the messages received."""
        self._stop.set()
        self._thread.join(30.0)
        if self.error is not None:
            raise RuntimeError(f'the live client failed: {self.error!r}')
        return self.received


def run_node(first: Path | None, scene: str, params: dict[str, str], seconds: float,
             warmup: float, listen: bool = False,
             live_client: int | None = None) -> tuple[float, str]:
    """Run a node for ``warmup + seconds``; return its CPU share after the warm-up and its
    shutdown summary. ``listen``: a subscriber in this process takes its joint_states and
    /clock meanwhile; ``live_client``: a Foxglove client reads its live view on that port."""
    import signal
    import subprocess

    root = first if first is not None else Path(__file__).resolve().parents[1]
    cmd, env = node_cmd(first)
    namespace = unique_namespace()
    cmd += ['--ros-args', '-r', f'__ns:={namespace}', '-r', f'/clock:={namespace}/clock',
            '--params-file', str(root / 'config' / f'{scene}.yaml'),
            *[x for k, v in params.items() for x in ('-p', f'{k}:={v}')]]
    # cwd: ``python -c`` puts it first on sys.path, so each node imports its own package.
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True, cwd=root)
    probe = Probe('bench_listener', executor='events') if listen else None
    client = LiveClient(live_client) if live_client is not None else None
    try:
        if probe is not None:
            best_effort = QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT)
            probe.subscribe(JointState, f'{namespace}/joint_states', best_effort)
            probe.subscribe(Clock, f'{namespace}/clock', best_effort)
        wait = probe.spin_for if probe is not None else time.sleep
        wait(warmup)   # a benchmark: start-up excluded by time, not asserted
        c0, w0 = cpu_seconds(proc.pid), time.monotonic()
        wait(seconds)
        share = (cpu_seconds(proc.pid) - c0) / (time.monotonic() - w0)
        if proc.poll() is not None:
            raise RuntimeError(f'the node ended early: {proc.communicate()[1][-2000:]}')
        if client is not None:
            got = client.stop()
            client = None
            if got == 0:
                raise RuntimeError('the live client received nothing')
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    finally:
        if client is not None:
            client.stop()
        if probe is not None:
            probe.close()
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return share, err


def summary_value(text: str, key: str) -> float:
    """Return a number from a node's shutdown summary."""
    for line in text.splitlines():
        if line.strip().startswith(key):
            return float(line.strip()[len(key):].split()[0])
    return float('nan')


def compare(args: argparse.Namespace) -> None:
    """Print the tick breakdown and the two nodes side by side, interleaved."""
    parts = per_tick(args.ticks)
    total = sum(parts.values())
    print(f'\nper-tick cost at 1 kHz (this node, mean of {args.ticks} ticks, us):')
    for name, us in parts.items():
        print(f'  {name:<28} {us:7.1f}')
    print(f'  {"sum":<28} {total:7.1f}  (= {total / 10:.1f} % of a core at 1 kHz)')
    first = Path(args.first) if args.first else None
    if first is not None and not (first / 'pendulum_sim' / 'node').is_dir():
        print(f'\n(no first release at {first}: git worktree add {first} e07fe85)')
        first = None
    nodes = [('first release e07fe85', first), ('this node', None)] if first else [
        ('this node', None)]
    cpu: dict[str, list[float]] = {name: [] for name, _ in nodes}
    rtf: dict[str, list[float]] = {name: [] for name, _ in nodes}
    heard: dict[str, list[float]] = {name: [] for name, _ in nodes}
    for _ in range(args.rounds):
        for name, path in nodes:
            share, _ = run_node(path, 'paper', {'publish_rate': '1000.0',
                                                'status_line': 'false'}, args.cpu_seconds, 3.0)
            cpu[name].append(100.0 * share)
            _, err = run_node(path, 'lockstep', {'status_line': 'false'},
                              args.lockstep_duration, 0.0)
            rtf[name].append(summary_value(err, 'achieved real-time factor'))
            _, err = run_node(path, 'lockstep', {'status_line': 'false'},
                              args.lockstep_duration, 2.0, listen=True)
            heard[name].append(summary_value(err, 'achieved real-time factor'))
    print(f'\nside by side, interleaved, {args.rounds} rounds (machine shared with other '
          f'work: read the ratios):')
    for name, _ in nodes:
        c, r = np.array(cpu[name]), np.array(rtf[name])
        ok_c = 'ok' if np.median(c) <= 25.0 else 'MISSED'
        ok_r = 'ok' if np.median(r) >= 50.0 else 'MISSED'
        print(f'  {name:<22} paper scene at 1 kHz: CPU median {np.median(c):5.1f} % of a core '
              f'({", ".join(f"{x:.1f}" for x in c)})  [target <= 25 %: {ok_c}]')
        print(f'  {"":<22} free lockstep {args.lockstep_duration:g} s: RTF median '
              f'{np.median(r):6.1f}x ({", ".join(f"{x:.1f}" for x in r)})  '
              f'[target >= 50x: {ok_r}]')
        hr = np.array(heard[name])
        print(f'  {"":<22} the same with this process subscribed to joint_states and /clock: '
              f'RTF median {np.median(hr):6.1f}x ({", ".join(f"{x:.1f}" for x in hr)})')
    if first is not None:
        a, b = nodes[0][0], nodes[1][0]
        print(f'  ratio this/first: CPU {np.median(cpu[b]) / np.median(cpu[a]):.2f}, '
              f'lockstep RTF {np.median(rtf[b]) / np.median(rtf[a]):.2f}, with a subscriber '
              f'{np.median(heard[b]) / np.median(heard[a]):.2f}')


def live_compare(args: argparse.Namespace) -> None:
    """Print the node with its Foxglove live view off, on without a client and on with one,
    side by side, interleaved (issue 27: the server off costs what the node did before)."""
    from foxglove_client import free_port

    variants = ('server off', 'on, no client', 'on, one client')
    cpu: dict[str, list[float]] = {v: [] for v in variants}
    rtf: dict[str, list[float]] = {v: [] for v in variants}
    for _ in range(args.rounds):
        for variant in variants:
            params = {'status_line': 'false'}
            port = None
            if variant != 'server off':
                port = free_port()
                params['foxglove_port'] = str(port)
            client = port if variant == 'on, one client' else None
            share, _ = run_node(None, 'paper', {**params, 'publish_rate': '1000.0'},
                                args.cpu_seconds, 3.0, live_client=client)
            cpu[variant].append(100.0 * share)
            if port is not None:
                port = free_port()
                params['foxglove_port'] = str(port)
            _, err = run_node(None, 'lockstep', params, args.lockstep_duration, 2.0,
                              live_client=port if client is not None else None)
            rtf[variant].append(summary_value(err, 'achieved real-time factor'))
    print(f'\nFoxglove live view (foxglove_port), interleaved, {args.rounds} rounds: paper '
          f'scene at 1 kHz for {args.cpu_seconds:g} s, free lockstep for '
          f'{args.lockstep_duration:g} s (the client reads every channel):')
    off_c, off_r = np.median(cpu['server off']), np.median(rtf['server off'])
    for v in variants:
        c, r = np.array(cpu[v]), np.array(rtf[v])
        print(f'  {v:<16} 1 kHz CPU median {np.median(c):5.1f} % of a core '
              f'({", ".join(f"{x:.1f}" for x in c)}), ratio to off {np.median(c) / off_c:.2f};'
              f'  free lockstep RTF median {np.median(r):6.1f}x '
              f'({", ".join(f"{x:.1f}" for x in r)}), ratio to off {np.median(r) / off_r:.2f}')


def main() -> int:
    """Run the phases and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--duration', type=float, default=60.0, help='real-time phase, s')
    parser.add_argument('--warmup', type=float, default=3.0, help='ignored start, s')
    parser.add_argument('--rate', type=float, default=1000.0, help='publish rate, Hz')
    parser.add_argument('--h', type=float, default=1e-3, help='integration step, s')
    parser.add_argument('--lockstep-duration', type=float, default=10.0, help='s')
    parser.add_argument('--skip-lockstep', action='store_true')
    parser.add_argument('--skip-realtime', action='store_true')
    parser.add_argument('--skip-compare', action='store_true')
    parser.add_argument('--only-compare', action='store_true',
                        help='only the tick breakdown and the side-by-side comparison')
    parser.add_argument('--first', default='/tmp/pendulum_first',
                        help='a checkout of the first release (git worktree add PATH e07fe85)')
    parser.add_argument('--rounds', type=int, default=2, help='comparison rounds')
    parser.add_argument('--ticks', type=int, default=20000, help='ticks in the breakdown')
    parser.add_argument('--cpu-seconds', type=float, default=10.0,
                        help='CPU measurement per comparison run, s')
    parser.add_argument('--skip-live', action='store_true',
                        help='skip the Foxglove live view comparison')
    parser.add_argument('--only-live', action='store_true',
                        help='only the Foxglove live view comparison (off / on / one client)')
    parser.add_argument('--executor', choices=('events', 'single'), default='events')
    parser.add_argument('--rt-priority', type=int, default=0,
                        help="the node's SCHED_FIFO priority (0 = normal scheduler)")
    args = parser.parse_args()
    print(f'machine: {machine()}')
    print(f'node executor: {args.executor}; ROS_DOMAIN_ID={os.environ["ROS_DOMAIN_ID"]}')
    if args.only_live:
        live_compare(args)
        rclpy.try_shutdown()
        return 0
    if not args.skip_compare:
        compare(args)
    if not args.skip_live:
        live_compare(args)
    if args.only_compare:
        rclpy.try_shutdown()
        return 0
    if not args.skip_realtime:
        print_real_time(args, real_time_phase(args))
    if not args.skip_lockstep:
        print(f'\nlockstep, as fast as possible, joint_states + energy + /clock every 1 ms of '
              f'simulated time, {args.lockstep_duration:g} s per measurement:')
        quiet = np.array(lockstep_phase(args, clock_subscriber=False)['rtf_node'])
        if quiet.size:
            ok = 'ok' if np.median(quiet) >= 50.0 else 'MISSED'
            print(f'  no /clock subscriber: node diagnostics median {np.median(quiet):.1f}x, '
                  f'min {quiet.min():.1f}x  [target >= 50x: {ok}]')
        busy = lockstep_phase(args, clock_subscriber=True)
        node_rtf = np.array(busy['rtf_node'])
        node_text = f'{np.median(node_rtf):.1f}x' if node_rtf.size else 'n/a'
        ok = 'ok' if busy.get('rtf_clock', 0.0) >= 50.0 else 'MISSED'
        print(f'  with this Python process taking every /clock tick: '
              f'{busy.get("rtf_clock", float("nan")):.1f}x from /clock, node diagnostics '
              f'{node_text}  [target >= 50x: {ok}]')
    rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
