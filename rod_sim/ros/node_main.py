"""The rod_sim node as a process (``sim_node``, ``rod-sim node``, ``python -m
rod_sim.ros.node``): argument parsing (``--help``, ROS arguments after ``--ros-args``), SIGINT /
SIGTERM handling that closes the log between callbacks, and exit codes (0, or 2 with a one-line
reason). :func:`parse_cli`, :func:`run_node`, :class:`StopRequest` and :func:`spin_until` also
serve the other rod_sim processes (controller, player, demo)."""
from __future__ import annotations

import argparse
import functools
import signal
import sys
import textwrap
import threading
from typing import Any, Callable

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args

from rod_sim.ros.errors import NodeConfigError, one_line
from rod_sim.ros.parameters import PARAMETERS


def parameter_help(specs=PARAMETERS, width: int = 79) -> str:
    """The parameters for ``--help``: one per line (``name  type, default: ...``), its
    description wrapped and indented below it."""
    kinds = {bool: "bool", float: "double", int: "integer", str: "string"}
    lines = ["parameters (set with --ros-args -p NAME:=VALUE or --params-file FILE):"]
    for spec in specs:
        default = (str(spec.default).lower() if isinstance(spec.default, bool)
                   else repr(spec.default))
        run_time = "" if spec.read_only else ", settable at run time"
        lines.append(f"  {spec.name} ({kinds[type(spec.default)]}, default {default}"
                     f"{run_time})")
        text = spec.description
        if spec.range is not None:
            text += f"; range {spec.range[0]:g} .. {spec.range[1]:g}"
        if spec.constraints and spec.constraints not in text:
            text += f"; {spec.constraints}"
        lines += textwrap.wrap(text, width, initial_indent=" " * 6, subsequent_indent=" " * 6,
                               break_on_hyphens=False)
    return "\n".join(lines)


def build_parser(prog: str = "sim_node") -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=prog, formatter_class=argparse.RawDescriptionHelpFormatter,
        description="rod_sim ROS 2 node: a chain of elastic rods driven by nodal forces\n"
        "(docs/interface.md section 3). Configure it with ROS arguments, e.g.\n"
        "  --ros-args --params-file config/sim_node.params.yaml -p scene_file:=SCENE.yaml",
        epilog=parameter_help())
    return parser


ROS_ARGS_HINT = "ROS arguments go after --ros-args, e.g. --ros-args -p scene_file:=SCENE.yaml"


def parse_cli(parser: argparse.ArgumentParser, args: list[str]) -> argparse.Namespace:
    """Parse the non-ROS arguments of ``args`` with ``parser`` (--help, typos). Malformed ROS
    arguments (e.g. a dangling ``--ros-args -p``) and ROS arguments given without
    ``--ros-args`` are usage errors (exit 2, one line)."""
    try:
        rest = remove_ros_args([parser.prog, *args])[1:]
    except RuntimeError as exc:    # rclpy's RCLInvalidROSArgsError
        text = one_line(exc).split(", at ")[0]
        parser.exit(2, f"{parser.prog}: error: invalid ROS arguments: {text}\n")
    namespace, unknown = parser.parse_known_args(rest)
    if unknown:
        ros_like = any(a in ("-p", "-r", "--param", "--remap", "--params-file") or ":=" in a
                       for a in unknown)
        parser.exit(2, f"{parser.prog}: error: unrecognized arguments: {' '.join(unknown)}"
                    + (f" ({ROS_ARGS_HINT})" if ros_like else "") + "\n")
    return namespace


def params_files(args: list[str]) -> tuple[str, ...]:
    """The files given with ``--params-file`` among ROS arguments ``args``."""
    return tuple(b for a, b in zip(args, args[1:]) if a == "--params-file")


class StopRequest:
    """SIGINT/SIGTERM handler: the first signal asks the spin loop to stop (so that the log is
    closed between callbacks, never in the middle of a write); a second one interrupts."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self):
        self.event = threading.Event()
        self._previous: dict[int, Any] = {}

    def __enter__(self) -> "StopRequest":
        for sig in self.SIGNALS:
            self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def __exit__(self, *exc) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)

    def _handle(self, signum, frame) -> None:
        if self.event.is_set():
            raise KeyboardInterrupt
        self.event.set()

    @property
    def requested(self) -> bool:
        return self.event.is_set()


def spin_until(executor, stop: StopRequest, done: Callable[[], bool] = lambda: False,
               timeout_sec: float = 0.1) -> None:
    """Spin ``executor`` until a stop is requested, ``done()`` is true or its context ends."""
    context = executor.context
    while not stop.requested and not done() and context.ok():
        executor.spin_once(timeout_sec=timeout_sec)


def main(argv: list[str] | None = None, prog: str = "sim_node") -> int:
    """Run the node until SIGINT/SIGTERM. Returns 0, or 2 (with a one-line reason on stderr)
    for bad arguments, parameters or scenes. ``prog`` names the command in messages."""
    from rod_sim.ros.node import RodSimNode   # the node module re-exports this function
    args = list(sys.argv[1:] if argv is None else argv)
    parse_cli(build_parser(prog), args)
    return run_node(prog, functools.partial(RodSimNode, params_files=params_files(args)),
                    args, NodeConfigError)


def run_node(prog: str, make_node, args: list[str], config_errors) -> int:
    """Create ``make_node()`` under rclpy and spin it until SIGINT/SIGTERM, then destroy it
    and shut rclpy down. Returns 0, or 2 with a one-line reason on stderr when creating the
    node raises one of ``config_errors``."""
    rclpy.init(args=[prog, *args], signal_handler_options=SignalHandlerOptions.NO)
    node = None
    with StopRequest() as stop:
        try:
            node = make_node()
            executor = SingleThreadedExecutor()
            executor.add_node(node)
            spin_until(executor, stop)
        except config_errors as exc:
            print(f"{prog}: error: {exc}", file=sys.stderr)
            return 2
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        finally:
            if node is not None:
                node.destroy_node()
            rclpy.try_shutdown()
    return 0

