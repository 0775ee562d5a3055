"""Embedded adaptive pairs: error-controlled substeps that cover one step of h.

The pair's two solutions differ by ``E`` (``tableaus.py``); a trial substep is accepted when
the scaled error norm is at most 1 and the next trial is ``0.9 err^(−1/(p̂+1))`` times the last,
within [0.2, 5] (Hairer, Nørsett and Wanner, *Solving ODEs I*, II.4). Where the damping is not
smooth at φ' = 0 (n even, non-integer, or 0) an accepted substep that crosses a reversal is cut
at it: the reversal is located on the branch continuation of the start (Hermite guess, Newton on
the substep's own φ'), so no substep straddles the kink and the pair's estimate stays valid.
The pair is an explicit one (``explicit.py``) or a Rosenbrock one (``rosenbrock.py``): both
steps have the same signature and results, and this one cover serves both.
"""
from __future__ import annotations

import math

from .engine import Engine, hermite_root
from .errors import IntegratorError
from .explicit import ErrStepFn, compile_step
from .guard import GuardStats
from .rosenbrock import compile_rosenbrock
from .tableaus import Tableau


def pair_steps(tab: Tableau, n: float) -> tuple[ErrStepFn, ErrStepFn]:
    """Return the embedded pair's compiled (plain law, branch law) steps with error estimate."""
    if tab.rosenbrock:
        return compile_rosenbrock(tab, n), compile_rosenbrock(tab, n, branch=True)
    return (compile_step(tab, n, with_error=True),
            compile_step(tab, n, branch=True, with_error=True))


class TooManySubsteps(Exception):
    """Raised by :func:`cover` when ``max_trials`` trial substeps did not cover the step."""


def cover(eng: Engine, p: float, v: float, h: float, ain: float, rtol: float, atol: float,
          h_try: float, stats: GuardStats, tableau: Tableau | None = None,
          max_trials: int = 0,
          steps: tuple[ErrStepFn, ErrStepFn] | None = None) -> tuple[float, float, float, float]:
    """Advance (φ, φ') by h with error-controlled substeps; return (φ₁, φ'₁, w, next trial).

    ``tableau`` is the embedded pair (default: the engine's method); every trial after the
    first counts as a substep in ``stats``; with ``max_trials`` > 0, :class:`TooManySubsteps`
    is raised once that many trials did not cover h. ``steps`` are the pair's compiled steps
    (:func:`pair_steps`) where the caller keeps them.
    """
    tab = eng.method.tableau if tableau is None else tableau
    trials = 0
    plain, branch = pair_steps(tab, eng.n) if steps is None else steps
    w2, g, n = eng.w2, eng.gamma, eng.n
    q = 1.0 / (tab.error_order + 1)
    done, w_total = 0.0, 0.0
    hh = h_try if h_try > 0.0 else h * 0.1
    while done < h:
        if eng.coulomb and v == 0.0:
            p, v, w = eng.from_rest(p, h - done, ain)
            w_total += w
            break
        trials += 1
        if trials > 1:
            stats.substeps += 1
        if max_trials and trials > max_trials:
            raise TooManySubsteps(f'{max_trials} trial substeps did not cover h = {h:g} s')
        last = hh >= h - done
        step_h = h - done if last else hh
        sign = 1.0 if v > 0.0 else -1.0
        fn = branch if (eng.nonsmooth and v != 0.0) else plain
        try:
            p1, v1, w, a0, ep, ev = fn(p, v, step_h, ain, w2, g, sign)
            sp = atol + rtol * max(abs(p), abs(p1))
            sv = atol + rtol * max(abs(v), abs(v1))
            err = math.sqrt(0.5 * ((ep / sp) ** 2 + (ev / sv) ** 2))
        except (OverflowError, ValueError):
            err = math.inf  # a trial step that overflows is rejected like any other
        if err <= 1.0 and math.isfinite(err):
            if eng.nonsmooth and v1 * v < 0.0:
                # Cut at the reversal: the branch continuation's φ'(θ step_h) = 0.
                def accel(pp: float, vv: float, sg: float = sign) -> float:
                    return float(ain - sg * g * abs(vv) ** n - w2 * math.sin(pp))

                th = hermite_root(v, v1, step_h * a0, step_h * accel(p1, v1))
                for _ in range(8):
                    pm, vm, wm, _, _, _ = fn(p, v, th * step_h, ain, w2, g, sign)
                    acc = accel(pm, vm)
                    if abs(vm) <= 1e-15 * abs(v) or acc == 0.0:
                        break
                    nth = th - vm / (acc * step_h)
                    if not 0.0 < nth <= 1.0:
                        break
                    th = nth
                stats.reversals += 1
                p, v = pm, 0.0
                w_total += wm
                done += th * step_h
                hh = max(th * step_h, 1e-6 * h)
                if eng.coulomb:
                    continue
                # Leave rest on the side the forces push to (a kink: the pair restarts small).
                continue
            if eng.coulomb and (v1 < 0.0 < v or v < 0.0 < v1) and abs(
                    ain - w2 * math.sin(p1)) <= g:
                v1 = 0.0
            done = h if last else done + step_h
            p, v = p1, v1
            w_total += w
            factor = 5.0 if err == 0.0 else min(5.0, 0.9 * err ** -q)
            hh = step_h * factor if not last else max(hh, step_h * factor)
        else:
            factor = 0.2 if not math.isfinite(err) else max(0.2, 0.9 * err ** -q)
            hh = step_h * factor
            if hh < 1e-14 * max(1.0, h):
                raise IntegratorError(f'adaptive step fell below {hh:.3g} s')
    return p, v, w_total, hh


class Cover:
    """The embedded adaptive method as an ``Advance``: :func:`cover` with its trial-step memory.

    Parameters
    ----------
    eng : Engine
        The pendulum and method (an embedded pair, e.g. ``dopri5``).
    rtol, atol : float
        Tolerances of the error control.
    """

    def __init__(self, eng: Engine, rtol: float, atol: float) -> None:
        self.eng, self.rtol, self.atol = eng, rtol, atol
        self.h_try = 0.0  # the next trial substep, carried from step to step
        self.steps = pair_steps(eng.method.tableau, eng.n)

    def __call__(self, p: float, v: float, h: float, ain: float,
                 stats: GuardStats) -> tuple[float, float, float]:
        """Cover one step of h; a non-finite result is replaced by the fallback's."""
        p1, v1, w, self.h_try = cover(self.eng, p, v, h, ain, self.rtol, self.atol, self.h_try,
                                      stats, steps=self.steps)
        if not (math.isfinite(p1) and math.isfinite(v1)):
            stats.fallbacks += 1
            return self.eng.last_resort(p, v, h, ain)
        return p1, v1, w
