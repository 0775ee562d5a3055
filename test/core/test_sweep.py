"""The vectorized sweep: agreement with scalar integrations, order, stiffness, validation."""
from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np
import pytest

from pendulum_sim.core import IntegratorError, ModelError, PendulumParams, Stepper, simulate
from pendulum_sim.core import sweep as sweep_module
from pendulum_sim.core.engine import guard_for
from pendulum_sim.core.reversal import hermite_root
from pendulum_sim.core.sweep import sweep
from pendulum_sim.core.tableaus import TABLEAUS

EPS = np.finfo(float).eps
W2 = 9.8  # the paper's ω0² (m = 0.2 kg, l = 1 m, I = 0.2 kg m², g = 9.8 m/s²)


def plain_rk(method: str, w2: float, gamma: float, n: float, phi: float, dphi: float,
             hs: list[float], tau: float = 0.0) -> tuple[float, float]:
    """Integrate one pendulum with a plain-Python explicit RK loop (first-order form)."""
    tab = TABLEAUS[method]

    def acc(p: float, v: float) -> float:
        damp = 0.0 if v == 0.0 else gamma * math.copysign(abs(v) ** n, v)
        return tau - w2 * math.sin(p) - damp

    s = tab.stages
    for h in hs:
        kp: list[float] = []
        kv: list[float] = []
        for i in range(s):
            p = phi + h * sum(tab.A[i, j] * kp[j] for j in range(i))
            v = dphi + h * sum(tab.A[i, j] * kv[j] for j in range(i))
            kp.append(v)
            kv.append(acc(p, v))
        phi = phi + h * sum(tab.B[i] * kp[i] for i in range(s))
        dphi = dphi + h * sum(tab.B[i] * kv[i] for i in range(s))
    return phi, dphi


def roundoff_tol(steps: int, scale: float) -> float:
    """Return a round-off bound: a few ulps of the state per step, accumulated linearly."""
    return 8.0 * steps * EPS * scale


# Smooth damping (odd n) or even n without a velocity reversal in the interval, so a plain loop
# that knows nothing of reversals is the same method. δ = h φ' spans both sin branches of the
# sweep: the short polynomials (small δ) and np.sin (h = 0.1, |φ'| ~ 4: δ ~ 0.4 rad, above the
# polynomials' 0.21 rad and below the guard's 0.5 rad per step).
AGREE = [
    # (method, ω0², γ, n, φ0, φ'0, τ/I, t_end, h)
    ('rk4', W2, 1.0, 1.0, 2.0, 0.0, 0.0, 1.0, 1e-3),
    ('rk4', W2, 0.5, 3.0, 1.0, 1.0, 0.0, 1.0, 1e-3),
    ('rk4', W2, 0.3, 5.0, 2.5, 0.0, 0.0, 0.5, 1e-3),
    ('rk4', W2, 0.2, 2.0, 0.5, 3.0, 0.0, 0.3, 1e-3),
    ('rk4', 4.0, 0.1, 4.0, -1.0, -2.0, 0.0, 0.2, 1e-2),
    ('rk4', W2, 0.0, 1.0, 3.0, 0.0, 0.0, 1.0, 1e-2),
    ('rk4', W2, 2.0, 1.0, 0.1, 0.0, 4.9, 2.0, 1e-2),
    ('rk4', 1.0, 0.01, 1.0, 0.0, 4.0, 0.0, 1.0, 0.1),
    ('rk4', W2, 0.2, 1.5, 0.3, 2.0, 0.0, 0.1, 1e-3),
    ('midpoint', W2, 1.0, 1.0, 2.0, 0.0, 0.0, 1.0, 1e-3),
    ('euler', W2, 1.0, 3.0, 2.0, 0.0, 0.0, 1.0, 1e-3),
]


def test_sweep_agrees_with_plain_python_rk_to_roundoff() -> None:
    for method in ('rk4', 'midpoint', 'euler'):
        cases = [c for c in AGREE if c[0] == method]
        for t_end, h in sorted({(c[7], c[8]) for c in cases}):
            group = [c for c in cases if (c[7], c[8]) == (t_end, h)]
            cols = np.array([c[1:7] for c in group]).T
            # No energy check: a plain loop does not redo Euler's energy-raising steps.
            res = sweep(*cols[:5], t_end, h, method=method, torque=cols[5],
                        energy_check=False)
            steps = round(t_end / h)
            assert res.steps == steps
            for i, (_, w2, g, n, p0, v0, tau, _, _) in enumerate(group):
                p, v = plain_rk(method, w2, g, n, p0, v0, [h] * steps, tau)
                scale = max(1.0, abs(p), abs(v))
                assert abs(res.phi[i] - p) <= roundoff_tol(steps, scale), group[i]
                assert abs(res.dphi[i] - v) <= roundoff_tol(steps, scale), group[i]
                assert res.reversals[i] == 0 and res.substeps[i] == 0


