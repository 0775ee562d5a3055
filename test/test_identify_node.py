"""Done when: pendulum_identify on a recording made by pendulum_node recovers the scene's law.

The node runs the free_swing scene in its own process over real DDS and records itself
(``-p recording.path:=...``); pendulum_identify, another process, fits the file.
"""
from __future__ import annotations

import csv
import math
import subprocess
import sys
from pathlib import Path

from node_harness import NodeProcess, Probe, stamp_ns
from sensor_msgs.msg import JointState

from pendulum_sim.node.scenes import find_scene, read_params_file

SCRIPT = Path(sys.executable).parent / 'pendulum_identify'
SECONDS = 12.0


def test_pendulum_identify_recovers_the_scene_of_a_node_recording(tmp_path: Path) -> None:
    scene = read_params_file(find_scene('free_swing'))
    path = tmp_path / 'swing.mcap'
    with NodeProcess('free_swing', {'recording.path': str(path), 'status_line': False}) as node, \
            Probe() as probe:
        states = probe.subscribe(JointState, f'{node.namespace}/joint_states')
        probe.spin_until(lambda: len(states) > 0 and stamp_ns(states.msgs[-1]) >= SECONDS * 1e9,
                         120.0, f'{SECONDS} s of simulated time')
        assert node.stop() == 0, node.output()
    out = tmp_path / 'fit'
    res = subprocess.run([str(SCRIPT), str(path), '--out', str(out), '--models',
                          'viscous,quadratic,power', '--no-jit', '--no-progress'],
                         capture_output=True, text=True, timeout=600, check=False)
    assert res.returncode == 0, res.stderr
    with (out / 'models.csv').open() as fh:
        rows = {r['model']: r for r in csv.DictReader(fh)}
    assert next(iter(rows)) == 'quadratic'   # ranked first by BIC

    def inside(model: str, name: str, truth: float) -> bool:
        r = rows[model]
        return float(r[f'{name}_ci95_low']) <= truth <= float(r[f'{name}_ci95_high'])

    omega0 = math.sqrt(0.2 * 9.8 * 1.0 / 0.2)   # the node's m, g, l and inertia
    for model in ('quadratic', 'power'):
        assert inside(model, 'omega0', omega0), rows[model]
        assert inside(model, 'gamma', scene['gamma']), rows[model]
    assert inside('power', 'n', scene['n']), rows['power']
