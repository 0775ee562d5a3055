"""Draw what a Foxglove client receives from the live view: docs/_static/foxglove_live.png.

This is not a screenshot of the Foxglove app (there is none on the build machine). A closed
loop runs with ``foxglove_port`` set; a plain ``foxglove.websocket`` client (test/support/
foxglove_client.py, on the ``websockets`` package) subscribes to the channels the shipped
layout shows, and matplotlib draws what arrived over the socket, panel by panel as the layout
arranges them: angle against the target, velocity, effort applied and commanded, the energy
terms, and the pendulum drawn from the ``/tf`` frames (the 3D panel's view, seen along the
joint axis).

    .venv/bin/python docs/_ext/live_figure.py docs/_static/foxglove_live.png
"""
from __future__ import annotations

import math
import sys
import threading
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / 'test' / 'support'))

import matplotlib  # noqa: E402

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
from foxglove_client import connect_when_up, free_port  # noqa: E402

from pendulum_sim.controller.pd_law import PDGains, pd_torque  # noqa: E402
from pendulum_sim.testing import closed_loop  # noqa: E402

PERIODS = 300
TOPICS = ('/joint_states', '/target', '/command', '/energy_terms', '/tf', '/physics',
          '/robot_description')


def receive(port: int, watched: threading.Event) -> list[tuple[str, int, Any]]:
    """Connect, subscribe to the layout's channels, return every message of the run."""
    with connect_when_up(port, 30.0) as client:
        client.subscribe(*TOPICS)
        client.messages(1, '/robot_description')   # the server has the subscriptions
        watched.set()
        return client.messages(PERIODS, '/joint_states')


def main() -> int:
    out = Path(sys.argv[1] if len(sys.argv) > 1 else ROOT / 'docs/_static/foxglove_live.png')
    port = free_port()
    gains = PDGains(kp=4.0, kd=1.0, target=0.5)
    watched = threading.Event()

    def law(t: float, x: float, v: float) -> float:
        watched.wait(30.0)
        return pd_torque(gains, x, v)

    runner = threading.Thread(target=lambda: closed_loop(
        law, periods=PERIODS, target=0.5, foxglove_port=port))
    runner.start()
    try:
        got = receive(port, watched)
    finally:
        watched.set()
        runner.join(60.0)
    series: dict[str, list[tuple[float, Any]]] = {}
    for topic, log_time, msg in got:
        series.setdefault(topic, []).append((log_time / 1e9, msg))

    def xy(topic: str, pick: Any) -> tuple[list[float], list[float]]:
        pts = [(t, pick(m)) for t, m in series.get(topic, [])]
        return [p[0] for p in pts], [p[1] for p in pts]

    fig = plt.figure(figsize=(12, 6.5), layout='constrained')
    grid = fig.add_gridspec(2, 3)
    # The layout's plot panels: (cell, title, [(topic, field of a message, line style)]).
    panels: list[tuple[Any, str, list[tuple[str, Any, dict[str, str]]]]] = [
        (grid[0, 0], 'angle against the target (rad)',
         [('/joint_states', lambda m: m['position'][0], {'label': 'angle'}),
          ('/target', lambda m: m['data'], {'linestyle': '--', 'label': 'target'})]),
        (grid[0, 1], 'angular velocity (rad/s)',
         [('/joint_states', lambda m: m['velocity'][0], {'color': 'C2'})]),
        (grid[1, 0], 'effort (N m)',
         [('/joint_states', lambda m: m['effort'][0], {'label': 'applied'}),
          ('/command', lambda m: m['commanded'], {'linestyle': '--', 'label': 'commanded'})]),
        (grid[1, 1], 'energy (J)',
         [('/energy_terms', lambda m, k=key: m[k], {'label': key})
          for key in ('kinetic', 'potential', 'dissipated', 'residual')]),
    ]
    for cell, title, lines in panels:
        ax = fig.add_subplot(cell)
        for topic, pick, style in lines:
            ax.plot(*xy(topic, pick), **style)
        ax.set(title=title, xlabel='t (s)')
        if any('label' in style for _, _, style in lines):
            ax.legend()
    ax = fig.add_subplot(grid[:, 2])
    frames = [m['transforms'][0] for _, m in series.get('/tf', [])]
    for i, frame in enumerate(frames[::30]):
        q = frame['rotation']
        phi = 2.0 * math.atan2(q['y'], q['w'])   # the turn about the joint's y axis
        x, z = -math.sin(phi), -math.cos(phi)    # the bob, 1 m below the pivot at phi = 0
        shade = 0.25 + 0.75 * i / max(1, len(frames[::30]) - 1)
        ax.plot([0, x], [0, z], color=(0, 0, 0, shade), lw=2)
        ax.plot(x, z, 'o', color=(0.8, 0.2, 0.2, shade), ms=12)
    ax.set(title='/tf base_link → pendulum_link\n(every 0.3 s, darker = later)',
           xlim=(-1.2, 1.2), ylim=(-1.3, 0.3), aspect='equal', xlabel='x (m)',
           ylabel='z (m)')
    fig.suptitle(f'Received over foxglove.websocket by a plain client: closed_loop(pd, '
                 f'target=0.5, foxglove_port=…), {len(got)} messages (not a Foxglove '
                 'screenshot)', fontsize=10)
    fig.savefig(out, dpi=90)
    print(out)
    return 0


if __name__ == '__main__':
    sys.exit(main())