def test_sweep_agrees_with_core_simulate() -> None:
    # Smooth n: the same RK4 steps as the scalar core, to round-off.
    ns = np.array([1.0, 3.0, 5.0, 1.0])
    gs = np.array([1.0, 0.5, 0.3, 10.0])
    p0 = np.array([2.0, 1.0, 2.5, 2.0])
    res = sweep(W2, gs, ns, p0, 0.0, 3.0, 0.01)
    for i in range(ns.size):
        tr = simulate(PendulumParams(gamma=gs[i], n=ns[i]), p0[i], 0.0, 3.0, 0.01)
        assert abs(res.phi[i] - tr.phi[-1]) <= roundoff_tol(300, 2.0)
        assert abs(res.dphi[i] - tr.dphi[-1]) <= roundoff_tol(300, 2.0)
    # Non-smooth n: both split the steps at the reversals, each its own way; they agree to far
    # better than the error of RK4 at this h, measured against h / 2.
    ns = np.array([2.0, 0.0, 4.0, 1.5, 2.5])
    gs = np.array([1.0, 0.5, 0.3, 2.0, 1.0])
    res = sweep(W2, gs, ns, 2.0, 0.0, 3.0, 0.01)
    half = sweep(W2, gs, ns, 2.0, 0.0, 3.0, 0.005)
    assert np.all(res.reversals >= 2)
    for i in range(ns.size):
        tr = simulate(PendulumParams(gamma=gs[i], n=ns[i]), 2.0, 0.0, 3.0, 0.01)
        err_h = math.hypot(res.phi[i] - half.phi[i], res.dphi[i] - half.dphi[i])
        diff = math.hypot(res.phi[i] - tr.phi[-1], res.dphi[i] - tr.dphi[-1])
        assert diff < 0.1 * err_h, (ns[i], diff, err_h)


def test_order_four_for_n1_and_n2_with_reversals() -> None:
    # Paper set-up, x0 = 2, γ = 1: n = 2 reverses 3 times in 4 s. The reference is an
    # independent route: the core's adaptive Dormand-Prince at tight tolerance.
    ns = np.array([1.0, 2.0, 3.0, 4.0])
    t_end = 4.0
    refs = [simulate(PendulumParams(gamma=1.0, n=n), 2.0, 0.0, t_end, t_end, method='dopri5',
                     rtol=1e-13, atol=1e-14) for n in ns]
    ref = np.array([[r.phi[-1], r.dphi[-1]] for r in refs])
    errs = []
    for h in (0.02, 0.01, 0.005):
        res = sweep(W2, 1.0, ns, 2.0, 0.0, t_end, h)
        errs.append(np.hypot(res.phi - ref[:, 0], res.dphi - ref[:, 1]))
        assert list(res.reversals[[1, 3]]) == [3, 3]
    errs_a = np.array(errs)
    ratios = errs_a[:-1] / errs_a[1:]
    assert np.all(errs_a[-1] > 1e3 * EPS)  # still above round-off: the ratios mean something
    # 16 = 2^4 for a 4th-order method; log2 within ±0.1.
    assert np.all(np.abs(np.log2(ratios) - 4.0) < 0.1), ratios


@pytest.mark.parametrize(('method', 'order'), [('euler', 1), ('midpoint', 2)])
def test_measured_order_of_the_low_order_methods(method: str, order: int) -> None:
    ref = simulate(PendulumParams(gamma=1.0, n=1.0), 2.0, 0.0, 1.0, 1.0, method='dopri5',
                   rtol=1e-13, atol=1e-14)
    errs = []
    for h in (4e-3, 2e-3, 1e-3):
        res = sweep(W2, 1.0, 1.0, 2.0, 0.0, 1.0, h, method=method)
        errs.append(math.hypot(res.phi[0] - ref.phi[-1], res.dphi[0] - ref.dphi[-1]))
    for a, b in itertools.pairwise(errs):
        assert abs(math.log2(a / b) - order) < 0.1


