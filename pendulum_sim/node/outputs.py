"""What the node sends out for each state: ``/clock``, ``joint_states``, energy, the recording.

The hot path: each message is packed as CDR bytes from a template (``serialized.py``) and
published as bytes; the same bytes go to the recording, stamped with simulated time. A broken
recorder is reported once and never stops the joint.
"""
from __future__ import annotations

import sys
from collections.abc import Callable, Mapping
from typing import Any

from pendulum_sim.joint.foxglove import LiveView, snapshot
from pendulum_sim.joint.joint import SimulatedJoint

from .errors import JointError
from .serialized import ClockBytes, Float64Bytes, JointStateBytes


class Recording:
    """The node's recorder, if any: writes that never raise, an error reported once."""

    def __init__(self, recorder: Any, log: Callable[[str, str], None]) -> None:
        self.recorder = recorder
        self._log = log   # (level, text), the node's log
        self._error_logged = False

    def open(self, path: str, overwrite: bool, metadata: dict[str, dict[str, str]],
             channels: list[tuple[str, Any, Any]]) -> None:
        """Open an MCAP recording at ``path`` with these channels and /parameter_events."""
        try:
            from pendulum_sim.recording import McapRecorder
        except ImportError as exc:
            self._log('error', f'recording is not available ({exc}); not recording')
            return
        from rcl_interfaces.msg import ParameterEvent

        rec = McapRecorder(path, overwrite=overwrite, metadata=metadata)
        rec.open()
        for topic, msg_type, qos in channels:
            rec.add_channel(topic, msg_type, qos)
        rec.add_channel('/parameter_events', ParameterEvent, 10)
        self.recorder = rec
        self._log('info', f'recording to {rec.path}')

    def write(self, topic: str, msg: Any, stamp_ns: int) -> None:
        """Write a message (or its CDR bytes) at ``stamp_ns``; never raise."""
        rec = self.recorder
        if rec is None:
            return
        try:
            if isinstance(msg, bytes):
                rec.write_serialized(topic, msg, stamp_ns)
            else:
                rec.write(topic, msg, stamp_ns)
        except Exception as exc:  # a broken recorder must not stop the joint
            self.failed(exc)

    def reset(self, stamp_ns: int, message: str) -> None:
        """Record a reset (a new segment starts at ``stamp_ns``)."""
        rec = self.recorder
        if rec is None:
            return
        try:
            rec.write_reset(stamp_ns, message)
        except Exception as exc:  # a broken recorder must not stop the joint
            self.failed(exc)

    def failed(self, exc: BaseException) -> None:
        """Report a recorder error once."""
        if not self._error_logged:
            self._error_logged = True
            self._log('error', f'recording failed, simulation continues: {exc}')

    def close(self) -> None:
        """Close the recording (report, never raise: the shutdown goes on)."""
        rec, self.recorder = self.recorder, None
        if rec is None:
            return
        try:
            rec.close()
        except Exception as exc:  # report, keep shutting down
            print(f'pendulum_node: closing the recording failed: {exc}', file=sys.stderr)
        if rec.error is not None:
            print(f'pendulum_node: recording error: {rec.error}', file=sys.stderr)

    def check(self) -> None:
        """Report an error the recorder met on its own (its writer process)."""
        rec = self.recorder
        if rec is not None and rec.error is not None:
            self.failed(rec.error)


