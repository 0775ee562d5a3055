"""Print how the joint's drive tracks velocity and position commands; draw the responses.

The joint is the node's own ``SimulatedJoint`` (no ROS) on the default scene's body, under
gravity, with the default servo gains, from the scene's start state (φ0 = 0.3 rad at rest):

- velocity: a 1 rad/s command at t = 0; the worst relative speed error from t = 1 s on, the
  settling time into 1 %, the peak torque;
- position: steps to 1.0, -0.5 and 2.5 rad; the worst error from t = 2 s on, the settling
  time into 1e-3 rad, the overshoot, the peak torque.

Targets (issue 17): velocity within 1 % after 1 s; position within 1e-3 rad. The figures are
computed, not timed: they are the same on every machine. ``test/bench/test_bench_servo.py`` asserts
the same thresholds on :func:`track`.

    .venv/bin/python bench/bench_servo.py --png servo.png
"""
from __future__ import annotations

import argparse
import math
from dataclasses import dataclass, field
from pathlib import Path

from pendulum_sim.core import PendulumParams
from pendulum_sim.joint.joint import JointConfig, SimulatedJoint
from pendulum_sim.joint.scenes import find_scene, read_params_file

VELOCITY_AFTER = 1.0      # s: from here on the speed must be within 1 %
POSITION_AFTER = 2.0      # s: from here on the angle must be within 1e-3 rad
POSITION_TARGETS = (1.0, -0.5, 2.5)


@dataclass
class Response:
    """One command's response: what was commanded and (t, φ, φ', τ) after every step."""

    interface: str
    target: float
    t: list[float] = field(default_factory=list)
    phi: list[float] = field(default_factory=list)
    dphi: list[float] = field(default_factory=list)
    tau: list[float] = field(default_factory=list)

    def worst_after(self, t0: float) -> float:
        """Return the largest tracking error from ``t0`` on (rad/s or rad)."""
        got = self.dphi if self.interface == 'velocity' else self.phi
        return max(abs(x - self.target) for t, x in zip(self.t, got, strict=True)
                   if t >= t0 - 1e-12)

    def settling_time(self, band: float) -> float:
        """Return the first time after which the error stays within ``band``."""
        got = self.dphi if self.interface == 'velocity' else self.phi
        last_out = 0.0
        for t, x in zip(self.t, got, strict=True):
            if abs(x - self.target) > band:
                last_out = t
        return last_out

    def overshoot(self, start: float) -> float:
        """Return how far the angle went past the target, rad (0 if it never did)."""
        direction = math.copysign(1.0, self.target - start)
        return max(0.0, max((p - self.target) * direction for p in self.phi))


def default_body() -> tuple[PendulumParams, dict[str, object]]:
    """Return the default scene's body and its parameter values."""
    values = read_params_file(find_scene('default'))
    params = PendulumParams(**{k: float(values[k])
                               for k in ('m', 'l', 'inertia', 'g', 'gamma', 'n')})
    return params, values


def respond(interface: str, target: float, seconds: float = 4.0) -> Response:
    """Command ``target`` at t = 0 on the default body and record the response."""
    params, values = default_body()
    h = float(values['h'])  # type: ignore[arg-type]
    joint = SimulatedJoint(JointConfig(
        params=params, h=h, phi0=float(values['phi0']),  # type: ignore[arg-type]
        max_effort=float(values['max_effort']),  # type: ignore[arg-type]
        command_interface=interface))
    joint.command(target)
    out = Response(interface, target)
    for _ in range(round(seconds / h)):
        joint.advance(1)
        st = joint.stepper
        out.t.append(joint.time)
        out.phi.append(st.phi)
        out.dphi.append(st.dphi)
        out.tau.append(joint.torque)
    return out


def track() -> dict[str, Response]:
    """Return the velocity response and each position step's response."""
    found = {'velocity 1.0': respond('velocity', 1.0)}
    for x in POSITION_TARGETS:
        found[f'position {x:g}'] = respond('position', x)
    return found


def draw(responses: dict[str, Response], path: Path) -> None:
    """Write the responses as a PNG: speed, angles and torques against time."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
    vel = responses['velocity 1.0']
    axes[0].plot(vel.t, vel.dphi, label="φ' (command 1 rad/s)")
    axes[0].axhspan(0.99, 1.01, color='0.85', label='±1 %')
    axes[0].axvline(VELOCITY_AFTER, color='0.5', ls=':')
    axes[0].set_ylabel("φ' / rad/s")
    axes[0].legend(loc='lower right')
    for i, (name, r) in enumerate(responses.items()):
        if r.interface == 'position':
            axes[1].plot(r.t, r.phi, color=f'C{i}', label=f'φ (command {r.target:g} rad)')
        axes[2].plot(r.t, r.tau, color=f'C{i}', label=name)
    axes[1].axvline(POSITION_AFTER, color='0.5', ls=':')
    axes[1].set_ylabel('φ / rad')
    axes[1].legend(loc='lower right')
    axes[2].set_ylabel('τ / N m')
    axes[2].set_xlabel('t / s')
    axes[2].legend(loc='upper right', fontsize='small')
    fig.suptitle('Drive of the default body under gravity (default servo gains)')
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main() -> None:
    """Print the tracking figures and write the PNG."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--png', type=Path, default=Path('servo_tracking.png'),
                        help='where to write the figure (default: servo_tracking.png)')
    args = parser.parse_args()
    _, values = default_body()
    phi0 = float(values['phi0'])  # type: ignore[arg-type]
    responses = track()
    vel = responses['velocity 1.0']
    worst = vel.worst_after(VELOCITY_AFTER)
    print(f"velocity 1 rad/s: worst error after {VELOCITY_AFTER:g} s {worst:.2e} rad/s "
          f"({100 * worst:.3f} %, target <= 1 %: {'met' if worst <= 0.01 else 'MISSED'}); "
          f'settles into 1 % at {vel.settling_time(0.01):.3f} s; peak torque '
          f'{max(map(abs, vel.tau)):.3f} N m')
    for name, r in responses.items():
        if r.interface != 'position':
            continue
        worst = r.worst_after(POSITION_AFTER)
        print(f'{name} rad: worst error after {POSITION_AFTER:g} s {worst:.2e} rad (target <= '
              f"1e-3: {'met' if worst <= 1e-3 else 'MISSED'}); settles into 1e-3 rad at "
              f'{r.settling_time(1e-3):.3f} s; overshoot {r.overshoot(phi0):.2e} rad; peak '
              f'torque {max(map(abs, r.tau)):.3f} N m')
    draw(responses, args.png)
    print(f'figure: {args.png}')


if __name__ == '__main__':
    main()
