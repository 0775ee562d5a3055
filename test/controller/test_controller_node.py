"""pendulum_pd_controller in its own process, over real DDS: one answer per state, and its value.

The controller is the installed executable; a probe node in the test publishes JointState
messages (reliable, as the joint does) and receives the Float64 answers. The expected torques
are computed here from the law's formula written out, not by calling the controller's module.
"Exactly one answer" is proven by order: commands arrive reliably and in order, so when the
answer to a final sentinel state arrives every earlier answer (or a duplicate) already has.
"""
from __future__ import annotations

import math
import re
import signal
import subprocess
import time
from typing import Any

import pytest
from controller_probe import NAME, RELIABLE, Controller, controller_command
from node_harness import NodeProcess, Probe, Received, unique_namespace
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

pytestmark = pytest.mark.ros

class Loop:
    """The probe's side of the loop: publish a state, wait for its answer."""

    def __init__(self, probe: Probe, ctl: Controller, joint: str = 'pendulum_joint') -> None:
        self.probe = probe
        self.joint = joint
        ns = ctl.namespace
        self.pub = probe.node.create_publisher(JointState, f'{ns}/joint_states', RELIABLE)
        self.answers: Received = probe.subscribe(Float64, f'{ns}/effort_command', RELIABLE)
        # Both directions matched, each on its writer's side: the probe's states reach the
        # controller's subscription, and the controller's answers reach this probe (its own
        # log of the match: an answer published before it would be lost).
        probe.spin_until(lambda: self.pub.get_subscription_count() >= 1
                         and re.search(r'effort_command reaches [1-9]', ctl.output())
                         is not None, 30.0, 'the controller to connect')

    def send(self, stamp_ns: int, phi: float, dphi: float,
             names: tuple[str, ...] = ('elbow', 'pendulum_joint')) -> None:
        msg = JointState()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
        msg.name = list(names)
        msg.position = [9.0 if n != self.joint else phi for n in names]
        msg.velocity = [-9.0 if n != self.joint else dphi for n in names]
        msg.effort = [0.0] * len(names)
        self.pub.publish(msg)

    def answer(self, stamp_ns: int, phi: float, dphi: float, **kw: Any) -> float:
        """Send a state, wait for one more answer, return it."""
        before = len(self.answers)
        self.send(stamp_ns, phi, dphi, **kw)
        self.probe.spin_until(lambda: len(self.answers) > before, 10.0, 'an answer')
        return float(self.answers.msgs[-1].data)


def expected(phi: float, dphi: float, kp: float, kd: float, target: float, mgl: float,
             limit: float) -> float:
    """τ = m g l sin φ + Kp (φ_ref − φ) − Kd φ', clipped (|φ_ref − φ| < π here: no wrap)."""
    assert abs(target - phi) < math.pi
    return min(max(mgl * math.sin(phi) + kp * (target - phi) - kd * dphi, -limit), limit)


def test_one_answer_per_state_with_the_law_value() -> None:
    gains = {'kp': 3.0, 'kd': 0.5, 'target': 0.2, 'mgl': 1.5, 'max_effort': 4.0}
    with Controller(params=gains) as ctl, Probe('pd_probe') as probe:
        loop = Loop(probe, ctl)
        states = [(k * 10_000_000, -2.0 + 0.08 * k, math.cos(k)) for k in range(50)]
        want = [expected(phi, dphi, gains['kp'], gains['kd'], gains['target'], gains['mgl'],
                         gains['max_effort']) for _, phi, dphi in states]
        assert min(want) == -4.0 or max(want) == 4.0  # some answers are clipped
        got = [loop.answer(*s) for s in states]
        assert got == pytest.approx(want, rel=1e-12, abs=1e-12)
        sentinel = loop.answer(states[-1][0] + 10_000_000, 0.2, 0.0)
        assert sentinel == pytest.approx(1.5 * math.sin(0.2), rel=1e-12)
        assert len(loop.answers) == len(states) + 1
        assert ctl.alive()
        # Live gains: a rejected value leaves the old one, an accepted one is used at once.
        result = probe.set_parameters(ctl.fqn, {'max_effort': 0.0})
        assert not result[0].successful
        assert result[0].reason == 'max_effort must be > 0, got 0.0'
        result = probe.set_parameters(ctl.fqn, {'kp': -1.0})
        assert not result[0].successful
        assert probe.set_parameters(ctl.fqn, {'kp': 1.0, 'mgl': 0.0})[0].successful
        assert loop.answer(0, -0.8, 0.0) == pytest.approx(1.0 * (0.2 + 0.8), rel=1e-12)
        assert ctl.stop(signal.SIGINT) == 0
        assert f'answered {len(states) + 2} states, skipped 0' in ctl.output()


