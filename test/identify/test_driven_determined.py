"""What a driven fit reports as determined: a value the determined ones fix stays determined.

Oracles: the delta method written out by hand on a covariance whose one parameter is not
determined, the joint a synthetic record was made with (no damping at all: γ = 0, so n does not
act), and a joint given by its parameters validated as a fit of them.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from synthetic_driven import joints, runs

from pendulum_sim.identify import IdentifyError, driven_record, fit, joint_fit, validate
from pendulum_sim.identify.driven import _delta


def test_the_delta_method_leaves_out_a_parameter_the_function_does_not_depend_on() -> None:
    free = ('inertia', 'mgl', 'n')
    cov = np.array([[4e-6, 1e-6, np.nan], [1e-6, 9e-4, np.nan], [np.nan, np.nan, np.nan]])
    inertia, mgl = 0.2, 3.7
    om = math.sqrt(mgl / inertia)
    g = np.array([-0.5 * om / inertia, 0.5 / math.sqrt(mgl * inertia)])
    want = math.sqrt(float(g @ cov[:2, :2] @ g))
    got = _delta({'inertia': g[0], 'mgl': g[1]}, free, cov)
    assert got == pytest.approx(want, rel=1e-12)
    # A function of n itself is as undetermined as n.
    assert _delta({'n': 1.0, 'inertia': 1.0}, free, cov) is None


def test_a_joint_without_damping_keeps_omega0_and_its_friction_and_predicts() -> None:
    """γ = 0: the damping ends at its bound, n does not act, all else is determined.

    The joint (seed 7's, its damping taken away) is run under the PD loop twice from other
    states; the first run, with 2 mrad of encoder noise, is fitted by ``power+coulomb``, the
    second is the held-out record.
    """
    joint = dataclasses.replace(joints(1, 7)[0], gamma=0.0)
    first, second = runs([joint, joint], 7, periods=300)
    rng = np.random.default_rng(9)

    def rec(run):  # type: ignore[no-untyped-def]
        return driven_record(run.t, run.position + rng.normal(0.0, 2e-3, run.t.size),
                             run.effort - joint.effort_offset)

    f = fit([rec(first)], model='power+coulomb')
    assert f.params['gamma'] == 0.0 and f.params['n'] is None
    assert f.reasons['n'] == ('n is not determined: the damping is 0 (at its bound), where the '
                              'exponent does not act; the law predicts without it')
    truth = {'omega0': math.sqrt(joint.mgl / joint.inertia),
             'friction_accel': joint.friction / joint.inertia, 'inertia': joint.inertia,
             'mgl': joint.mgl, 'friction': joint.friction, 'gamma': 0.0}
    for k, v in truth.items():
        ci = f.ci95[k]
        assert ci is not None and ci[0] <= v <= ci[1], (k, v, ci)
    v = validate(f, rec(second))
    assert v.fit_prediction > 95.0 and v.fit_simulation > 80.0


def test_a_joint_given_by_its_parameters_is_validated_as_a_fit_of_them() -> None:
    """The joint a record was made with, given to ``joint_fit``, predicts it to its noise."""
    joint = joints(1, 3)[0]
    [run] = runs([joint], 3, periods=200)
    noise = 2e-3
    rec = driven_record(run.t, run.position + np.random.default_rng(1).normal(
        0.0, noise, run.t.size), run.effort - joint.effort_offset)
    given = joint_fit('power+coulomb', inertia=joint.inertia, mgl=joint.mgl, gamma=joint.gamma,
                      n=joint.n, friction=joint.friction, effort_offset=joint.effort_offset,
                      window=0.5)
    assert given.params['omega0'] == math.sqrt(joint.mgl / joint.inertia)
    assert given.samples == 0 and given.window == 0.5 and given.ci95['n'] == (joint.n, joint.n)
    v = validate(given, rec)
    # Over the windows the states are fitted and the joint is the truth: the residual is the
    # encoder's noise.
    assert float(np.sqrt(np.mean(v.residual ** 2))) == pytest.approx(noise, rel=0.15)
    assert v.fit_prediction > 99.0
    # Without a window, a driven fit's default: half the joint's period.
    assert joint_fit('viscous', inertia=0.2, mgl=2.0, gamma=0.5, n=1.0).window == pytest.approx(
        math.pi / math.sqrt(2.0 / 0.2))
    with pytest.raises(IdentifyError) as info:
        joint_fit('viscous', inertia=0.2, mgl=2.0, gamma=0.5, n=1.5)
    assert str(info.value) == 'the viscous law has n = 1, got n = 1.5'
    with pytest.raises(IdentifyError) as info:
        joint_fit('power', inertia=0.0, mgl=2.0, gamma=0.5, n=1.5)
    assert str(info.value) == "known['inertia'] must be in [1e-06, 10000], got 0.0"
    with pytest.raises(IdentifyError) as info:
        joint_fit('power', inertia=0.2, mgl=2.0, gamma=0.5, n=1.5, friction=0.1)
    assert str(info.value) == 'the power law has no Coulomb friction, got friction = 0.1'
