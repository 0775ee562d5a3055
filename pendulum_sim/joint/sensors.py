"""What a real joint sensor adds to the true state: seeded noise and encoder steps.

The node publishes measured values on ``joint_states``; the ``energy`` topic always reports the
true state.
"""
from __future__ import annotations

import random


class SensorModel:
    """Turn the true (φ, φ') into a measurement: Gaussian noise, then encoder quantisation.

    Parameters
    ----------
    seed : int
        Seed of the noise generator: the same seed gives the same noise sequence.
    position_noise, velocity_noise : float
        Standard deviations of the additive Gaussian noise, rad and rad/s (0 = none).
    resolution : float
        Encoder resolution in rad per count (0 = no quantisation): the measured angle is the
        nearest multiple of it.
    """

    def __init__(self, seed: int, position_noise: float = 0.0, velocity_noise: float = 0.0,
                 resolution: float = 0.0) -> None:
        self._rng = random.Random(seed)
        self.position_noise = position_noise
        self.velocity_noise = velocity_noise
        self.resolution = resolution

    @property
    def ideal(self) -> bool:
        """Return True when measurements equal the true state."""
        return self.position_noise == 0.0 and self.velocity_noise == 0.0 and (
            self.resolution == 0.0)

    def measure(self, phi: float, dphi: float) -> tuple[float, float]:
        """Return the measured angle and velocity for the true ones."""
        if self.position_noise > 0.0:
            phi += self._rng.gauss(0.0, self.position_noise)
        if self.velocity_noise > 0.0:
            dphi += self._rng.gauss(0.0, self.velocity_noise)
        if self.resolution > 0.0:
            counts = phi / self.resolution
            # Counts beyond 2**52 are whole numbers already: a resolution finer than the spacing
            # of doubles at this angle leaves it unchanged (and round() of an inf would raise).
            if abs(counts) < 2.0**52:
                phi = self.resolution * round(counts)
        return phi, dphi