def test_a_state_without_the_joint_is_not_answered() -> None:
    with Controller(params={'joint_name': 'knee'}) as ctl, Probe('pd_probe') as probe:
        loop = Loop(probe, ctl, joint='knee')
        loop.send(0, 0.1, 0.0, names=('elbow', 'pendulum_joint'))
        probe.spin_until(lambda: "has no position and velocity for joint 'knee'"
                         in ctl.output(), 10.0, 'the missing-joint error')
        value = loop.answer(10_000_000, 0.3, 0.0, names=('knee',))
        assert len(loop.answers) == 1  # the answer to the bad state never came
        assert value == pytest.approx(1.96 * math.sin(0.3) + 4.0 * 0.2, rel=1e-12)
        assert ctl.stop(signal.SIGTERM) == 0
        assert 'answered 1 states, skipped 1' in ctl.output()


def test_settling_is_judged_by_stamps_not_wall_time() -> None:
    """States 0.1 s apart in stamps, sent within milliseconds: settled at 0.5 s of stamps."""
    params = {'target': 0.5, 'settle_hold': 0.5, 'settle_position_tolerance': 0.01,
              'settle_velocity_tolerance': 0.01}
    with Controller(params=params) as ctl, Probe('pd_probe') as probe:
        loop = Loop(probe, ctl)
        for k in range(5):  # 0 … 0.4 s, at the target and at rest
            loop.answer(k * 100_000_000, 0.5, 0.0)
        # The log line is written before the answer is published.
        assert 'settled at' not in ctl.output()
        loop.answer(500_000_000, 0.5 + 0.009, -0.009)
        assert ctl.output().count('settled at t = 0.500 s (state stamp)') == 1
        loop.answer(600_000_000, 0.5 + 0.05, 0.0)  # off, but not 10x the tolerance: noise
        assert ctl.output().count('settled at') == 1
        assert 'left the target' not in ctl.output()
        loop.answer(700_000_000, 0.7, 0.0)  # far off (a reset with time going on, a push)
        assert 'left the target at t = 0.700 s (state stamp)' in ctl.output()
        loop.answer(0, 1.0, 0.0)  # time went back
        assert 'simulated time went back to t = 0.000 s' in ctl.output()
        for k in range(1, 6):  # inside from 0.1 s: not settled at 0.5 s …
            loop.answer(k * 100_000_000, 0.5, 0.0)
        assert ctl.output().count('settled at') == 1
        loop.answer(600_000_000, 0.5, 0.0)  # … but at 0.6 s
        assert ctl.output().count('settled at t = 0.600 s') == 1
        assert ctl.stop() == 0


