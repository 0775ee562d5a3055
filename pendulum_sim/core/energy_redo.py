"""The energy redo: an explicit step whose energy rose without input, redone and projected.

With τ = 0 and γ > 0 the energy never increases (eq 26); an explicit step that raised it by more
than round-off (``decisions.energy_rose``) is redone by the L-stable fallback, and where even
that rose it is projected (Hairer, Lubich and Wanner, Geometric Numerical Integration, IV.4):
φ₁ is kept and |φ'₁| rescaled onto the energy E₀ − W the step itself says was dissipated, the
energy balance the exact flow obeys.

Written to compile (numbers in, numbers out): the careful step (``careful.careful_settle``)
runs these functions as Python and compiled; it checks the fallback's work bound first
(``implicit.fallback_refused``).
"""
from __future__ import annotations

import math

from .decisions import energy_rose, specific_energy
from .dirk import StageLaw
from .implicit import fallback_run


def project(p: float, p1: float, v1: float, w: float, e0: float,
            w2: float) -> tuple[float, float, float]:
    """Return (φ₁, φ'₁, w) projected onto the energy E₀ − max(w, 0) (E/I units).

    Where even the angle φ₁ would hold more potential energy than E₀, the pendulum stays put
    at rest (φ, 0); ``w`` becomes E₀ − E₁, the work the projected step dissipated.
    """
    u1 = 2.0 * w2 * math.sin(0.5 * p1) ** 2
    target = max(e0 - max(w, 0.0), u1)
    v1 = math.copysign(math.sqrt(2.0 * (target - u1)), v1)
    if u1 > e0:
        p1 = p  # even the angle would climb above the energy available: stay put
        v1 = 0.0
    return p1, v1, e0 - specific_energy(v1, math.sin(0.5 * p1), w2)


def redo(p: float, v: float, h: float, e0: float, w2: float, gamma: float, n: float,
         omega0: float, law: StageLaw) -> tuple[float, float, float, bool]:
    """Redo a step of h from (φ, φ') without input by the fallback; project if it rose too.

    ``e0`` is E/I at the start, ``law`` the stage law (``dirk.stage_law``). Returns
    ``(φ₁, φ'₁, w, projected)``.
    """
    p1, v1, w = fallback_run(p, v, h, 0.0, w2, gamma, n, omega0, law)
    e1 = specific_energy(v1, math.sin(0.5 * p1), w2)
    if not energy_rose(e0, e1, w2):
        return p1, v1, w, False
    p1, v1, w = project(p, p1, v1, w, e0, w2)
    return p1, v1, w, True


__all__ = ['project', 'redo']
