"""``pendulum_node``'s command line: options, scenes, the executor, and a clean shutdown.

Run it as::

    pendulum_node --scene default
    pendulum_node --ros-args --params-file config/default.yaml

Every command-line and parameter-file error is found before ``rclpy.init`` where possible (and
what rcl still refuses is caught): the process exits 2 with the reason on stderr, never a
traceback. Ctrl-C (SIGINT) and SIGTERM end it with exit 0 after the summary. Imported as the
``pendulum_node`` executable, this module takes both signals at once, before numpy and rclpy
load: a signal during the imports is remembered and ``main`` returns at once, one during
start-up aborts it, and one while the node runs only asks the loop to stop, so nothing is
interrupted inside a callback. (Only the interpreter's own start-up, before this module, is
left: there the ROS wheels' bootstrap re-executes Python, and a signal is lost or kills.)
"""
from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, NoReturn


class Signals:
    """SIGINT and SIGTERM: remember them, and raise KeyboardInterrupt only while starting up.

    rclpy is initialised without signal handlers of its own, so a signal never shuts the
    context down under a running callback.
    ``abort`` is True only between the start of ``main`` and the start of the loop.
    """

    def __init__(self) -> None:
        self.abort = False
        self.received: int | None = None

    def install(self) -> None:
        """Handle SIGINT and SIGTERM in this process from now on (main thread only)."""
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                signal.signal(sig, self)

    def __call__(self, signum: int, frame: FrameType | None) -> None:
        self.received = signum
        if self.abort:
            raise KeyboardInterrupt


SIGNALS = Signals()
if __name__ == '__main__' or Path(sys.argv[0] if sys.argv else '').name == 'pendulum_node':
    SIGNALS.install()  # the executable: before the imports below take their half second

from pendulum_sim.core import PendulumError  # noqa: E402 - after the signal handlers
from pendulum_sim.dds import (  # noqa: E402
    add_executor_option,
    exit_with,
    make_executor,
    release,
    shut_down,
    use_loopback_profile,
)
from pendulum_sim.joint.scenes import (  # noqa: E402
    available_scenes,
    find_scene,
    known_parameters,
    read_params_file,
    unknown_parameter,
)

from .errors import NodeError, SceneError  # noqa: E402

if TYPE_CHECKING:

    from .pendulum_node import PendulumNode


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='pendulum_node',
        description='Serve a damped physical pendulum as a real-time simulated ROS 2 joint.',
        epilog='ROS arguments follow --ros-args, e.g. --ros-args --params-file scene.yaml '
               '-p gamma:=2.0')
    parser.add_argument('--scene', help='load the installed scene config/NAME.yaml (or a '
                        'YAML path) before any other ROS parameters')
    parser.add_argument('--list-scenes', action='store_true', help='list the scenes and exit')
    parser.add_argument('--rt-priority', type=int, default=0, metavar='N',
                        help='run with SCHED_FIFO priority N (1-99, as rttest does; needs '
                        'CAP_SYS_NICE); 0 (default) keeps the normal scheduler')
    add_executor_option(parser)
    return parser


def _rcl_error() -> type[Exception]:
    """Return rcl's error class (RCLInvalidROSArgsError and UnknownROSArgsError derive from it)."""
    from rclpy.impl.implementation_singleton import rclpy_implementation

    error: type[Exception] = rclpy_implementation.RCLError
    return error


# ---------------------------------------------------------------- ROS arguments, checked
PROG = 'pendulum_node'
# rcl's ROS arguments (rcl/arguments.h, ROS 2 Jazzy): flags that take one value, flags alone.
VALUE_FLAGS = {
    '-p': '--param', '--param': '--param', '-r': '--remap', '--remap': '--remap',
    '--params-file': '--params-file', '--log-level': '--log-level', '-e': '--enclave',
    '--enclave': '--enclave', '--log-config-file': '--log-config-file',
    '--log-file-name': '--log-file-name',
}
SWITCH_FLAGS = frozenset(f'--{on}-{what}-logs' for on in ('enable', 'disable')
                         for what in ('rosout', 'stdout', 'external-lib'))
