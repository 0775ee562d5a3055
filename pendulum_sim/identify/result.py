"""What every fit returns: the :class:`Fit` of a law to one record or several."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
Value = float | None

N_UNDETERMINED = 1.0
"""n is reported as not determined when its 95 % interval is wider than ± this (it then
cannot tell viscous from quadratic damping)."""


@dataclass(frozen=True)
class Fit:
    """A fitted law: the estimates, their uncertainty and how well the law fits.

    Attributes
    ----------
    params : dict
        ``omega0`` (rad/s), ``gamma`` (s^(n−2); for ``coulomb`` the friction deceleration in
        rad/s²), ``n``, ``friction`` (Coulomb torque in N m: γ I for ``coulomb``, f for
        ``power+coulomb``, where the inertia is known; 0 for laws without friction),
        ``friction_accel`` (its deceleration f/I in rad/s², which a free swing determines
        without the inertia), ``phi_offset`` (rad, the sensor's zero:
        measured = φ + phi_offset), ``phi0``, ``dphi0`` (the state at the first sample), and
        ``inertia`` (kg m²) where ``known`` gives it. A value that the record does not determine
        is None, and ``reasons`` says why.
    stderr, ci95 : dict
        Standard error and 95 % interval (low, high) of each parameter; 0 and (v, v) for one
        the model or ``known`` fixes, None where the value is None.
    rms_residual : float
        RMS of measured minus fitted angle, rad.
    aic, bic : float
        Akaike and Bayesian information criteria (lower is better; inf when nothing was fitted).
    model : str
        The law: ``viscous``, ``quadratic``, ``coulomb``, ``power`` or ``power+coulomb``.
    samples : int
        Samples fitted.
    fixed : tuple of str
        Parameters the model or ``known`` fixed.
    reasons : dict
        Why each None parameter is not determined.
    correlation : dict
        Correlation coefficients between pairs of fitted parameters, keyed ``'a/b'``.
    t, position, fitted : ndarray
        The record's times (s), its angle (rad, unwrapped) and the fitted angle there (the
        records one after another where several were fitted together: ``segments``).
    iterations, starts : int
        Iterations of the best start, and how many starts were run.
    at_optimum : int
        How many starts ended at the law's optimum, the best of them (within
        ``starts.REACHED`` on the BIC scale); 0 where nothing was fitted.
    window : float or None
        The windows' length in s of a fit over windows re-anchored on the measurement (a
        driven fit's method, ``windows.py``); None for one simulation of each whole record.
    segments : tuple of int
        Where each record's samples begin in ``t``, ``position`` and ``fitted``.
    driven : bool
        Whether the fit used the record's effort; it then also gives ``inertia`` (kg m²),
        ``mgl`` (N m), ``friction`` (N m), ``effort_offset`` (N m, the torque τ_off added to
        the effort) and ``command_delay`` (s, the dead time d of the effort), each determined
        where the record moves the joint enough (``driven.py``).
    """

    params: dict[str, Value]
    stderr: dict[str, Value]
    ci95: dict[str, tuple[float, float] | None]
    rms_residual: float
    aic: float
    bic: float
    model: str
    samples: int
    fixed: tuple[str, ...]
    reasons: dict[str, str]
    correlation: dict[str, float]
    t: FloatArray
    position: FloatArray
    fitted: FloatArray
    iterations: int
    starts: int
    at_optimum: int = 0
    window: float | None = None
    segments: tuple[int, ...] = (0,)
    driven: bool = False

    @property
    def residual(self) -> FloatArray:
        """Return measured minus fitted angle at each sample, rad."""
        return self.position - self.fitted


def exponent_undetermined(half_width: float, advice: str, params: dict[str, Value],
                          stderr: dict[str, Value],
                          ci95: dict[str, tuple[float, float] | None],
                          reasons: dict[str, str]) -> bool:
    """Report n and γ as not determined where n's 95 % interval is ±``half_width`` wide.

    Where ``half_width`` exceeds :data:`N_UNDETERMINED`, n and γ (whose unit s^(n−2) moves
    with n) become None with the reason, which ends with ``advice`` (what would determine it);
    return whether they did.
    """
    if not half_width > N_UNDETERMINED:
        return False
    why = f'n is not determined: its 95 % interval is ±{half_width:.2g} wide{advice}'
    reasons['n'] = why
    reasons['gamma'] = 'gamma is in s^(n-2) and ' + why
    for k in ('n', 'gamma'):
        params[k], stderr[k], ci95[k] = None, None, None
    return True


__all__ = ['N_UNDETERMINED', 'Fit', 'Value', 'exponent_undetermined']