def test_the_settle_log_names_its_rule_and_gives_the_metrics_settling_time() -> None:
    """The README's run, state by state: the controller's own rule says 2.670 s, and the same
    line gives the test bench's settling time of that run, 1.300 s, as ``metrics()`` does;
    the first tutorial shows this very line."""
    from pathlib import Path

    from pendulum_sim.controller.pd_law import PDGains, pd_torque
    from pendulum_sim.testing import closed_loop

    gains = PDGains(kp=4.0, kd=1.0, target=0.5)
    run = closed_loop(lambda t, x, v: pd_torque(gains, x, v), periods=400)
    with Controller(params={'target': 0.5}) as ctl, Probe('pd_probe') as probe:
        loop = Loop(probe, ctl, joint='pendulum_joint')
        for t, x, v, tau in zip(run.t, run.position, run.velocity, run.command, strict=True):
            # The answers are the run's commands, bit for bit: the same loop over DDS.
            assert loop.answer(round(t * 1e9), float(x), float(v),
                               names=('pendulum_joint',)) == tau
            if 'settled at' in ctl.output():
                break
        assert ctl.stop() == 0
        output = ctl.output()
    (line,) = [ln.split(']: ', 1)[1] for ln in output.splitlines() if 'settled at' in ln]
    metric = run.metrics(0.5).settling_time
    assert metric == 1.3
    assert line == (
        "settled at t = 2.670 s (state stamp) by the controller's rule: |angle - target| < "
        '0.01 rad and |velocity| < 0.01 rad/s since t = 2.170 s (settle_hold 0.5 s); angle '
        f'{run.position[267]:.6f} rad, target 0.5 rad; step-response settling time '
        f't = {metric:.3f} s so far (within 2 % of the step from 1 rad to 0.5 rad since; the '
        'settling_time of python-control step_info, as pendulum_sim.testing measures it)')
    page = (Path(__file__).resolve().parents[2] / 'docs' / 'tutorials'
            / 'first-controller-test.md').read_text(encoding='utf-8')
    shown = re.search(r'^    \[pendulum_pd_controller\]: (settled at .*?)\n\n', page,
                      re.S | re.M)
    assert shown is not None
    assert ' '.join(shown[1].split()) == line


def test_count_exits_by_itself() -> None:
    with Controller(args=['--count', '3']) as ctl, Probe('pd_probe') as probe:
        loop = Loop(probe, ctl)
        for k in range(3):
            loop.answer(k, 0.1, 0.0)
        assert ctl.wait(timeout=20.0) == 0
        assert 'answered 3 states, skipped 0' in ctl.output()


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM])
def test_signal_while_answering_exits_zero_without_traceback(sig: int) -> None:
    with Controller() as ctl, Probe('pd_probe') as probe:
        loop = Loop(probe, ctl)
        for k in range(20):
            loop.answer(k * 10_000_000, 0.1, 0.0)
        assert ctl.proc is not None
        ctl.proc.send_signal(sig)
        k = 20
        deadline = time.monotonic() + 10.0
        while ctl.alive():  # keep it busy until it stops
            assert time.monotonic() < deadline, f'ignored signal {sig}:\n{ctl.output()}'
            loop.send(k * 10_000_000, 0.1, 0.0)
            probe.spin_for(0.001)
            k += 1
        assert ctl.wait() == 0
        out = ctl.output()
    assert 'Traceback' not in out
    assert 'FATAL' not in out
    assert 'answered ' in out


def test_bad_start_up_value_exits_2_with_the_reason() -> None:
    ns = unique_namespace()
    result = subprocess.run(
        [*controller_command(), '--ros-args', '-r', f'__ns:={ns}', '-p', 'max_effort:=0.0'],
        capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert f'{NAME}: max_effort must be > 0, got 0.0' in result.stderr
    assert 'Traceback' not in result.stderr


def test_settles_against_the_real_time_joint() -> None:
    """Real-time scene default (200 Hz, starts at 0.3 rad): the loop reaches the target."""
    ns = unique_namespace()
    with NodeProcess('default', {'status_line': False}, namespace=ns) as node, \
            Controller(params={'target': 0.5, 'use_sim_time': True}, namespace=ns) as ctl, \
            Probe('pd_probe') as probe:
        states = probe.subscribe(JointState, f'{ns}/joint_states', RELIABLE)
        probe.spin_until(lambda: 'settled at' in ctl.output(), 30.0, 'the loop to settle')
        n = len(states)
        probe.spin_until(lambda: len(states) >= n + 20, 10.0, 'more states')
        last = states.msgs[-1]
        assert abs(last.position[0] - 0.5) < 0.01
        assert abs(last.velocity[0]) < 0.01
        # The joint applies the controller's torque, computed from a state in the band:
        # |τ − m g l sin 0.5| < m g l·0.01 + kp·0.01 + kd·0.01 (|sin a − sin b| <= |a − b|).
        bound = (1.96 + 4.0 + 1.0) * 0.01
        assert abs(last.effort[0] - 1.96 * math.sin(0.5)) < bound
        assert ctl.stop() == 0
        assert node.stop() == 0
