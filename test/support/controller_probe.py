"""The example controller ``pendulum_pd_controller`` in its own process, for tests over DDS."""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from node_harness import NodeProcess
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

NAME = 'pendulum_pd_controller'
RELIABLE = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)


def controller_command() -> list[str]:
    """Return the command that starts the controller: the venv's entry point if installed."""
    script = Path(sys.executable).parent / NAME
    if script.is_file():
        return [str(script)]
    return [sys.executable, '-m', 'pendulum_sim.controller.pd_controller']


class Controller(NodeProcess):
    """The controller in its own process (NodeProcess's start/stop/output, another command)."""

    def __init__(self, params: dict[str, Any] | None = None, args: list[str] | None = None,
                 namespace: str | None = None) -> None:
        super().__init__(scene=None, params=params, namespace=namespace)
        self.cmd = controller_command() + list(args or []) + self.cmd[self.cmd.index(
            '--ros-args'):]
        self.fqn = f'{self.namespace}/{NAME}'
