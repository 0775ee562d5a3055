"""The campaign file: YAML keys, their checks, and the parsed :class:`CampaignSpec`.

Keys: ``controller`` (``module:function`` or a command line as a list), ``scene``,
``episodes``, ``seed``, ``periods``, ``target``, ``parameters`` (node parameter names mapped to
a value, a list taken in episode order, or a distribution ``{distribution: uniform, low,
high}``, ``{distribution: normal, mean, std}``, ``{distribution: loguniform, low, high}``) and
``requirements`` (strings such as ``'settling_time < 3.0'``). ``target`` is a scenario
dimension read by the same rules as a parameter (a number, a list of numbers or a
distribution); when it varies, the controller must be able to receive it (a law with a keyword
``target``, or a command line with the placeholder ``{target}``). Every problem is a
:class:`~pendulum_sim.testing.errors.CampaignError` with a one-line reason.
"""
from __future__ import annotations

import importlib
import math
import operator
import re
import shutil
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from pendulum_sim.joint.errors import SceneError
from pendulum_sim.joint.scenes import find_scene, unknown_parameter

from ..errors import CampaignError
from ..metrics import METRIC_NAMES
from ..scene import FORCED
from ..target import PLACEHOLDER, has_placeholder, takes_target

KEYS = ('controller', 'scene', 'episodes', 'seed', 'periods', 'target', 'parameters',
        'requirements', 'episode_timeout', 'jit')
REQUIRED = ('controller', 'episodes', 'periods', 'target')
DISTRIBUTIONS: dict[str, tuple[str, ...]] = {'uniform': ('low', 'high'),
                                             'normal': ('mean', 'std'),
                                             'loguniform': ('low', 'high')}
OPERATORS: dict[str, Callable[[float, float], bool]] = {
    '<=': operator.le, '>=': operator.ge, '==': operator.eq, '!=': operator.ne,
    '<': operator.lt, '>': operator.gt}
MAX_EPISODES = 10_000_000
EPISODE_TIMEOUT = 60.0   # wall-clock s one episode may take, unless the file says
MAX_DEPTH = 32           # nesting of lists and mappings in a campaign file
MAX_NODES = 10_000       # values in a campaign file, its aliases expanded
SHOWN = 60               # characters of a value shown in a message
_REQUIREMENT = re.compile(r'^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(<=|>=|==|!=|<|>)\s*(\S+)\s*$')

Value = bool | int | float | str


def shown(value: Any) -> str:
    """Return ``repr(value)``, shortened to :data:`SHOWN` characters (for messages)."""
    text = repr(value)
    return text if len(text) <= SHOWN else text[:SHOWN - 3] + '...'


@dataclass(frozen=True)
class Requirement:
    """``metric op bound``: what every episode must meet."""

    metric: str
    op: str
    bound: float

    def check(self, value: float) -> str:
        """Return why ``value`` fails the requirement, or '' when it meets it."""
        if math.isnan(value):
            return f'{self.metric} is nan (not {self.op} {self.bound:g})'
        if OPERATORS[self.op](value, self.bound):
            return ''
        return f'{self.metric} = {value:.6g} (not {self.op} {self.bound:g})'

    def __str__(self) -> str:
        return f'{self.metric} {self.op} {self.bound:g}'


@dataclass(frozen=True)
class Distribution:
    """A seeded distribution of one parameter."""

    kind: str
    a: float
    b: float


Space = Value | tuple[Value, ...] | Distribution
TargetSpace = float | tuple[float, ...] | Distribution


@dataclass(frozen=True)
class CampaignSpec:
    """A checked campaign file."""

    controller: str | tuple[str, ...]
    scene: str
    episodes: int
    seed: int
    periods: int
    target: TargetSpace
    parameters: tuple[tuple[str, Space], ...]
    requirements: tuple[Requirement, ...]
    text: str
    episode_timeout: float = EPISODE_TIMEOUT
    jit: bool = False   # a vectorised law's batches on the compiled sweep (numba)

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """Return the scenario parameters, in file order (the table's columns)."""
        return tuple(name for name, _ in self.parameters)

    @property
    def scenario_names(self) -> tuple[str, ...]:
        """Return the table's scenario columns: the parameters in file order, then ``target``."""
        return (*self.parameter_names, 'target')

    @property
    def is_command_line(self) -> bool:
        """Return True when the controller is a command line (ROS episodes)."""
        return isinstance(self.controller, tuple)


