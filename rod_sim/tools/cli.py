"""The ``rod-sim`` command line: one entry point, one subcommand per job.

``build_parser()`` builds the parser, ``run(args) -> int`` does the work and returns the exit
status (0 success, 1 a check failed or the run stopped, 2 bad input), ``main()`` wraps both
and turns library errors into one-line messages on stderr.

``simulate``, ``table1`` and ``node`` are defined here; every other module of
``rod_sim.tools`` that defines ``COMMAND`` adds its own subcommand (see
:mod:`rod_sim.tools.common`).
"""
from __future__ import annotations

import argparse
import contextlib
import importlib
import json
import math
import pkgutil
import re
import signal
import sys
import threading
import time
from pathlib import Path

from .. import __version__
from ..core.names import INTEGRATOR_NAMES as INTEGRATORS
from ..core.names import MODEL_NAMES
from ..core.scene import SceneError

from . import limits
from .common import (EXIT_BAD_INPUT, EXIT_CHECK_FAILED, EXIT_OK, PAPER_EXAMPLE, UsageError,
                     compile_notice, load_scene, new_output_path)
from .common import positive_float as _positive_float

__all__ = ["EXIT_OK", "EXIT_CHECK_FAILED", "EXIT_BAD_INPUT", "PAPER_EXAMPLE", "UsageError",
           "build_parser", "run", "main"]


_COMMAND_LINE = re.compile(r"^COMMAND\s*=", re.MULTILINE)


def plugin_modules() -> dict:
    """``{COMMAND: module}`` of the ``rod_sim.tools`` modules that define a subcommand (only
    those are imported: a module-level ``COMMAND = ...`` line marks them)."""
    from .. import tools

    found = {}
    for info in pkgutil.iter_modules(tools.__path__):
        if info.name in ("cli", "common"):
            continue
        path = Path(info.module_finder.path) / f"{info.name}.py"
        if path.is_file() and not _COMMAND_LINE.search(path.read_text(encoding="utf-8")):
            continue
        module = importlib.import_module(f"{tools.__name__}.{info.name}")
        if hasattr(module, "COMMAND"):
            found[module.COMMAND] = module
    return found


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rod-sim", description="Plane chains of elastic rods with visco-elastic hinges.")
    parser.add_argument("--version", action="version", version=f"rod-sim {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    sim = sub.add_parser("simulate", help="offline run of a scene, written as an MCAP log",
                         description="Offline run of a scene (no ROS graph); writes the log of "
                                     "docs/interface.md section 4 sampled at --rate in simulated "
                                     "time, the t = 0 state first. Limits: docs/interface.md "
                                     "section 6.")
    sim.add_argument("scene", help="scene YAML file (docs/interface.md section 1)")
    sim.add_argument("--model", choices=sorted(MODEL_NAMES), default="reduced",
                     help="full (3n ODEs), reduced (n ODEs, quasi-static bending) or rigid "
                          "(default reduced)")
    sim.add_argument("--t-end", type=_positive_float, required=True,
                     help=f"end time [s], at most {limits.MAX_T_END:g}")
    sim.add_argument("--out", required=True, help="MCAP log to write (must not exist)")
    sim.add_argument("--rate", type=_positive_float, default=100.0,
                     help="sampling rate of the log [Hz of simulated time], at most "
                          f"{limits.MAX_RATE:g} (default 100)")
    sim.add_argument("--integrator", choices=INTEGRATORS, default="dop853-jit",
                     help="dop853-jit (default; compiled adaptive Dormand-Prince 8(5,3), "
                          "--rtol/--atol), radau-jit (compiled implicit Radau IIA order 5, for "
                          "stiff scenes, --rtol/--atol), rk4, rk2, euler (compiled fixed step, "
                          "--step) or scipy's RK45, DOP853, Radau, BDF, LSODA")
    sim.add_argument("--rtol", type=_positive_float, default=None,
                     help="relative tolerance of adaptive integrators, "
                          f"{limits.RTOL_RANGE[0]:g} .. {limits.RTOL_RANGE[1]:g} (default 1e-8)")
    sim.add_argument("--atol", type=_positive_float, default=None,
                     help="absolute tolerance (default = rtol)")
    sim.add_argument("--step", type=_positive_float, default=None,
                     help="largest step of fixed-step integrators [s], at least 1e-9 "
                          "(default 1e-3)")
    sim.add_argument("--frame-id", default="world",
                     help="frame of the logged headers, poses and markers (default world)")

    t1 = sub.add_parser("table1", help="recompute Table 1 of the paper",
                        description="Recompute Table 1 of the paper with the full and "
                                    "reduced models and print it beside the published values.")
    t1.add_argument("--json", action="store_true", help="machine-readable output")
    t1.add_argument("--scene", default=str(PAPER_EXAMPLE), help=argparse.SUPPRESS)
    node = sub.add_parser("node", help="the ROS 2 simulator node (docs/interface.md section 3)",
                          description="Run the rod_sim ROS 2 node until SIGINT/SIGTERM. ROS "
                                      "arguments follow --ros-args, e.g. --ros-args -p "
                                      "scene_file:=config/paper_example.yaml -p sync_mode:=true "
                                      "(see `python -m rod_sim.ros.node --help`).")
    node.add_argument("ros_args", nargs=argparse.REMAINDER, metavar="--ros-args ...",
                      help="ROS 2 arguments (parameters, remappings, --params-file)")

    for name, module in sorted(plugin_modules().items()):
        module.configure(sub.add_parser(name, help=module.HELP, description=module.HELP))
    return parser


