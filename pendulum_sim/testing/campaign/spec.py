"""The campaign file: YAML keys, their checks, and the parsed :class:`CampaignSpec`.

Keys: ``controller`` (``module:function`` or a command line as a list), ``scene``,
``episodes``, ``seed``, ``periods``, ``target``, ``parameters`` (node parameter names mapped to
a value, a list taken in episode order, a grid ``{grid: [low, high, count], stride: S}`` or a
distribution ``{distribution: uniform, low, high}``, ``{distribution: normal, mean, std}``,
``{distribution: loguniform, low, high}``), ``requirements`` (strings such as
``'settling_time < 3.0'``), ``task`` (``step``, the default: the step metrics towards the
target; ``swing_up``: the swing-up metrics into ``goal_box``, ``[angle rad, rate rad/s]``
around the target, π unless given) and ``disturbances`` (torque pulses, each ``{torque,
start, duration}`` in N m, s, s, each drawn like a parameter, given to the joint as its
``disturbance.pulses``) and ``keep_failures`` (``true``, the default: each failing episode's
run is written to ``failures/``; ``false`` for a campaign whose failures are its data, as a
region of attraction's). ``target`` is a scenario
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

from ..errors import CampaignError, TestingError
from ..metrics import METRIC_NAMES
from ..scene import FORCED
from ..swing_up.metrics import BOX, GOAL, SWING_UP_NAMES, check_box
from ..target import PLACEHOLDER, has_placeholder, takes_target

KEYS = ('controller', 'scene', 'episodes', 'seed', 'periods', 'target', 'parameters',
        'requirements', 'episode_timeout', 'jit', 'task', 'goal_box', 'disturbances',
        'keep_failures')
REQUIRED = ('controller', 'episodes', 'periods')
# What an episode is measured by: a step towards the target (StepMetrics), or a swing-up
# into the goal box around the target (SwingUpMetrics; the target is π, upright, unless
# given).
TASKS: dict[str, tuple[str, ...]] = {'step': METRIC_NAMES, 'swing_up': SWING_UP_NAMES}
PULSE_KEYS = ('torque', 'start', 'duration')
PULSES = 'disturbance.pulses'   # the node parameter the drawn pulses are given as
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


@dataclass(frozen=True)
class Grid:
    """``count`` evenly spaced values from ``low`` to ``high``, each held for ``stride``
    episodes: episode ``i`` takes value ``(i // stride) % count`` (a grid of start states is
    two grids, the second with the first's count as its stride)."""

    low: float
    high: float
    count: int
    stride: int = 1

    def value(self, episode: int) -> float:
        """Return episode ``episode``'s value."""
        j = (episode // self.stride) % self.count
        if self.count == 1:
            return self.low
        return self.low + (self.high - self.low) * j / (self.count - 1)


Space = Value | tuple[Value, ...] | Distribution | Grid
TargetSpace = float | tuple[float, ...] | Distribution | Grid
Pulse = tuple[Space, Space, Space]   # torque (N m), start (s), duration (s)


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
    task: str = 'step'
    goal_box: tuple[float, float] = BOX
    disturbances: tuple[Pulse, ...] = ()
    keep_failures: bool = True   # write each failing episode's run to failures/

    @property
    def metric_names(self) -> tuple[str, ...]:
        """Return the names of the task's metrics (the table's metric columns)."""
        return TASKS[self.task]

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """Return the scenario parameters, in file order (the table's columns)."""
        return tuple(name for name, _ in self.parameters)

    @property
    def scenario_names(self) -> tuple[str, ...]:
        """Return the table's scenario columns: the parameters in file order, the drawn
        ``disturbance.pulses`` when the campaign has ``disturbances``, then ``target``."""
        return (*self.parameter_names, *((PULSES,) if self.disturbances else ()), 'target')

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
    return (isinstance(space, Distribution) or (isinstance(space, Grid) and space.count > 1)
            or (isinstance(space, tuple) and len(set(space)) > 1))


def describe(space: Space) -> str:
    """Return ``space`` as a short text (for summaries)."""
    if isinstance(space, Grid):
        return (f'grid({space.low:g} to {space.high:g}, {space.count} values, stride '
                f'{space.stride})')
    if isinstance(space, Distribution):
        a, b = DISTRIBUTIONS[space.kind]
        return f'{space.kind}({a} = {space.a:g}, {b} = {space.b:g})'
    if isinstance(space, tuple):
        return '[' + ', '.join(f'{v:g}' if isinstance(v, float) else str(v) for v in space) + ']'
    return f'{space:g}' if isinstance(space, float) else str(space)


def _grid(where: str, value: dict[str, Any]) -> Grid:
    """Return the grid ``{grid: [low, high, count], stride: S}`` (stride 1 unless given)."""
    extra = sorted(set(value) - {'grid', 'stride'})
    grid = value['grid']
    if extra or not isinstance(grid, list) or len(grid) != 3:
        raise CampaignError(f'{where}: a grid reads {{grid: [low, high, count], stride: S}}, '
                            f'got {shown(value)}')
    low, high = _number(f'{where}.grid low', grid[0]), _number(f'{where}.grid high', grid[1])
    count = _integer(f'{where}.grid count', grid[2], 1, MAX_EPISODES)
    stride = _integer(f'{where}.stride', value.get('stride', 1), 1, MAX_EPISODES)
    if count > 1 and not low < high:
        raise CampaignError(f'{where}: a grid needs low < high, got low = {low:g}, '
                            f'high = {high:g}')
    return Grid(low, high, count, stride)


def _space(where: str, value: Any) -> Space:
    """Return the space of a scenario dimension: a value, a list, a grid or a distribution."""
    if isinstance(value, dict) and 'grid' in value:
        return _grid(where, value)
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
    if isinstance(space, (Distribution, Grid)):
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


def _task(value: Any) -> str:
    if value not in TASKS:
        raise CampaignError(f'task must be one of {", ".join(TASKS)}, got {shown(value)}')
    return str(value)


def _goal_box(value: Any) -> tuple[float, float]:
    """Return the ``goal_box`` key: ``[angle rad, rate rad/s]``, both > 0."""
    if not isinstance(value, list):
        raise CampaignError(f'goal_box must be [angle rad, rate rad/s], two numbers > 0, got '
                            f'{shown(value)}')
    try:
        _, width, rate = check_box(GOAL, value)
    except TestingError as exc:
        raise CampaignError(f'goal_box: {exc}') from None
    return width, rate


def _disturbances(value: Any) -> tuple[Pulse, ...]:
    """Return the ``disturbances`` key: a list of pulses ``{torque, start, duration}``, each
    a value, a list, a grid or a distribution (N m, s, s)."""
    if not isinstance(value, list):
        raise CampaignError(f'disturbances must be a list of pulses {{torque, start, '
                            f'duration}}, got {shown(value)}')
    pulses = []
    for i, pulse in enumerate(value):
        where = f'disturbances[{i}]'
        if not isinstance(pulse, dict) or sorted(pulse) != sorted(PULSE_KEYS):
            raise CampaignError(f'{where} must be a pulse {{torque, start, duration}} (N m, s, '
                                f's), got {shown(pulse)}')
        torque, start, duration = (_space(f'{where}.{k}', pulse[k]) for k in PULSE_KEYS)
        for key, space in zip(PULSE_KEYS, (torque, start, duration), strict=True):
            for v in space if isinstance(space, tuple) else (space,):
                if not isinstance(v, (Distribution, Grid)):
                    _number(f'{where}.{key}', v)
        pulses.append((torque, start, duration))
    return tuple(pulses)


def _requirement(text: Any, names: tuple[str, ...] = METRIC_NAMES) -> Requirement:
    if not isinstance(text, str):
        raise CampaignError(f"a requirement must be a string like 'settling_time < 3.0', got "
                            f'{shown(text)}')
    found = _REQUIREMENT.match(text)
    if found is None:
        raise CampaignError(f"requirement {shown(text)} must read 'metric op number' with op one "
                            f'of <, <=, >, >=, ==, !=')
    metric, op, bound = found.groups()
    if metric not in names:
        raise CampaignError(f'requirement {shown(text)} names an unknown metric {shown(metric)}; '
                            f'metrics: {", ".join(names)}')
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
    task = _task(data.get('task', 'step'))
    missing = [k for k in (*REQUIRED, *(('target',) if task == 'step' else ())) if k not in data]
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
        if name == PULSES and data.get('disturbances'):
            raise CampaignError(f'parameters.{PULSES} and disturbances both set the pulses; '
                                'give them in one')
        spaces.append((str(name), _space(f'parameters.{name}', value)))
    reqs = data.get('requirements') or []
    if not isinstance(reqs, list):
        raise CampaignError(f'requirements must be a list of strings, got {shown(reqs)}')
    controller = _controller(data['controller'])
    target = _target(data.get('target', GOAL))
    if 'goal_box' in data and task != 'swing_up':
        raise CampaignError('goal_box is a key of task: swing_up')
    _receives_target(controller, target)
    timeout = _number('episode_timeout', data.get('episode_timeout', EPISODE_TIMEOUT))
    if timeout <= 0.0:
        raise CampaignError(f'episode_timeout must be > 0 s, got {timeout:g}')
    jit = _jit(data.get('jit', False))
    keep = data.get('keep_failures', True)
    if not isinstance(keep, bool):
        raise CampaignError(f'keep_failures must be true or false, got {shown(keep)}')
    spec = CampaignSpec(
        controller=controller, scene=scene,
        episodes=_integer('episodes', data['episodes'], 1, MAX_EPISODES),
        seed=_integer('seed', data.get('seed', 0), 0, 2**63 - 1),
        periods=_integer('periods', data['periods'], 1, 10_000_000),
        target=target, parameters=tuple(spaces),
        requirements=tuple(_requirement(r, TASKS[task]) for r in reqs), text=text,
        episode_timeout=timeout, jit=jit, task=task,
        goal_box=_goal_box(data['goal_box']) if 'goal_box' in data else BOX,
        disturbances=_disturbances(data.get('disturbances') or []), keep_failures=keep)
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
            'task': spec.task,
            'requirements': [str(r) for r in spec.requirements]}