def energy_per_inertia(res: sweep_module.SweepResult, w2: float) -> np.ndarray:
    assert res.phi_record is not None and res.dphi_record is not None
    return 0.5 * res.dphi_record ** 2 + 2.0 * w2 * np.sin(0.5 * res.phi_record) ** 2


def test_stiff_cells_stay_finite_and_never_gain_energy() -> None:
    # γ = 1000 at 60 Hz: h λ ≈ −16.7, far outside RK4's interval [−2.785, 0].
    gs = np.array([1000.0, 1000.0, 1e6, 1e6, 1e6, 1e6, 1e3])
    ns = np.array([1.0, 2.0, 1.0, 2.0, 0.0, 0.5, 3.0])
    v0 = np.array([0.0, 0.0, 0.0, 50.0, 100.0, 0.0, 100.0])
    h = 1.0 / 60.0
    res = sweep(W2, gs, ns, 2.0, v0, 2.0, h, record_every=1)
    assert res.phi_record is not None and res.dphi_record is not None
    assert np.isfinite(res.phi_record).all() and np.isfinite(res.dphi_record).all()
    e = energy_per_inertia(res, W2)
    assert np.all(np.diff(e, axis=0) <= 0.0)
    np.testing.assert_allclose(res.energy, e[-1], rtol=1e-14)
    # The guard acted and says how: substeps for γ = 1000 (n = 1), the fallback at γ = 1e6.
    assert res.substeps[0] > 0 and res.fallbacks[0] == 0
    assert res.fallbacks[2] > 0
    assert res.capped == int(np.count_nonzero(res.fallbacks))
    # The overdamped creep is right even in the fallback: φ' ≈ −ω0² sin φ / γ.
    creep = -W2 * math.sin(res.phi[2]) / 1e6
    assert res.dphi[2] == pytest.approx(creep, rel=0.01)
    # Coulomb friction of 1e6 rad/s² stops the pendulum at once and holds it.
    assert res.dphi[4] == 0.0 and res.sticks[4] > 0
    # Without the guard the same γ = 1000 cell explodes: the guard is what keeps it finite.
    with pytest.raises(IntegratorError, match=r'^the unguarded rk4 step diverged beyond float64'):
        sweep(W2, 1000.0, 1.0, 2.0, 0.0, 2.0, h, guard=False, energy_check=False)


def guard_substeps(w2: float, gamma: float, phi: float, h: float) -> int:
    """Return the fewest m with h |λ| / m inside the guard's share of RK4's real interval.

    n = 1, γ = 1000: both eigenvalues are real (overdamped), so the interval [−2.785, 0]
    (RK4's stability function) times the guard's safety factor decides; computed here.
    """
    c = w2 * math.cos(phi)
    lam = (gamma + math.sqrt(gamma * gamma - 4.0 * c)) / 2.0
    return math.ceil(h * lam / (2.785293563405 * guard_for(TABLEAUS['rk4']).safety))


def test_guard_substeps_are_plain_rk4_substeps_and_reported() -> None:
    h, gamma, phi0 = 1.0 / 60.0, 1000.0, 2.0
    res = sweep(W2, gamma, 1.0, phi0, 0.0, h, h)
    m = guard_substeps(W2, gamma, phi0, h)
    assert m > 1
    assert res.substeps[0] == m - 1
    p, v = plain_rk('rk4', W2, gamma, 1.0, phi0, 0.0, [h / m] * m)
    assert res.phi[0] == pytest.approx(p, abs=roundoff_tol(m, 2.0))
    assert res.dphi[0] == pytest.approx(v, abs=roundoff_tol(m, 1.0))


def test_step_count_rounds_and_lands_on_t_end() -> None:
    # 0.7 / 0.001 = 699.999…: int() would drop a step (the seed code's bug).
    res = sweep(W2, 1.0, 1.0, 2.0, 0.0, 0.7, 0.001, record_every=100)
    assert res.steps == 700
    assert res.t_record is not None and res.t_record[-1] == 0.7
    assert res.t_record.shape == (8,) and res.phi_record is not None
    assert res.phi_record.shape == (8, 1)
    assert res.phi_record[-1, 0] == res.phi[0]
    # t_end not a multiple of h: two steps of 0.1 and a last one of 0.05.
    res = sweep(W2, 0.5, 1.0, 2.0, 0.0, 0.25, 0.1, record_every=1)
    assert res.steps == 3 and res.t_record is not None
    assert res.t_record.tolist() == [0.0, 0.1, 0.2, 0.25]
    p, v = plain_rk('rk4', W2, 0.5, 1.0, 2.0, 0.0, [0.1, 0.1, 0.25 - 0.2])
    assert abs(res.phi[0] - p) <= roundoff_tol(3, 2.0)
    assert abs(res.dphi[0] - v) <= roundoff_tol(3, 2.0)


