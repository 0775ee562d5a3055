"""Benchmark the synchronous closed loop against a bare rclpy ping-pong, in one run; print both.

(a) ping-pong: process A publishes a std_msgs/Float64 (reliable), process B answers each one at
    once, A sends the next only when the answer is in: round trips per second. This is the
    ceiling for any loop in which two rclpy processes take turns.
(a') the same with ``pendulum_pd_controller`` as B, pinged with JointState messages: what the
    controller's side of the loop costs against a bare echo.
(b) synchronous closed loop: ``pendulum_node --scene controller_test`` (synchronous lockstep,
    a 10 ms control period) and ``pendulum_pd_controller`` in separate processes: control
    periods per second, from the simulated time in the node's /diagnostics (1 Hz) over the wall
    time between their arrivals here; the controller's own count of answers is printed beside.
(b') the same with the controller not using sim time (it needs no /clock: its time is the
    states' stamps).
(c) free lockstep (scene ``lockstep``): real-time factor from the node's diagnostics, alone and
    with ``pendulum_pd_controller`` (use_sim_time) answering every state.

    .venv/bin/python bench/bench_sync.py --rounds 3 --seconds 5

(a), (b) and (b') run in turn, round after round, and the ratio printed is the median of the
rounds' ratios: on a shared machine the load moves between phases.

Targets (issue 8): (b) >= 0.6 x (a); free lockstep >= 50x real time. Figures to read, not
assertions. Every process uses the same rclpy executor (--executor, default 'events').
"""
from __future__ import annotations

import argparse
import json
import os
import random
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(150, 199)))
os.environ.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'test' / 'support'))

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from node_harness import NodeProcess, Probe, unique_namespace
from rclpy.executors import Executor, SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from pendulum_sim.node.diagnostics import values_of
from pendulum_sim.reports.report import machine_info

RELIABLE = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)
CONTROLLER = 'pendulum_pd_controller'
CLK_TCK = os.sysconf('SC_CLK_TCK')


def executor(kind: str) -> Executor:
    """Return the executor the node and the controller use by default (or the single one)."""
    if kind == 'events':
        from rclpy.experimental import EventsExecutor
        return EventsExecutor()
    return SingleThreadedExecutor()


# ---------------------------------------------------------------------- (a) ping-pong roles
def role_pong(ns: str, kind: str) -> None:
    """Answer every Float64 on ``ping`` with one on ``pong`` until SIGINT/SIGTERM."""
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    stop: list[int] = []
    signal.signal(signal.SIGINT, lambda *_: stop.append(1))
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    node = rclpy.create_node('bench_pong', namespace=ns)
    pub = node.create_publisher(Float64, 'pong', RELIABLE)
    node.create_subscription(Float64, 'ping', lambda m: pub.publish(Float64(data=m.data)),
                             RELIABLE)
    ex = executor(kind)
    ex.add_node(node)
    print('ready', flush=True)
    while not stop:
        ex.spin_once(timeout_sec=0.1)
    node.destroy_node()
    rclpy.try_shutdown()


