"""The rod_sim ROS 2 node (docs/interface.md section 3): chains of elastic rods driven by nodal
forces and hinge torques, on a base driven by a wrench and a reaction wheel; ``sim_node`` /
``rod-sim node`` / ``python -m rod_sim.ros.node --ros-args -p
scene_file:=config/paper_example.yaml [-p sync_mode:=true]``.

This module is wiring: ROS entities whose callbacks call parts with one job each, none needing
a ROS graph: parameters (settings), simulation (scene, model, simulator, work budget), inputs
(command intakes, held inputs, lockstep queue), period (one control period: integration within
the budget, energy ledger, validity), pacing (real-time pace), outputs (the table of output
topics: each message encoded once, the same bytes published and recorded), control (pause,
step, reset), recording (the log) and process (the process). Time advances in whole control
periods of simulated time with the inputs held, paced in real time, as fast as possible, or
one period per command in lockstep; every stamp and log time is simulated time.
"""
from __future__ import annotations

import dataclasses
import functools
import sys
import time
from pathlib import Path

from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from std_srvs.srv import SetBool, Trigger

from rod_sim.core.units import NS_PER_S
from rod_sim.io import topics
from rod_sim.io.log_writer import LogWriter
from rod_sim.io.scene_yaml import scene_to_yaml
from rod_sim.ros import simulation
from rod_sim.ros.applied_base import base_values
from rod_sim.ros.command_layout import CommandLayout
from rod_sim.ros.commands import FORCES, MESSAGE_TYPES, TORQUES, WRENCH, CommandIntake
from rod_sim.ros.control import NextTurn, RunControl
from rod_sim.ros.conversions import message_class, message_to_dict
from rod_sim.ros.errors import NodeConfigError, ThrottledLog
from rod_sim.ros.inputs import Inputs
from rod_sim.ros.live import NodeLiveView
from rod_sim.ros.monitor import DiagnosticReport, node_report
from rod_sim.ros.outputs import (OUTPUTS, Outputs, SimClock, create_publishers, divider,
                                 has_hinge_events, log_depths, quiet_events)
from rod_sim.ros.pacing import Pacing
from rod_sim.ros.parameters import (NODE_NAME, PARAMETERS, build_parser, declare_settings,
                                    unknown_overrides, unknown_warning, validate_change)
from rod_sim.ros.process import params_files, parse_cli, run_node, same_name_warning
from rod_sim.ros.qos import COMMAND_QOS, SERVICE_QOS, SERVICE_QUEUE_DEPTH, clock_qos
from rod_sim.ros.recording import NodeRecording, create_log, node_log_metadata, offered_qos

__all__ = ["RodSimNode", "NodeConfigError", "main", "PARAMETERS", "SERVICE_QUEUE_DEPTH",
           "params_files", "has_hinge_events"]
COMMAND_TYPE = "std_msgs/msg/Float64MultiArray"
CDR_LE = b"\x00\x01"
"""The encapsulation of little-endian (plain) CDR, the first two bytes of a serialized message."""
DIAGNOSTICS_TOPIC = "/diagnostics"
"""Absolute, where diagnostic_aggregator listens (as diagnostic_updater publishes)."""
DIAGNOSTICS_STATUS_NAME = topics.DIAGNOSTICS_STATUS_NAME
DIAGNOSTICS_PERIOD_S = 1.0   # [s] wall period of diagnostics
IDLE_CLOCK_PERIOD_S = 0.1    # [s] wall period of /clock while no period advances
WAITING_LOG_PERIOD_S = 3.0   # [s] wall period of the "waiting for ..." line at t = 0
WAITING_REPUBLISH_PERIOD_S = 0.5  # [s] lockstep before the first command: state again
NAME_CHECK_DELAY_S = 2.0     # [s] after start: another node of the same name on the graph?
SYNC_BATCH = 16              # lockstep periods per callback before yielding to others
STEP_SLICE_S = 0.1           # [s] ~/step stepping before the executor serves others


