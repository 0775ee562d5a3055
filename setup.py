"""Install pendulum_sim as a ROS 2 ament_python package or with pip into a plain venv."""
import os
from glob import glob

from setuptools import find_packages, setup

package_name = 'pendulum_sim'

# Pinned ROS 2 Jazzy wheels from the package index, for machines without a ROS install.
# In a colcon workspace these come from the ROS installation instead (package.xml).
ROS_WHEELS = [
    'ros-jazzy-rclpy==7.1.6',
    'ros-jazzy-common-interfaces==5.3.6',
    'ros-jazzy-rmw-fastrtps-cpp==8.4.3',
]

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*', 'bench']),
    package_data={package_name: ['py.typed', 'foxglove_layout.json',
                                 'testing/swing_up/references.yaml']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        (os.path.join('share', package_name, 'config'),
         [*sorted(glob('config/*.yaml')), 'config/fastdds_localhost.xml']),
        (os.path.join('share', package_name, 'urdf'), sorted(glob('urdf/*.urdf'))),
    ],
    python_requires='>=3.10',
    install_requires=['setuptools', 'numpy>=1.24', 'pyyaml>=6', 'mcap>=1.2'],
    extras_require={
        'ros': ROS_WHEELS,
        'plots': ['matplotlib>=3.7'],
        'peers': ['scipy>=1.10', 'mujoco>=3.2', 'pybullet>=3.2', 'pin>=4.1', 'drake>=1.51'],
        'jit': ['numba>=0.59'],
        # Gymnasium environments of the joint (pendulum_sim.gym).
        'gym': ['gymnasium>=1.0'],
        'docs': ['sphinx>=8', 'myst-parser>=4'],
        # The live view (node parameter foxglove_port): a foxglove.websocket server.
        'foxglove': ['foxglove-sdk>=0.30'],
        'test': [
            'pytest>=8', 'wheel>=0.40', 'ruff>=0.6', 'mypy>=1.10', 'scipy>=1.10',
            'mcap-ros2-support>=0.5',
            'mujoco>=3.2', 'pin>=4.1', 'drake>=1.51', 'urdf_parser_py>=0.0.4', 'types-PyYAML>=6',
            'colcon-core>=0.17', 'colcon-ros>=0.5', 'colcon-python-setup-py>=0.2',
            # The test bench's peers and campaigns: python-control checks step_metrics.
            'control>=0.10', 'dask[distributed]>=2024.1', 'pyarrow>=14',
            # Property tests of the fast path's sound pre-tests.
            'hypothesis>=6.100',
            # The Gymnasium environments, their checker and Pendulum-v1 (the benchmark's peer).
            'gymnasium>=1.0',
            # The live view and a plain client of its protocol.
            'foxglove-sdk>=0.30', 'websockets>=13',
        ],
        'identify': ['scipy>=1.10', 'matplotlib>=3.7'],
        'campaign': ['dask[distributed]>=2024.1', 'pyarrow>=14', 'matplotlib>=3.7'],
        # pendulum_benchmark: campaigns, figures, the GIF (Pillow comes with matplotlib) and
        # the reference controllers' LQR gain from python-control.
        'benchmark': ['dask[distributed]>=2024.1', 'pyarrow>=14', 'matplotlib>=3.7',
                      'control>=0.10'],
    },
    zip_safe=True,
    maintainer='pendulum_sim developers',
    maintainer_email='pendulum-sim@example.com',
    description='Damped physical pendulum with power-law damping as a ROS 2 simulated joint.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'pendulum_node = pendulum_sim.node.cli:entry',
            'pendulum_pd_controller = pendulum_sim.controller.pd_controller:entry',
            'pendulum_swing_up_controller = pendulum_sim.controller.swing_up_controller:entry',
            'pendulum_replay = pendulum_sim.recording.replay:main',
            'pendulum_report = pendulum_sim.reports.cli:main',
            'pendulum_demo = pendulum_sim.demo:main',
            'pendulum_campaign = pendulum_sim.testing.campaign.cli:main',
            'pendulum_identify = pendulum_sim.identify.cli:main',
            'pendulum_twin = pendulum_sim.testing.twin_cli:main',
            'pendulum_benchmark = pendulum_sim.testing.swing_up.cli:main',
        ],
        'pytest11': ['pendulum_sim = pendulum_sim.testing.pytest_plugin'],
        # Gymnasium's plugin group before 1.0 (1.x registers on `import pendulum_sim.gym`).
        'gymnasium.envs': ['pendulum_sim = pendulum_sim.gym:register_envs'],
    },
)
