"""The live view of an in-process closed loop: ``closed_loop(..., foxglove_port=)``.

The run in this process hands each state it sends to a
:class:`~pendulum_sim.joint.foxglove.LiveView`, as ``pendulum_node`` does. While a client
watches, the run is paced to the scene's ``real_time_factor`` of wall time (so the swing can be
seen); with nobody watching it runs as fast as it computes.
"""
from __future__ import annotations

import time
from collections.abc import Mapping

from pendulum_sim.joint.errors import LiveError
from pendulum_sim.joint.foxglove import LiveView, snapshot
from pendulum_sim.joint.joint import Sample, SimulatedJoint
from pendulum_sim.joint.urdf import urdf_from_values

from .errors import TestingError
from .scene import Value


class LiveLoop:
    """Serve the states of an in-process run; a context manager (None port: nothing)."""

    def __init__(self, values: Mapping[str, Value], target: float | None) -> None:

        try:
            self.view = LiveView.of(values, urdf_from_values(values), target)
        except LiveError as exc:
            raise TestingError(str(exc)) from None
        rtf = float(values['real_time_factor'])
        self._rtf = rtf if rtf > 0.0 else 1.0
        self._anchor: tuple[int, float] | None = None   # (wall ns, simulated s) when watched

    def offer(self, joint: SimulatedJoint, sample: Sample, counters: Mapping[str, int]) -> None:
        """Send ``sample`` (with the driver's ``counters``) if a client watches, after waiting
        for its time to come."""
        view = self.view
        if not view.watching:
            self._anchor = None
            return
        now = time.monotonic_ns()
        if self._anchor is None:
            self._anchor = (now, joint.time)
        wall0, sim0 = self._anchor
        due = wall0 + round((joint.time - sim0) / self._rtf * 1e9)
        if due > now:
            time.sleep((due - now) / 1e9)
        view.offer(snapshot(joint, sample, counters))

    def close(self) -> None:
        """Stop the server."""
        self.view.close()

    def __enter__(self) -> LiveLoop:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
