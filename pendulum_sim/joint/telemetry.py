"""What the node reports about itself, without ROS: the diagnostics values, the status line's
text and the shutdown summary.

:class:`Telemetry` reads the joint, the driver, the gate and the counters of dropped commands;
the node only publishes what it returns (``diagnostics.status_array``) and prints the summary.
"""
from __future__ import annotations

import math
from collections.abc import Mapping

from pendulum_sim.core import PendulumError

from .commands import Drops
from .drivers import Driver, SyncDriver
from .errors import JointError
from .exchange import Gate
from .foxglove import LiveView
from .joint import SimulatedJoint
from .realtime import WakeStats
from .status import status_text

REPORT_PERIOD_NS = 1_000_000_000
"""The period of the diagnostics report (and of the window figures), steady clock."""


class Telemetry:
    """Collect the node's figures: wake statistics, the local error estimate, the counters.

    Parameters
    ----------
    joint, driver, gate, drops
        What is reported on.
    wakes : WakeStats
        The timer's wake statistics.
    incompatible : mapping
        Incompatible-QoS events per command topic.
    rtf_target : float
        The ``real_time_factor`` parameter (the node updates it).
    start_ns : int
        Steady-clock time at start: the first report is due one period later.
    """

    def __init__(self, joint: SimulatedJoint, driver: Driver, gate: Gate, drops: Drops,
                 wakes: WakeStats, incompatible: Mapping[str, int],
                 rtf_target: float = 0.0, start_ns: int = 0) -> None:
        self.joint = joint
        self.driver = driver
        self.gate = gate
        self.drops = drops
        self.wakes = wakes
        self.incompatible = incompatible
        self.rtf_target = rtf_target
        self._last_error = math.nan
        self._max_error = 0.0
        self.live: LiveView | None = None   # the node sets its live view, if it has one
        self._next_report_ns = start_ns + REPORT_PERIOD_NS

    def report_due(self, now_ns: int) -> bool:
        """Return True when a report is due at ``now_ns`` (steady clock): once every
        :data:`REPORT_PERIOD_NS`, the missed ones skipped, not made up."""
        if now_ns < self._next_report_ns:
            return False
        self._next_report_ns += REPORT_PERIOD_NS * max(
            1, (now_ns - self._next_report_ns) // REPORT_PERIOD_NS + 1)
        return True

    def start_text(self, values: Mapping[str, object]) -> str:
        """Return the line logged at start: mode, step, integrator, period, commands, joint."""
        v = values
        mode = ('synchronous lockstep' if v['synchronous'] else 'lockstep' if v['lockstep']
                else 'real time')
        return (f'{mode}: h = {v["h"]:g} s, {v["integrator"]}, control period '
                f'{self.joint.config.period_steps} steps ({v["publish_rate"]:g} Hz), '
                f'real_time_factor = {v["real_time_factor"]:g}, {v["command_interface"]} '
                f'commands, joint {v["joint_name"]!r}'
                + (', paused (~/step or ~/pause false to go on)' if self.gate.paused else ''))

    def estimate_error(self) -> float:
        """Return the core's local error estimate of the next step (nan if it cannot say)."""
        joint = self.joint
        if joint.failed is not None:
            return self._last_error
        try:
            err = joint.stepper.local_error_estimate(joint.torque)
        except (PendulumError, OverflowError, ZeroDivisionError):
            err = math.nan
        self._last_error = err
        if math.isfinite(err):
            self._max_error = max(self._max_error, err)
        return err

    def energy_or_nan(self) -> float:
        """Return the energy of the true state, nan if it has none."""
        try:
            return self.joint.energy()
        except JointError:
            return math.nan

    def status(self, now_ns: int) -> str:
        """Return the live status line."""
        st = self.joint.stepper
        return status_text(st.t, st.phi, self.energy_or_nan(), self.driver.rate.total(now_ns),
                           self.gate.paused)

    def level(self) -> tuple[str, str]:
        """Return the diagnostics level name ('OK' or 'ERROR') and message."""
        failed = self.joint.failed
        if failed is not None:
            return 'ERROR', f'stopped: {failed}'
        return 'OK', 'paused' if self.gate.paused else 'running'

    def values(self, now_ns: int) -> dict[str, object]:
        """Return the diagnostics key/values; restart the window figures."""
        err = self.estimate_error()
        wakes = self.wakes
        rate = self.driver.rate
        lat, spw = wakes.window()
        total = wakes.summary()
        joint = self.joint
        c = joint.counters
        try:
            terms = joint.terms()
            energy, residual = terms.energy, terms.residual
        except JointError:
            energy = residual = math.nan
        values: dict[str, object] = {
            'sim_time': joint.time,
            'steps': joint.steps,
            'epoch_ns': joint.config.epoch_ns,
            'paused': self.gate.paused,
            'real_time_factor_target': self.rtf_target,
            'real_time_factor_achieved': rate.window(now_ns),
            'real_time_factor_total': rate.total(now_ns),
            'wake_latency_p50_us': lat.p50_us,
            'wake_latency_p99_us': lat.p99_us,
            'wake_latency_max_us': lat.max_us,
            'wake_latency_p99_us_total': total.p99_us,
            'wake_latency_max_us_total': total.max_us,
            'steps_per_wake': spw,
            'steps_per_wake_max': wakes.max_steps,
            'wakes': wakes.wakes,
            'overruns': wakes.overruns,
            'missed_wakes': wakes.missed,
            'schedule_slips': self.driver.slips,
            'parameter_sets': self.driver.parameter_sets,
            'reconfigures': self.driver.reconfigures,
            **{f'guard_{k}': val for k, val in joint.guard_stats().items()},
            'energy': energy,
            'energy_residual': residual,
            'local_error_estimate': err,
            'local_error_max': self._max_error,
            'commands_received': c.received,
            'commands_rejected_nonfinite': c.rejected_nonfinite,
            'commands_saturated': c.saturated,
            'commands_limited': c.limited,
            'command_timeouts': c.timeouts,
            'commands_dropped': self.drops.total,
            **{f'commands_dropped[{k}]': n for k, n in self.drops.counts.items()},
            'torque': joint.torque,
            'phase_time_since_reset': joint.stepper.t,
        }
        if isinstance(self.driver, SyncDriver):
            values.update({f'sync_{k}': n for k, n in self.driver.exchange.stats.items()})
        if self.live is not None:
            values.update(self.live.stats())
        for topic, n in self.incompatible.items():
            values[f'incompatible_qos[{topic}]'] = n
        return values

    def window(self, now_ns: int) -> None:
        """Restart the window figures without reporting (no diagnostics publisher)."""
        self.wakes.window()
        self.driver.rate.window(now_ns)

    def summary(self, now_ns: int) -> dict[str, object]:
        """Return the figures printed at shutdown."""
        lat = self.wakes.summary()
        joint = self.joint
        rate = self.driver.rate
        err = self.estimate_error()
        guard = joint.guard_stats()
        c = joint.counters
        out: dict[str, object] = {
            'steps': joint.steps,
            'simulated time (s)': joint.time,
            'wall time running (s)': rate.running_ns(now_ns) / 1e9,
            'achieved real-time factor': rate.total(now_ns),
            'wakes': self.wakes.wakes,
            'wake latency p50/p99/max (us)': f'{lat.p50_us:.0f} / {lat.p99_us:.0f} / '
                                             f'{lat.max_us:.0f}',
            'overruns / missed wakes / slips': f'{self.wakes.overruns} / '
                                               f'{self.wakes.missed} / {self.driver.slips}',
            'guard substeps / fallbacks / reversals': f'{guard.get("substeps", 0)} / '
                                                      f'{guard.get("fallbacks", 0)} / '
                                                      f'{guard.get("reversals", 0)}',
            'guard sticks / energy rejections': f'{guard.get("sticks", 0)} / '
                                                f'{guard.get("energy_rejections", 0)}',
            'energy-balance residual (J)': joint.stepper.residual,
            'local error estimate (last / max)': f'{err:.3g} / {self._max_error:.3g}',
            'commands received / rejected / dropped': f'{c.received} / '
                                                      f'{c.rejected_nonfinite} / '
                                                      f'{self.drops.total}',
        }
        if isinstance(self.driver, SyncDriver):
            s = self.driver.exchange.stats
            out['sync answered / timeouts / late / duplicates'] = (
                f'{s["answered"]} / {s["timeouts"]} / {s["late"]} / {s["duplicates"]}')
            out['sync ahead / republished'] = f'{s["ahead"]} / {s["republished"]}'
        out['stopped by'] = joint.failed or '-'
        return out