class RodSimNode(Node):
    """The simulator node. ``node_kwargs`` go to :class:`rclpy.node.Node` (``context``,
    ``parameter_overrides``, ``namespace``, ...). Raises NodeConfigError for bad parameters, a
    missing or invalid scene, or a log that cannot be created."""

    def __init__(self, params_files: tuple[str, ...] = (), **node_kwargs):
        super().__init__(NODE_NAME, **node_kwargs)
        self._recording = NodeRecording(lambda path: self._open_log(path), self.get_logger())
        self._throttle = ThrottledLog(self.get_logger())
        self._throttle_until, self._log_throttled = self._throttle.until, self._throttle.log
        self._params_files = tuple(params_files)
        self.name_conflict = False
        """True once another node with this node's full name was seen on the graph."""
        try:
            s = self.settings = declare_settings(self, self._params_files)
            self.add_on_set_parameters_callback(validate_change)
            self.add_post_set_parameters_callback(self._apply_parameters)
            built = simulation.build(s, self.get_fully_qualified_name(), self._params_files)
            if built.note:
                self.get_logger().warning(built.note)
            self.scene_path, self.scene, self.model = built.scene_path, built.scene, built.model
            self.sim, self.period_ns = built.sim, built.period_ns
            self.period = simulation.start(built, s)
            self._budget = built.budget
            layout = CommandLayout.of_scene(self.scene)
            self.inputs = Inputs(self.scene.n, s.command_timeout, layout, self._base_angle,
                                 s.frame_id)
            self.control = RunControl(s.sync_mode, s.start_paused, s.real_time_factor)
            self._tick_timer = None
            self._pacing = Pacing(self.period_ns, s.real_time_factor)
            self._topic_names = {o.name: self.resolve_topic_name(o.name) for o in OUTPUTS}
            self._topic_names.update({t: self.resolve_topic_name(t)
                                      for t in (FORCES, TORQUES, WRENCH)})
            self._topic_names["diagnostics"] = self.resolve_topic_name(DIAGNOSTICS_TOPIC)
            self._recording.start(Path(s.record_path) if s.record_path else None)
            self._create_interfaces()
        except BaseException:
            self.destroy_node()
            raise
        self._outputs.descriptions(self.sim.t_ns)
        self._publish_state(self.sim.snapshot())
        self.unknown_parameters = unknown_overrides(self)
        if self.unknown_parameters:
            self.get_logger().warning(unknown_warning(self.unknown_parameters))
        self.get_logger().info(simulation.start_line(
            self.get_fully_qualified_name(), built, self.control.mode(),
            tuple(self._topic_names[t] for t in self._command_topics()), self.log_path, s))

    def _command_topics(self) -> tuple[str, ...]:
        """The command topics the start-up line names (base_wrench only for a free base; it
        is subscribed in any case, so that a wrench sent to another base is counted)."""
        return (FORCES, TORQUES) + ((WRENCH,) if self.inputs.layout.free_base else ())

    def _base_angle(self) -> float:
        """The base's angle psi [rad] now (turns a base-frame wrench into Oxy)."""
        return self.model.base_state(self.sim.t, self.sim.y).psi

    def _create_interfaces(self) -> None:
        s = self.settings
        self._pubs = create_publishers(self, self._topic_names, self.scene, s.sync_mode)
        self._outputs = Outputs(self.scene, self._topic_names, self._pubs, self._recording,
                                self.period_ns, s.frame_id,
                                {o.name: divider(s.rate_hz, getattr(s, o.rate_parameter))
                                 for o in OUTPUTS if o.rate_parameter})
        self._sim_clock = SimClock(self.create_publisher(
            message_class(topics.TOPIC_TYPES["clock"]), "/clock", clock_qos(s.clock_reliability),
            event_callbacks=quiet_events()) if s.publish_clock else None, IDLE_CLOCK_PERIOD_S)
        for topic, intake in self.inputs.intakes.items():   # raw: length checked first
            self.create_subscription(intake.message_class, self._topic_names[topic],
                                     functools.partial(self._on_command_bytes, intake=intake),
                                     COMMAND_QOS, raw=True)
        self.create_service(Trigger, "~/reset", self._on_reset, qos_profile=SERVICE_QOS)
        # its own reentrant group: between the slices of a long ~/step the other callbacks
        # run (single-threaded executor: they interleave only where _on_step awaits)
        self.create_service(Trigger, "~/step", self._on_step, qos_profile=SERVICE_QOS,
                            callback_group=ReentrantCallbackGroup())
        self.create_service(SetBool, "~/pause", self._on_pause, qos_profile=SERVICE_QOS)
        self._step_wake = self.create_guard_condition(lambda: None)
        self._sync_trigger = self.create_guard_condition(self._on_sync_trigger)
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        timers = [(DIAGNOSTICS_PERIOD_S, self.publish_diagnostics),
                  (WAITING_LOG_PERIOD_S, self._log_waiting)]
        if s.publish_clock:
            timers.append((IDLE_CLOCK_PERIOD_S, lambda: self._sim_clock.idle(self.sim.t_ns)))
        if s.sync_mode:
            timers.append((WAITING_REPUBLISH_PERIOD_S, self._republish_waiting))
        for period, callback in timers:
            self.create_timer(period, callback, clock=self._steady)
        self._name_timer = self.create_timer(NAME_CHECK_DELAY_S, self._check_name_unique,
                                             clock=self._steady)
        self._configure_pacing()
        self._live = None if not s.live_view_port else NodeLiveView(self, s.live_view_port)

    def _check_name_unique(self) -> None:
        """Once, after discovery: warn when another node has this node's full name."""
        self._name_timer.cancel()
        warning = same_name_warning(self)
        if warning:
            self.name_conflict = True
            self.get_logger().warning(warning)

    def _log_waiting(self) -> None:
        """Every few seconds while the simulation waits at its start: say what it waits for."""
        line = self.control.waiting_line(self.sim.t, self._topic_names[FORCES],
                                         self._topic_names[TORQUES], self.inputs.any_command())
        if line:
            self.get_logger().info(line)

    def _configure_pacing(self) -> None:
        """(Re)create the pacing timer for the current real-time factor (none in lockstep)."""
        if self._tick_timer is not None:
            self.destroy_timer(self._tick_timer)
        self._pacing.set_rtf(self.control.rtf)
        self._tick_timer = (None if self.control.sync_mode else self.create_timer(
            self._pacing.tick_period_s(), self._on_tick, clock=self._steady))

    def _apply_parameters(self, params) -> None:
        for p in params:
            if p.name == "real_time_factor":
                self.control.rtf = float(p.value)
                self._configure_pacing()
                self.period.meter.restart(time.monotonic_ns())
            elif p.name == "command_timeout":
                self.inputs.set_timeout(float(p.value))
            elif p.name == "frame_id":
                self._outputs.frame_id = str(p.value)
                self.inputs.set_inertial_frame(str(p.value))
                self._outputs.descriptions(self.sim.t_ns, record=False,
                                           which=("robot_description",))
            elif p.name == "step_count":
                self.settings = dataclasses.replace(self.settings, step_count=int(p.value))

    sim_time = property(lambda self: self.sim.t, doc="Simulated time [s].")
    paused = property(lambda self: self.control.paused)
    error = property(lambda self: self.control.error, doc="The cause of the last failure.")
    commands_rejected = property(lambda self: self.inputs.forces.rejected)
    log_path = property(lambda self: self._recording.path, doc="The log being written.")

    def _on_command_bytes(self, data: bytes, intake: CommandIntake | None = None) -> None:
        """A serialized command: checked, recorded, validated, held (lockstep: queued)."""
        intake = self.inputs.forces if intake is None else intake
        command, warning = self.inputs.receive(
            data, intake, self.sim.t_ns, functools.partial(self._record_command, intake.kind))
        if command is None:
            self._log_throttled(f"rejected {intake.kind}", "warning", warning)
            return
        if self.control.first_command():
            self._pacing.unanchor()
            self.get_logger().info(f"first command received: running from t = {self.sim.t:g} s")
        if self.settings.sync_mode and self.control.running():
            self.inputs.queue.append(command)
            # its period at once, in this callback: a round through the guard condition
            # costs the executor another wait (rclpy rebuilds its wait set: ~0.2-0.4 ms)
            self._on_sync_trigger()

    def _record_command(self, kind: str, msg, data: bytes) -> None:
        """Record a received command: its bytes as they came (as rosbag2 records) when they
        are little-endian CDR, else re-encoded from the message (the log is little-endian)."""
        topic, type_name = self._topic_names[kind], MESSAGE_TYPES[kind]
        if bytes(data[:2]) == CDR_LE:
            self._recording.record_cdr(topic, type_name, self.sim.t_ns, bytes(data))
        else:
            self._recording.record(topic, type_name, self.sim.t_ns, message_to_dict(msg))

    def _held(self, wall_age: bool):
        held, notes = self.inputs.held(self.sim.t_ns, wall_age)
        for kind, note in notes:
            self._log_throttled(f"timeout {kind}", "info", note)
        return held

    def _on_tick(self) -> None:
        """Pacing timer: advance the periods that are due (never in lockstep)."""
        if not self.control.running():
            self._pacing.unanchor()
            return
        self._pacing.tick(self.sim.t_ns, lambda wall_age: self._step_period(self._held(wall_age)),
                          self.control.running, self._budget.seconds,
                          lambda text: self._log_throttled("dropped", "warning", text))

    def _on_sync_trigger(self) -> None:
        """Lockstep: one period per queued command, a bounded batch per callback."""
        if self.inputs.drain(self._step_period, self.control.running, time.monotonic_ns()
                             + self._budget.seconds * NS_PER_S, SYNC_BATCH):
            self._sync_trigger.trigger()

    def _step_period(self, held) -> bool:
        """One period holding ``held`` ((n, 3) [X, Y, T], (n + 2, 3) with a free base's rows,
        or (n, 2) forces) and publish its outputs; False (paused, reported) when the
        integration fails."""
        snap = self.period.run(held, self._publish_applied)
        if snap is None:
            self.control.fail(self.period.error)
            self.get_logger().error(f"integration failed: {self.control.error}; simulation "
                                    "paused (call ~/reset, or ~/pause false to retry)")
            self._pacing.unanchor()
            self.publish_diagnostics()
            return False
        self._publish_state(snap)
        self._outputs.events(self.sim.events[self.period.events_seen:])
        self.period.events_seen = len(self.sim.events)
        return True

    def _publish_applied(self, t_ns: int) -> None:
        n, held = self.scene.n, self.sim.held
        loads = self.model.loads_at(t_ns / NS_PER_S, held)
        self._outputs.applied(t_ns, loads[:n, :2].copy(), held[:n, 2].copy(),
                              base_values(loads) if self.inputs.layout.free_base else None)

    def _publish_state(self, snap) -> None:
        self.period.note_state(snap)
        self._sim_clock.publish(self.sim.t_ns)   # /clock first: no output is stamped later
        self._outputs.state(snap, self.sim.t_ns)

    def _republish_waiting(self) -> None:
        """Lockstep before the first command: the waiting state again (not recorded)."""
        if not (self.inputs.any_command() or self.inputs.queue or self.control.error):
            self._outputs.state(self.sim.snapshot(), self.sim.t_ns, record=False)

    def diagnostic_report(self) -> DiagnosticReport:
        """The health of the simulation over the window since the last diagnostics."""
        return node_report(
            self.control, self.period, self.inputs, self._pacing.dropped, self.sim.t,
            self.period_ns, self.sim.integrator.describe(), self._recording.error,
            {"scene": self.scene.name, "rate_hz": f"{self.settings.rate_hz:g}",
             "recording": str(self.log_path) if self.log_path else "off",
             "work_budget": self._budget.describe(), "node": self.get_fully_qualified_name()})

    def publish_diagnostics(self) -> None:
        """Publish (and record) one ``diagnostics`` message and start a new window."""
        level, message, values = self.diagnostic_report().status()
        self._outputs.message("diagnostics", self.sim.t_ns, topics.diagnostics(
            self.sim.t, values, self.scene.name, level=level, message=message, frame_id="",
            name=DIAGNOSTICS_STATUS_NAME))
        self.period.meter.restart(time.monotonic_ns())
        self.period.take_extremes()

    # ----- services (logic in rod_sim.ros.control) -----

    def _on_reset(self, request, response):
        """Back to the initial state at t = 0 (commands and errors cleared); a ~/step in
        progress ends ("interrupted"); the log continues in the next file."""
        response.success, response.message = True, self.reset()
        return response

    def reset(self) -> str:
        self.control.reset()
        self.period.reset()
        self.inputs.clear()
        self._outputs.forget_applied()
        self._pacing.unanchor()
        note = self._recording.roll()
        self._outputs.descriptions(self.sim.t_ns)
        self._publish_state(self.sim.snapshot())
        message = "reset to the initial state at t = 0 s" + note
        self.get_logger().info(message)
        return message

    async def _on_step(self, request, response):
        """``step_count`` periods while paused, in slices (see RunControl.step)."""
        async def next_turn():
            self._step_wake.trigger()
            await NextTurn()
        response.success, response.message = await self.control.step(
            self.settings.step_count, lambda: self._step_period(self._held(wall_age=False)),
            lambda: self.sim.t, next_turn, min(STEP_SLICE_S, self.settings.max_period_cost))
        return response

    def _on_pause(self, request, response):
        response.success, response.message = True, self.pause(request.data)
        return response

    def pause(self, pause: bool) -> str:
        """True: pause; False: resume (re-anchors the real-time clock)."""
        message = self.control.pause(pause, self.sim.t)
        if not pause and self.inputs.queue:
            self._sync_trigger.trigger()  # commands received before the pause
        self._pacing.unanchor()
        self.get_logger().info(message)
        return message

    def _open_log(self, path: Path) -> LogWriter:
        """A new log at ``path`` with this run's metadata (raises NodeConfigError)."""
        return create_log(path, node_log_metadata(
            scene_to_yaml(self.scene), self.model.name, self.sim.integrator.describe(),
            self.settings, self.control.mode(), self.get_fully_qualified_name()),
            offered_qos(self._topic_names, log_depths(self.settings.sync_mode, self.scene)))

    def destroy_node(self) -> None:
        """Close the log (with its summary) and the live view, then destroy the node."""
        self._recording.close()
        if getattr(self, "_live", None) is not None:
            self._live.close()
        super().destroy_node()


def main(argv: list[str] | None = None, prog: str = "sim_node") -> int:
    """Run the node until SIGINT/SIGTERM. Returns 0, or 2 (with a one-line reason on stderr)
    for bad arguments, parameters or scenes. ``prog`` names the command in messages."""
    args = list(sys.argv[1:] if argv is None else argv)
    parse_cli(build_parser(prog), args)
    return run_node(prog, functools.partial(RodSimNode, params_files=params_files(args)),
                    args, NodeConfigError)


if __name__ == "__main__":
    sys.exit(main())