def _number(where: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise CampaignError(f'{where} must be a number, got {shown(value)}')
    if not math.isfinite(value):
        raise CampaignError(f'{where} must be finite, got {shown(value)}')
    return float(value)


def _integer(where: str, value: Any, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise CampaignError(f'{where} must be an integer in [{low}, {high}], got {shown(value)}')
    return value


def load_controller(name: str) -> Callable[..., Any]:
    """Return the callable ``module:function`` names; CampaignError if it cannot be imported."""
    module, _, attr = name.partition(':')
    if not module or not attr:
        raise CampaignError(f"controller must be 'module:function' or a command line (a "
                            f'list), got {shown(name)}')
    try:
        obj: Any = importlib.import_module(module)
        for part in attr.split('.'):
            obj = getattr(obj, part)
    except Exception as exc:
        raise CampaignError(f'controller {shown(name)} cannot be imported: '
                            f'{type(exc).__name__}: {exc}') from None
    if not callable(obj):
        raise CampaignError(f'controller {shown(name)} is not callable')
    return obj  # type: ignore[no-any-return]


def _controller(value: Any) -> str | tuple[str, ...]:
    if isinstance(value, str):
        load_controller(value)
        return value
    if isinstance(value, list) and value and all(isinstance(a, str) for a in value):
        if shutil.which(value[0]) is None and not Path(value[0]).is_file():
            raise CampaignError(f'controller command {shown(value[0])} cannot be started: no such '
                                'executable')
        return tuple(value)
    raise CampaignError(f"controller must be 'module:function' or a command line (a list of "
                        f'strings), got {shown(value)}')


def varies(space: Space) -> bool:
    """Return True when ``space`` can give episodes different values."""
    return isinstance(space, Distribution) or (isinstance(space, tuple) and len(set(space)) > 1)


def describe(space: Space) -> str:
    """Return ``space`` as a short text (for summaries)."""
    if isinstance(space, Distribution):
        a, b = DISTRIBUTIONS[space.kind]
        return f'{space.kind}({a} = {space.a:g}, {b} = {space.b:g})'
    if isinstance(space, tuple):
        return '[' + ', '.join(f'{v:g}' if isinstance(v, float) else str(v) for v in space) + ']'
    return f'{space:g}' if isinstance(space, float) else str(space)


def _space(where: str, value: Any) -> Space:
    """Return the space of a scenario dimension: a value, a list or a distribution."""
    if isinstance(value, dict):
        kind = value.get('distribution')
        if kind not in DISTRIBUTIONS:
            raise CampaignError(f"{where}: distribution must be one of "
                                f"{', '.join(DISTRIBUTIONS)}, got {shown(kind)}")
        keys = DISTRIBUTIONS[kind]
        extra = sorted(set(value) - {'distribution', *keys})
        missing = [k for k in keys if k not in value]
        if extra or missing:
            raise CampaignError(f'{where}: a {kind} distribution takes {", ".join(keys)}, got '
                                f'{", ".join(k for k in value if k != "distribution")}')
        a, b = (_number(f'{where}.{k}', value[k]) for k in keys)
        if not math.isfinite(b - a):
            raise CampaignError(f'{where}: {kind} needs {keys[1]} - {keys[0]} finite, got '
                                f'{keys[0]} = {a:g}, {keys[1]} = {b:g}')
        if kind == 'normal' and b < 0:
            raise CampaignError(f'{where}: normal needs std >= 0, got std = {b:g}')
        if kind != 'normal' and not a < b:
            raise CampaignError(f'{where}: {kind} needs low < high, got low = {a:g}, '
                                f'high = {b:g}')
        if kind == 'loguniform' and a <= 0:
            raise CampaignError(f'{where}: loguniform needs low > 0, got low = {a:g}')
        return Distribution(kind, a, b)
    if isinstance(value, list):
        if not value:
            raise CampaignError(f'{where}: a list of values must not be empty')
        return tuple(_fixed(where, v) for v in value)
    return _fixed(where, value)


def _fixed(where: str, value: Any) -> Value:
    if isinstance(value, (bool, int, float, str)):
        if isinstance(value, float) and math.isnan(value):
            raise CampaignError(f'{where} must not be nan')
        return value
    raise CampaignError(f'{where} must be a value, a list or a distribution, got {shown(value)}')


def _target(value: Any) -> TargetSpace:
    """Return the target's space: as a parameter's, with numbers only."""
    space = _space('target', value)
    if isinstance(space, tuple):
        return tuple(_number('target', v) for v in space)
    if isinstance(space, Distribution):
        return space
    return _number('target', space)


def _receives_target(controller: str | tuple[str, ...], target: TargetSpace) -> None:
    """Refuse a target that varies per episode when the controller cannot be given it."""
    if not varies(target):
        return
    if isinstance(controller, tuple):
        if not has_placeholder(controller):
            raise CampaignError(f'target varies per episode but the controller command line '
                                f'has no {PLACEHOLDER} placeholder to receive it (e.g. '
                                f"'-p', 'target:={PLACEHOLDER}')")
    elif not takes_target(load_controller(controller)):
        raise CampaignError(f'target varies per episode but controller {shown(controller)} takes '
                            'no keyword argument target to receive it')


def _requirement(text: Any) -> Requirement:
    if not isinstance(text, str):
        raise CampaignError(f"a requirement must be a string like 'settling_time < 3.0', got "
                            f'{shown(text)}')
    found = _REQUIREMENT.match(text)
    if found is None:
        raise CampaignError(f"requirement {shown(text)} must read 'metric op number' with op one "
                            f'of <, <=, >, >=, ==, !=')
    metric, op, bound = found.groups()
    if metric not in METRIC_NAMES:
        raise CampaignError(f'requirement {shown(text)} names an unknown metric {shown(metric)}; '
                            f'metrics: {", ".join(METRIC_NAMES)}')
    try:
        value = float(bound)
    except ValueError:
        raise CampaignError(f'requirement {shown(text)}: {shown(bound)} is not a number') from None
    if math.isnan(value):
        raise CampaignError(f'requirement {shown(text)}: the bound must be a number, got nan')
    return Requirement(metric, op, value)


def load_yaml(text: str, label: str) -> Any:
    """Return the YAML ``text`` as Python values, refusing what a campaign file never needs.

    Refused, each with a one-line reason: invalid YAML; lists and mappings nested deeper than
    :data:`MAX_DEPTH`; more than :data:`MAX_NODES` values once anchors and aliases are
    expanded (a "billion laughs" file); a key given twice in one mapping (as rosbag2 and ROS
    parameter files refuse it).
    """
    try:
        depth = 0
        for event in yaml.parse(text, Loader=yaml.SafeLoader):
            if isinstance(event, (yaml.SequenceStartEvent, yaml.MappingStartEvent)):
                depth += 1
                if depth > MAX_DEPTH:
                    line = '' if event.start_mark is None else (
                        f' (line {event.start_mark.line + 1})')
                    raise CampaignError(f'{label}: lists and mappings are nested more than '
                                        f'{MAX_DEPTH} deep{line}')
            elif isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
                depth -= 1
        loader = yaml.SafeLoader(text)
        try:
            node = loader.get_single_node()
            if node is None:
                return None
            _check_nodes(node, label)
            return loader.construct_document(node)
        finally:
            loader.dispose()
    except yaml.YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None)
        at = f' at line {mark.line + 1}' if mark is not None else ''
        raise CampaignError(f'{label} is not valid YAML{at}') from None


def _check_nodes(root: yaml.Node, label: str) -> None:
    """Refuse a duplicated key, or more than MAX_NODES values with the aliases expanded."""
    sizes: dict[int, int] = {}
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        node, children_done = stack.pop()
        if id(node) in sizes:
            continue
        if isinstance(node, yaml.ScalarNode):
            sizes[id(node)] = 1
            continue
        pairs = node.value if isinstance(node, yaml.MappingNode) else [(v, None) for v in
                                                                       node.value]
        kids = [n for pair in pairs for n in pair if n is not None]
        if children_done:
            sizes[id(node)] = 1 + sum(sizes[id(k)] for k in kids)
            if sizes[id(node)] > MAX_NODES:
                raise CampaignError(f'{label}: anchors and aliases expand to more than '
                                    f'{MAX_NODES} values (line {node.start_mark.line + 1}); '
                                    'write the values out')
            continue
        if isinstance(node, yaml.MappingNode):
            seen: set[str] = set()
            for key, _ in node.value:
                if isinstance(key, yaml.ScalarNode):
                    if key.value in seen:
                        raise CampaignError(f'{label}: key {shown(key.value)} is given twice '
                                            f'(line {key.start_mark.line + 1})')
                    seen.add(key.value)
        stack.append((node, True))
        stack.extend((k, False) for k in kids if id(k) not in sizes)


def parse_spec(text: str, label: str = 'campaign file') -> CampaignSpec:
    """Return the checked campaign of the YAML ``text``; CampaignError says what is wrong."""
    data = load_yaml(text, label)
    if not isinstance(data, dict):
        raise CampaignError(f'{label} must be a mapping of {", ".join(KEYS)}')
    unknown = sorted(set(data) - set(KEYS))
    if unknown:
        raise CampaignError(f'{label}: unknown key {shown(unknown[0])}; keys: {", ".join(KEYS)}')
    missing = [k for k in REQUIRED if k not in data]
    if missing:
        raise CampaignError(f'{label}: missing key {shown(missing[0])}')

    scene = data.get('scene', 'controller_test')
    if not isinstance(scene, str):
        raise CampaignError(f'scene must be a scene name or file, got {shown(scene)}')
    try:
        find_scene(scene)
    except SceneError as exc:
        raise CampaignError(str(exc)) from None
    params = data.get('parameters') or {}
    if not isinstance(params, dict):
        raise CampaignError(f'parameters must map node parameter names to values, got '
                            f'{shown(params)}')
    spaces: list[tuple[str, Space]] = []
    for name, value in params.items():
        reason = unknown_parameter(str(name), 'parameters')
        if reason is not None:
            raise CampaignError(reason)
        if name in FORCED:
            raise CampaignError(f'parameters.{name} is fixed for a closed loop')
        spaces.append((str(name), _space(f'parameters.{name}', value)))
    reqs = data.get('requirements') or []
    if not isinstance(reqs, list):
        raise CampaignError(f'requirements must be a list of strings, got {shown(reqs)}')
    controller = _controller(data['controller'])
    target = _target(data['target'])
    _receives_target(controller, target)
    timeout = _number('episode_timeout', data.get('episode_timeout', EPISODE_TIMEOUT))
    if timeout <= 0.0:
        raise CampaignError(f'episode_timeout must be > 0 s, got {timeout:g}')
    jit = _jit(data.get('jit', False))
    spec = CampaignSpec(
        controller=controller, scene=scene,
        episodes=_integer('episodes', data['episodes'], 1, MAX_EPISODES),
        seed=_integer('seed', data.get('seed', 0), 0, 2**63 - 1),
        periods=_integer('periods', data['periods'], 1, 10_000_000),
        target=target, parameters=tuple(spaces),
        requirements=tuple(_requirement(r) for r in reqs), text=text, episode_timeout=timeout,
        jit=jit)
    return spec


def _jit(value: object) -> bool:
    """Return the ``jit`` key: True runs a vectorised law's batches on the compiled sweep."""
    if not isinstance(value, bool):
        raise CampaignError(f'jit must be true or false, got {shown(value)}')
    if value:
        from pendulum_sim.core.jit import INSTALL_HINT, available

        if not available():
            raise CampaignError(f'jit: true needs numba, which is not installed: '
                                f'{INSTALL_HINT}')
    return value


def read_spec(path: str | Path) -> CampaignSpec:
    """Read and check the campaign file ``path``."""
    p = Path(path)
    try:
        text = p.read_text(encoding='utf-8')
    except FileNotFoundError:
        raise CampaignError(f"campaign file '{p}' does not exist") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise CampaignError(f"cannot read campaign file '{p}': {exc}") from None
    return parse_spec(text, p.name)


def as_mapping(spec: CampaignSpec) -> Mapping[str, Any]:
    """Return the campaign as plain values (for summaries)."""
    return {'controller': spec.controller, 'scene': spec.scene, 'episodes': spec.episodes,
            'seed': spec.seed, 'periods': spec.periods, 'target': describe(spec.target),
            'requirements': [str(r) for r in spec.requirements]}