class StateOutputs:
    """Publish the joint's state: /clock (lockstep), joint_states, energy and its terms.

    Parameters
    ----------
    joint : SimulatedJoint
        Whose state is sent.
    joint_name : str
        The name in joint_states.
    states, clock, energy : publisher or None
        rclpy publishers (``publish`` takes bytes); None for what the scene switches off.
    terms : list of publishers
        energy_terms/{kinetic, potential, dissipated_power, residual}, or empty.
    recording : Recording
        Where every publication (but /clock and the terms) is also written.
    live : LiveView, optional
        The Foxglove server, handed a snapshot of each state sent while a client watches;
        ``live_counters`` returns the counters it shows.
    """

    def __init__(self, joint: SimulatedJoint, joint_name: str, states: Any, clock: Any,
                 energy: Any, terms: list[Any], recording: Recording,
                 live: LiveView | None = None) -> None:
        self.joint = joint
        self.live = live
        self.live_counters: Callable[[], Mapping[str, int]] = lambda: vars(joint.counters)
        self._states = states
        self._clock = clock
        self._energy = energy
        self._terms = terms
        self._recording = recording
        self._js_bytes = JointStateBytes(joint_name)
        self._clock_bytes = ClockBytes()
        self._float_bytes = Float64Bytes()
        self.last_states: bytes | None = None
        self._to_states = self._to_clock = self._to_energy = True
        self._to_terms = bool(terms)
        self._states_topic = str(states.topic_name)
        self._energy_topic = str(energy.topic_name) if energy is not None else ''

    def refresh(self) -> None:
        """Look up, once per wake, which topics have subscribers: a message nobody would
        receive is not published (it is still recorded). A subscriber that matches gets
        messages from the next wake on."""
        self._to_states = self._states.get_subscription_count() > 0
        self._to_clock = self._clock is not None and self._clock.get_subscription_count() > 0
        self._to_energy = (self._energy is not None
                           and self._energy.get_subscription_count() > 0)
        self._to_terms = any(pub.get_subscription_count() > 0 for pub in self._terms)

    def remind(self, stamp_ns: int, with_state: bool) -> None:
        """Publish /clock at ``stamp_ns`` again, and the last joint_states if ``with_state``
        (nothing is recorded again): for best-effort subscribers matched only just now."""
        if with_state and self.last_states is not None:
            self._states.publish(self.last_states)
        if self._clock is not None:
            self._clock.publish(self._clock_bytes.pack(*divmod(stamp_ns, 1_000_000_000)))

    def __call__(self, with_clock: bool) -> bool:
        """Publish the state now (and /clock when ``with_clock`` and lockstep); return whether a
        state went out (none while a sensor delay fills, nor once the simulation stopped)."""
        joint = self.joint
        if joint.failed is not None:
            return False
        stamp_ns = joint.stamp_ns()
        sample = joint.sample()   # always: the sensor noise sequence must not depend on readers
        record = self._recording.recorder is not None
        if sample is not None and (self._to_states or record):
            sec, nanosec = divmod(sample.stamp_ns, 1_000_000_000)
            data = self._js_bytes.pack(sec, nanosec, sample.position, sample.velocity,
                                       sample.effort)
            if self._to_states:
                self._states.publish(data)
            self.last_states = data
            if record:
                self._recording.write(self._states_topic, data, stamp_ns)
        live = self.live
        if live is not None and live.watching and sample is not None:
            live.offer(snapshot(joint, sample, self.live_counters()))
        # /clock after the state: a controller manager woken by /clock (ros2_control_node on
        # use_sim_time) finds the state of that time already sent when it reads.
        if with_clock and self._to_clock:
            self._clock.publish(self._clock_bytes.pack(*divmod(stamp_ns, 1_000_000_000)))
        if self._energy is None and not self._terms:
            return sample is not None
        try:
            energy = joint.energy()
            terms = joint.terms() if self._to_terms else None
        except JointError as exc:
            joint.fail(str(exc))
            return sample is not None
        pack = self._float_bytes.pack
        if self._energy is not None and (self._to_energy or record):
            e = pack(energy)
            if self._to_energy:
                self._energy.publish(e)
            if record:
                self._recording.write(self._energy_topic, e, stamp_ns)
        if terms is not None:
            values = (terms.kinetic, terms.potential, terms.dissipated_power, terms.residual)
            for pub, value in zip(self._terms, values, strict=True):
                pub.publish(pack(value))
        return sample is not None