def test_coulomb_friction_sticks_where_static_friction_holds() -> None:
    gamma = 5.0
    res = sweep(W2, gamma, 0.0, 1.0, 0.0, 3.0, 1e-3, record_every=10)
    assert res.phi_record is not None and res.dphi_record is not None
    # It moved (ω0² sin 1 > γ), then came to rest where |ω0² sin φ| ≤ γ and stayed there.
    assert res.phi[0] < 1.0 and res.dphi[0] == 0.0
    assert abs(W2 * math.sin(res.phi[0])) <= gamma
    assert res.sticks[0] > 0 and res.reversals[0] >= 1
    still = np.flatnonzero(res.dphi_record[:, 0] != 0.0)[-1] + 1
    assert still < res.dphi_record.shape[0] - 10
    assert np.all(res.phi_record[still:, 0] == res.phi[0])


def test_order_and_grouping_do_not_change_results() -> None:
    rng = np.random.default_rng(7)
    size = 60
    ns = rng.choice([0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0], size)
    gs = rng.uniform(0.0, 3.0, size)
    p0 = rng.uniform(-3.0, 3.0, size)
    v0 = rng.uniform(-5.0, 5.0, size)
    whole = sweep(W2, gs, ns, p0, v0, 0.5, 1e-2)
    perm = rng.permutation(size)
    shuffled = sweep(W2, gs[perm], ns[perm], p0[perm], v0[perm], 0.5, 1e-2)
    assert np.array_equal(shuffled.phi, whole.phi[perm])
    assert np.array_equal(shuffled.dphi, whole.dphi[perm])


def test_extreme_inputs_stay_finite() -> None:
    gs = np.array([0.1, 1.0, 1e3, 1e6])
    ns = np.array([0.0, 0.5, 1.0, 2.0, 3.0, 10.0, 1.5])
    x0 = np.array([0.1, 3.1, 4.0])
    v0 = np.array([0.0, 100.0])
    grid = [a.ravel() for a in np.meshgrid(gs, ns, x0, v0, indexing='ij')]
    res = sweep(W2, grid[0], grid[1], grid[2], grid[3], 0.3, 0.1)
    assert np.isfinite(res.phi).all() and np.isfinite(res.dphi).all()
    assert np.isfinite(res.energy).all()
    assert res.guarded > 0 and res.capped > 0


BAD = [
    ({'gamma': [1.0, 1.0, 1.0, -1.0]}, ModelError,
     'gamma must be >= 0 s^(n-2), got -1.0 at index 3'),
    ({'gamma': -1.0}, ModelError, 'gamma must be >= 0 s^(n-2), got -1.0'),
    ({'n': [0.0, -0.5]}, ModelError, 'n must be >= 0, got -0.5 at index 1'),
    ({'omega0_sq': -9.8}, ModelError, 'omega0_sq must be >= 0 s^-2, got -9.8'),
    ({'omega0_sq': math.inf}, ModelError, 'omega0_sq must be finite, got inf'),
    ({'phi0': [0.0, math.nan]}, ModelError, 'phi0 must be finite, got nan at index 1'),
    ({'dphi0': -math.inf}, ModelError, 'dphi0 must be finite, got -inf'),
    ({'torque': [1.0, math.nan]}, ModelError, 'torque must be finite, got nan at index 1'),
    ({'phi0': [[1.0, 2.0]]}, ModelError, 'phi0 must be a scalar or a 1-D array, got shape (1, 2)'),
    ({'gamma': 1 + 2j}, ModelError,
     'gamma must be a real number, got (1+2j)'),
    ({'gamma': 'strong'}, ModelError,
     "gamma must be a real number, got 'strong'"),
    ({'gamma': [1.0, 2.0, 3.0], 'n': [1.0, 2.0]}, ModelError,
     'arrays must all have the same length N, got gamma (3,), n (2,)'),
    ({'phi0': []}, ModelError, 'a sweep needs at least one pendulum, got arrays of length 0'),
    ({'h': 0.0}, IntegratorError, 'h must be a finite step > 0 s, got 0.0'),
    ({'h': math.nan}, IntegratorError, 'h must be a finite step > 0 s, got nan'),
    ({'t_end': -1.0}, IntegratorError, 't_end must be > 0 s, got -1.0'),
    ({'method': 'dopri5'}, IntegratorError,
     "sweep supports the explicit methods euler, midpoint, rk4, got 'dopri5'"),
    ({'phi0': [1.0, [2.0]]}, ModelError,  # ragged: numpy's ValueError before
     'phi0 must be a real number or a 1-D array of them, got [1.0, [2.0]]'),
    ({'method': np.array(['rk4'])}, IntegratorError,  # TypeError: unhashable before
     "sweep supports the explicit methods euler, midpoint, rk4, got array(['rk4'], dtype='<U3')"),
    ({'record_every': 0}, IntegratorError, 'record_every must be an integer >= 1, got 0'),
    ({'record_every': 2.5}, IntegratorError, 'record_every must be an integer >= 1, got 2.5'),
]


