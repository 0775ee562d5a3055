"""The damping laws a record can be fitted with, and what each one fixes.

Each model is the core's law (Quiroga and Ospina-Henao 2017, eq 15-16)::

    φ'' = −ω0² sin φ − γ φ'|φ'|^(n−1) − (f/I) sgn φ' + τ/I

with the exponent fixed (``viscous`` n = 1, ``quadratic`` n = 2, ``coulomb`` n = 0: dry friction
of constant deceleration γ, i.e. a friction torque γ I) or free (``power``), and
``power+coulomb``: the power law with n free beside the core's Coulomb ``friction`` f, its
deceleration f/I fitted (``friction_accel``).
"""
from __future__ import annotations

from dataclasses import dataclass

from .errors import IdentifyError


@dataclass(frozen=True)
class Law:
    """A model of ``fit``: its name and the exponent it fixes (None: n is fitted)."""

    name: str
    n: float | None
    description: str
    friction: bool = False   # a Coulomb friction beside the law is fitted


LAWS: dict[str, Law] = {
    'viscous': Law('viscous', 1.0, 'viscous damping, n = 1'),
    'quadratic': Law('quadratic', 2.0, 'quadratic drag, n = 2'),
    'coulomb': Law('coulomb', 0.0, 'Coulomb friction only, n = 0'),
    'power': Law('power', None, 'power-law damping, n free (real >= 0)'),
    'power+coulomb': Law('power+coulomb', None, 'power-law damping, n free, beside Coulomb '
                         'friction', friction=True),
}
"""The models ``fit`` takes, by name."""

MODELS = tuple(LAWS)
"""Every model name the issue defines."""

COMPARED = MODELS
"""The models ``compare`` fits unless told otherwise: all five, ranked by BIC (its penalty,
p ln m, weighs ``power+coulomb``'s extra parameters against the ``power`` and ``coulomb`` laws
it nests)."""


def get_law(model: object) -> Law:
    """Return the law of ``model`` or say which models exist."""
    if not isinstance(model, str) or model not in LAWS:
        raise IdentifyError(f'model must be one of {", ".join(LAWS)}, got {model!r}')
    return LAWS[model]
