"""The model: validated parameters with exact messages, energy, eigenvalues; no ROS in the core."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pendulum_sim.core import ModelError, PendulumParams, energy
from pendulum_sim.core.model import dissipated_power


@pytest.mark.parametrize(('field', 'value', 'message'), [
    ('m', 0.0, 'm must be > 0 kg, got 0.0'),
    ('m', -1.0, 'm must be > 0 kg, got -1.0'),
    ('l', 0.0, 'l must be > 0 m, got 0.0'),
    ('inertia', -0.2, 'inertia must be > 0 kg m^2, got -0.2'),
    ('g', -9.8, 'g must be >= 0 m/s^2, got -9.8'),
    ('gamma', -1.0, 'gamma must be >= 0 s^(n-2), got -1.0'),
    ('n', -0.5, 'n must be >= 0, got -0.5'),
    ('gamma', math.nan, 'gamma must be finite, got nan'),
    ('n', math.inf, 'n must be finite, got inf'),
    ('m', 'heavy', "m must be a real number, got 'heavy'"),
])
def test_bad_parameters_raise_exact_messages(field: str, value: object, message: str) -> None:
    with pytest.raises(ModelError) as info:
        PendulumParams(**{field: value})  # type: ignore[arg-type]
    assert str(info.value) == message
    assert isinstance(info.value, ValueError)


def test_paper_parameters_give_omega0_sq_9_8() -> None:
    p = PendulumParams()
    assert (p.m, p.l, p.inertia, p.g) == (0.2, 1.0, 0.2, 9.8)
    assert p.omega0_sq == pytest.approx(9.8, rel=1e-15)


def test_with_changes_validates() -> None:
    p = PendulumParams()
    assert p.with_changes(n=2.5).n == 2.5
    with pytest.raises(ModelError, match=r'^gamma must be >= 0 s\^\(n-2\), got -3.0$'):
        p.with_changes(gamma=-3.0)


def test_energy_is_eq_23_and_exact_near_the_bottom() -> None:
    p = PendulumParams()
    phi, dphi = 2.0, 1.5
    expected = 0.5 * 0.2 * 1.5**2 + 0.2 * 9.8 * 1.0 * (1 - math.cos(2.0))
    assert energy(p, phi, dphi) == pytest.approx(expected, rel=1e-14)
    # The half-angle form keeps relative precision where 1 − cos φ cancels.
    tiny = 1e-9
    assert energy(p, tiny, 0.0) == pytest.approx(0.5 * p.mgl * tiny**2, rel=1e-12)


@pytest.mark.parametrize('n', [0.0, 0.5, 1.0, 2.0, 3.0, 4.5])
def test_damping_and_dissipated_power_match_eq_15_and_26(n: float) -> None:
    p = PendulumParams(gamma=0.7, n=n)
    for v in (-2.0, -0.3, 0.4, 3.0):
        assert p.damping(v) == pytest.approx(0.7 * v * abs(v) ** (n - 1), rel=1e-14)
        assert dissipated_power(p, v) == pytest.approx(p.inertia * v * p.damping(v), rel=1e-14)
    assert p.damping(0.0) == 0.0


def test_jacobian_eigenvalues_match_numpy() -> None:
    p = PendulumParams(gamma=3.0, n=2.0)
    for phi, v in ((0.3, 1.2), (2.5, -0.4), (1.0, 5.0)):
        d = 3.0 * 2.0 * abs(v)
        jac = np.array([[0.0, 1.0], [-p.omega0_sq * math.cos(phi), -d]])
        ours = sorted(p.jacobian_eigenvalues(phi, v), key=lambda z: (z.real, z.imag))
        ref = sorted(np.linalg.eigvals(jac), key=lambda z: (z.real, z.imag))
        np.testing.assert_allclose(ours, ref, rtol=1e-12, atol=1e-12)