def cmd_node(args) -> int:
    from ..ros.node import main as node_main

    # reached only through run(); main() forwards
    return node_main(list(args.ros_args), prog="rod-sim node")


def _sample_grid_ns(rate_hz: float, k: int) -> int:
    """Time [ns] of sample k of the log's grid (as Simulator.run places its samples)."""
    return int(round(k * (1e9 / rate_hz)))


def cmd_simulate(args) -> int:
    from ..core.integrators import IntegrationError, make_integrator
    from ..core.models import make_model
    from ..core.simulator import Simulator
    from ..io.log_source import SCENE_TOPIC
    from ..io.log_writer import LogWriter, offered_qos_yaml
    from ..io.scene_yaml import scene_to_yaml

    if not args.frame_id:                   # as the node's frame_id parameter
        raise UsageError("--frame-id: must not be empty")
    scene = load_scene(args.scene)
    limits.check_rtol(args.rtol)
    limits.check_sampling(args.t_end, args.rate, scene.n)
    integrator = make_integrator(args.integrator, rtol=args.rtol, atol=args.atol, step=args.step)
    if not integrator.adaptive and args.t_end / integrator.step > limits.MAX_FIXED_STEPS:
        raise UsageError(f"--step: {args.t_end:g} s in steps of {integrator.step:g} s is more "
                         f"than {limits.MAX_FIXED_STEPS:g} steps")
    limits.check_model_memory(scene.n)
    model = make_model(args.model, scene)
    out = new_output_path(args.out)
    with compile_notice():
        try:            # compile (or load) the kernels before the clock starts
            Simulator(model, make_integrator(args.integrator)).advance(1e-3)
        except IntegrationError:
            pass        # the run below meets the same failure and reports it
    sim = Simulator(model, integrator)
    metadata = {"scene": scene_to_yaml(scene), "model": model.name,
                "integrator": integrator.describe(), "version": __version__,
                "rate_hz": repr(args.rate), "source": "rod-sim simulate"}
    try:
        log = LogWriter(out, metadata=metadata, qos={SCENE_TOPIC: offered_qos_yaml(
            depth=1, durability="transient_local")})
        # the scene also as a latched topic: a log converted by rosbag2 tools (which drop MCAP
        # metadata records) stays self-contained
        log.write(SCENE_TOPIC, "std_msgs/msg/String", 0, {"data": metadata["scene"]})
    except OSError as err:
        raise UsageError(f"--out: cannot write {out}: {err.strerror or err}") from None
    run = _LoggedRun(sim, scene, log, args.frame_id)
    try:
        try:
            status = run.integrate(args.t_end, args.rate, IntegrationError)
        finally:
            with signals_deferred():        # the summary is written whole, even on Ctrl-C
                log.close()
    except OSError as err:
        print(f"rod-sim simulate: error: writing {out} failed at t = {run.t_logged:g} s: "
              f"{err.strerror or err}; {_salvage(out)}", file=sys.stderr)
        return EXIT_CHECK_FAILED
    rtf = sim.t / run.wall if run.wall > 0 else math.inf
    print(f"{scene.name}: {model.name} model, {integrator.describe()}, t = 0..{sim.t:g} s, "
          f"{run.samples} samples -> {out} (integration {run.wall:.3f} s wall, {rtf:.0f}x real "
          f"time, {sim.stats.nfev} rhs evaluations"
          + (f", {run.logged_events} hinge events" if run.logged_events else "") + ")")
    if run.validity.summary():
        print(f"rod-sim simulate: validity warning: {run.validity.summary()}", file=sys.stderr)
    return status


