"""The texts the node's services answer with: ``~/reset``, ``~/pause``, ``~/step``."""
from __future__ import annotations

from collections.abc import Mapping

from .joint import SimulatedJoint


def reset_reply(values: Mapping[str, object], t: float, was_failed: str | None) -> str:
    """Return the ``~/reset`` answer: the state reset to and the time it happened at."""
    return (f'reset to phi = {values["phi0"]} rad, dphi = {values["dphi0"]} rad/s at '
            f't = {t:.9g} s (simulated time goes on)'
            + (f' (was stopped: {was_failed})' if was_failed else ''))


def pause_reply(paused: bool, changed: bool, t: float) -> str:
    """Return the ``~/pause`` answer: paused or resumed at ``t``, or already so."""
    if changed:
        return f'{"paused" if paused else "resumed"} at t = {t:.9g} s'
    return f'already {"paused" if paused else "running"} at t = {t:.9g} s'


def step_reply(joint: SimulatedJoint, budget: int, count: int) -> str:
    """Return the ``~/step`` answer for ``count`` more periods after a budget of ``budget``
    (call before the periods are taken): the period length and the time they end at."""
    k = joint.config.period_steps
    h = joint.config.h
    target = (joint.steps // k + budget + count) * k
    return f'stepping {count} control period(s) of {k * h:g} s to t = {target * h:.9g} s'
