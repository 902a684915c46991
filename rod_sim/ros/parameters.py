"""The rod_sim node's parameters (docs/interface.md section 3): their declarations with descriptors (type,
units, range, read-only), the settings read once at start and their checks, the texts of
rejected values, and the run-time check of a parameter change."""
from __future__ import annotations

import argparse
import textwrap
from dataclasses import dataclass
from typing import Any

from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                ParameterType, SetParametersResult)
from rclpy.exceptions import ParameterException

from rod_sim.core.integrators import INTEGRATORS
from rod_sim.core.models import MODELS
from rod_sim.app import limits
from rod_sim.ros.errors import NodeConfigError, one_line
from rod_sim.ros.qos import CLOCK_RELIABILITY

NODE_NAME = "rod_sim"
"""The node's default name: a params file applies under ``/rod_sim:`` (or ``/**:``)."""


@dataclass(frozen=True)
class ParameterSpec:
    """One node parameter: default (its type sets the ROS type), description with units,
    whether it can change at run time, an optional closed range and a constraint text."""

    name: str
    default: Any
    description: str
    read_only: bool = True
    range: tuple[float, float] | None = None
    constraints: str = ""

    def descriptor(self) -> ParameterDescriptor:
        kinds = {bool: ParameterType.PARAMETER_BOOL, float: ParameterType.PARAMETER_DOUBLE,
                 str: ParameterType.PARAMETER_STRING, int: ParameterType.PARAMETER_INTEGER}
        d = ParameterDescriptor(name=self.name, type=kinds[type(self.default)],
                                description=self.description, read_only=self.read_only,
                                additional_constraints=self.constraints)
        if self.range is not None and isinstance(self.default, int):
            d.integer_range = [IntegerRange(
                from_value=int(self.range[0]), to_value=int(self.range[1]), step=1)]
        elif self.range is not None:
            d.floating_point_range = [FloatingPointRange(
                from_value=float(self.range[0]), to_value=float(self.range[1]), step=0.0)]
        return d


PARAMETERS = (
    ParameterSpec("scene_file", "", "scene YAML file (docs/interface.md section 1): absolute, "
                  "package://PKG/PATH, or relative to the params file that sets it (else to "
                  "the working directory); required", constraints="an existing, valid scene file"),
    ParameterSpec("model", "reduced", "fidelity level of the chain model",
                  constraints="one of: " + ", ".join(MODELS)),
    ParameterSpec("rate_hz", 100.0, "control and publish rate [Hz]; every control period "
                  "1/rate_hz [s] of simulated time holds one command", range=(0.1, 10000.0)),
    ParameterSpec("real_time_factor", 1.0, "simulated seconds per wall second [1]: 1.0 = "
                  "wall-clock pace, 0 = as fast as possible; ignored in sync_mode",
                  read_only=False, range=(0.0, 1000.0)),
    ParameterSpec("sync_mode", False, "lockstep: advance exactly one control period per "
                  "received valid nodal_forces command, nothing before the first"),
    ParameterSpec("record_path", "", "MCAP log to write (docs/interface.md section 4); '' = no recording; "
                  "an existing file is refused"),
    ParameterSpec("command_timeout", 0.5, "[s] after the last valid command at which the "
                  "command force falls back to zero: wall time at a real-time pace, simulated "
                  "time when as fast as possible or stepped by ~/step; 0 = hold forever",
                  read_only=False, range=(0.0, 3600.0)),
    ParameterSpec("integrator", "dop853-jit", "time stepper",
                  constraints="one of: " + ", ".join(INTEGRATORS)),
    ParameterSpec("rtol", 1e-8, "relative and absolute tolerance of adaptive integrators [1]",
                  range=(1e-14, 1e-2)),
    ParameterSpec("publish_clock", True, "publish simulated time on /clock (also while "
                  "paused or waiting: the frozen time, every 0.1 s of wall time)"),
    ParameterSpec("clock_reliability", "reliable", "QoS reliability of /clock (depth 1, "
                  "volatile): reliable reaches both default-QoS and ClockQoS (best effort) "
                  "subscribers", constraints="one of: " + ", ".join(CLOCK_RELIABILITY)),
    ParameterSpec("start_paused", False, "start paused at t = 0 until ~/pause false or the "
                  "first valid nodal_forces command"),
    ParameterSpec("step_count", 1, "control periods one ~/step call advances",
                  read_only=False, range=(1, 10000)),
    ParameterSpec("max_period_cost", 0.5, "[s] wall time one control period may cost: the "
                  "integrator's work per period is capped accordingly (steps or derivative "
                  "evaluations, cost measured at start); a period that needs more pauses the "
                  "simulation with 'work budget exceeded' (ERROR on diagnostics)",
                  range=(0.01, 3600.0)),
    ParameterSpec("frame_id", "world", "frame_id of the published headers", read_only=False),
    ParameterSpec("markers_rate_hz", limits.MARKERS_RATE_HZ, "rate of the markers topic [Hz of "
                  "simulated time], for display (RViz, Foxglove): published and recorded with "
                  "the states of every k-th control period, k = max(1, round(rate_hz / "
                  "markers_rate_hz)), counted from t = 0; 0 = every control period",
                  range=(0.0, limits.MAX_MARKERS_RATE_HZ)),
    ParameterSpec("live_view_port", 0, "TCP port of the live view (a Foxglove WebSocket "
                  "server on 127.0.0.1, foxglove-sdk: 3-D scene, frame transforms, joint states, "
                  "plot series, pause/step/reset); 0 = off", range=(0, 65535)),
)


