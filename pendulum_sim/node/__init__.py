"""The ROS 2 adapter: ``pendulum_node`` serves the core's pendulum as a real-time joint.

Everything ROS lives here; the physics stays in :mod:`pendulum_sim.core` and the node only drives
a :class:`~pendulum_sim.core.Stepper` and fills messages.
"""
