"""Declare the joint's parameters on a ROS node: the table's specs as ParameterDescriptors.

The table and its validation are ROS-free (:mod:`pendulum_sim.joint.parameters`); this module
is the one place that turns a :class:`~pendulum_sim.joint.parameters.Spec` into what rclpy
checks (type, range, read-only flag) before any parameter callback runs.
"""
from __future__ import annotations

from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

from pendulum_sim.joint.parameters import FIXED, SPECS, Spec, Value


def descriptor(spec: Spec) -> ParameterDescriptor:
    """Return the ParameterDescriptor declaring ``spec``."""
    text = spec.description + (f' {FIXED}' if spec.read_only and 'Read-only' not in
                               spec.description else '')
    desc = ParameterDescriptor(description=text, read_only=spec.read_only,
                               additional_constraints=spec.constraints)
    if spec.low is not None and spec.high is not None:
        if isinstance(spec.default, bool):
            raise TypeError(f'{spec.name}: a bool parameter has no range')
        if isinstance(spec.default, int):
            desc.integer_range = [IntegerRange(from_value=int(spec.low),
                                               to_value=int(spec.high), step=0)]
        else:
            desc.floating_point_range = [FloatingPointRange(from_value=spec.low,
                                                            to_value=spec.high, step=0.0)]
    return desc


def declare_all(node: Any) -> dict[str, Value]:
    """Declare every parameter on ``node`` and return the values it starts with."""
    node.declare_parameters('', [(s.name, s.default, descriptor(s)) for s in SPECS])
    return {s.name: node.get_parameter(s.name).value for s in SPECS}
