"""A physically reasoned first guess: period from zero crossings, damping from the envelope.

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

    ``crossings`` counts the zero crossings (around the guessed zero offset); ``peaks_t`` and
    ``peaks_a`` are the swing's extrema (time, amplitude about the offset). ``omega0`` is None
    when the record has fewer than three crossings (no whole period to time); ``oscillates`` is
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


def _crossings(t: FloatArray, z: FloatArray) -> FloatArray:
    """Return the times where ``z`` changes sign (linear interpolation between samples)."""
    s = np.sign(z)
    i = np.flatnonzero((s[:-1] * s[1:]) < 0)
    return t[i] - z[i] * (t[i + 1] - t[i]) / (z[i + 1] - z[i])


def _extrema(t: FloatArray, z: FloatArray, cross: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Return the extremum of |z| in each half swing (from the start to each crossing)."""
    edges = np.concatenate(([t[0] - 1.0], cross))
    pt, pa = [], []
    for a, b in itertools.pairwise(edges):
        inside = np.flatnonzero((t > a) & (t < b))
        if inside.size == 0:
            continue
        k = inside[np.argmax(np.abs(z[inside]))]
        pt.append(t[k])
        pa.append(abs(z[k]))
    return np.asarray(pt, dtype=np.float64), np.asarray(pa, dtype=np.float64)


def first_look(t: FloatArray, y: FloatArray) -> Guess:
    """Return the offset, crossings, period-based ω0, extrema and initial state of a record."""
    offset = 0.5 * float(np.max(y) + np.min(y))   # the first swing's midpoint, nearly
    cross = _crossings(t, y - offset)
    for _ in range(3):   # the midpoints of successive extrema: the swing's centre
        _, signed = _signed_extrema(t, y - offset, cross)
        if signed.size < 2:
            break
        offset += float(np.mean(0.5 * (signed[:-1] + signed[1:])))
        cross = _crossings(t, y - offset)
    peaks_t, peaks_a = _extrema(t, y - offset, cross)
    omega0 = None
    if cross.size >= 3:
        period = 2.0 * float(np.mean(np.diff(cross)))
        amp = float(np.median(peaks_a)) if peaks_a.size else 0.0
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
                 peaks_a=peaks_a, phi0=phi0, dphi0=dphi0, noise=noise_level(y),
                 oscillates=oscillates)


def _signed_extrema(t: FloatArray, z: FloatArray, cross: FloatArray
                    ) -> tuple[FloatArray, FloatArray]:
    edges = np.concatenate(([t[0] - 1.0], cross, [t[-1] + 1.0]))
    pt, pz = [], []
    for a, b in itertools.pairwise(edges[1:-1]):   # whole half swings only
        inside = np.flatnonzero((t > a) & (t < b))
        if inside.size == 0:
            continue
        k = inside[np.argmax(np.abs(z[inside]))]
        pt.append(t[k])
        pz.append(z[k])
    return np.asarray(pt, dtype=np.float64), np.asarray(pz, dtype=np.float64)


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