LOG_LEVELS = ('debug', 'info', 'warn', 'error', 'fatal', 'unset')
NEEDS = {'--param': 'name:=value', '--remap': 'from:=to', '--params-file': 'a YAML file',
         '--log-level': 'a level: ' + ', '.join(LOG_LEVELS)}


class UsageError(NodeError):
    """The command line cannot be used; the message says why."""


@dataclass
class RosArgs:
    """What the ROS arguments of the command line ask for."""

    params_files: list[str] = field(default_factory=list)
    params: list[tuple[str, str]] = field(default_factory=list)


def _ros_sections(argv: list[str]) -> Iterator[tuple[bool, str]]:
    """Yield (is_ros_argument, argument) the way rcl splits them: --ros-args ... [--]."""
    in_ros = False
    for arg in argv:
        if arg == '--ros-args':
            in_ros = True
        elif in_ros and arg == '--':
            in_ros = False
        else:
            yield in_ros, arg


def _rule(flag: str, value: str, need: str) -> tuple[str, str]:
    name, sep, rhs = value.partition(':=')
    if not sep or not name or not rhs:
        raise UsageError(f"{flag} needs {need}, got '{value}'")
    return name, rhs


def check_ros_args(argv: list[str]) -> RosArgs:
    """Check the ROS arguments in ``argv`` (no program name); raise UsageError with the reason."""
    out = RosArgs()
    args = [a for ros, a in _ros_sections(argv) if ros]
    i = 0
    while i < len(args):
        arg = args[i]
        if arg in SWITCH_FLAGS:
            i += 1
            continue
        if arg not in VALUE_FLAGS:
            raise UsageError(f"unknown ROS argument '{arg}' (see ros2 run --help or "
                             'https://docs.ros.org/en/jazzy/How-To-Guides/Node-arguments.html)')
        flag = VALUE_FLAGS[arg]
        if i + 1 >= len(args):
            raise UsageError(f"{arg} needs {NEEDS.get(flag, 'a value')}")
        value = args[i + 1]
        i += 2
        if flag == '--param':
            out.params.append(_rule(arg, value, 'name:=value'))
        elif flag == '--remap':
            _rule(arg, value, 'from:=to')
        elif flag == '--params-file':
            if not Path(value).is_file():
                raise UsageError(f"parameter file '{value}' does not exist")
            out.params_files.append(value)
        elif flag == '--log-level':
            level = value.rpartition(':=')[2]
            if level.lower() not in LOG_LEVELS:
                raise UsageError(f"--log-level must be one of {', '.join(LOG_LEVELS)} (or "
                                 f"logger:=level), got '{value}'")
    return out


def check_parameters(ros: RosArgs) -> None:
    """Check the parameter files and the -p names; raise SceneError with the reason."""
    for name in ros.params_files:
        read_params_file(Path(name), name)
    known = known_parameters()
    for name, value in ros.params:
        reason = unknown_parameter(name, f'-p {name}:={value}', known)
        if reason:
            raise SceneError(reason)


def _rcl_reason(exc: BaseException) -> str:
    """Return rcl's message without its source locations (', at .../arguments.c:356')."""
    text = str(exc).strip()
    while ', at /' in text:
        text = text[:text.rindex(', at /')]
    return text


def _fail(message: object) -> int:
    print(f'{PROG}: {message}', file=sys.stderr)
    return 2


def main(args: list[str] | None = None) -> int:
    """Run the node until Ctrl-C or SIGTERM, then print a summary.

    Returns 0 after a signal, 2 for a command line, scene or parameter the node cannot use.
    """
    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    signals = SIGNALS
    signals.install()
    if signals.received is not None:  # a signal while this module loaded
        return 0
    signals.abort = True
    try:
        return _main(list(sys.argv if args is None else args), signals)
    except KeyboardInterrupt:  # a signal before the node ran: nothing to close or summarise
        return 0
    finally:
        signals.abort = False
        if threading.current_thread() is threading.main_thread():
            for sig, handler in previous.items():
                if handler is not None:  # None: a handler from outside Python, not ours to set
                    signal.signal(sig, handler)


