"""Many start states of one parameter set, checked together as check checks each alone."""
from __future__ import annotations

import math

import numpy as np

from pendulum_sim.core.errors import ModelError
from pendulum_sim.core.model import MAX_SPEED, states_accepted, validate_state
from pendulum_sim.joint.parameters import check, check_states, physics
from pendulum_sim.testing.scene import scene_values

EDGE = [0.0, MAX_SPEED, -MAX_SPEED, math.nextafter(MAX_SPEED, math.inf),
        -math.nextafter(MAX_SPEED, math.inf), math.inf, math.nan, 1e300]


def test_the_array_rule_is_validate_states_rule_at_its_edges() -> None:
    params = physics(scene_values('controller_test', {}))
    for phi in (0.0, 1e300, math.inf, -math.inf, math.nan):
        for dphi in EDGE:
            try:
                validate_state(phi, dphi, params)
                alone = True
            except ModelError:
                alone = False
            assert bool(states_accepted(phi, dphi, params)) is alone, (phi, dphi)
            assert bool(states_accepted(np.array([phi]), np.array([dphi]), params)[0]) is alone


def test_check_states_names_the_first_state_check_refuses_with_its_reason() -> None:
    values = scene_values('controller_test', {})
    phi0 = np.array([0.1, 2.0, -3.0, 0.5, math.nan, 0.0])
    dphi0 = np.array([0.0, MAX_SPEED, -1.0, math.nextafter(MAX_SPEED, math.inf), 0.0, 2e4])
    alone = [check({**values, 'phi0': float(p), 'dphi0': float(v)})
             for p, v in zip(phi0, dphi0, strict=True)]
    assert [r is None for r in alone] == [True, True, True, False, False, False]
    assert check_states(values, phi0, dphi0) == (3, alone[3])
    assert check_states(values, phi0[4:], dphi0[4:]) == (0, alone[4])
    assert check_states(values, phi0[:3], dphi0[:3]) is None
    # A set refused whatever its state: the first state carries the reason.
    bad = {**values, 'integrator': 'leapfrog'}
    found = check_states(bad, phi0[:3], dphi0[:3])
    assert found is not None and found == (0, check({**bad, 'phi0': 0.1, 'dphi0': 0.0}))
    assert found[1].startswith('integrator must be one of ')
