"""pendulum_sim: a damped physical pendulum with power-law damping, as a ROS 2 simulated joint."""

__version__ = '0.1.0'
