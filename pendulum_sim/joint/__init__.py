"""The simulated joint, ROS-free: what ``pendulum_node``, the test bench, Gymnasium and the
identification all drive.

The joint's configuration and parameter table (``parameters``), :class:`SimulatedJoint`
(``joint``), its servo and sensors, commands, the synchronous exchange and the drivers that
pace it, telemetry and the status line, URDF, scenes and the Foxglove view. It imports the
core and never rclpy; :mod:`pendulum_sim.node` wires it to ROS.
"""
from __future__ import annotations

from .errors import JointError, LiveError, ParameterError, SceneError
from .exchange import Gate, StepError, SyncExchange
from .joint import INTERFACES, JointConfig, Sample, SimulatedJoint
from .parameters import SPEC_BY_NAME, SPECS, check, joint_config
from .sensors import SensorModel
from .servo import Servo, ServoGains

__all__ = ['INTERFACES', 'SPECS', 'SPEC_BY_NAME', 'Gate', 'JointConfig', 'JointError',
           'LiveError', 'ParameterError', 'Sample', 'SceneError', 'SensorModel', 'Servo',
           'ServoGains', 'SimulatedJoint', 'StepError', 'SyncExchange', 'check', 'joint_config']
