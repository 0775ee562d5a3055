"""The expected real-time factor: a short trial of the joint's own stepping, and its log line.

The trial's clock is injected: the tests count what it reads, never how long anything took.
"""
from __future__ import annotations

import math

import pytest
from joint_fixtures import PARAMS, H

from pendulum_sim.joint.cost import (
    TRIAL_CHUNK,
    TRIAL_STEPS,
    CostEstimate,
    cost_line,
    estimate_real_time_factor,
)
from pendulum_sim.joint.joint import JointConfig


class Ticks:
    """A clock that moves ``tick`` ns at every reading, and counts its readings."""

    def __init__(self, tick: int) -> None:
        self.tick, self.reads = tick, 0

    def __call__(self) -> int:
        self.reads += 1
        return self.reads * self.tick


CONFIG = JointConfig(params=PARAMS, h=H, phi0=0.3)


def test_the_estimate_is_the_trials_simulated_time_over_its_clock_time() -> None:
    clock = Ticks(40_000)
    est = estimate_real_time_factor(CONFIG, clock=clock, budget_ns=10**15)
    chunks = TRIAL_STEPS // TRIAL_CHUNK
    assert clock.reads == 1 + chunks   # the start, then once after each chunk
    assert est == CostEstimate(TRIAL_STEPS, chunks * 40_000, H)
    assert est.step_us == chunks * 40.0 / TRIAL_STEPS
    assert est.real_time_factor == TRIAL_STEPS * H * 1e9 / (chunks * 40_000)


def test_the_trial_stops_once_it_has_cost_its_budget() -> None:
    est = estimate_real_time_factor(CONFIG, clock=Ticks(1_000_000), budget_ns=2_000_000)
    assert est == CostEstimate(2 * TRIAL_CHUNK, 2_000_000, H)


def test_the_trial_measures_the_joints_steps_with_the_threads_cpu_clock() -> None:
    est = estimate_real_time_factor(CONFIG, steps=60, budget_ns=10**15)
    assert est.steps == 60 and est.h == H
    assert est.cpu_ns >= 0 and est.real_time_factor > 0.0


def test_an_estimate_without_steps_or_time_says_so() -> None:
    assert math.isnan(CostEstimate(0, 0, H).real_time_factor)
    assert math.isnan(CostEstimate(0, 0, H).step_us)
    assert CostEstimate(10, 0, H).real_time_factor == math.inf
    assert cost_line(CostEstimate(0, 0, H), 1.0, True) == (
        'info', 'expected real-time factor unknown: the trial took no step (the joint failed '
        'at once)')


def test_the_line_warns_where_the_stepping_cannot_keep_the_configured_pace() -> None:
    slow = CostEstimate(200, 250_000_000, 1e-3)  # 1250 us a step of 1 ms: 0.8 of real time
    assert slow.real_time_factor == pytest.approx(0.8, rel=1e-15)
    assert cost_line(slow, 1.0, True) == (
        'warning', 'expected real-time factor 0.8 is below real_time_factor = 1: a step of '
        'h = 0.001 s costs 1250.0 us of CPU time (measured over 200 steps from the initial '
        'state), more than the 1000 us of wall time a step has at that pace; the joint will '
        'fall behind its schedule')
    # Not paced by the wall clock (synchronous, or lockstep as fast as it goes): said, no more.
    assert cost_line(slow, 1.0, False) == (
        'info', 'expected real-time factor 0.8: a step of h = 0.001 s costs 1250.0 us of CPU '
        'time (measured over 200 steps from the initial state)')
    # A pace it keeps: no warning, down to the factor itself.
    assert cost_line(slow, 0.8, True)[0] == 'info'
    assert cost_line(slow, 0.81, True)[0] == 'warning'
