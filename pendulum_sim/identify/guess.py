"""A physically reasoned first guess: period and damping envelope from the turning points.

The turning points are the extrema of the swing about its centre in each whole half swing
(between two zero crossings): the partial half swing before the first crossing is dropped, so
a record that starts anywhere in the swing (released from rest, or passing the centre at full
speed) reads the same period and envelope.

The envelope of a lightly damped swing decays as the law says (energy averaged over one
small-amplitude cycle): exponentially for n = 1 (A ∝ e^(−γt/2)), linearly for Coulomb
friction (A falls by 2γ/ω0² each half period), and for n > 1 algebraically,
``A^(1−n) = A0^(1−n) + (n−1) γ c_n ω0^(n−1) t`` with ``c_n = Γ((n+2)/2) / (√π Γ((n+3)/2))``
(4/(3π) for n = 2, 1/t-like). Each law's γ is read from the slope of the envelope so
transformed; the law whose transformed envelope is straightest is the best first guess of n.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.special import ellipk  # type: ignore[import-untyped]

FloatArray = npt.NDArray[np.float64]

ENVELOPE_EXPONENTS = (0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0)
"""Exponents whose envelope shapes are tried for the first guess of n."""


@dataclass(frozen=True)
class Guess:
    """What the record says before any fit.

    ``crossings`` counts the zero crossings (around the guessed zero offset, beyond the noise);
    ``peaks_t`` and ``peaks_a`` are the swing's turning points (time, amplitude about the
    offset), one per whole half swing. ``omega0`` is None when the record has fewer than three
    crossings (two turning points: no half period to time); ``oscillates`` is
    False when the angle never turns back after crossing (an overdamped creep, or none).
    """

    offset: float
    crossings: int
    omega0: float | None
    peaks_t: FloatArray
    peaks_a: FloatArray
    phi0: float
    dphi0: float
    noise: float
    oscillates: bool


def c_n(n: float) -> float:
    """Return the cycle average c_n of |cos|^(n+1) (Γ((n+2)/2) / (√π Γ((n+3)/2)))."""
    return math.exp(math.lgamma((n + 2.0) / 2.0) - math.lgamma((n + 3.0) / 2.0)) / math.sqrt(
        math.pi)


def noise_level(y: FloatArray) -> float:
    """Return the white-noise standard deviation the second differences of ``y`` show."""
    if y.size < 5:
        return 0.0
    d2 = np.diff(y, 2)
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))


def _crossings(t: FloatArray, z: FloatArray, band: float) -> FloatArray:
    """Return the times where ``z`` passes from one side of ``±band`` to the other.

    A noisy signal that dithers about zero inside the band crosses once, not at every sign
    change: the crossing is interpolated linearly between the last sample beyond the band on
    one side and the first beyond it on the other (adjacent samples where the swing is fast).
    """
    side = np.where(z > band, 1, np.where(z < -band, -1, 0))
    out = np.flatnonzero(side)
    change = np.flatnonzero(side[out[:-1]] != side[out[1:]])
    a, b = out[change], out[change + 1]
    return np.asarray(t[a] - z[a] * (t[b] - t[a]) / (z[b] - z[a]), dtype=np.float64)


def turning_points(t: FloatArray, z: FloatArray, cross: FloatArray
                   ) -> tuple[FloatArray, FloatArray]:
    """Return the turning points of the swing: the extremum of ``z`` in each whole half swing.

    A half swing runs from one crossing to the next; the partial ones before the first crossing
    and after the last are dropped, so the points are turning points wherever the record starts
    (a release from rest, or mid-swing through the centre at full speed) and ends.
    """
    pt, pz = [], []
    for a, b in itertools.pairwise(cross):
        inside = np.flatnonzero((t > a) & (t < b))
        if inside.size == 0:
            continue
        k = inside[np.argmax(np.abs(z[inside]))]
        pt.append(t[k])
        pz.append(z[k])
    return np.asarray(pt, dtype=np.float64), np.asarray(pz, dtype=np.float64)


def first_look(t: FloatArray, y: FloatArray) -> Guess:
    """Return the offset, crossings, period-based ω0, turning points and state of a record.

    The period and the decay envelope are read from the turning points (``turning_points``),
    whatever the phase of the swing at the first sample.
    """
    noise = noise_level(y)
    band = 3.0 * noise   # a crossing leaves the noise on both sides of the centre
    offset = 0.5 * float(np.max(y) + np.min(y))   # the first swing's midpoint, nearly
    cross = _crossings(t, y - offset, band)
    for _ in range(3):   # the midpoints of successive turning points: the swing's centre
        _, signed = turning_points(t, y - offset, cross)
        if signed.size < 2:
            break
        offset += float(np.mean(0.5 * (signed[:-1] + signed[1:])))
        cross = _crossings(t, y - offset, band)
    peaks_t, signed = turning_points(t, y - offset, cross)
    peaks_a = np.abs(signed)
    omega0 = None
    if peaks_t.size >= 2:   # three crossings: two whole half swings
        period = 2.0 * float(peaks_t[-1] - peaks_t[0]) / (peaks_t.size - 1)
        amp = float(np.median(peaks_a))
        # The nonlinear pendulum's period is 4 K(m)/ω0 with m = sin²(A/2).
        omega0 = 2.0 * math.pi / period * 2.0 * float(ellipk(math.sin(min(amp, 3.0) / 2) ** 2)
                                                      ) / math.pi
    k = min(7, t.size)
    if k >= 3:
        c = np.polyfit(t[:k] - t[0], y[:k], 2)
        phi0, dphi0 = float(c[2]) - offset, float(c[1])
    else:
        phi0, dphi0 = float(y[0]) - offset, 0.0
    oscillates = cross.size >= 2
    if cross.size == 1:   # it turns back if its furthest point past the crossing is not the end
        after = np.flatnonzero(t > cross[0])
        far = after[np.argmax(np.abs(y[after] - offset))]
        oscillates = bool(far < t.size - max(2, t.size // 20))
    return Guess(offset=offset, crossings=int(cross.size), omega0=omega0, peaks_t=peaks_t,
                 peaks_a=peaks_a, phi0=phi0, dphi0=dphi0, noise=noise,
                 oscillates=oscillates)


def envelope_gamma(n: float, omega0: float, peaks_t: FloatArray, peaks_a: FloatArray
                   ) -> tuple[float, float]:
    """Return γ read from the envelope's slope under exponent ``n``, and the envelope's misfit.

    The misfit is the RMS of the amplitudes minus the law's envelope (rad), to rank the shapes.
    """
    if peaks_a.size < 2 or not np.all(peaks_a > 0):
        return 0.0, math.inf
    t, a = peaks_t - peaks_t[0], peaks_a
    if n == 0.0:
        s, b = np.polyfit(t, a, 1)
        gamma = -s * math.pi * omega0 / 2.0
        model = b + s * t
    elif n == 1.0:
        s, b = np.polyfit(t, np.log(a), 1)
        gamma = -2.0 * s
        model = np.exp(b + s * t)
    else:
        s, b = np.polyfit(t, a ** (1.0 - n), 1)
        gamma = s / ((n - 1.0) * c_n(n) * omega0 ** (n - 1.0))
        with np.errstate(invalid='ignore', divide='ignore'):
            model = np.abs(b + s * t) ** (1.0 / (1.0 - n))
    misfit = float(np.sqrt(np.mean((model - a) ** 2)))
    return max(float(gamma), 0.0), misfit if math.isfinite(misfit) else math.inf


def best_exponent(omega0: float, peaks_t: FloatArray, peaks_a: FloatArray) -> float:
    """Return the exponent whose envelope shape fits the extrema best."""
    misfits = [envelope_gamma(n, omega0, peaks_t, peaks_a)[1] for n in ENVELOPE_EXPONENTS]
    return ENVELOPE_EXPONENTS[int(np.argmin(misfits))]
