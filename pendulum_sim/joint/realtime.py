"""Real-time stepping on an absolute schedule, and its self-measurement in the manner of rttest.

The node's timer wakes at the publish rate. At each wake the number of steps due is computed from
the wall clock, not from the previous wake: ``floor((now − start) · rtf / h)``. A late wake takes
more steps, an early one fewer, so timer jitter never accumulates as drift and the simulated time
stays within one step of the scaled wall time.

What is measured, per wake (rttest's vocabulary, github.com/ros2/realtime_support ``rttest``):

- wake latency: actual wake time minus the timer's scheduled time;
- steps per wake;
- overruns: wakes whose work ended after the next scheduled wake (the period was exceeded),
  and missed wakes: scheduled wakes the timer skipped because the previous one was late;
- achieved real-time factor: simulated time over wall time.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# Wake latencies are kept in a histogram of 1 µs bins up to this bound (larger ones in the
# last bin, their maximum kept exactly), so percentiles of runs of any length cost fixed memory.
HISTOGRAM_US = 100_000


class Schedule:
    """Count the steps due at a wall time: ``base_steps + floor((now − base) · rtf / h)``.

    Parameters
    ----------
    h : float
        The step in s.
    rtf : float
        The real-time factor (simulated seconds per wall second, > 0).
    now_ns : int
        The wall time (steady clock, ns) of simulated step ``steps``.
    steps : int
        The step count at ``now_ns``.
    """

    def __init__(self, h: float, rtf: float, now_ns: int, steps: int = 0) -> None:
        self._h_ns = h * 1e9
        self.rtf = rtf
        self._base_ns = now_ns
        self._base_steps = steps

    def rebase(self, now_ns: int, steps: int, rtf: float | None = None) -> None:
        """Restart the schedule at ``steps`` now (after a reset, a pause or a new factor)."""
        self._base_ns = now_ns
        self._base_steps = steps
        if rtf is not None:
            self.rtf = rtf

    def due(self, now_ns: int) -> int:
        """Return the step count the simulation should have reached at ``now_ns``."""
        # The tiny offset keeps an exact multiple of h from being floored one step short by
        # round-off in the product.
        ratio = (now_ns - self._base_ns) * self.rtf / self._h_ns
        return self._base_steps + math.floor(ratio + 1e-9)

    def lag(self, now_ns: int, steps: int) -> float:
        """Return how many steps ``steps`` is behind the schedule at ``now_ns`` (> 0: late)."""
        return (now_ns - self._base_ns) * self.rtf / self._h_ns - (steps - self._base_steps)


@dataclass(frozen=True)
class LatencySummary:
    """Percentiles of wake latency in µs, and the wake counts behind them."""

    count: int
    p50_us: float
    p99_us: float
    max_us: float
    mean_us: float


def _summary_from_histogram(hist: np.ndarray, max_ns: int, total_ns: int) -> LatencySummary:
    count = int(hist.sum())
    if count == 0:
        return LatencySummary(0, math.nan, math.nan, math.nan, math.nan)
    cum = np.cumsum(hist)

    def pct(q: float) -> float:
        # The upper edge of the bin holding the q-quantile: conservative by at most 1 µs.
        idx = int(np.searchsorted(cum, math.ceil(q * count)))
        return min(float(idx + 1), max_ns / 1e3)

    return LatencySummary(count, pct(0.5), pct(0.99), max_ns / 1e3, total_ns / count / 1e3)


class WakeStats:
    """Record each wake of a periodic timer: latency, steps taken, overruns and missed wakes."""

    def __init__(self, period_ns: int) -> None:
        self.period_ns = period_ns
        self._hist = np.zeros(HISTOGRAM_US + 1, dtype=np.int64)
        self._max_ns = 0
        self._total_ns = 0
        self.wakes = 0
        self.steps = 0
        self.max_steps = 0
        self.overruns = 0
        self.missed = 0
        self._last_sched: int | None = None
        self._window: list[int] = []
        self._window_steps = 0
        self._window_wakes = 0

    def wake(self, sched_ns: int, now_ns: int) -> None:
        """Record a wake at ``now_ns`` scheduled for ``sched_ns``."""
        lat = max(0, now_ns - sched_ns)
        self._hist[min(lat // 1000, HISTOGRAM_US)] += 1
        self._max_ns = max(self._max_ns, lat)
        self._total_ns += lat
        self._window.append(lat)
        self.wakes += 1
        self._window_wakes += 1
        if self._last_sched is not None and self.period_ns > 0:
            skipped = round((sched_ns - self._last_sched) / self.period_ns) - 1
            if skipped > 0:
                self.missed += skipped
        self._last_sched = sched_ns

    def overdue(self, now_ns: int) -> int | None:
        """Return the scheduled time of the latest wake due by ``now_ns`` and not yet taken,
        or None (none is, or the timer has no period: it runs as fast as it can).

        The node serves it ahead of other callbacks queued before the timer's event.
        """
        period, last = self.period_ns, self._last_sched
        if period <= 0 or last is None or now_ns < last + period:
            return None
        return last + period * ((now_ns - last) // period)

    def taken(self, sched_ns: int) -> bool:
        """Return True if the wake scheduled at ``sched_ns`` was already taken (served early,
        so the timer's own event for it has nothing left to do)."""
        return self.period_ns > 0 and self._last_sched is not None and (
            sched_ns <= self._last_sched)

    def done(self, sched_ns: int, end_ns: int, steps: int) -> None:
        """Record the end of a wake's work and the steps it took; count an overrun if late."""
        self.steps += steps
        self._window_steps += steps
        self.max_steps = max(self.max_steps, steps)
        if self.period_ns > 0 and end_ns > sched_ns + self.period_ns:   # 0: no period to
            self.overruns += 1                                             # overrun (lockstep)

    def summary(self) -> LatencySummary:
        """Return the latency percentiles over the whole run."""
        return _summary_from_histogram(self._hist, self._max_ns, self._total_ns)

    def window(self) -> tuple[LatencySummary, float]:
        """Return the latency percentiles and mean steps per wake since the last call; restart."""
        lat = np.asarray(self._window, dtype=np.float64) / 1e3
        wakes, steps = self._window_wakes, self._window_steps
        self._window = []
        self._window_wakes = 0
        self._window_steps = 0
        if lat.size == 0:
            return LatencySummary(0, math.nan, math.nan, math.nan, math.nan), math.nan
        p50, p99 = np.percentile(lat, [50.0, 99.0])
        return (LatencySummary(int(lat.size), float(p50), float(p99), float(lat.max()),
                               float(lat.mean())), steps / wakes)


class RateMeter:
    """Measure the achieved real-time factor: simulated time over running wall time."""

    def __init__(self, now_ns: int) -> None:
        self._running_ns = 0
        self._since: int | None = now_ns
        self._sim = 0.0
        self._win_wall = now_ns
        self._win_running = 0
        self._win_sim = 0.0

    def pause(self, now_ns: int) -> None:
        """Stop counting wall time (the simulation is paused)."""
        if self._since is not None:
            self._running_ns += now_ns - self._since
            self._since = None

    def resume(self, now_ns: int) -> None:
        """Count wall time again."""
        if self._since is None:
            self._since = now_ns

    def advance(self, sim_seconds: float) -> None:
        """Add simulated time."""
        self._sim += sim_seconds

    def running_ns(self, now_ns: int) -> int:
        """Return the wall time spent running (not paused), in ns."""
        return self._running_ns + (0 if self._since is None else now_ns - self._since)

    def total(self, now_ns: int) -> float:
        """Return simulated seconds per running wall second over the whole run."""
        wall = self.running_ns(now_ns) / 1e9
        return self._sim / wall if wall > 0.0 else math.nan

    @property
    def sim_seconds(self) -> float:
        """Return the simulated time over the whole run (across resets), in s."""
        return self._sim

    def window(self, now_ns: int) -> float:
        """Return the factor since the last call and restart the window."""
        running = self.running_ns(now_ns)
        wall = (running - self._win_running) / 1e9
        sim = self._sim - self._win_sim
        self._win_running, self._win_sim = running, self._sim
        return sim / wall if wall > 0.0 else math.nan