@pytest.mark.parametrize(('changes', 'error', 'message'), BAD)
def test_bad_inputs_raise_exact_messages(changes: dict[str, object], error: type[Exception],
                                         message: str) -> None:
    args: dict[str, object] = {'omega0_sq': W2, 'gamma': 1.0, 'n': 1.0, 'phi0': 2.0,
                               'dphi0': 0.0, 't_end': 1.0, 'h': 0.01}
    args.update(changes)
    with pytest.raises(error) as info:
        sweep(**args)  # type: ignore[arg-type]
    assert str(info.value) == message
    assert isinstance(info.value, ValueError)


def test_spinning_pendulum_is_resolved_and_loses_energy() -> None:
    # 100 rad/s at h = 0.1 sweeps 10 rad per step: gravity is forced at 100 rad/s, which the
    # Jacobian at one point does not show. The guard limits a step to 0.5 rad, as the scalar one.
    res = sweep(W2, 0.05, 1.0, 0.0, 100.0, 2.0, 0.1, record_every=1)
    # |φ'| stays above 90 rad/s: every step is cut into m >= 0.1 * 90 / 0.5 = 18 substeps.
    assert np.all(np.abs(res.dphi_record) > 90.0)
    assert res.substeps[0] >= (18 - 1) * res.steps
    e = energy_per_inertia(res, W2)
    assert np.all(np.diff(e, axis=0) <= 0.0)


def hermite(th: np.ndarray, v0: np.ndarray, v1: np.ndarray, dv0: np.ndarray, dv1: np.ndarray
            ) -> np.ndarray:
    """Evaluate the cubic Hermite interpolant on [0, 1] in the textbook basis."""
    t2, t3 = th * th, th * th * th
    return ((2 * t3 - 3 * t2 + 1) * v0 + (t3 - 2 * t2 + th) * dv0 + (-2 * t3 + 3 * t2) * v1
            + (t3 - t2) * dv1)


def test_hermite_root_is_a_root_in_the_step() -> None:
    rng = np.random.default_rng(3)
    size = 200
    v0 = rng.uniform(0.1, 1.0, size) * rng.choice([-1.0, 1.0], size)
    v1 = -np.sign(v0) * rng.uniform(1e-6, 1.0, size)
    slope = v1 - v0
    dv0 = slope * rng.uniform(0.5, 1.5, size)
    dv1 = slope * rng.uniform(0.5, 1.5, size)
    # Wiggly cubics too, where Newton from the linear guess leaves [0, 1] (bisection safeguard).
    dv0[:20] = -8.0 * slope[:20]
    dv1[:20] = -8.0 * slope[:20]
    th = np.array([hermite_root(*args) for args in zip(v0, v1, dv0, dv1, strict=True)])
    assert np.all((th >= 0.0) & (th <= 1.0))
    scale = np.abs(v0) + np.abs(v1) + np.abs(dv0) + np.abs(dv1)
    assert np.all(np.abs(hermite(th, v0, v1, dv0, dv1)) <= 16 * EPS * scale)


