"""The registry of integration methods: name → what it is and how it steps."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from .errors import IntegratorError
from .guard import GuardStats
from .tableaus import (
    DOP853,
    DOPRI5,
    EULER,
    EXTRAP6,
    EXTRAP8,
    MIDPOINT,
    RK4,
    RODAS4,
    SDIRK2,
    SDIRK3,
    Extrapolation,
    Tableau,
)


class Advance(Protocol):
    """The one protocol every kind of method implements (``Engine.fresh_advance``).

    Cover a step of h from (φ, φ') under the input acceleration ``ain`` = τ/I, count what was
    done beyond a plain step in ``stats`` and return (φ₁, φ'₁, w), w the damping work per unit
    inertia. Explicit methods: ``Engine.careful`` (generated steps of ``explicit.py``); diagonally
    implicit: ``Engine.implicit_advance`` (``dirk.py``); embedded adaptive (explicit or
    Rosenbrock pair): ``embedded.Cover``.
    """

    def __call__(self, p: float, v: float, h: float, ain: float,
                 stats: GuardStats) -> tuple[float, float, float]:
        """Advance one step of h."""


@dataclass(frozen=True)
class Family:
    """A family of methods: how its steps are taken, read by the drivers instead of its name.

    ``fast_path``: plain explicit steps of h, guarded, with the fast path and the careful path
    (``engine.py``); ``error_controlled``: embedded pairs that choose their own substeps within
    each step of h (``embedded.py``), h being the output spacing; neither: the implicit DIRK
    family (``implicit.py``), one step of h each.
    """

    name: str
    fast_path: bool
    error_controlled: bool


EXPLICIT = Family('explicit', fast_path=True, error_controlled=False)
IMPLICIT = Family('implicit', fast_path=False, error_controlled=False)
ADAPTIVE = Family('adaptive', fast_path=False, error_controlled=True)


@dataclass(frozen=True)
class Method:
    """An integration method of the core: a name, its family and its data.

    ``family`` is :data:`EXPLICIT` (fixed step, guarded), :data:`ADAPTIVE` (embedded pair with
    error control: explicit ``dopri5`` for offline accuracy, ``dop853`` for tight tolerances,
    linearly implicit ``rodas4`` for long stiff runs and ``extrap6``/``extrap8`` for tight
    tolerances on them) or :data:`IMPLICIT` (L-stable DIRK, for stiff damping). ``tableau`` is
    the method's data: a Butcher tableau, or the step sequence of an extrapolation method.
    """

    name: str
    family: Family
    tableau: Tableau | Extrapolation

    @property
    def kind(self) -> str:
        """Return the family's name: ``'explicit'``, ``'adaptive'`` or ``'implicit'``."""
        return self.family.name

    @property
    def order(self) -> int:
        """Return the declared order (measured by the test suite)."""
        return self.tableau.order

    @property
    def fixed_step(self) -> bool:
        """Return True unless the method chooses its own substeps (h is then output spacing)."""
        return not self.family.error_controlled

    @property
    def description(self) -> str:
        """Return a one-line description."""
        return self.tableau.description


METHODS: dict[str, Method] = {
    'euler': Method('euler', EXPLICIT, EULER),
    'midpoint': Method('midpoint', EXPLICIT, MIDPOINT),
    'rk4': Method('rk4', EXPLICIT, RK4),
    'dopri5': Method('dopri5', ADAPTIVE, DOPRI5),
    'dop853': Method('dop853', ADAPTIVE, DOP853),
    'sdirk2': Method('sdirk2', IMPLICIT, SDIRK2),
    'sdirk3': Method('sdirk3', IMPLICIT, SDIRK3),
    'rodas4': Method('rodas4', ADAPTIVE, RODAS4),
    'extrap6': Method('extrap6', ADAPTIVE, EXTRAP6),
    'extrap8': Method('extrap8', ADAPTIVE, EXTRAP8),
}

def get_method(name: str) -> Method:
    """Return the method called ``name`` or raise IntegratorError listing the known ones."""
    try:
        return METHODS[name]
    except (KeyError, TypeError):
        known = ', '.join(sorted(METHODS))
        raise IntegratorError(f'unknown method {name!r}; known methods: {known}') from None