def role_ping(ns: str, kind: str, warmup: float, seconds: float, peer: int,
              states: bool) -> None:
    """Play ping-pong for ``warmup`` + ``seconds``; print round trips and CPU of that part.

    With ``states`` the ping is a JointState on ``joint_states`` (serialized once) and the
    answer a Float64 on ``effort_command``: the peer is then the controller.
    """
    rclpy.init()
    node = rclpy.create_node('bench_ping', namespace=ns)
    count = [0]
    if states:
        state = JointState(name=['pendulum_joint'], position=[0.7], velocity=[0.1],
                           effort=[0.0])
        data = serialize_message(state)
        pub = node.create_publisher(JointState, 'joint_states', RELIABLE)

        def on_answer(msg: Float64) -> None:
            count[0] += 1
            pub.publish(data)

        sub = node.create_subscription(Float64, 'effort_command', on_answer, RELIABLE)
        first: Any = data
    else:
        pub = node.create_publisher(Float64, 'ping', RELIABLE)

        def on_pong(msg: Float64) -> None:
            count[0] += 1
            pub.publish(Float64(data=msg.data + 1.0))

        sub = node.create_subscription(Float64, 'pong', on_pong, RELIABLE)
        first = Float64(data=0.0)
    ex = executor(kind)
    ex.add_node(node)
    end = time.monotonic() + 30.0
    while pub.get_subscription_count() < 1 or sub.get_publisher_count() < 1:
        if time.monotonic() > end:
            raise SystemExit('ping: pong did not connect within 30 s')
        ex.spin_once(timeout_sec=0.05)
    pub.publish(first)
    t_start = time.monotonic() + warmup
    t_end = t_start + seconds
    n0 = -1
    now = time.monotonic()
    while now < t_end:
        ex.spin_once(timeout_sec=0.1)
        now = time.monotonic()
        if n0 < 0 and now >= t_start:
            n0, t0 = count[0], now
            cpu0 = (time.process_time(), cpu_seconds(peer))
    cpu1 = (time.process_time(), cpu_seconds(peer))
    print(json.dumps({'round_trips': count[0] - n0, 'seconds': now - t0,
                      'cpu_ping': cpu1[0] - cpu0[0], 'cpu_pong': cpu1[1] - cpu0[1]}),
          flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


def ping_pong(args: argparse.Namespace, controller: bool = False) -> dict[str, float]:
    """Run (a) in two child processes; return round trips, seconds and CPU seconds.

    With ``controller`` the answering process is pendulum_pd_controller, pinged with
    JointState messages: (a') in the output.
    """
    ns = unique_namespace()
    me = [sys.executable, str(Path(__file__).resolve())]
    common = ['--ns', ns, '--executor', args.executor]
    ctl: ControllerProcess | None = None
    pong: subprocess.Popen[str] | None = None
    try:
        if controller:
            ctl = ControllerProcess(ns, args.executor, False, f'{ns}/clock')
            end = time.monotonic() + 30.0
            while 'PD + gravity compensation' not in ctl.output():
                if time.monotonic() > end or ctl.proc.poll() is not None:
                    raise SystemExit(f'the controller did not start:\n{ctl.output()}')
                time.sleep(0.05)
            peer = ctl.proc.pid
        else:
            pong = subprocess.Popen([*me, '--role', 'pong', *common], stdout=subprocess.PIPE,
                                    text=True)
            assert pong.stdout is not None
            if pong.stdout.readline().strip() != 'ready':
                raise SystemExit('pong did not start')
            peer = pong.pid
        ping = subprocess.run([*me, '--role', 'ping', *common, '--warmup', str(args.warmup),
                               '--seconds', str(args.seconds), '--peer', str(peer),
                               *(['--states'] if controller else [])],
                              capture_output=True,
                              text=True, timeout=args.warmup + args.seconds + 60)
        if ping.returncode != 0:
            raise SystemExit(f'ping failed:\n{ping.stderr}')
        result = json.loads(ping.stdout.strip().splitlines()[-1])
    finally:
        if pong is not None:
            pong.send_signal(signal.SIGINT)
            pong.wait(timeout=10)
        if ctl is not None:
            ctl.stop()
    return {k: float(v) for k, v in result.items()}


# ---------------------------------------------------------------------- (b), (c) the loop
def controller_command() -> list[str]:
    """Return the controller's command: the venv's entry point if installed."""
    script = Path(sys.executable).parent / CONTROLLER
    if script.is_file():
        return [str(script)]
    return [sys.executable, '-m', 'pendulum_sim.controller.pd_controller']


class ControllerProcess:
    """pendulum_pd_controller in its own process, in the node's namespace."""

    def __init__(self, ns: str, kind: str, use_sim_time: bool, clock_topic: str) -> None:
        self._log = tempfile.TemporaryFile(mode='w+')
        cmd = [*controller_command(), '--executor', kind, '--ros-args', '-r', f'__ns:={ns}',
               '-r', f'/clock:={clock_topic}',
               '-p', f'use_sim_time:={"true" if use_sim_time else "false"}']
        self.proc = subprocess.Popen(cmd, stdout=self._log, stderr=subprocess.STDOUT,
                                     text=True)

    def output(self) -> str:
        """Return what it wrote so far."""
        self._log.flush()
        self._log.seek(0)
        return self._log.read()

    def stop(self) -> str:
        """Stop it with SIGINT; return its output."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        out = self.output()
        self._log.close()
        return out


def cpu_seconds(pid: int) -> float:
    """Return user + system CPU time of process ``pid`` in s, from /proc/<pid>/stat."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK


def cpu_text(run: dict[str, Any], periods: float) -> str:
    """Return the processes' CPU per control period (approximate: the window ends differ)."""
    return ', '.join(f'{k} {1e6 * v / periods:.0f} us' for k, v in run['cpu'].items())


def answers_of(output: str) -> int | None:
    """Return the controller's count from its exit line ('answered N states, ...')."""
    for line in output.splitlines():
        if line.startswith(f'{CONTROLLER}: answered '):
            return int(line.split()[2])
    return None


def run_loop(args: argparse.Namespace, scene: str, with_controller: bool,
             use_sim_time: bool) -> dict[str, Any]:
    """Run the node on ``scene`` (and the controller); measure simulated time per wall time.

    Returns the node's parameters of interest, the windows (wall s, simulated s) between
    diagnostics after the warm-up, the last diagnostics, the outputs and the controller's count.
    """
    ns = unique_namespace()
    clock_topic = f'{ns}/clock'  # remapped, so no other run in the domain interferes
    out: dict[str, Any] = {'ok': False}
    ctl = ControllerProcess(ns, args.executor, use_sim_time, clock_topic) \
        if with_controller else None
    try:
        with Probe('bench_sync', executor='events') as probe:
            if ctl is not None:  # the controller waits for the joint, not the other way round
                probe.spin_until(lambda: 'PD + gravity compensation' in ctl.output(), 30.0,
                                 'the controller to start')
            node = NodeProcess(scene, {'status_line': False}, namespace=ns,
                               remap={'/clock': clock_topic},
                               extra_args=['--executor', args.executor])
            with node:
                arrivals: list[tuple[float, dict[str, str]]] = []

                def on_diag(msg: DiagnosticArray) -> None:
                    if msg.status and msg.status[0].name.startswith(node.fqn):
                        arrivals.append((time.monotonic(), values_of(msg)))

                probe.subscribe(DiagnosticArray, '/diagnostics', 10, on_diag)
                end = time.monotonic() + 30.0
                while not arrivals:
                    if not node.alive():
                        out['node_output'] = node.output()
                        return out
                    if time.monotonic() > end:
                        out['node_output'] = node.output()
                        return out
                    probe.spin_for(0.05)
                params = probe.get_parameters(node.fqn, ['synchronous', 'lockstep',
                                                         'publish_rate', 'h'])
                out['params'] = params
                probe.spin_for(args.warmup)
                first = len(arrivals)
                pids = {'node': node.proc.pid if node.proc else 0,
                        'controller': ctl.proc.pid if ctl is not None else 0}
                pids = {k: v for k, v in pids.items() if v}
                probe.spin_until(lambda: len(arrivals) > first, 10.0, 'diagnostics')
                cpu0 = {k: cpu_seconds(v) for k, v in pids.items()}
                probe.spin_until(lambda: len(arrivals) - first >= args.seconds + 2,
                                 args.seconds + 30.0, 'diagnostics')
                cpu1 = {k: cpu_seconds(v) for k, v in pids.items()}
                window = arrivals[first + 1:]
                (w0, d0), (w1, d1) = window[0], window[-1]
                out['wall'] = w1 - w0
                out['sim'] = float(d1['sim_time']) - float(d0['sim_time'])
                out['cpu'] = {k: cpu1[k] - cpu0[k] for k in pids}
                out['last'] = d1
                out['node_alive'] = node.alive()
                node.stop()
                out['node_output'] = node.output()
                out['ok'] = True
    finally:
        if ctl is not None:
            text = ctl.stop()
            out['controller_output'] = text
            out['answers'] = answers_of(text)
    return out


def tail(text: str, n: int = 15) -> str:
    """Return the last ``n`` lines of ``text``, indented."""
    return '\n'.join('    ' + line for line in text.strip().splitlines()[-n:])


def sync_figures(args: argparse.Namespace, use_sim_time: bool) -> dict[str, Any] | None:
    """Run (b) or (b') once; print why and return None when it cannot be measured."""
    sync = run_loop(args, 'controller_test', with_controller=True, use_sim_time=use_sim_time)
    params = sync.get('params', {})
    if not sync['ok'] or params.get('synchronous') is not True:
        why = ('the node does not declare the parameter synchronous (this pendulum_node has '
               'no synchronous mode yet)' if sync['ok'] else
               'the node did not run the scene controller_test (rejected it or failed)')
        print(f'    synchronous closed loop: NOT MEASURED: {why}')
        if sync.get('node_output'):
            print('    pendulum_node said:\n' + tail(sync['node_output']))
        return None
    rate = float(params['publish_rate'])
    sync['rate'] = rate
    sync['periods'] = sync['sim'] * rate
    sync['per_s'] = sync['periods'] / sync['wall']
    return sync


def main() -> int:
    """Run (a), (b), (b') in alternating rounds, then (c); print the figures side by side."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--seconds', type=float, default=5.0, help='measured time per phase')
    parser.add_argument('--rounds', type=int, default=3,
                        help="rounds of (a), (b), (b') in turn; the ratio is the median of "
                        "the rounds' ratios, so a change of machine load between phases "
                        'shows as spread instead of bias')
    parser.add_argument('--warmup', type=float, default=2.0, help='ignored start, s')
    parser.add_argument('--executor', choices=('events', 'single'), default='events')
    parser.add_argument('--skip-lockstep', action='store_true', help='skip (c)')
    parser.add_argument('--role', choices=('ping', 'pong'), help=argparse.SUPPRESS)
    parser.add_argument('--ns', help=argparse.SUPPRESS)
    parser.add_argument('--peer', type=int, help=argparse.SUPPRESS)
    parser.add_argument('--states', action='store_true', help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.role == 'pong':
        role_pong(args.ns, args.executor)
        return 0
    if args.role == 'ping':
        role_ping(args.ns, args.executor, args.warmup, args.seconds, args.peer, args.states)
        return 0

    load = ', '.join(f'{x:.2f}' for x in os.getloadavg())
    print(f'machine: {machine_info()}; load average {load}')
    print(f'executor: {args.executor} in every process; ROS_DOMAIN_ID='
          f'{os.environ["ROS_DOMAIN_ID"]}; {args.rounds} rounds, {args.seconds:g} s measured '
          f'per phase after {args.warmup:g} s warm-up')
    print('(a)  bare rclpy ping-pong: A publishes Float64 (reliable), B answers each at once, A '
          'sends the next on the answer')
    print('(b)  synchronous closed loop: pendulum_node --scene controller_test + '
          f"{CONTROLLER} (no use_sim_time: its time is the states' stamps)")
    print("(a') ping-pong with pendulum_pd_controller as B, pinged with JointState (its share)")
    print("(b') the same with use_sim_time:=true (the controller also takes every /clock tick)\n")
    ratios: dict[str, list[float]] = {"a'": [], 'b': [], "b'": []}
    shown = False
    for r in range(1, args.rounds + 1):
        pp = ping_pong(args)
        rate_pp = pp['round_trips'] / pp['seconds']
        print(f'round {r}: (a) {rate_pp:.0f} round trips/s ({1e6 / rate_pp:.0f} us each; CPU '
              f'per round trip ping {1e6 * pp["cpu_ping"] / pp["round_trips"]:.0f} us, pong '
              f'{1e6 * pp["cpu_pong"] / pp["round_trips"]:.0f} us)')
        pc = ping_pong(args, controller=True)
        rate_pc = pc['round_trips'] / pc['seconds']
        ratios["a'"].append(rate_pc / rate_pp)
        print(f"         (a') {rate_pc:.0f} round trips/s with {CONTROLLER} answering "
              f'JointState pings, ratio to (a) {rate_pc / rate_pp:.2f} (CPU per round trip '
              f'ping {1e6 * pc["cpu_ping"] / pc["round_trips"]:.0f} us, controller '
              f'{1e6 * pc["cpu_pong"] / pc["round_trips"]:.0f} us)')
        for key, use_sim_time in (('b', False), ("b'", True)):
            sync = sync_figures(args, use_sim_time)
            if sync is None:
                return 1
            ratio = sync['per_s'] / rate_pp
            ratios[key].append(ratio)
            print(f'         ({key}){" " if key == "b" else ""} {sync["per_s"]:.0f} control '
                  f'periods/s ({1e6 / sync["per_s"]:.0f} us each, '
                  f'{sync["per_s"] / sync["rate"]:.1f}x real time), ratio to (a) {ratio:.2f}; '
                  f'CPU per period {cpu_text(sync, sync["periods"])}')
            if not shown:
                shown = True
                last = sync['last']
                extra = {k: v for k, v in last.items() if k.startswith('sync_')}
                print(f'         node diagnostics at t = {float(last["sim_time"]):.2f} s '
                      f'(simulated): ' + ', '.join(f'{k} {v}' for k, v in extra.items()))
                print(f'         the controller answered {sync["answers"]} states; ' + next(
                    (ln.split(']: ', 1)[-1] for ln in sync.get('controller_output', '')
                     .splitlines() if 'settled at' in ln), 'the loop did not report settling'))
    print()
    for key, values in ratios.items():
        med = statistics.median(values)
        target = '' if key == "a'" else f"  [target >= 0.6: {'met' if med >= 0.6 else 'NOT met'}]"
        spread = ', '.join(f'{v:.2f}' for v in values)
        print(f'ratio ({key}) / (a), median of {len(values)} rounds: {med:.2f} ({spread})'
              f'{target}')

    if not args.skip_lockstep:
        for label, with_ctl in (('alone', False), (f'with {CONTROLLER} answering', True)):
            free = run_loop(args, 'lockstep', with_controller=with_ctl, use_sim_time=True)
            if not free['ok']:
                print(f'(c) free lockstep {label}: NOT MEASURED\n' + tail(
                    free.get('node_output', '')))
                continue
            rtf = free['sim'] / free['wall']
            ok = 'met' if rtf >= 50.0 else 'NOT met'
            answered = f'; controller answered {free["answers"]} states' if with_ctl else ''
            print(f'(c) free lockstep {label}: {rtf:.1f}x real time  [target >= 50x: {ok}]'
                  f'{answered}')
    load = ', '.join(f'{x:.2f}' for x in os.getloadavg())
    print(f'load average at the end: {load}')
    if os.getloadavg()[0] > (os.cpu_count() or 1):
        print('note: other work kept every core busy during this run; rates are low and noisy, '
              'same-round ratios are the figures to read')
    return 0

if __name__ == '__main__':
    sys.exit(main())