@pytest.mark.parametrize('vary', ['none', 'gamma', 'all'])
def test_per_pendulum_constants_are_the_engines_own(vary: str) -> None:
    # The sweep computes the stiff-transient speed and the grading window once per distinct
    # (ω0², γ) and maps them back, and the guard's speed range per pendulum and torque octave,
    # remade where the octave moved: each pendulum must get exactly what its own Engine
    # computes, whichever columns vary and however rows repeat.
    from pendulum_sim.core.engine import Engine
    from pendulum_sim.core.methods import METHODS

    rng = np.random.default_rng(5)
    size = 40
    om2 = np.full(size, W2)
    gam = np.full(size, 0.7)
    tau = np.zeros(size)
    if vary != 'none':
        gam = rng.choice([0.0, 0.3, 0.7, 2.0, 50.0], size)
    if vary == 'all':
        om2 = rng.choice([1.0, W2, 40.0], size)
        tau = rng.choice([0.0, -3.0, 0.4, 9.0], size)
    h = 2e-2
    for n in (0.5, 2.0, 5.0):
        prepared = sweep_module.Sweep(om2, gam, n, 0.0, 0.0, h, torque=tau)
        (grp,) = prepared._groups
        engines = [Engine(float(om2[i]), float(gam[i]), n, METHODS['rk4']) for i in range(size)]
        # Then a second torque: the ranges are remade where the torque's octave moved.
        for torque in (tau, tau * rng.choice([1.0, 0.3, 5.0], size)):
            prepared.advance(h, torque)
            for i, eng in enumerate(engines):
                assert (grp.lo[i], grp.hi[i]) == eng.fast_range(h, float(torque[i])), (n, i)
                assert grp.v_acc[i] == eng.v_acc, (n, i)
                if gam[i] > 0.0:  # the window is used only where the damping is not smooth
                    assert grp.reach[i] == eng.reach, (n, i)


def _reference_range(guard: Any, w2: float, gamma: float, n: float, h: float,
                     bound: float) -> tuple[float, float]:
    """Return the guard's safe speed range of one pendulum, on Python floats: the oracle.

    The definition of ``guard.safe_speed_ranges`` (the cheap sufficient test at the speed the
    step can reach) evaluated branch by branch on floats, each power the C library's.
    """
    force = bound + w2
    omega0 = math.sqrt(w2)
    try:
        term = (force / gamma) ** (1.0 / n) if gamma > 0.0 and n != 0.0 else math.inf
    except OverflowError:
        term = math.inf
    margin = 0.0 + min(h * force, term)
    hi = guard.max_angle / h - margin
    room = guard.disk / h - omega0
    empty = (math.inf, -math.inf)
    if room < 0.0 or hi < 0.0:
        return empty
    if gamma == 0.0 or n == 0.0:
        return 0.0, hi
    if n == 1.0:
        return (0.0, hi) if gamma <= room else empty
    if room == 0.0:
        return empty
    try:
        s = (room / (gamma * n)) ** (1.0 / (n - 1.0))
    except (OverflowError, ZeroDivisionError):
        s = math.inf if n > 1.0 else 0.0
    if n > 1.0:
        hi = min(hi, s - margin)
        return (0.0, hi) if hi >= 0.0 else empty
    lo = s + h * force
    return (lo, hi) if lo <= hi else empty


