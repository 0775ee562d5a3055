"""The controller test bench: closed-loop runs, their verdict and picture, campaigns.

Importing this package imports neither rclpy nor matplotlib nor Dask: the in-process path
(a Python callable against the ROS-free simulated joint) needs none of them, and the names below
are imported on first use. The command-line path starts ``pendulum_node`` and the controller in
processes of their own.
"""
from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from pendulum_sim.testing.errors import CampaignError, ControllerFailed, TestingError
    from pendulum_sim.testing.loop import closed_loop
    from pendulum_sim.testing.metrics import StepMetrics, step_metrics
    from pendulum_sim.testing.run import ClosedLoopRun
    from pendulum_sim.testing.swing_up.benchmark import BenchmarkResult, benchmark
    from pendulum_sim.testing.swing_up.metrics import (
        SwingUpMetrics,
        swing_up_metrics,
        swing_up_metrics_batch,
    )
    from pendulum_sim.testing.twin_report import TwinReport, twin
    from pendulum_sim.testing.vector import vectorised

__all__ = ['BenchmarkResult', 'CampaignError', 'ClosedLoopRun', 'ControllerFailed',
           'StepMetrics', 'SwingUpMetrics', 'TestingError', 'TwinReport', 'benchmark',
           'closed_loop', 'step_metrics', 'swing_up_metrics', 'swing_up_metrics_batch', 'twin',
           'vectorised']

_WHERE = {'CampaignError': 'errors', 'ControllerFailed': 'errors', 'TestingError': 'errors',
          'ClosedLoopRun': 'run', 'closed_loop': 'loop', 'StepMetrics': 'metrics',
          'step_metrics': 'metrics', 'vectorised': 'vector', 'TwinReport': 'twin_report',
          'twin': 'twin_report',
          'SwingUpMetrics': 'swing_up.metrics', 'swing_up_metrics': 'swing_up.metrics',
          'swing_up_metrics_batch': 'swing_up.metrics', 'benchmark': 'swing_up.benchmark',
          'BenchmarkResult': 'swing_up.benchmark'}


def __getattr__(name: str) -> Any:
    if name not in _WHERE:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    return getattr(importlib.import_module(f'{__name__}.{_WHERE[name]}'), name)
