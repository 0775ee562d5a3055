"""The configured law's cost: the real-time factor the joint's stepping can reach, measured.

What one step of h costs depends on the law far more than on anything else the joint does: the
stability guard's substeps, reversals split in the step, Coulomb rest, stiff transients (the
worst law at h = 1 ms costs some fifty times the median, ``bench/bench_worst_law.py``). A joint
whose law costs more than h of CPU time a step cannot keep real time however it is paced, and
would fall behind its schedule silently. :func:`estimate_real_time_factor` therefore runs a
short trial of the joint's own stepping (a second :class:`~pendulum_sim.joint.joint.SimulatedJoint`
of the same configuration, from its initial state, with no command: the node's joint is not
touched) and measures the CPU time of its steps; :func:`cost_line` says what that means for
the configured pace, which ``pendulum_node`` logs at start (a warning where the joint cannot
keep it). The trial measures the stepping alone, not the node's publishing and callbacks
(``bench/bench_node.py``), and the stretch of motion from the initial state only: a law whose
cost rises later (a kick into a stiff transient) is not seen.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import NamedTuple

from .joint import JointConfig, SimulatedJoint

TRIAL_STEPS = 500
"""Steps of the trial (0.5 s of simulated time at h = 1 ms)."""
TRIAL_BUDGET_NS = 50_000_000
"""CPU time after which the trial stops early (ns): a slow law is known slow by then."""
TRIAL_CHUNK = 25
"""Steps taken between two readings of the clock."""


class CostEstimate(NamedTuple):
    """What a trial measured: ``steps`` steps of ``h`` s took ``cpu_ns`` ns of CPU time."""

    steps: int
    cpu_ns: int
    h: float

    @property
    def step_us(self) -> float:
        """Return the CPU time of one step in µs (NaN where no step was timed)."""
        return self.cpu_ns / self.steps * 1e-3 if self.steps else math.nan

    @property
    def real_time_factor(self) -> float:
        """Return the simulated seconds the stepping takes per CPU second, h / (cost of a step).

        inf where the steps took no measurable time, NaN where no step was timed.
        """
        if not self.steps:
            return math.nan
        if self.cpu_ns <= 0:
            return math.inf
        return self.steps * self.h * 1e9 / self.cpu_ns


def estimate_real_time_factor(config: JointConfig, *, steps: int = TRIAL_STEPS,
                              budget_ns: int = TRIAL_BUDGET_NS,
                              clock: Callable[[], int] = time.thread_time_ns) -> CostEstimate:
    """Measure the joint's stepping of ``config`` over a short trial; return its cost.

    A joint of the same configuration takes one step (what is made once per law, such as the
    generated steps, is made there and not timed), then up to ``steps`` steps in chunks of
    :data:`TRIAL_CHUNK`, timed by ``clock`` (the CPU time of the calling thread, ns), and
    stops once they have cost ``budget_ns`` or the joint failed. Raises JointError where the
    configuration makes no joint (as ``SimulatedJoint`` does).
    """
    joint = SimulatedJoint(config)
    joint.advance(1)
    taken, spent = 0, 0
    start = clock()
    while taken < steps:
        done = joint.advance(min(TRIAL_CHUNK, steps - taken))
        spent = clock() - start
        taken += done
        if done == 0 or spent >= budget_ns:
            break
    return CostEstimate(taken, spent, config.h)


def cost_line(estimate: CostEstimate, real_time_factor: float,
              paced: bool) -> tuple[str, str]:
    """Return (level, text): the estimate as ``pendulum_node`` logs it at start.

    ``paced``: the joint follows a wall-clock schedule at ``real_time_factor`` (real time, or
    lockstep with a factor > 0; not the synchronous exchange, which the controller paces).
    The level is ``'warning'`` where the stepping alone cannot keep that pace (its expected
    real-time factor below the configured one), ``'info'`` otherwise.
    """
    rtf = estimate.real_time_factor
    measured = (f'a step of h = {estimate.h:g} s costs {estimate.step_us:.1f} us of CPU time '
                f'(measured over {estimate.steps} steps from the initial state)')
    if not estimate.steps:
        return 'info', ('expected real-time factor unknown: the trial took no step '
                        '(the joint failed at once)')
    if paced and not rtf >= real_time_factor:
        return 'warning', (f'expected real-time factor {rtf:.3g} is below real_time_factor = '
                           f'{real_time_factor:g}: {measured}, more than the '
                           f'{estimate.h / real_time_factor * 1e6:.4g} us of wall time a step '
                           f'has at that pace; the joint will fall behind its schedule')
    return 'info', f'expected real-time factor {rtf:.3g}: {measured}'


__all__ = ['TRIAL_BUDGET_NS', 'TRIAL_CHUNK', 'TRIAL_STEPS', 'CostEstimate', 'cost_line',
           'estimate_real_time_factor']
