"""The effort a record was driven by, as a signal held between its stamps (a zero-order hold).

A joint's torque is recorded in one of two ways, and each is read by its own convention:

- **beside the angle** (``JointState.effort``, a CSV column, the ``effort=`` array of ``fit``):
  the value at stamp t_k is the torque applied over the sample period that ENDS at t_k,
  (t_{k-1}, t_k]. That is what ``pendulum_node`` publishes (the torque of the step that led to
  the state it stamps) and what ``closed_loop(..., record=...)`` writes; the first value
  covers the period before the first stamp (one median period long).
- **as a command stream** on its own topic (``effort_command`` ``std_msgs/Float64``,
  ``joint_commands`` ``sensor_msgs/JointState``): the value stamped c_j holds from c_j to the
  next command, as the node holds a command until the next one.

Either way the torque is a piecewise-constant function u(t); the fit takes its exact average
over each step of the simulation grid, delayed by the dead time d (u(t − d)), which is the
torque impulse the step receives: a delay that is not a whole number of steps is then a smooth
parameter of the fit.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from .errors import IdentifyError

FloatArray = npt.NDArray[np.float64]

GAP = 5.0
"""An effort whose stamps leave a hole of more than this many median spacings has a gap: the
torque over it is not known."""


@dataclass(frozen=True)
class Effort:
    """A torque held between knots: ``values[i]`` over [``knots[i]``, ``knots[i + 1]``).

    Before the first knot the first value holds, after the last the last one (a hold). Times
    are in s on the record's clock; ``source`` says where the values were read.
    """

    knots: FloatArray
    values: FloatArray
    source: str

    def integral(self, t: npt.ArrayLike) -> FloatArray:
        """Return ∫ u dt from the first knot to ``t`` (N m s; negative before the first knot)."""
        x = np.asarray(t, dtype=np.float64)
        k, v = self.knots, self.values
        cum = np.concatenate(([0.0], np.cumsum(v[:-1] * np.diff(k))))
        out = np.interp(x, k, cum)
        before, after = x < k[0], x > k[-1]
        out = np.where(before, (x - k[0]) * v[0], out)
        out = np.where(after, cum[-1] + (x - k[-1]) * v[-1], out)
        return np.asarray(out, dtype=np.float64)

    def average(self, a: npt.ArrayLike, b: npt.ArrayLike) -> FloatArray:
        """Return the mean torque over each interval [a, b) (b > a), N m."""
        lo, hi = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
        return np.asarray((self.integral(hi) - self.integral(lo)) / (hi - lo), dtype=np.float64)

    def shifted(self, dt: float) -> Effort:
        """Return the same signal on a clock whose zero is at ``dt`` on this one."""
        return Effort(self.knots - dt, self.values, self.source)

    @property
    def peak(self) -> float:
        """Return the largest |torque|, N m."""
        return float(np.max(np.abs(self.values)))


def _finite(name: str, stamps: FloatArray, values: FloatArray) -> None:
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raise IdentifyError(f'{name} is missing (NaN or infinite) in {bad.size} of '
                            f'{values.size} samples, the first at t = {stamps[bad[0]]:.6g} s; '
                            f'the torque there is not known: pass a record with the effort in '
                            f'every sample, or cut the record to where it is')


def _gaps(name: str, knots: FloatArray, spacing: float) -> None:
    steps = np.diff(knots)
    bad = np.flatnonzero(steps > GAP * spacing)
    if bad.size:
        i = int(bad[0])
        raise IdentifyError(f'{name} has a gap of {steps[i]:.6g} s after t = {knots[i]:.6g} s '
                            f'(more than {GAP:g} times its median spacing, {spacing:.6g} s): '
                            f'the torque there is not known; cut the record at the gap')


def from_samples(t: FloatArray, effort: FloatArray, name: str = 'effort') -> Effort:
    """Return the effort recorded beside the angle: ``effort[k]`` over (t[k−1], t[k]]."""
    _finite(name, t, effort)
    steps = np.diff(t)
    spacing = float(np.median(steps))
    _gaps(name, t, spacing)
    knots = np.concatenate(([t[0] - spacing], t[:-1]))
    return Effort(knots=knots, values=np.asarray(effort, dtype=np.float64),
                  source=f'{name} (the torque over the period ending at each stamp)')


def from_commands(stamps: npt.ArrayLike, values: npt.ArrayLike, t: FloatArray,
                  name: str = 'command') -> Effort:
    """Return a command stream held from each stamp to the next, checked to cover ``t``.

    The commands must start at or before the first angle sample (the torque before the first
    command is not known) and go on to within one median spacing of the last.
    """
    c = np.asarray(stamps, dtype=np.float64)
    v = np.asarray(values, dtype=np.float64)
    if c.size == 0:
        raise IdentifyError(f'{name} has no messages; pass a record with the commands in it')
    order = np.argsort(c, kind='stable')
    c, v = c[order], v[order]
    _finite(name, c, v)
    keep = np.r_[np.diff(c) > 0.0, True]   # of commands with one stamp, the last one holds
    c, v = c[keep], v[keep]
    spacing = float(np.median(np.diff(c))) if c.size > 1 else math.inf
    if c[0] > t[0] or (c[-1] < t[-1] - spacing if c.size > 1 else c[0] < t[-1]):
        raise IdentifyError(f'{name} stamps cover {c[0]:.6g} to {c[-1]:.6g} s but the angle '
                            f'runs from {t[0]:.6g} to {t[-1]:.6g} s: the torque is not known '
                            f'over all of it; cut the record to the commands, or pass the '
                            f'topic that drove the joint')
    if c.size > 1:   # from the command in effect at the first sample to the last sample
        first = int(np.searchsorted(c, t[0], side='right')) - 1
        last = int(np.searchsorted(c, t[-1], side='right'))
        _gaps(name, np.append(c[first:last], t[-1]), spacing)
    return Effort(knots=c, values=v, source=f'{name} (each command held to the next)')


__all__ = ['GAP', 'Effort', 'from_commands', 'from_samples']
