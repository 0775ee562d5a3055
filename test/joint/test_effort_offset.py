"""The effort offset: a constant torque on the pendulum in every step, as a drive's bias.

The oracles: with gamma = 0 and g = 0 the joint is a free rotor, phi'' = T / I, and RK4 is exact
for a torque constant over each step, so the offset alone grows the angular momentum by T h a
step and moves the angle along the closed-form parabola. With gravity and damping the joint
comes to rest where the offset balances gravity, m g l sin(phi) = T; the offset's work is the
input work of the energy balance (eq 26 with the input T), and it is not in the effort the
joint publishes. A PD law with gravity compensation then settles off its target by T / kp.
"""
from __future__ import annotations

import math
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from pendulum_sim.controller.pd_law import PDGains
from pendulum_sim.core import PendulumParams
from pendulum_sim.joint.errors import JointError
from pendulum_sim.joint.joint import JointConfig, SimulatedJoint
from pendulum_sim.joint.parameters import SPEC_BY_NAME, SPECS, check, joint_config
from pendulum_sim.testing import TestingError, closed_loop
from pendulum_sim.testing.batch import batchable, run_batch
from pendulum_sim.testing.examples import pd, pd_batch
from pendulum_sim.testing.scene import scene_values

H = 1e-3
ROTOR = PendulumParams(m=0.2, l=1.0, inertia=0.2, g=0.0, gamma=0.0, n=1.0)
BODY = PendulumParams(m=0.2, l=1.0, inertia=0.2, g=9.8, gamma=5.0, n=1.0)
MGL = 0.2 * 9.8 * 1.0


def joint(offset: float = 0.0, params: PendulumParams = ROTOR, **changes: object
          ) -> SimulatedJoint:
    base: dict[str, object] = {'params': params, 'h': H, 'phi0': 0.3, 'dphi0': 0.1,
                               'effort_offset': offset}
    base.update(changes)
    return SimulatedJoint(JointConfig(**base))  # type: ignore[arg-type]


def momentum_after_each_step(j: SimulatedJoint, k: int) -> np.ndarray:
    out = np.empty(k)
    for i in range(k):
        j.advance(1)
        out[i] = j.config.params.inertia * j.stepper.dphi
    return out


def test_the_parameter_is_live_in_n_m_with_a_range_and_none_by_default() -> None:
    spec = SPEC_BY_NAME['effort_offset']
    assert (spec.default, spec.unit, spec.read_only, spec.low, spec.high) == (
        0.0, 'N m', False, -1e6, 1e6)
    assert 'Live' in spec.description
    values = {s.name: s.default for s in SPECS}
    assert joint_config(values).effort_offset == 0.0
    values['effort_offset'] = -0.25
    assert joint_config(values).effort_offset == -0.25


def test_the_offset_alone_accelerates_a_free_rotor_by_t_over_i() -> None:
    torque, steps = 0.3, 500
    pushed = joint(torque)
    p0 = ROTOR.inertia * 0.1
    momentum = momentum_after_each_step(pushed, steps)
    # Every step, commanded or not: the momentum grows by T h a step.
    np.testing.assert_allclose(momentum - p0, torque * H * np.arange(1, steps + 1), rtol=0,
                               atol=1e-13)
    t = steps * H
    closed = 0.3 + 0.1 * t + 0.5 * torque / ROTOR.inertia * t**2
    assert pushed.stepper.phi == pytest.approx(closed, rel=0, abs=1e-12)


def test_it_is_added_to_every_applied_torque_a_command_that_cancels_it_leaves_the_joint_still(
        ) -> None:
    still = joint(0.3, BODY, phi0=0.0, dphi0=0.0, max_effort=5.0, timeout_steps=0)
    assert still.command(-0.3)
    still.advance(2000)
    # tau + offset = -0.3 + 0.3 = 0 exactly: at the bottom at rest nothing moves.
    assert (still.stepper.phi, still.stepper.dphi) == (0.0, 0.0)
    assert still.torque == -0.3


def test_at_rest_it_balances_gravity_at_asin_offset_over_mgl_and_its_work_is_input() -> None:
    offset = 0.5
    j = joint(offset, BODY, phi0=0.0, dphi0=0.0)
    start_energy = j.energy()
    efforts = []
    for _ in range(200):   # 20 s: gamma = 5 s^-1 damps the swing by e^-50
        j.advance(100)
        sample = j.sample()
        assert sample is not None
        efforts.append(sample.effort)
    st = j.stepper
    assert st.phi == pytest.approx(math.asin(offset / MGL), rel=0, abs=1e-12)
    assert abs(st.dphi) < 1e-12
    assert efforts == [0.0] * 200 and j.torque == 0.0   # not in the published effort
    # The offset's work is T (phi - phi0); energy = work - dissipated, the balance closes.
    assert st.input_work == pytest.approx(offset * st.phi, rel=1e-12)
    assert abs(st.residual) < 1e-9
    stored = MGL * (1.0 - math.cos(st.phi))
    assert j.energy() - start_energy == pytest.approx(stored, rel=1e-12)
    assert st.input_work > stored   # the damping took the rest


