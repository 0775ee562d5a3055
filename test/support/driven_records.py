"""The measured records of a driven pendulum under ``test/data/``, read as a user reads them.

``test/data/dfki_torque_limited_pendulum/SOURCE.md`` says where they come from (the DFKI RIC
Underactuated Lab's torque-limited simple pendulum, BSD 3-Clause), their licence, columns and
units. Each run is read by ``pendulum_identify``'s own CSV reader, its columns mapped by their
header names (:data:`COLUMNS`), and the lab's identified parameters are read from the file the
lab published and written in this package's terms (:func:`published`).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

from pendulum_sim.identify.inputs import Samples, read_record

DFKI = Path(__file__).resolve().parents[1] / 'data' / 'dfki_torque_limited_pendulum'
COLUMNS = 'time=t,position=position,velocity=velocity,torque=effort'
"""``--columns`` for the lab's files: their header is ``time,position,velocity,torque``."""
RUNS = {
    'pd system identification': 'pd_system_identification.csv',
    'ddp': 'ddp.csv',
    'direct collocation': 'direct_collocation.csv',
    'energy shaping + lqr': 'energy_shaping_lqr.csv',
    'ilqr': 'ilqr.csv',
}
"""Each run's name in the docs and its file."""
G = 9.81
"""The gravity the lab's identification used (``simple_pendulum.model.parameters.earth``)."""
TERMS = 'tau = J * qdotdot + m*cx * g*sin(q) + Fv * qdot + Fc * atan(100*qdot) + offset * 1'
"""The lab's model, as its file writes it."""


def read(name: str) -> Samples:
    """Return run ``name``: time (s), position (rad), velocity (rad/s), torque (N m)."""
    return read_record(DFKI / RUNS[name], columns=COLUMNS)


@dataclass(frozen=True)
class Published:
    """The lab's identified parameters as its file gives them (SI units)."""

    J: float          # kg m²
    m_cx: float       # kg m
    Fv: float         # N m s
    Fc: float         # N m, the coefficient of atan(100 q')
    offset: float     # N m, on the side of the measured torque

    def in_package_terms(self) -> dict[str, float]:
        """Return the same joint in this package's model (see SOURCE.md).

        ``I φ'' = −m g l sin φ − γ I φ'|φ'|^(n−1) − f sgn φ' + τ + τ_off``: inertia = J,
        m g l = m·cx g, viscous (n = 1) γ = Fv / J, f = Fc π/2 (atan(100 φ') is ±π/2 away
        from rest) and τ_off = −offset.
        """
        mgl = self.m_cx * G
        return {'inertia': self.J, 'mgl': mgl, 'omega0': math.sqrt(mgl / self.J),
                'gamma': self.Fv / self.J, 'n': 1.0, 'friction': self.Fc * math.pi / 2.0,
                'effort_offset': -self.offset}


def published() -> Published:
    """Return the parameters of the lab's ``system_identification.txt``."""
    text = (DFKI / 'system_identification.txt').read_text(encoding='utf-8')
    lines = text.splitlines()
    if lines[0].strip() != 'System Identification:  Simple Pendulum' or lines[-1] != TERMS:
        raise ValueError(f'{DFKI / "system_identification.txt"} is not the file the lab '
                         'published')
    values = dict(re.findall(r'^(\S+)\s*= ([+-][\d.]+e[+-]\d+)$', text, re.M))
    return Published(J=float(values['J']), m_cx=float(values['m*cx']), Fv=float(values['Fv']),
                     Fc=float(values['Fc']), offset=float(values['offset']))
