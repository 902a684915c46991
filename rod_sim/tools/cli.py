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
import importlib
import json
import math
import pkgutil
import re
import sys
import time
from pathlib import Path

from .. import __version__
from ..core.names import INTEGRATOR_NAMES as INTEGRATORS
from ..core.names import MODEL_NAMES
from ..core.scene import SceneError

from .common import (EXIT_BAD_INPUT, EXIT_CHECK_FAILED, EXIT_OK, PAPER_EXAMPLE, UsageError,
                     load_scene, new_output_path)
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
                                     "SPEC section 5 sampled at --rate in simulated time.")
    sim.add_argument("scene", help="scene YAML file")
    sim.add_argument("--model", choices=sorted(MODEL_NAMES), default="reduced",
                     help="fidelity: full (3n ODEs), reduced (n ODEs, quasi-static bending) or "
                          "rigid (default reduced)")
    sim.add_argument("--t-end", type=_positive_float, required=True, help="end time [s]")
    sim.add_argument("--out", required=True, help="MCAP log to write (must not exist)")
    sim.add_argument("--rate", type=_positive_float, default=100.0,
                     help="sampling rate of the log [Hz of simulated time] (default 100)")
    sim.add_argument("--integrator", choices=INTEGRATORS, default="dop853-jit",
                     help="time stepper: dop853-jit (compiled adaptive Dormand-Prince 8(5,3), "
                          "--rtol/--atol; the default), rk4, rk2, euler (compiled fixed step, "
                          "--step) or scipy's RK45, DOP853, Radau, BDF, LSODA")
    sim.add_argument("--rtol", type=_positive_float, default=None,
                     help="relative tolerance of adaptive integrators (default 1e-8)")
    sim.add_argument("--atol", type=_positive_float, default=None,
                     help="absolute tolerance (default = rtol)")
    sim.add_argument("--step", type=_positive_float, default=None,
                     help="largest step of fixed-step integrators [s] (default 1e-3)")
    sim.add_argument("--frame-id", default="world",
                     help="frame_id of the logged headers, poses and markers (default world)")

    t1 = sub.add_parser("table1", help="recompute the seed paper's Table 1",
                        description="Recompute Table 1 of the seed paper with the full and "
                                    "reduced models and print it beside the published values.")
    t1.add_argument("--json", action="store_true", help="machine-readable output")
    t1.add_argument("--scene", default=str(PAPER_EXAMPLE), help=argparse.SUPPRESS)
    node = sub.add_parser("node", help="the ROS 2 simulator node (SPEC section 4)",
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


def cmd_simulate(args) -> int:
    from ..core.integrators import IntegrationError, make_integrator
    from ..core.models import make_model
    from ..core.simulator import Simulator
    from ..io.hinge_events import write_events
    from ..io.mcap_log import LogWriter
    from ..io.scene_yaml import scene_to_yaml

    scene = load_scene(args.scene)
    model = make_model(args.model, scene)
    integrator = make_integrator(args.integrator, rtol=args.rtol, atol=args.atol, step=args.step)
    out = new_output_path(args.out)
    Simulator(model, make_integrator(args.integrator, step=args.step)).advance(1e-3)  # JIT warm-up
    sim = Simulator(model, integrator)
    metadata = {"scene": scene_to_yaml(scene), "model": model.name,
                "integrator": integrator.describe(), "version": __version__,
                "rate_hz": repr(args.rate), "source": "rod-sim simulate"}
    from ..core.validity import ValidityMonitor

    validity = ValidityMonitor(model)
    wall = 0.0
    samples = 0
    status = EXIT_OK
    chunk = 0.5                                  # simulated seconds integrated per call
    logged_events = 0                            # hinge events (docs/hinges.md) written so far
    with LogWriter(out, metadata=metadata) as log:
        first = True

        def write(traj) -> None:
            """Log the samples of ``traj`` (its first one is the previous call's last) and the
            hinge events since the last call; the validity monitor sees every sample."""
            nonlocal first, samples, logged_events
            for i in range(0 if first else 1, traj.t.size):
                snap = traj.snapshot(i)
                validity.update(snap.t, traj.y[i], None, snap.alpha, snap.beta)
                log.write_snapshot(snap, scene, frame_id=args.frame_id)
                samples += 1
            first = False
            logged_events += write_events(log, sim.events[logged_events:])

        while sim.t_ns < round(args.t_end * 1e9):
            t_next = min(args.t_end, (math.floor(sim.t / chunk + 1e-9) + 1) * chunk)
            started = time.perf_counter()
            try:
                traj = sim.run(t_next, args.rate)
            except IntegrationError as err:
                # redo the chunk one sample at a time so the log keeps every finite sample
                try:
                    while True:
                        write(sim.run(min(t_next, sim.t + 1.0 / args.rate), args.rate))
                except IntegrationError as again:
                    err = again
                except ValueError:
                    pass
                print(f"rod-sim: {err}; the log holds the samples up to t = {sim.t:g} s",
                      file=sys.stderr)
                status = EXIT_CHECK_FAILED
                break
            wall += time.perf_counter() - started
            write(traj)
    rtf = sim.t / wall if wall > 0 else math.inf
    print(f"{scene.name}: {model.name} model, {integrator.describe()}, t = 0..{sim.t:g} s, "
          f"{samples} samples -> {out} (integration {wall:.3f} s wall, {rtf:.0f}x real time, "
          f"{integrator.stats.nfev} rhs evaluations"
          + (f", {logged_events} hinge events" if logged_events else "") + ")")
    if validity.summary():
        print(f"rod-sim simulate: validity warning: {validity.summary()}", file=sys.stderr)
    return status


def cmd_table1(args) -> int:
    from . import table1

    scene = load_scene(args.scene)
    rows = table1.compute(scene)
    if args.json:
        print(json.dumps({"rows": [r.as_dict() for r in rows]}, indent=1))
    else:
        print("Table 1 of the seed paper (n = 8, tip pulse): published values beside ours")
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


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
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
        message = str(err).splitlines()[0] if str(err) else type(err).__name__
        print(f"rod-sim {args.command}: error: {message}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("rod-sim: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
