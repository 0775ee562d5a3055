"""Benchmark the numerical core: the scalar RK4 step, the sweep, scipy's RHS call, MuJoCo's RK4.

Run: ``.venv/bin/python bench/bench_core.py [--quick]``. Prints a table; asserts nothing.

1. ``Stepper.step()`` (RK4, guard on, the paper's pendulum, n = 1…5) in µs per step;
   target ≤ 1.5 µs.
2. ``sweep()`` in ns per pendulum-step at 10³, 10⁴, 10⁵ pendulums with mixed n = 1…5
   (γ ∈ [0.1, 2], φ0 ∈ [−2, 2], φ'0 ∈ [−3, 3], h = 1 ms, RK4, guard on), and one damping law
   at a time; at 10⁵, where the time goes (the set-up, and the pendulums the fast path refused
   and the careful path stepped one by one).
3. With scipy: one right-hand-side call of ``scipy.integrate.solve_ivp`` on the same problem,
   as solve_ivp's time divided by ``nfev`` (RK45) and as a bare call of the function.
4. With MuJoCo (extra ``peers``): the same pendulum, n = 1 (MuJoCo's joint damping is linear),
   m = 0.2 kg at l = 1 m, γ = 1, x0 = 2, its RK4 integrator at h = 1 ms: ``mj_step`` called from
   Python per step and ``mj_step(nstep=…)`` looping in C, side by side with ``Stepper.step()``,
   and the angle both reach after 20 s.

Every figure is the best of several repeats, as wall clock (``time.perf_counter``) and, for the
sweep, as the process's CPU time (``time.process_time``): the machine may be shared, the best
run is the one least disturbed, and CPU time does not count the time other processes held the
core. The load average is printed with the machine.
"""
from __future__ import annotations

import argparse
import math
import os
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from pendulum_sim.core import PendulumParams, Stepper
from pendulum_sim.core import sweep as sweep_module
from pendulum_sim.core.engine import Engine
from pendulum_sim.core.sweep import sweep
from pendulum_sim.reports.report import machine_info

W2 = 9.8
H = 1e-3


def best_of(fn: Callable[[], Any], repeats: int) -> float:
    """Return the shortest wall time of ``repeats`` calls of ``fn`` in s."""
    return best_of_both(fn, repeats)[0]