class _LoggedRun:
    """A simulator run logged sample by sample: the t = 0 state first, then chunks of at most
    CHUNK_SAMPLES samples on the grid of --rate (plus the end time), with the hinge events."""

    CHUNK_SAMPLES = 10_000
    CHUNK_SECONDS = 0.5          # simulated seconds integrated per call at most

    def __init__(self, sim, scene, log, frame_id: str):
        from ..core.validity import EnergyBalance, ValidityMonitor

        self.sim, self.scene, self.log, self.frame_id = sim, scene, log, frame_id
        self.validity = ValidityMonitor(sim.model)
        self.balance = None             # the energy balance (the node judges the same one)
        self._last = None               # BalanceSample of the previous sample
        self.balanced_events = 0
        self.samples = 0
        self.logged_events = 0
        self.wall = 0.0
        self.t_logged = 0.0

    def _write(self, t: float, y, mode=None) -> None:
        from ..core.validity import EnergyBalance, balance_sample

        model = self.sim.model
        snap = model.snapshot(t, y, None, mode)
        self.validity.update(snap.t, y, None, snap.alpha, snap.beta)
        sample = balance_sample(model, t, y, None, mode, (snap.alpha, snap.beta))
        if self.balance is None:
            self.balance = EnergyBalance.for_model(model, sample.energy)
        else:
            events = self.sim.events
            k = self.balanced_events
            while k < len(events) and events[k].t < t:    # a sample at a latch's time: before it
                k += 1
            self.balance.add(self._last, sample, events[self.balanced_events:k])
            self.balanced_events = k
            self.validity.update_energy(t, self.balance.residual, self.balance.scale)
        self._last = sample
        with signals_deferred():            # every record of a sample whole, or none
            self.log.write_snapshot(snap, self.scene, frame_id=self.frame_id)
            self.samples += 1
            self.t_logged = t

    def _write_traj(self, traj) -> None:
        """The samples of ``traj`` after its first (the previous call's last), then the hinge
        events since the last call."""
        from ..io.hinge_events import write_events

        for i in range(1, traj.t.size):
            self._write(float(traj.t[i]), traj.y[i],
                        None if traj.modes is None else traj.modes[i])
        with signals_deferred():
            self.logged_events += write_events(self.log, self.sim.events[self.logged_events:])

    def integrate(self, t_end: float, rate_hz: float, failure) -> int:
        """Run to t_end [s]; on ``failure`` (IntegrationError) keep every finite sample, print
        one line and return EXIT_CHECK_FAILED."""
        sim = self.sim
        self._write(sim.t, sim.y, sim.mode)
        end_ns = round(t_end * 1e9)
        per_chunk = max(1, min(self.CHUNK_SAMPLES, math.floor(self.CHUNK_SECONDS * rate_hz)))
        k = 0
        while sim.t_ns < end_ns:
            k += per_chunk
            t_next = min(end_ns, _sample_grid_ns(rate_hz, k)) / 1e9
            started = time.perf_counter()
            try:
                traj = sim.run(t_next, rate_hz)
            except failure as err:
                # redo the chunk one sample at a time so the log keeps every finite sample
                try:
                    while sim.t_ns < round(t_next * 1e9):
                        j = math.floor(sim.t_ns * rate_hz / 1e9 + 1e-6) + 1
                        self._write_traj(sim.run(min(t_next, _sample_grid_ns(rate_hz, j) / 1e9),
                                                 rate_hz))
                except failure as again:
                    err = again
                print(f"rod-sim: {err}; the log holds {self.samples} samples, t = 0.."
                      f"{self.t_logged:g} s", file=sys.stderr)
                return EXIT_CHECK_FAILED
            self.wall += time.perf_counter() - started
            self._write_traj(traj)
        return EXIT_OK


def _salvage(path: Path) -> str:
    """After a failed write: keep ``path`` if it holds complete samples (say which), else
    remove it. Returns what was done, for the error line."""
    from ..io.series import read_rod_states

    try:
        t, _, _ = read_rod_states(path)
    except Exception:                         # nothing readable: no complete chunk
        t = ()
    if len(t):
        return (f"{path} keeps the {len(t)} samples of t = 0..{t[-1]:g} s written in complete "
                "chunks (no summary: readers scan it)")
    try:
        path.unlink()
    except OSError as err:
        return f"{path} holds no complete sample and could not be removed: {err.strerror or err}"
    return f"removed {path}, which held no complete sample"


def cmd_table1(args) -> int:
    from . import table1

    scene = load_scene(args.scene)
    rows = table1.compute(scene)
    if args.json:
        print(json.dumps({"rows": [r.as_dict() for r in rows]}, indent=1))
    else:
        print("Table 1 of the paper (n = 8, tip pulse): published values beside ours")
        print(table1.format_table(rows))
        worst = table1.summary(rows)
        print("largest |ours - paper|: " + ", ".join(f"{k} {v:.2g}" for k, v in worst.items()))
    return EXIT_OK


