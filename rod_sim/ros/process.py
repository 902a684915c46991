"""A rod_sim ROS 2 process (the node, the controller, the player, the demo): argument parsing
(ROS arguments after ``--ros-args``), SIGINT / SIGTERM handling that stops the spin loop
between callbacks (so a log is closed whole), and exit codes (0, or 2 with a one-line reason).
Knows no particular node: :mod:`rod_sim.ros.node` wires its node class into :func:`run_node`."""
from __future__ import annotations

import argparse
import gc
import signal
import sys
import threading
from typing import Any, Callable

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args

from rod_sim.app.signals import ArrivalWatch, Watchdog, write_line
from rod_sim.ros.errors import one_line
from rod_sim.ros.executor import LeanExecutor
from rod_sim.ros.startup import Progress, on_started

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
    closed between callbacks, never in the middle of a write); a second one interrupts. While
    ``starting`` (the node is being created: nothing to close yet) the first signal
    interrupts at once (KeyboardInterrupt), so a long start-up stops within its current
    bounded call; ``signum`` is the first signal received.

    Python cannot raise that interruption everywhere: inside a ctypes callback (numba's
    machine-code cache, llvmlite's ``_raw_object_cache_notify``) it is printed as "Exception
    ignored ..." and dropped, and the start-up ran on. So a signal during the start-up also
    starts a watchdog that ends the process :data:`START_GRACE_S` later with the start-up's
    one line and 130 / 143 unless :meth:`claim` was called first, and an interruption Python
    drops is not printed (``sys.unraisablehook``). The watchdog starts when the signal
    arrives (:class:`rod_sim.app.signals.ArrivalWatch`), not when Python gets round to the
    handler, which waits for the end of a long compiled call."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)
    START_GRACE_S = 0.75
    """[s] from a signal during the start-up to the forced end of a start-up still running."""

    def __init__(self, starting: bool = False, prog: str = "rod_sim"):
        self.event = threading.Event()
        self.starting = starting
        self.prog = prog
        self.signum: int | None = None
        self.during_startup = False
        """Whether the first signal arrived while ``starting``."""
        self._previous: dict[int, Any] = {}
        self._first_lock = threading.RLock()     # the handler may run inside itself
        self._watchdog = Watchdog(self.interrupted_line, self.exit_status, self.START_GRACE_S,
                                  "rod-sim-start-watchdog")
        self._unraisablehook = None
        self._arrivals = ArrivalWatch(self._arrived, self.SIGNALS)

    def __enter__(self) -> "StopRequest":
        for sig in self.SIGNALS:
            self._previous[sig] = signal.signal(sig, self._handle)
        self._unraisablehook = sys.unraisablehook
        sys.unraisablehook = self._quiet_unraisable
        if self.starting:           # it acts only during a start-up (replay, demo: none)
            self._arrivals.__enter__()
        return self

    def __exit__(self, *exc) -> None:
        self._arrivals.__exit__(*exc)
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        if sys.unraisablehook == self._quiet_unraisable:
            sys.unraisablehook = self._unraisablehook

    def _quiet_unraisable(self, unraisable) -> None:
        if self.requested:
            # the stop is reported once, by its one line: its interruption, and that
            # interruption's fallout in a finaliser of an object it cut in half (as
            # rod_sim.app.signals.quiet_unraisable)
            return
        self._unraisablehook(unraisable)

    def _handle(self, signum, frame) -> None:
        if self.event.is_set():
            if self.starting:
                return              # the start-up is already being interrupted
            raise KeyboardInterrupt
        self._first(signum)
        self.event.set()
        if self.starting:
            raise KeyboardInterrupt

    def _arrived(self, signum: int) -> None:
        """A signal has arrived (the :class:`ArrivalWatch` thread): during the start-up the
        watchdog starts now; the handler interrupts when the main thread gets to it."""
        if self.starting:
            self._first(signum)

    def _first(self, signum: int) -> None:
        """Record the first signal; during the start-up, start the watchdog (once)."""
        with self._first_lock:
            if self.signum is None:
                self.signum = signum
            if self.starting:
                self.during_startup = True
                self._watchdog.start()

    def startup_over(self) -> None:
        """The start-up has ended (:func:`rod_sim.ros.startup.started`, or the node returned):
        a signal from now on stops a running node."""
        self.starting = False

    def interrupted_line(self) -> str:
        """The one line of a start-up ended by the first signal."""
        return (f"{self.prog}: interrupted during start-up"
                + (" (SIGTERM)" if self.signum == signal.SIGTERM else ""))

    def exit_status(self) -> int:
        """130 / 143: the exit status of a start-up the first signal ended."""
        return 128 + (self.signum or signal.SIGINT)

    def claim(self) -> bool:
        """The caller reports the interrupted start-up (True once; then the watchdog stands
        down), or the watchdog already has (False)."""
        return self._watchdog.claim()

    @property
    def requested(self) -> bool:
        return self.event.is_set()


def spin_until(executor, stop: StopRequest, done: Callable[[], bool] = lambda: False,
               timeout_sec: float = 0.1) -> None:
    """Spin ``executor`` until a stop is requested, ``done()`` is true or its context ends."""
    context = executor.context
    while not stop.requested and not done() and context.ok():
        executor.spin_once(timeout_sec=timeout_sec)


def run_node(prog: str, make_node, args: list[str], config_errors) -> int:
    """Create ``make_node()`` under rclpy and spin it until SIGINT/SIGTERM, then destroy it
    and shut rclpy down. Returns 0, or 2 with a one-line reason on stderr when creating the
    node raises one of ``config_errors``, or 130 / 143 (SIGINT / SIGTERM) with one line when a
    signal stops the start-up (which prints what it is doing after 2 s: :mod:`startup`)."""
    from rod_sim.app.common import watch_compiles

    watch_compiles(prog)        # a driver not in numba's cache: what, why, how long
    rclpy.init(args=[prog, *args], signal_handler_options=SignalHandlerOptions.NO)
    node = None
    with StopRequest(starting=True, prog=prog) as stop:
        spinning = False
        try:
            on_started(stop.startup_over)
            try:
                with Progress(prog):
                    node = make_node()
            finally:
                on_started(None)
            stop.startup_over()
            if stop.during_startup:
                # a signal during the start-up whose interruption Python dropped (a ctypes
                # callback), or whose handler ran only after the node said it had started:
                # the start-up was interrupted all the same
                raise KeyboardInterrupt
            # the start-up heap (numba, rclpy, the model) out of the collector's full passes:
            # they stalled a 1024-rod node ~60 ms every few seconds (rate_bench --record:
            # inter-arrival p99 67 ms before, 13 ms after)
            gc.freeze()
            executor = LeanExecutor()
            executor.add_node(node)
            spinning = True
            spin_until(executor, stop)
        except config_errors as exc:
            print(f"{prog}: error: {exc}", file=sys.stderr)
            return 2
        except (KeyboardInterrupt, ExternalShutdownException):
            if not spinning:        # stopped during the start-up: one line, 130 / 143
                if stop.claim():
                    write_line(stop.interrupted_line(), sys.stderr)
                return stop.exit_status()
        finally:
            if node is not None:
                node.destroy_node()
            rclpy.try_shutdown()
    return 0


NAME_CHECK_DELAY_S = 2.0
"""[s] after the start (discovery) when :func:`same_name_warning` looks at the graph."""


def same_name_warning(node) -> str | None:
    """The warning when other nodes on the graph have ``node``'s fully qualified name
    (services and parameters would reach only one of them), else None."""
    full = node.get_fully_qualified_name()
    same = sum(1 for name, ns in node.get_node_names_and_namespaces()
               if f"{ns.rstrip('/')}/{name}" == full)
    if same <= 1:
        return None
    return (f"{same} nodes named {full} are on the graph (ROS_DOMAIN_ID "
            f"{node.context.get_domain_id()}): services and parameters reach only one of them; "
            "give this one another name (-r __node:=NAME) or namespace (-r __ns:=/NS)")
