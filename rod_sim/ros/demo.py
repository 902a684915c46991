"""Demo: the simulator node, a PD controller and a recording, in one process.

    python -m rod_sim.ros.demo --out out/demo.mcap --duration 3
    python -m rod_sim.ros.demo --scene config/two_wing_deployment.yaml

On a scene with a free base (the second line) the controller is the attitude controller
(:mod:`rod_sim.ros.attitude`: the base's moment from its angle), the run is in lockstep and
lasts 15 s by default (the wings of config/two_wing_deployment.yaml have latched by 13.4 s),
uses the full model by default and ``rod-sim compare`` is run on the log at the end
(``--no-compare`` skips it): compare re-runs the log through the full model, and a reduced-model
log of the 15 s deployment departs from it by 0.25-0.35 rad once the panels latch (measured,
with and without the controller), so only a full-model log can pass at the default 0.01 rad;
otherwise
the hinge PD controller (:mod:`rod_sim.ros.controller`), as before.

Both nodes share one executor; the simulator records the log of docs/interface.md section 4. After
``--duration`` seconds of simulated time (or on Ctrl-C/SIGTERM) both nodes are shut down, the
log is closed with its summary and its path is printed. The ROS graph stays on this machine:
``ROS_AUTOMATIC_DISCOVERY_RANGE`` is set to LOCALHOST and, unless already set,
``ROS_DOMAIN_ID`` to a value derived from the process id.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

DEMO_DOMAIN_BASE = 120
"""ROS_DOMAIN_ID = DEMO_DOMAIN_BASE + pid % DEMO_DOMAIN_SPAN when none is set."""
DEMO_DOMAIN_SPAN = 40


def isolate_ros_graph(environ=os.environ) -> int:
    """Keep discovery on this machine and pick a domain id if none is set; returns it."""
    environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    if not environ.get("ROS_DOMAIN_ID"):
        environ["ROS_DOMAIN_ID"] = str(DEMO_DOMAIN_BASE + os.getpid() % DEMO_DOMAIN_SPAN)
    return int(environ["ROS_DOMAIN_ID"])


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m rod_sim.ros.demo",
        description="Run the rod_sim node with the hinge PD controller in one process and "
                    "record an MCAP log.")
    parser.add_argument("--out", type=Path, default=Path("out/demo.mcap"),
                        help="MCAP log to write (default out/demo.mcap)")
    parser.add_argument("--duration", type=float, default=None,
                        help="simulated time to run [s] (default 3; 15 on a free base)")
    parser.add_argument("--scene", default="config/paper_example.yaml",
                        help="scene file (default config/paper_example.yaml)")
    parser.add_argument("--model", default=None,
                        help="reduced, full or rigid (default reduced; full on a free base)")
    parser.add_argument("--rate", type=float, default=100.0, help="control rate [Hz]")
    parser.add_argument("--rtf", type=float, default=1.0,
                        help="real-time factor (1 = wall-clock pace, 0 = as fast as possible)")
    parser.add_argument("--sync", action="store_true",
                        help="lockstep: one control period per controller command")
    parser.add_argument("--kp", type=float, default=None,
                        help="controller proportional gain [N m/rad] (default: the node's)")
    parser.add_argument("--kd", type=float, default=None,
                        help="controller derivative gain [N m s/rad] (default: the node's)")
    parser.add_argument("--force", action="store_true", help="overwrite an existing --out")
    parser.add_argument("--no-compare", action="store_true",
                        help="free base: do not run rod-sim compare on the log")
    return parser


def _free_base(scene_file: str) -> bool:
    """Whether the scene file (if it loads) has a free base; a scene that does not load is
    the node's to report."""
    from rod_sim.core.scene import SceneError
    from rod_sim.io.scene_yaml import load_scene

    try:
        return load_scene(scene_file).base.mode == "free"
    except (SceneError, OSError, ValueError):
        return False


def _controller(free_base: bool, args, scene: str):
    """The attitude controller on a free base, else the hinge PD controller."""
    from rclpy.parameter import Parameter

    gains = [Parameter(name, value=float(value)) for name, value in
             (("kp", args.kp), ("kd", args.kd)) if value is not None]
    if free_base:
        from rod_sim.ros.attitude import AttitudePDController

        return AttitudePDController(parameter_overrides=gains)
    from rod_sim.ros.controller import HingePDController

    return HingePDController(parameter_overrides=[Parameter("scene_file", value=scene),
                                                  *gains])


def _compare(log: Path) -> int:
    """``rod-sim compare`` on the log (its report printed); its exit code."""
    import subprocess

    print(f"demo: rod-sim compare {log}", flush=True)
    return subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", "compare", str(log)]
                          ).returncode


def run(args: argparse.Namespace) -> int:
    """Run the demo; 0 on success (a free base: compare's exit code), 2 for bad input (one
    line on stderr)."""
    free_base = _free_base(str(args.scene))
    if args.duration is None:
        args.duration = 15.0 if free_base else 3.0
    if args.model is None:      # compare judges a free base's log against the full model
        args.model = "full" if free_base else "reduced"
    if free_base:
        args.sync = True
    if not (args.duration > 0):
        print(f"demo: error: --duration must be > 0 s (got {args.duration})", file=sys.stderr)
        return 2
    if args.out.exists():
        if not args.force:
            print(f"demo: error: {args.out} exists (remove it or pass --force)", file=sys.stderr)
            return 2
        args.out.unlink()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    isolate_ros_graph()

    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.parameter import Parameter
    from rclpy.signals import SignalHandlerOptions

    from rod_sim.core.scene import SceneError
    from rod_sim.ros.node import NodeConfigError, RodSimNode
    from rod_sim.ros.executor import LeanExecutor
    from rod_sim.ros.process import StopRequest, spin_until

    from rod_sim.app.common import watch_compiles

    watch_compiles("demo")      # a driver not in numba's cache: what, why, how long
    rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
    nodes = []
    with StopRequest() as stop:
        try:
            sim = RodSimNode(parameter_overrides=[
                Parameter("scene_file", value=str(args.scene)),
                Parameter("model", value=args.model),
                Parameter("rate_hz", value=float(args.rate)),
                Parameter("real_time_factor", value=float(args.rtf)),
                Parameter("sync_mode", value=bool(args.sync)),
                Parameter("record_path", value=str(args.out))])
            nodes.append(sim)
            controller = _controller(free_base, args, str(args.scene))
            nodes.append(controller)
            executor = LeanExecutor()
            for node in nodes:
                executor.add_node(node)
            spin_until(executor, stop, done=lambda: sim.sim_time >= args.duration)
            summary = (f"simulated {sim.sim_time:.3f} s, {controller.commands_sent} commands, "
                       f"{sim.commands_rejected} rejected")
            if free_base and controller.psi_history:
                psi = [p for _, p in controller.psi_history]
                summary += (f"; bus angle psi: max |psi| {max(map(abs, psi)):.3g} rad, "
                            f"final {psi[-1]:.3g} rad")
        except (NodeConfigError, SceneError) as exc:
            print(f"demo: error: {exc}", file=sys.stderr)
            return 2
        except (KeyboardInterrupt, ExternalShutdownException):
            summary = "interrupted"
        finally:
            for node in reversed(nodes):
                node.destroy_node()
            rclpy.try_shutdown()
    print(f"demo: {summary}; log: {args.out}", flush=True)
    if free_base and not args.no_compare and summary != "interrupted":
        return _compare(args.out)
    return 0


def main(argv: list[str] | None = None) -> int:
    return run(build_parser().parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