COMMANDS = {"simulate": cmd_simulate, "table1": cmd_table1, "node": cmd_node}


def run(args: argparse.Namespace) -> int:
    """Run a parsed command; library errors propagate (``main`` reports them)."""
    if args.command in COMMANDS:
        return COMMANDS[args.command](args)
    return plugin_modules()[args.command].run(args)


def _error(command: str, err, status: int) -> int:
    """Print the first line of ``err`` as ``rod-sim COMMAND: error: ...``; return ``status``."""
    message = str(err).splitlines()[0] if str(err) else type(err).__name__
    print(f"rod-sim {command}: error: {message}", file=sys.stderr)
    return status


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread like Ctrl-C's KeyboardInterrupt, so that the same
    cleanup runs (a log is closed with its summary, a sweep writes its finished rows)."""


_deferring = 0
_pending: list = []


def _on_signal(signum, frame) -> None:
    """SIGINT raises KeyboardInterrupt, SIGTERM :class:`Terminated`; inside
    :func:`signals_deferred` (a log write) the exception waits until the write is done. The
    first SIGTERM interrupts; a second one during the cleanup is ignored (SIGKILL is the way
    to stop a cleanup that hangs)."""
    if signum == signal.SIGTERM:
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
    stop = Terminated if signum == signal.SIGTERM else KeyboardInterrupt
    if _deferring:
        _pending.append(stop)
        return
    raise stop


@contextlib.contextmanager
def signals_deferred():
    """A Ctrl-C or SIGTERM arriving inside the block is raised when the block ends, so that
    a log record is never left half written (the log could not be closed cleanly then)."""
    global _deferring
    _deferring += 1
    try:
        yield
    finally:
        _deferring -= 1
    if not _deferring and _pending:
        stop = _pending[0]
        _pending.clear()
        raise stop


def handle_sigterm() -> None:
    """SIGTERM raises :class:`Terminated` (a KeyboardInterrupt) in the main thread, as SIGINT
    does: ``simulate``, ``compare``, ``sweep`` and the other commands close their files and
    exit with status 130, as for Ctrl-C (the node and ``replay`` install their own handler).
    Both wait for the end of a log write (:func:`signals_deferred`)."""
    if threading.current_thread() is threading.main_thread():
        # a mask inherited from the launcher (or left by a library's worker threads in this
        # process) would make the command deaf to Ctrl-C and SIGTERM
        if hasattr(signal, "pthread_sigmask"):
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})
        signal.signal(signal.SIGTERM, _on_signal)
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            signal.signal(signal.SIGINT, _on_signal)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    _pending.clear()
    handle_sigterm()
    log_module = sys.modules.get("rod_sim.io.log_reader")
    if log_module is not None:          # a log's damage warnings: once per command
        log_module._reported.clear()
    if argv[:1] == ["node"]:
        # argparse cannot hand "--ros-args ..." through a subparser untouched; the node has
        # its own parser (for --help and typos) and reports bad parameters with status 2.
        from ..ros.node import main as node_main

        return node_main(argv[1:], prog="rod-sim node")
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return run(args)
    except (SceneError, UsageError, FileExistsError, ValueError) as err:   # ModelError too
        return _error(args.command, err, EXIT_BAD_INPUT)
    except OSError as err:                  # a file that cannot be read or written
        where = f"{err.filename}: " if err.filename else ""
        return _error(args.command, f"{where}{err.strerror or err}", EXIT_BAD_INPUT)
    except MemoryError:
        return _error(args.command, "out of memory", EXIT_CHECK_FAILED)
    except RuntimeError as err:             # IntegrationError: the run could not go on
        return _error(args.command, err, EXIT_CHECK_FAILED)
    except KeyboardInterrupt as err:
        return _interrupted(args.command, err)
    except SystemError as err:
        # a signal handler's exception raised inside a compiled (numba) call comes back as
        # "SystemError: ... returned a result with an exception set", caused by it
        stop = _interruption(err)
        if stop is None:
            raise
        return _interrupted(args.command, stop)


def _interruption(err: BaseException) -> KeyboardInterrupt | None:
    """The KeyboardInterrupt (Ctrl-C or SIGTERM) that ``err`` was raised from, if any."""
    seen = set()
    while err is not None and id(err) not in seen:
        if isinstance(err, KeyboardInterrupt):
            return err
        seen.add(id(err))
        err = err.__cause__ or err.__context__
    return None


def _interrupted(command: str, err: KeyboardInterrupt) -> int:
    how = " (SIGTERM)" if isinstance(err, Terminated) else ""
    print(f"rod-sim {command}: interrupted{how}", file=sys.stderr)
    return 130


if __name__ == "__main__":
    sys.exit(main())