def test_safe_speed_ranges_are_the_definitions_floats_exactly() -> None:
    # The guard's ranges are computed once, over arrays (the sweep's; the Stepper's is one
    # element): every element must be the definition's float on Python floats, bit for bit
    # (numpy's power differs from C's pow in the last bit for a few % of random inputs, so the
    # random rows catch a numpy power), on the grid's edges too: ω0² = 0, γ = 0 and extreme,
    # n = 0, 1 and next to 1 (the power overflows), large torque.
    from pendulum_sim.core.guard import safe_speed_range, safe_speed_ranges

    guard = guard_for(TABLEAUS['rk4'])
    rng = np.random.default_rng(17)
    grid = np.array(list(itertools.product(
        [0.0, 1.0, W2, 1e4, 4e6], [0.0, 1e-300, 0.1, 1.0, 30.0, 1e3, 1e6, 1e300],
        [0.0, 1.0, 2.0 ** 20])))
    rand = np.column_stack((rng.uniform(0.0, 50.0, 400), 10.0 ** rng.uniform(-3.0, 4.0, 400),
                            2.0 ** rng.integers(-2, 8, 400)))
    rows = np.vstack((grid, rand))
    kinds = set()
    for n in (0.0, 0.3, 0.5, 0.999999, 1.0, 1.0000001, 1.5, 2.0, 2.7, 5.0, 30.0):
        for h in (1e-3, 2e-2, 0.3):
            lo, hi = safe_speed_ranges(guard, rows[:, 0], rows[:, 1], n, h, rows[:, 2])
            for k, (w2, gamma, bound) in enumerate(rows.tolist()):
                ref = _reference_range(guard, w2, gamma, n, h, bound)
                assert (lo[k], hi[k]) == ref, (n, h, w2, gamma, bound)
                if k % 40 == 0:  # the Stepper's, one pendulum: the same floats
                    assert safe_speed_range(guard, w2, gamma, n, h, bound) == ref
                kinds.add('empty' if ref[0] > ref[1] else 'low end' if ref[0] > 0.0
                          else 'open')
    assert kinds == {'empty', 'low end', 'open'}
    # One exponent per row (a group of distinct n): each the scalar function's float as well.
    exps = np.array([0.0, 0.3, 0.5, 0.999999, 1.0, 1.0000001, 1.5, 2.0, 2.7, 5.0, 30.0])
    nn = np.concatenate([exps[rng.integers(0, exps.size, rows.shape[0])],
                         rng.uniform(0.2, 3.0, rows.shape[0])])
    both = np.vstack((rows, rows))
    for h in (1e-3, 2e-2, 0.3):
        lo, hi = safe_speed_ranges(guard, both[:, 0], both[:, 1], nn, h, both[:, 2])
        for k, (w2, gamma, bound) in enumerate(both.tolist()):
            ref = _reference_range(guard, w2, gamma, float(nn[k]), h, bound)
            assert (lo[k], hi[k]) == ref, (nn[k], h, w2, gamma, bound)


@pytest.mark.parametrize('column', ['omega0_sq', 'gamma', 'torque'])
def test_uniform_constants_give_the_same_floats_as_arrays(column: str) -> None:
    # A group passes ω0², γ and τ/I to the numpy step as one float where they are uniform and
    # as an array where not: one extra pendulum per damping law with a different value turns
    # every group's constant into an array; the other pendulums' results must not move a bit.
    rng = np.random.default_rng(23)
    ns = np.repeat([0.5, 1.0, 2.0, 3.0, 5.0], 6)
    size = ns.size
    args = {'omega0_sq': np.full(size, W2), 'gamma': np.full(size, 0.8), 'n': ns,
            'phi0': rng.uniform(-3.0, 3.0, size), 'dphi0': rng.uniform(-4.0, 4.0, size),
            'torque': np.zeros(size)}
    if column == 'torque':
        args['torque'] = np.full(size, 0.6)
    base = sweep(**args, t_end=0.3, h=1e-2)
    other = {'omega0_sq': 4.0, 'gamma': 2.5, 'torque': -1.5}[column]
    extra = {k: np.concatenate((a, a[::6])) for k, a in args.items()}
    extra[column][size:] = other
    mixed = sweep(**extra, t_end=0.3, h=1e-2)
    for name in ('phi', 'dphi', 'substeps', 'fallbacks', 'reversals', 'sticks'):
        assert np.array_equal(getattr(mixed, name)[:size], getattr(base, name)), name
    assert np.any(mixed.reversals[:size] > 0)  # the careful path took part


def test_stiff_test_on_the_last_bit_decides_as_the_stepper() -> None:
    # The stiff-transient test compares |a0| with 0.5 γ |φ'|^n; numpy's power and C's pow (the
    # Stepper's) differ in the last bit for a few % of speeds. States with |a0| placed exactly
    # on the larger of the two thresholds (ω0² = 0, so a0 = a_in − γ φ'^5 to the bit) are
    # stiff for one and not for the other: the sweep must take the Stepper's decision, both
    # where numpy's power is the larger and where C's is.
    n, gamma = 5.0, 1.0
    speeds = np.random.default_rng(1).uniform(2.5, 3.0, 4000)
    cases: dict[bool, list[tuple[float, float]]] = {True: [], False: []}
    for v in speeds.tolist():
        p_np, p_c = float(np.power(np.array([v]), n)[0]), v ** n
        if p_np == p_c:
            continue
        top = 0.5 * gamma * max(p_np, p_c)
        d0 = gamma * v * v * v * v * v
        ain = d0 - top
        if abs(ain - d0) == top and len(cases[p_np > p_c]) < 3:
            cases[p_np > p_c].append((v, ain))
    for v, ain in cases[True] + cases[False]:
        st = Stepper(PendulumParams.from_omega0_sq(0.0, gamma, n), 0.5, v, 1e-3)
        st.step(ain)  # I = 1: the torque is a_in
        res = sweep(0.0, gamma, n, 0.5, v, 1e-3, 1e-3, torque=ain)
        assert res.substeps[0] == st.stats.substeps, (v, ain)
        assert res.phi[0] == st.phi and res.dphi[0] == st.dphi, (v, ain)
    if not cases[True]:  # the case a numpy threshold alone would get wrong
        pytest.skip("numpy's power is never above the C library's pow here")


