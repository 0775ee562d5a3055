"""The simulated joint every ROS-free joint test starts from."""
from __future__ import annotations

from pendulum_sim.core import PendulumParams
from pendulum_sim.joint.joint import JointConfig, SimulatedJoint

PARAMS = PendulumParams(m=0.2, l=1.0, inertia=0.2, g=9.8, gamma=0.1, n=1.0)
H = 1e-3


def joint(**changes: object) -> SimulatedJoint:
    base: dict[str, object] = {'params': PARAMS, 'h': H, 'phi0': 0.3, 'max_effort': 5.0}
    base.update(changes)
    return SimulatedJoint(JointConfig(**base))  # type: ignore[arg-type]
