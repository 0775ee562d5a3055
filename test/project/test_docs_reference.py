"""The generated reference tables hold every parameter, diagnostics key, scene and option.

The tables are written by ``docs/_ext/reftables.py`` from the code's own data. These tests read
the tables back as a reader would (the Markdown rows) and hold them against the code and
against a running ``pendulum_node``: the parameters it declares over DDS (with their
descriptors) and the ``/diagnostics`` keys it publishes.
"""
from __future__ import annotations

import math
import re
import sys
from pathlib import Path

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from foxglove_client import free_port
from node_harness import NodeProcess, Probe
from rcl_interfaces.srv import DescribeParameters, ListParameters
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray

from pendulum_sim.joint.parameters import SPECS
from pendulum_sim.joint.scenes import ROS_PARAMETERS, read_params_file
from pendulum_sim.node.declare import descriptor
from pendulum_sim.node.diagnostics import KEYS, declared, values_of

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / 'docs' / '_ext'))
import reftables  # noqa: E402 - the docs' generator lives with the docs

DASH = reftables.DASH


def rows(markdown: str) -> dict[str, list[str]]:
    """Return the body rows of the Markdown tables in ``markdown``, by their first cell."""
    out: dict[str, list[str]] = {}
    for line in markdown.splitlines():
        if not line.startswith('| ') or line.startswith('|---'):
            continue
        cells = [c.strip() for c in re.split(r'(?<!\\)\|', line)[1:-1]]
        key = cells[0].strip('`')
        if key not in ('name', 'key', 'option', 'scene', 'parameter'):
            out[key] = cells
    return out


def plain(text: str) -> str:
    return text.strip('`').replace('\\|', '|')


def expected_default(value: object) -> str:
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float) and math.isinf(value):
        return '.inf' if value > 0 else '-.inf'
    return f"'{value}'" if isinstance(value, str) else repr(value)


def test_every_parameter_has_default_type_unit_range_and_live() -> None:
    table = rows(reftables.parameters_markdown())
    assert set(table) == {s.name for s in SPECS}
    missing_units = [s.name for s in SPECS
                     if not isinstance(s.default, (bool, str)) and not s.unit]
    assert missing_units == [], f'numeric parameters without a unit: {missing_units}'
    for spec in SPECS:
        _name, default, kind, unit, allowed, live, meaning = table[spec.name]
        assert plain(default) == expected_default(spec.default), spec.name
        assert kind == {bool: 'bool', int: 'integer', float: 'double', str: 'string'}[
            type(spec.default)], spec.name
        assert unit == (spec.unit or DASH), spec.name
        desc = descriptor(spec)
        bounds = [*desc.floating_point_range, *desc.integer_range]
        if bounds:
            low, high = (float(x) for x in allowed.strip('[]').split(','))
            assert (low, high) == (bounds[0].from_value, bounds[0].to_value), spec.name
        elif desc.additional_constraints:
            assert allowed == desc.additional_constraints, spec.name
        else:
            assert allowed == 'any', spec.name
        assert live == ('read-only' if desc.read_only else 'live'), spec.name
        assert plain(meaning) == spec.description, spec.name


def test_every_diagnostics_key_has_type_unit_and_meaning() -> None:
    table = rows(reftables.diagnostics_markdown())
    assert list(table) == [k.name for k in KEYS]
    for key in KEYS:
        _name, kind, unit, when, meaning = table[key.name]
        assert (kind, unit, when) == (key.type, key.unit or DASH, key.when), key.name
        assert plain(meaning) == key.description and meaning != DASH, key.name
        assert kind in ('int', 'float', 'bool'), key.name


def test_diagnostics_families_match_their_members_only() -> None:
    assert declared('guard_substeps') is not None
    family = declared('commands_dropped[/a/commands: length 2, expected 1]')
    assert family is not None and family.name == 'commands_dropped[<topic>: <reason>]'
    assert declared('incompatible_qos[/a/effort_command]') is not None
    assert declared('commands_dropped[]') is None
    assert declared('sim_time_x') is None


