"""Write the golden outputs of the core's public API: ``python test/golden/make_golden.py``.

The arrays in ``core.npz`` are what ``simulate``, ``Stepper`` and ``sweep`` return on a grid of
methods, exponents n, damping coefficients γ (stiff ones included) and torques;
``test/core/test_core_golden.py`` recomputes them and asserts they are equal to the last bit, so a
restructuring of the core cannot change a result unnoticed. Regenerate only for a deliberate
change of the numerics (and say so in the changelog).
"""
from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from pendulum_sim.core import METHODS, PendulumParams, Stepper, simulate
from pendulum_sim.core.sweep import sweep

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'support'))
from sweep_population import mixed_population

GOLDEN = Path(__file__).resolve().parent / 'core.npz'
N_VALUES = (0.0, 0.01, 0.5, 1.0, 2.0, 3.7)
GAMMAS = (0.3, 10.0, 1000.0)
TORQUES = (0.0, 0.4)
W2 = 9.8


def simulate_cases() -> Iterator[tuple[str, dict[str, np.ndarray]]]:
    """Yield (key, arrays) of ``simulate`` for every method, n, γ and torque of the grid."""
    for method in METHODS:
        # n = 0.01 only for the fixed-step methods: an adaptive cover of a near-Coulomb
        # law at rest takes its substeps down to round-off (tens of seconds a run).
        for n in N_VALUES if METHODS[method].fixed_step else N_VALUES[:1] + N_VALUES[2:]:
            for gamma in GAMMAS:
                for tau in TORQUES:
                    params = PendulumParams.from_omega0_sq(W2, gamma, n)
                    run = simulate(params, 2.0, 0.5, 1.5, 0.01, method, torque=tau,
                                   rtol=1e-6, atol=1e-8)
                    stats = np.array(list(run.stats.as_dict().values()), dtype=np.int64)
                    yield (f'sim/{method}/n={n}/g={gamma}/tau={tau}',
                           {'phi': run.phi, 'dphi': run.dphi, 'energy': run.energy,
                            'wd': run.dissipated_work, 'wi': run.input_work, 'stats': stats})


def stepper_cases() -> Iterator[tuple[str, dict[str, np.ndarray]]]:
    """Yield Stepper runs: steps under a varying torque, a one-off step, live parameters."""
    for method in ('rk4', 'euler', 'midpoint', 'sdirk3', 'dopri5', 'rodas4'):
        for n in N_VALUES if METHODS[method].fixed_step else N_VALUES[:1] + N_VALUES[2:]:
            for gamma in (1.0, 1000.0):
                st = Stepper(PendulumParams.from_omega0_sq(W2, gamma, n), 1.0, -2.0, 0.02,
                             method, rtol=1e-6, atol=1e-8)
                rows = []
                for k in range(60):
                    st.step(0.1 * ((k % 7) - 3))
                    rows.append((st.phi, st.dphi, st.dissipated_work, st.input_work))
                st.step_by(0.013, 0.05)
                rows.append((st.phi, st.dphi, st.dissipated_work, st.input_work))
                st.set_params(PendulumParams.from_omega0_sq(W2, 2.0 * gamma, n + 1.0))
                st.advance(20, -0.2)
                rows.append((st.phi, st.dphi, st.dissipated_work, st.input_work))
                rows.append((st.local_error_estimate(0.1), st.residual, st.t, 0.0))
                stats = np.array(list(st.stats.as_dict().values()), dtype=np.int64)
                yield (f'stepper/{method}/n={n}/g={gamma}',
                       {'rows': np.array(rows), 'stats': stats})


def sweep_cases() -> Iterator[tuple[str, dict[str, np.ndarray]]]:
    """Yield sweeps over mixed n, γ, states and torques, with and without recording."""
    w2, gamma, n, phi0, dphi0, tau = mixed_population()
    for method in ('rk4', 'midpoint', 'euler'):
        # The lower-order methods on a subset: their careful path runs per pendulum.
        k = n.size if method == 'rk4' else 60
        for torque in (0.0, tau[:k]):
            res = sweep(w2[:k], gamma[:k], n[:k], phi0[:k], dphi0[:k], 1.005, 0.01,
                        method=method, torque=torque, record_every=25)
            assert res.phi_record is not None and res.dphi_record is not None
            yield (f'sweep/{method}/torque={np.ndim(torque)}',
                   {'phi': res.phi, 'dphi': res.dphi, 'energy': res.energy,
                    'phi_record': res.phi_record, 'dphi_record': res.dphi_record,
                    'counters': np.array([res.substeps, res.fallbacks, res.reversals,
                                          res.sticks])})


def golden() -> dict[str, np.ndarray]:
    """Return every golden array, keyed ``case/field``."""
    out: dict[str, np.ndarray] = {}
    for cases in (simulate_cases, stepper_cases, sweep_cases):
        for key, arrays in cases():
            for field, arr in arrays.items():
                out[f'{key}/{field}'] = np.asarray(arr)
    return out


def main() -> int:
    """Write ``core.npz`` next to this script."""
    data = golden()
    np.savez_compressed(GOLDEN, **data)  # type: ignore[arg-type]
    print(f'wrote {len(data)} arrays to {GOLDEN} ({GOLDEN.stat().st_size / 1e6:.2f} MB)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
