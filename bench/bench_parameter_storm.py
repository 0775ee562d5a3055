"""Benchmark a parameter storm against the real-time node: does the tick keep its schedule?

The node runs the default scene in real time (h = 1 ms, publishing at 100 Hz) in its own process.
A storm client in another process (``test/support/parameter_storm.py``) sends ``set_parameters``
requests (gamma) at RATE per second with at most 10 unanswered. Printed, from the node's
/diagnostics before and after the storm: ``schedule_slips``, ``steps_per_wake_max``,
``wake_latency_max_us_total``, ``overruns``, ``parameter_sets`` and ``reconfigures`` (the
driver applies pending parameters once per wake), and the storm's achieved rate.

    .venv/bin/python bench/bench_parameter_storm.py --count 10000 --rate 1000

Figures to read, not assertions.
"""
from __future__ import annotations

import argparse
import json
import os
import random
import subprocess
import sys
from pathlib import Path

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(40, 49)))
TEST = Path(__file__).resolve().parents[1] / 'test' / 'support'
sys.path.insert(0, str(TEST))

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from node_harness import NodeProcess, Probe  # noqa: E402

from pendulum_sim.node.diagnostics import values_of  # noqa: E402

CLK_TCK = os.sysconf('SC_CLK_TCK')


def cpu_seconds(pid: int) -> float:
    """Return user + system CPU time of process ``pid`` in s, from /proc/<pid>/stat."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK


KEYS = ('steps', 'schedule_slips', 'steps_per_wake_max', 'wake_latency_max_us_total',
        'overruns', 'missed_wakes', 'wakes', 'parameter_sets', 'reconfigures')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--count', type=int, default=10000)
    parser.add_argument('--rate', type=float, default=1000.0)
    parser.add_argument('--in-flight', type=int, default=10)
    parser.add_argument('--executor', choices=('events', 'single'), default='events',
                        help="the node's executor (pendulum_node --executor)")
    args = parser.parse_args()
    with NodeProcess('default', {'status_line': False},
                     extra_args=['--executor', args.executor]) as node, Probe() as probe:
        diags = probe.subscribe(DiagnosticArray, '/diagnostics')

        def latest() -> dict[str, str]:
            mine = [values_of(a) for a in diags.msgs
                    if a.status and a.status[0].name.startswith(node.fqn)]
            return mine[-1] if mine else {}

        probe.spin_until(lambda: len([a for a in diags.msgs]) >= 3, 30.0, 'diagnostics')
        before = latest()
        assert node.proc is not None
        cpu0 = cpu_seconds(node.proc.pid)
        storm = subprocess.Popen(
            [sys.executable, str(TEST / 'parameter_storm.py'), node.fqn, str(args.count),
             str(args.rate), str(args.in_flight)], stdout=subprocess.PIPE, text=True)
        assert storm.stdout is not None
        assert storm.stdout.readline().strip() == 'ready'
        seen = len(diags.msgs)
        windows = []
        while storm.poll() is None:
            probe.spin_for(0.1)
            if len(diags.msgs) > seen:
                seen = len(diags.msgs)
                windows.append(latest())
        result = json.loads(storm.stdout.readline())
        cpu = cpu_seconds(node.proc.pid) - cpu0
        count = len(diags.msgs)
        probe.spin_until(lambda: len(diags.msgs) >= count + 2, 10.0, 'diagnostics after')
        after = latest()
        node.stop()
    rate = result['answered'] / result['seconds']
    print(f"storm: {result['sent']} sent, {result['answered']} answered, "
          f"{result['successful']} successful in {result['seconds']:.2f} s = {rate:.0f}/s "
          f"(asked {args.rate:.0f}/s, <= {args.in_flight} in flight)")
    print(f"node CPU during the storm: {cpu:.2f} s = {1e3 * cpu / result['answered']:.2f} ms "
          f"per set ({100 * cpu / result['seconds']:.0f} % of one core)")
    print('each diagnostics window during the storm (about 1 s): wake latency p99 / max (us), '
          'mean steps per wake, missed wakes so far')
    for w in windows:
        print(f"  {w.get('wake_latency_p99_us', '-'):>10} {w.get('wake_latency_max_us', '-'):>10}"
              f" {w.get('steps_per_wake', '-'):>8} {w.get('missed_wakes', '-'):>6}")
    print(f"{'figure':<28}{'before':>12}{'after':>12}")
    for key in KEYS:
        print(f'{key:<28}{before.get(key, "-"):>12}{after.get(key, "-"):>12}')


if __name__ == '__main__':
    main()
