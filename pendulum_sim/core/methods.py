"""The registry of integration methods: name → what it is and how it steps."""
from __future__ import annotations

from dataclasses import dataclass

from .errors import IntegratorError
from .tableaus import DOPRI5, EULER, MIDPOINT, RK4, SDIRK2, SDIRK3, Tableau


@dataclass(frozen=True)
class Method:
    """An integration method of the core.

    ``kind`` is ``'explicit'`` (fixed step, guarded), ``'adaptive'`` (embedded pair with error
    control, for offline accuracy) or ``'implicit'`` (L-stable DIRK, for stiff damping).
    """

    name: str
    kind: str
    tableau: Tableau

    @property
    def order(self) -> int:
        """Return the declared order (measured by the test suite)."""
        return self.tableau.order

    @property
    def description(self) -> str:
        """Return a one-line description."""
        return self.tableau.description


METHODS: dict[str, Method] = {
    'euler': Method('euler', 'explicit', EULER),
    'midpoint': Method('midpoint', 'explicit', MIDPOINT),
    'rk4': Method('rk4', 'explicit', RK4),
    'dopri5': Method('dopri5', 'adaptive', DOPRI5),
    'sdirk2': Method('sdirk2', 'implicit', SDIRK2),
    'sdirk3': Method('sdirk3', 'implicit', SDIRK3),
}

FALLBACK_METHOD = METHODS['sdirk3']


def get_method(name: str) -> Method:
    """Return the method called ``name`` or raise IntegratorError listing the known ones."""
    try:
        return METHODS[name]
    except (KeyError, TypeError):
        known = ', '.join(sorted(METHODS))
        raise IntegratorError(f'unknown method {name!r}; known methods: {known}') from None