@dataclass(frozen=True)
class NodeSettings:
    """The node's parameters, read once at start (see :data:`PARAMETERS` for units)."""

    scene_file: str
    model: str
    rate_hz: float
    real_time_factor: float
    sync_mode: bool
    record_path: str
    command_timeout: float
    integrator: str
    rtol: float
    publish_clock: bool
    frame_id: str
    markers_rate_hz: float
    clock_reliability: str
    start_paused: bool
    step_count: int
    max_period_cost: float
    live_view_port: int = 0

    def check(self, full_name: str = NODE_NAME, params_files: tuple[str, ...] = ()) -> None:
        """Raise NodeConfigError for values the descriptors' ranges do not cover. The node's
        ``full_name`` and the ``params_files`` given explain a missing scene_file."""
        if not self.scene_file:
            hint = (f"; {', '.join(params_files)} has no entry for this node: a params file "
                    f"applies under its full name {full_name}: or under /**:"
                    if params_files else "")
            raise NodeConfigError("scene_file: parameter is required (e.g. -p scene_file:="
                                  "config/paper_example.yaml)" + hint)
        if self.clock_reliability not in CLOCK_RELIABILITY:
            raise NodeConfigError(f"clock_reliability: unknown value {self.clock_reliability!r}"
                                  f" (choose from {', '.join(CLOCK_RELIABILITY)})")
        if self.model not in MODELS:
            raise NodeConfigError(f"model: unknown model {self.model!r} "
                                  f"(choose from {', '.join(MODELS)})")
        if self.integrator not in INTEGRATORS:
            raise NodeConfigError(f"integrator: unknown integrator {self.integrator!r} "
                                  f"(choose from {', '.join(INTEGRATORS)})")
        if not self.frame_id:
            raise NodeConfigError("frame_id: must not be empty")



def parameter_error(spec: ParameterSpec, exc: ParameterException) -> str:
    """One line for a rejected parameter value (rclpy appends the name; we lead with it)."""
    text = one_line(exc)
    if text.endswith(f": {spec.name}"):
        text = text[:-len(spec.name) - 2]
    if isinstance(spec.default, float) and "of type 'INTEGER'" in text:
        text += " (write a double, e.g. 100.0)"
    return f"{spec.name}: {text}"


def declare_settings(node, params_files: tuple[str, ...] = ()) -> NodeSettings:
    """Declare :data:`PARAMETERS` on ``node`` (an rclpy Node) and return their checked values.
    Raises NodeConfigError for a refused or unusable value (``params_files`` explain a
    missing scene_file)."""
    values = {}
    for spec in PARAMETERS:
        try:
            values[spec.name] = node.declare_parameter(
                spec.name, spec.default, spec.descriptor()).value
        except ParameterException as exc:
            raise NodeConfigError(parameter_error(spec, exc)) from None
    settings = NodeSettings(**values)
    settings.check(node.get_fully_qualified_name(), params_files)
    return settings


def validate_change(params) -> SetParametersResult:
    """On-set callback: refuse run-time values the descriptors do not rule out."""
    for p in params:
        if p.name == "frame_id" and not p.value:
            return SetParametersResult(successful=False, reason="frame_id: must not be empty")
    return SetParametersResult(successful=True)


def unknown_overrides(node) -> list[str]:
    """Overrides (-p, params files) given to ``node`` that name none of its parameters."""
    known = {spec.name for spec in PARAMETERS} | {"use_sim_time"}
    return sorted(set(getattr(node, "_parameter_overrides", {})) - known)


def unknown_warning(unknown: list[str]) -> str:
    """The warning about overrides that name no parameter of the node."""
    return (f"unknown parameter(s) ignored: {', '.join(unknown)} (parameters of this node: "
            f"{', '.join(spec.name for spec in PARAMETERS)})")


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
    """The node's command line (its own options: --help; the rest are ROS arguments)."""
    return argparse.ArgumentParser(
        prog=prog, formatter_class=argparse.RawDescriptionHelpFormatter,
        description="rod_sim ROS 2 node: a chain of elastic rods driven by nodal forces\n"
        "(docs/interface.md section 3). Configure it with ROS arguments, e.g.\n"
        "  --ros-args --params-file config/sim_node.params.yaml -p scene_file:=SCENE.yaml",
        epilog=parameter_help())
