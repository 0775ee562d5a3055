"""The per-pendulum problem: what one pendulum's (ω0², γ, n) fixes, computed once.

A :class:`Problem` is frozen and knows nothing of methods or drivers: the Stepper (through its
engine), the sweep (one per distinct pendulum it hands to the careful path) and every method
family (explicit, implicit, embedded) read the same object, so a decision that depends only on
the pendulum (is the law smooth, is it Coulomb friction, how wide is the graded window around
a reversal) is taken in one place.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from .decisions import accuracy_speed
from .law import DampingFn, compile_damping
from .model import coulomb_level, smooth_law
from .reversal import grade_window, graded_law


@dataclass(frozen=True)
class Problem:
    """One pendulum: φ'' = a_in − γ φ'|φ'|^(n−1) − c_f sgn φ' − ω0² sin φ (eq 16 over I).

    Parameters
    ----------
    w2, gamma, n : float
        ω0² in s⁻², γ in s^(n−2) and n >= 0 (eq 11, 15).
    friction : float
        The Coulomb friction beside the power law per unit inertia, c_f = f/I in rad/s² (>= 0).

    Attributes
    ----------
    omega0 : float
        ω0 in s⁻¹.
    damped : bool
        γ > 0: energy can only fall without input (the energy check applies).
    level : float
        The Coulomb level (``model.coulomb_level``): c_f, plus γ where n = 0.
    coulomb : bool
        Dry friction (level > 0): the pendulum sticks where the forces allow.
    nonsmooth : bool
        The damping has a kink at φ' = 0 (γ > 0 and not n = 1, 3, 5, ..., or c_f > 0): steps
        are split at velocity reversals.
    reach : float
        The window S (s) around a reversal inside which steps are graded (0: no grading).
    v_acc : float
        The speed above which a damping-dominated n > 1 transient is taken by error-controlled
        substeps (``decisions.accuracy_speed``; inf for n <= 1 or γ = 0).
    damping : callable
        The damping acceleration D(φ') = γ φ'|φ'|^(n−1), compiled for this n and γ.
    """

    w2: float
    gamma: float
    n: float
    friction: float = 0.0
    omega0: float = field(init=False)
    damped: bool = field(init=False)
    level: float = field(init=False)
    coulomb: bool = field(init=False)
    nonsmooth: bool = field(init=False)
    reach: float = field(init=False)
    v_acc: float = field(init=False)
    damping: DampingFn = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        omega0 = math.sqrt(self.w2)
        set_(self, 'omega0', omega0)
        set_(self, 'damped', self.gamma > 0.0 or self.friction > 0.0)
        level = coulomb_level(self.gamma, self.n, self.friction)
        set_(self, 'level', level)
        set_(self, 'coulomb', level > 0.0)
        kink = self.gamma > 0.0 and not smooth_law(self.n)
        set_(self, 'nonsmooth', kink or self.friction > 0.0)
        set_(self, 'reach', grade_window(omega0) if kink and graded_law(self.n) else 0.0)
        set_(self, 'v_acc', accuracy_speed(self.gamma, self.n, omega0))
        law = compile_damping(self.n)
        g = self.gamma
        set_(self, 'damping', lambda v: law(v, g, 1.0))

    def speed_gain(self, h: float, ain: float) -> float:
        """Return the most |φ'| can grow in h (:func:`speed_gain`)."""
        return speed_gain(h, ain, self.w2)


def speed_gain(h: float, ain: float, w2: float) -> float:
    """Return the most |φ'| can grow in h: h (|τ/I| + ω0²), damping only opposes motion."""
    return h * (abs(ain) + w2)


__all__ = ['Problem', 'speed_gain']