def test_a_prepared_sweep_advances_as_a_chain_of_sweeps_to_the_bit() -> None:
    # Stretches of one control period under a torque that changes each time, over every kind
    # of law (dry, near-Coulomb, viscous, fractional, quadratic, stiff), each one the sweep
    # that starts from the stretch's first state: states, recordings and counters alike.
    rng = np.random.default_rng(31)
    size = 120
    ns = rng.choice([0.0, 0.3, 1.0, 1.5, 2.0, 3.0, 5.0], size)
    gs = rng.choice([0.0, 0.2, 1.0, 30.0, 1000.0], size)
    om2 = rng.choice([0.0, W2, 40.0], size)
    p = rng.uniform(-3.0, 3.0, size)
    v = rng.uniform(-4.0, 4.0, size)
    v[::7] = 0.0
    h, period = 1e-2, 0.05
    prepared = sweep_module.Sweep(om2, gs, ns, p, v, h)
    careful = 0
    for k in range(12):
        tau = rng.uniform(-20.0, 20.0, size) * (rng.uniform(size=size) < 0.7)
        if k == 5:
            tau = np.zeros(size)  # the energy check applies where the input is zero
        got = prepared.advance(period, tau, record_every=2)
        want = sweep(om2, gs, ns, p, v, period, h, torque=tau, record_every=2)
        for name in ('phi', 'dphi', 'energy', 'phi_record', 'dphi_record', 't_record',
                     'substeps', 'fallbacks', 'reversals', 'sticks'):
            a, b = getattr(got, name), getattr(want, name)
            assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), (k, name)
        assert prepared.phi.tobytes() == want.phi.tobytes()
        assert prepared.dphi.tobytes() == want.dphi.tobytes()
        careful += int(np.sum(want.substeps + want.fallbacks + want.reversals + want.sticks))
        p, v = want.phi, want.dphi
    assert careful > 0  # the careful path took part
    # No torque: the last one is kept.
    again = prepared.advance(period)
    want = sweep(om2, gs, ns, p, v, period, h, torque=tau)
    assert again.phi.tobytes() == want.phi.tobytes()


def test_array_torque_bounds_are_the_scalar_ones_exactly() -> None:
    from pendulum_sim.core.decisions import ain_bound, ain_bounds

    rng = np.random.default_rng(2)
    ain = np.concatenate((rng.uniform(-1e4, 1e4, 500), 10.0 ** rng.uniform(-320, 5, 500),
                          [0.0, -0.0, 5e-324, 1.0, -1.0, 2.0, 0.5, 1e5, np.nextafter(1.0, 2)]))
    want = np.array([ain_bound(a) for a in ain.tolist()])
    assert ain_bounds(ain).tobytes() == want.tobytes()


@pytest.mark.parametrize(('torque', 'message'), [
    ([1.0, math.nan, 1.0], 'torque must be finite, got nan at index 1'),
    (math.inf, 'torque must be finite, got inf'),
    ([1.0, 2.0], 'torque must be a scalar or an array of length N = 3, got shape (2,)'),
    ([0.0, 0.0, 2e8], 'torque must be within +-1e+08 N m (|torque/I| <= 1e+08 rad/s^2), got 2e+08'
     ' at index 2'),
])
def test_a_new_torque_is_validated_with_exact_messages(torque: object, message: str) -> None:
    prepared = sweep_module.Sweep(W2, 1.0, 1.0, [0.1, 0.2, 0.3], 0.0, 1e-2)
    with pytest.raises(ModelError) as info:
        prepared.advance(0.1, torque)
    assert str(info.value) == message
    # The refused torque changed nothing: the next advance starts where the sweep stood.
    assert prepared.phi.tolist() == [0.1, 0.2, 0.3]