def best_of_both(fn: Callable[[], Any], repeats: int) -> tuple[float, float]:
    """Return the shortest wall time and the shortest process CPU time of ``repeats`` calls."""
    wall = cpu = math.inf
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall = min(wall, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    return wall, cpu


def machine() -> str:
    """Return the machine and library versions (as the reports print them) and the load."""
    load = ', '.join(f'{x:.2f}' for x in os.getloadavg())
    return f'{machine_info()}; load average {load}'



def bench_stepper(steps: int, repeats: int) -> dict[float, float]:
    """Return µs per ``Stepper.step()`` for each n (RK4, guard on, paper set-up)."""
    out = {}
    for n in (1.0, 2.0, 3.0, 4.0, 5.0):
        st = Stepper(PendulumParams(gamma=1.0, n=n), 2.0, 0.0, H, 'rk4', guard=True)

        def run(step: Callable[[], None] = st.step) -> None:
            for _ in range(steps):
                step()

        run()  # warm-up: compile the specialised step
        out[n] = best_of(run, repeats) / steps * 1e6
    return out


def sweep_problem(size: int, ns: np.ndarray | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return (γ, n, φ0, φ'0) of ``size`` pendulums, mixed n = 1…5 unless ``ns`` is given."""
    rng = np.random.default_rng(2017)
    n = rng.integers(1, 6, size).astype(float) if ns is None else ns
    return (rng.uniform(0.1, 2.0, size), n, rng.uniform(-2.0, 2.0, size),
            rng.uniform(-3.0, 3.0, size))


def bench_sweep(size: int, steps: int, repeats: int, ns: np.ndarray | None = None
                ) -> tuple[float, float, Any]:
    """Return ns per pendulum-step of the sweep (wall, CPU) and the last result."""
    g, n, p0, v0 = sweep_problem(size, ns)
    sweep(W2, g, n, p0, v0, 10 * H, H)  # warm-up (the guard's region radius is cached)
    res: list[Any] = []

    def run() -> None:
        res.append(sweep(W2, g, n, p0, v0, steps * H, H))

    wall, cpu = best_of_both(run, repeats)
    return wall / (size * steps) * 1e9, cpu / (size * steps) * 1e9, res[-1]


def sweep_breakdown(size: int, steps: int, repeats: int, ns: np.ndarray | None = None
                    ) -> tuple[float, float, float, float, float]:
    """Return where a sweep's time goes: first step, careful-path calls, µs, share, plain step.

    The best time of a one-step sweep (the set-up: validation, the guard's speed ranges and the
    other per-pendulum constants, plus the first step, where transients start) is given in ns
    per pendulum-step of a ``steps``-step run; the careful path is timed by wrapping
    ``Engine.careful``, and the plain numpy step by wrapping the steps the sweep compiles, for
    one ``steps``-step run (ns per pendulum-step). The rest is the fast-path decisions and the
    sweep's own bookkeeping.
    """
    g, n, p0, v0 = sweep_problem(size, ns)
    setup = best_of(lambda: sweep(W2, g, n, p0, v0, H, H), repeats)
    calls, spent, stepping = 0, 0.0, 0.0
    plain = Engine.careful
    compile_plain = sweep_module.compile_step  # type: ignore[attr-defined]

    def timed(self: Engine, *args: Any) -> tuple[float, float, float]:
        nonlocal calls, spent
        t0 = time.perf_counter()
        try:
            return plain(self, *args)
        finally:
            spent += time.perf_counter() - t0
            calls += 1

    def timed_compile(*args: Any, **kwargs: Any) -> Callable[..., Any]:
        step = compile_plain(*args, **kwargs)

        def timed_step(*a: Any) -> Any:
            nonlocal stepping
            t0 = time.perf_counter()
            try:
                return step(*a)
            finally:
                stepping += time.perf_counter() - t0

        return timed_step

    Engine.careful = timed  # type: ignore[method-assign]
    sweep_module.compile_step = timed_compile  # type: ignore[attr-defined,assignment]
    try:
        t0 = time.perf_counter()
        sweep(W2, g, n, p0, v0, steps * H, H)
        total = time.perf_counter() - t0
    finally:
        Engine.careful = plain  # type: ignore[method-assign]
        sweep_module.compile_step = compile_plain  # type: ignore[attr-defined]
    return (setup / (size * steps) * 1e9, calls / steps, spent / max(calls, 1) * 1e6,
            spent / total, stepping / (size * steps) * 1e9)


def bench_scipy(repeats: int) -> tuple[float, float, int] | None:
    """Return (µs per RHS call inside solve_ivp, µs per bare call, nfev) or None."""
    try:
        from scipy.integrate import solve_ivp
    except ImportError:
        return None
    gamma, n = 1.0, 2.0

    def fun(t: float, y: np.ndarray) -> np.ndarray:
        v = y[1]
        return np.array([v, -W2 * math.sin(y[0]) - gamma * math.copysign(abs(v) ** n, v)])

    sols: list[Any] = []

    def run() -> None:
        sols.append(solve_ivp(fun, (0.0, 20.0), [2.0, 0.0], method='RK45', rtol=1e-8,
                              atol=1e-10))

    t = best_of(run, repeats)
    nfev = sols[-1].nfev
    y = np.array([2.0, 0.5])
    calls = 20000

    def bare() -> None:
        for _ in range(calls):
            fun(0.0, y)

    tb = best_of(bare, repeats)
    return t / nfev * 1e6, tb / calls * 1e6, nfev


MJCF = """
<mujoco model="pendulum">
  <option timestep="0.001" integrator="RK4" gravity="0 0 -9.8"/>
  <worldbody>
    <body name="arm">
      <joint name="hinge" type="hinge" axis="0 1 0" damping="0.2"/>
      <inertial pos="0 0 -1" mass="0.2" diaginertia="1e-12 1e-12 1e-12"/>
    </body>
  </worldbody>
</mujoco>
"""
"""The paper's pendulum as MuJoCo sees it: a point mass 0.2 kg at 1 m (I = m l² = 0.2 kg m²),
joint damping b = γ I = 0.2 N m s (n = 1, γ = 1), RK4 at h = 1 ms."""


def bench_mujoco(steps: int, repeats: int) -> tuple[float, float, float, float] | None:
    """Return (µs per mj_step from Python, µs per step in C, φ(20 s) MuJoCo, φ(20 s) core)."""
    try:
        import mujoco
    except ImportError:
        return None
    model = mujoco.MjModel.from_xml_string(MJCF)
    data = mujoco.MjData(model)

    def reset() -> None:
        mujoco.mj_resetData(model, data)
        data.qpos[0] = 2.0

    def per_call() -> None:
        reset()
        for _ in range(steps):
            mujoco.mj_step(model, data)

    def in_c() -> None:
        reset()
        mujoco.mj_step(model, data, nstep=steps)

    py = best_of(per_call, repeats) / steps * 1e6
    c = best_of(in_c, repeats) / steps * 1e6
    reset()
    mujoco.mj_step(model, data, nstep=20000)
    st = Stepper(PendulumParams(gamma=1.0, n=1.0), 2.0, 0.0, H)
    st.advance(20000)
    return py, c, float(data.qpos[0]), st.phi


def main() -> None:
    """Print the benchmark table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='fewer steps and repeats')
    args = parser.parse_args()
    reps = 2 if args.quick else 5
    print(machine())
    print()

    scalar = bench_stepper(20000 if args.quick else 100000, reps)
    print('1. scalar RK4 step, Stepper.step() with the guard (paper set-up, x0 = 2, γ = 1)')
    for n, us in scalar.items():
        print(f'   n = {n:.0f}: {us:6.2f} µs/step')
    mean_scalar = sum(scalar.values()) / len(scalar)
    print(f'   target <= 1.5 µs: {"met" if max(scalar.values()) <= 1.5 else "NOT met"}')
    print()

    print('2. vectorized sweep, RK4 + guard, h = 1 ms, ns per pendulum-step (wall, CPU)')
    print('   pendulums  damping         wall     CPU  reversals/step  guarded')
    rows: list[tuple[int, str, np.ndarray | None, int]] = [
        (1000, 'mixed n=1..5', None, 2000),
        (10000, 'mixed n=1..5', None, 500),
        (100000, 'mixed n=1..5', None, 200),
    ]
    for size, label, ns, steps in rows:
        steps = steps // 4 if args.quick else steps
        t, c, res = bench_sweep(size, steps, reps, ns)
        print(f'   {size:>9}  {label:<13} {t:7.1f} {c:7.1f}'
              f'  {res.reversals.sum() / res.steps:14.1f}  {res.guarded:7d}')
        if size == 100000:
            sweep_ns, sweep_cpu = t, c
    big = 100000
    steps = 50 if args.quick else 200
    for k in (1.0, 2.0, 5.0):
        t, c, res = bench_sweep(big, steps, reps, np.full(big, k))
        label = f'n = {k:.0f} only'
        print(f'   {big:>9}  {label:<13} {t:7.1f} {c:7.1f}'
              f'  {res.reversals.sum() / res.steps:14.1f}  {res.guarded:7d}')
    verdict = ', '.join(f'{"met" if x <= 30.0 else "NOT met"} ({what} {x:.1f} ns)'
                        for what, x in (('wall', sweep_ns), ('CPU', sweep_cpu)))
    print(f'   (the earlier target <= 30 ns at 10^5 mixed: {verdict})')
    print('   where the time goes at 10^5 (one run each): a one-step sweep (set-up + first step)')
    print('   as ns per pendulum-step of the run; careful-path calls per step, µs per call,')
    print('   share; the plain numpy step (all pendulums, every step) in ns per pendulum-step')
    for label, ns in (('mixed n=1..5', None), ('n = 1 only', np.full(big, 1.0)),
                      ('n = 2 only', np.full(big, 2.0)), ('n = 5 only', np.full(big, 5.0))):
        setup, per_step, us, share, plain_ns = sweep_breakdown(big, steps, reps, ns)
        print(f'   {big:>9}  {label:<13} 1 step {setup:5.1f} ns, careful {per_step:6.0f}/step '
              f'x {us:5.1f} µs = {100 * share:3.0f} %, plain step {plain_ns:5.1f} ns')
    print()

    mj = bench_mujoco(20000 if args.quick else 100000, reps)
    if mj is None:
        print('4. mujoco not installed (extra peers): no MuJoCo comparison')
    else:
        py, c, phi_mj, phi_core = mj
        print('4. MuJoCo RK4 on the same pendulum (n = 1, γ = 1, x0 = 2, h = 1 ms), per step')
        print(f'   Stepper.step() (n = 1):               {scalar[1.0]:6.2f} µs')
        print(f'   mujoco.mj_step() called from Python:  {py:6.2f} µs')
        print(f'   mujoco.mj_step(nstep=N), loop in C:   {c:6.2f} µs')
        print(f'   φ(20 s): core {phi_core:.12f}, MuJoCo {phi_mj:.12f} '
              f'(difference {abs(phi_core - phi_mj):.1e} rad)')
    print()

    sp = bench_scipy(reps)
    if sp is None:
        print('3. scipy not installed: no solve_ivp comparison')
        return
    per_call, bare, nfev = sp
    print('3. scipy.integrate.solve_ivp (RK45, rtol 1e-8, n = 2, 20 s), one RHS call')
    print(f'   inside solve_ivp: {per_call:6.2f} µs/call (time / nfev, nfev = {nfev})')
    print(f'   bare fun(t, y):   {bare:6.2f} µs/call')
    print('   ratios (an RK4 step is 4 RHS calls):')
    print(f'   solve_ivp RHS call / Stepper step (mean over n): {per_call / mean_scalar:6.1f}x')
    print(f'   solve_ivp RHS call / sweep pendulum-step (10^5): '
          f'{per_call * 1e3 / sweep_ns:6.0f}x')
    print(f'   bare RHS call / sweep pendulum-step (10^5):      {bare * 1e3 / sweep_ns:6.0f}x')


if __name__ == '__main__':
    main()