def test_without_damping_energy_minus_the_offsets_work_is_kept() -> None:
    offset = 0.4
    undamped = PendulumParams(m=0.2, l=1.0, inertia=0.2, g=9.8, gamma=0.0, n=1.0)
    j = joint(offset, undamped, phi0=0.2, dphi0=0.0)
    e0 = j.energy()
    drift = []
    for _ in range(100):   # 10 s: a swing about asin(0.4 / 1.96) = 0.206 rad
        j.advance(100)
        drift.append(j.energy() - offset * (j.stepper.phi - 0.2) - e0)
    assert max(abs(d) for d in drift) < 1e-10   # RK4's drift at h = 1 ms
    assert j.stepper.phi != 0.2   # it swings: the check is not of a joint at rest


def test_a_live_change_applies_from_the_next_step() -> None:
    j = joint()
    j.advance(50)
    before = j.stepper.dphi
    j.reconfigure(JointConfig(params=ROTOR, h=H, phi0=0.3, dphi0=0.1, effort_offset=0.2))
    j.advance(20)
    assert ROTOR.inertia * (j.stepper.dphi - before) == pytest.approx(0.2 * 20 * H, abs=1e-15)


def test_bad_values_are_refused_with_the_value() -> None:
    with pytest.raises(JointError, match=re.escape(
            'effort_offset must be a finite number of N m, got inf')):
        joint(math.inf)
    values = {s.name: s.default for s in SPECS}
    values['effort_offset'] = math.nan
    assert check(values) == 'effort_offset must be a finite number of N m, got nan'
    with pytest.raises(TestingError, match=re.escape(
            'effort_offset must be a finite number of N m, got -inf')):
        scene_values('controller_test', {'effort_offset': -math.inf})


# ------------------------------------------------------------------ closed loops and campaigns
@pytest.mark.ros
def test_a_pd_law_settles_off_its_target_by_the_offset_over_kp(tmp_path: Path) -> None:
    offset = 0.4
    run = closed_loop(pd, periods=1500, target=0.5, overrides={'effort_offset': offset},
                      record=tmp_path / 'biased.mcap')
    calm = closed_loop(pd, periods=1500, target=0.5)
    # Gravity is compensated (the law's m g l is the scene's): kp e + T = 0 at rest.
    assert PDGains().mgl == MGL
    assert run.metrics().steady_state_error == pytest.approx(offset / PDGains().kp, abs=1e-9)
    assert abs(calm.metrics().steady_state_error) < 1e-9
    assert run.parameters['effort_offset'] == offset
    # The record keeps it with the scene (what a twin or a fit reads back).
    from pendulum_sim.recording import load

    assert load(tmp_path / 'biased.mcap').scene['effort_offset'] == repr(offset)


def test_a_batch_leaves_the_offset_to_the_scalar_joint_and_agrees_with_it() -> None:
    values = scene_values('controller_test', {'effort_offset': 0.4})
    assert batchable(values) == 'effort_offset is not 0'
    [batched] = run_batch(pd_batch, [values], 300)
    scalar = closed_loop(pd_batch_scalar, periods=300, overrides={'effort_offset': 0.4})
    assert not isinstance(batched, TestingError)
    assert batched.position.tobytes() == scalar.position.tobytes()


def pd_batch_scalar(t: float, position: float, velocity: float) -> float:
    return float(pd_batch(t, np.array([position]), np.array([velocity]))[0])


@pytest.mark.ros
def test_the_node_applies_the_offset_over_dds_as_the_joint_does(tmp_path: Path) -> None:
    """pendulum_node (its own process, real DDS) under the PD controller's node, the offset
    set in the scene: the same trajectory as the in-process joint, bit for bit."""
    controller = str(Path(sys.executable).parent / 'pendulum_pd_controller')
    remote = closed_loop([controller], periods=300, overrides={'effort_offset': 0.4},
                         record=tmp_path / 'offset.mcap')
    local = closed_loop(pd, periods=300, overrides={'effort_offset': 0.4})
    for name in ('t', 'position', 'velocity', 'effort', 'command'):
        assert getattr(remote, name).tobytes() == getattr(local, name).tobytes(), name
