"""The ROS 2 adapter: ``pendulum_node`` wires the simulated joint to ROS.

Only what imports rclpy or message types lives here: the node, its command line, parameter
declarations, QoS, diagnostics and serialized messages. The joint itself (configuration,
servo, sensors, the synchronous exchange, drivers, scenes, URDF, the Foxglove view) is the
ROS-free :mod:`pendulum_sim.joint`; its old names here still import, with a deprecation warning.
"""
from .moved import install

install()