def _main(argv: list[str], signals: Signals) -> int:
    from rclpy.utilities import remove_ros_args

    rcl_error = _rcl_error()
    try:
        ros = check_ros_args(argv[1:])
        check_parameters(ros)
        user_args = remove_ros_args(argv)[1:]
    except (UsageError, SceneError) as exc:
        return _fail(exc)
    except rcl_error as exc:  # what rcl refuses beyond the checks above
        return _fail(f'invalid ROS arguments: {_rcl_reason(exc)}')
    opts = _parser().parse_args(user_args)
    if opts.list_scenes:
        print('\n'.join(available_scenes()))
        return 0
    ros_argv = argv
    scene: Path | None = None
    try:
        if opts.scene:
            scene = find_scene(opts.scene)
            is_path = Path(opts.scene).suffix in ('.yaml', '.yml')
            read_params_file(scene, opts.scene if is_path else scene.name)
    except SceneError as exc:
        return _fail(exc)
    if scene is not None:
        # The scene comes first, so parameters given after --ros-args override it.
        ros_argv = [argv[0], '--ros-args', '--params-file', str(scene), '--', *argv[1:]]
    # DDS on 127.0.0.1 unless the user chose a profile or a wider discovery range.
    use_loopback_profile(os.environ)
    if opts.rt_priority:
        # Before rclpy.init, so the DDS and executor threads inherit the policy.
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(opts.rt_priority))
        except (OSError, ValueError) as exc:
            print(f'{PROG}: cannot use SCHED_FIFO priority {opts.rt_priority} ({exc}); '
                  'running with the normal scheduler', file=sys.stderr)
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    try:
        # rclpy's own handlers would shut the context down at once, from another thread, in
        # the middle of a callback that is publishing (a FATAL log and a traceback): the
        # handlers installed above only ask the loop to stop, between callbacks.
        rclpy.init(args=ros_argv, signal_handler_options=SignalHandlerOptions.NO)
    except rcl_error as exc:
        return _fail(f'invalid ROS arguments: {_rcl_reason(exc)}')
    except KeyboardInterrupt:
        rclpy.try_shutdown()
        return 0
    return _run(opts.executor, signals)


def _run(executor_kind: str, signals: Signals) -> int:
    """Create the node and spin until a signal or shutdown; return the exit code."""
    import rclpy
    from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
    from rclpy.executors import Executor, ExternalShutdownException

    from pendulum_sim.joint.status import StatusLine

    from .pendulum_node import PendulumNode

    node: PendulumNode | None = None
    executor: Executor | None = None
    code = 0
    try:
        executor = make_executor(executor_kind)
        node = PendulumNode(status=StatusLine())
        executor.add_node(node)
        signals.abort = False
        # spin_once in a loop rather than spin(): the EventsExecutor's spin() does not return
        # to Python, so it would miss Ctrl-C. A signal is recorded by our handler and the loop
        # ends between callbacks (as it does when the node saw a KeyboardInterrupt inside a
        # callback, raised by another handler).
        while rclpy.ok() and signals.received is None and not node.stop_requested:
            executor.spin_once(timeout_sec=0.25)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (NodeError, InvalidParameterValueException, InvalidParameterTypeException) as exc:
        hint = ' (write doubles with a decimal point, e.g. 2.0)' if isinstance(
            exc, InvalidParameterTypeException) else ''
        code = _fail(f'{exc}{hint}')
    except PendulumError as exc:  # e.g. RecorderError: the recording cannot be opened
        code = _fail(exc)
    except _rcl_error() as exc:
        # A signal shuts the context down under the executor ('failed to initialize wait set:
        # the given context is not valid'): that is the end asked for. Otherwise rcl refused
        # something, e.g. a parameter override it parsed but rclpy cannot use.
        if signals.received is None and rclpy.ok():
            code = _fail(_rcl_reason(exc))
    finally:
        signals.abort = False  # a signal while closing must not interrupt the close
        release(executor, node)
        if node is not None:
            node.close()  # the summary and the recording, before the DDS teardown
        shut_down(node, code)
    return code


def entry() -> NoReturn:
    """The console script ``pendulum_node``: :func:`main`, ended by ``dds.exit_with``."""
    exit_with(main)


if __name__ == '__main__':
    entry()