def test_every_scene_is_listed_with_every_parameter_it_sets() -> None:
    text = reftables.scenes_markdown()
    scenes = sorted((ROOT / 'config').glob('*.yaml'))
    assert scenes
    for path in scenes:
        section = text.split(f'## `{path.stem}`', 1)[1].split('\n## ', 1)[0]
        table = rows(section)
        values = read_params_file(path)
        assert set(table) == set(values), path.name
        for name, value in values.items():
            assert plain(table[name][1]) == expected_default(value), (path.name, name)


def test_every_console_script_and_option_is_listed() -> None:
    text = reftables.cli_markdown()
    scripts = reftables.console_scripts()
    assert {name for name, _ in scripts} >= {'pendulum_node', 'pendulum_pd_controller',
                                             'pendulum_replay', 'pendulum_report',
                                             'pendulum_demo'}
    for name, target in scripts:
        section = text.split(f'## `{name}`', 1)[1].split('\n## ', 1)[0]
        parser = reftables.parser_of(target)
        assert parser.prog.split()[0] == name
        for action in parser._actions:
            for flag in action.option_strings:
                if flag not in ('-h', '--help'):
                    assert re.search(rf'`{re.escape(flag)}[ ,`]', section), (name, flag)


@pytest.mark.ros
@pytest.mark.slow
def test_the_running_node_declares_and_publishes_what_the_reference_lists() -> None:
    """Parameters over DDS and every /diagnostics key, families included, are in the tables."""
    params = {'lockstep': True, 'synchronous': True, 'sync_timeout': 0.02,
              'publish_rate': 100.0, 'array_command_input': True, 'foxglove_port': free_port()}
    table = rows(reftables.parameters_markdown())
    with NodeProcess('default', params) as node, Probe() as probe:
        ns = node.namespace
        states = probe.subscribe(JointState, f'{ns}/joint_states')
        diags = probe.subscribe(DiagnosticArray, '/diagnostics')
        reliable = probe.node.create_publisher(Float64, f'{ns}/effort_command', 10)
        array = probe.node.create_publisher(Float64MultiArray, f'{ns}/commands', 10)
        best_effort = probe.node.create_publisher(
            Float64, f'{ns}/effort_command',
            QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT))
        probe.spin_until(lambda: len(states) >= 3 and array.get_subscription_count() > 0,
                         30.0, 'joint_states and the commands subscription')
        array.publish(Float64MultiArray(data=[1.0, 2.0]))   # dropped: length 2
        reliable.publish(Float64(data=0.1))
        seen: dict[str, str] = {}

        def all_seen() -> bool:
            for msg in diags.msgs:
                if msg.status and msg.status[0].name.startswith(node.fqn):
                    seen.update(values_of(msg))
            return (any(k.startswith('commands_dropped[') for k in seen)
                    and any(k.startswith('incompatible_qos[') for k in seen))

        probe.spin_until(all_seen, 30.0, 'diagnostics with every family of keys')
        names = probe.call(ListParameters, f'{node.fqn}/list_parameters',
                           ListParameters.Request()).result.names
        own = sorted(n for n in names
                     if n not in ROS_PARAMETERS and not n.startswith('qos_overrides.'))
        described = probe.call(DescribeParameters, f'{node.fqn}/describe_parameters',
                               DescribeParameters.Request(names=own)).descriptors
        best_effort.destroy()
    assert set(own) == set(table)
    for desc in described:
        assert table[desc.name][5] == ('read-only' if desc.read_only else 'live'), desc.name
        bounds = [*desc.floating_point_range, *desc.integer_range]
        if bounds:
            low, high = (float(x) for x in table[desc.name][4].strip('[]').split(','))
            assert (low, high) == (bounds[0].from_value, bounds[0].to_value), desc.name
    undeclared = sorted(k for k in seen if declared(k) is None)
    assert undeclared == [], f'/diagnostics keys missing from diagnostics.KEYS: {undeclared}'
    present = {declared(k).name for k in seen}  # type: ignore[union-attr]
    assert present == {k.name for k in KEYS}
