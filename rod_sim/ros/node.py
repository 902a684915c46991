"""The rod_sim ROS 2 node (docs/interface.md section 3): chains of elastic rods driven by nodal
forces and hinge torques, on a base driven by a wrench and a reaction wheel; ``sim_node`` /
``rod-sim node`` / ``python -m rod_sim.ros.node --ros-args -p
scene_file:=config/paper_example.yaml [-p sync_mode:=true]``.

This module is wiring: ROS entities whose callbacks call parts with one job each, none needing
a ROS graph: parameters (settings), simulation (scene, model, simulator, work budget), inputs
(command intakes, held inputs, lockstep queue), period (one control period: integration within
the budget, energy ledger, validity), stepper (a period with its outputs), pacing (real-time
pace), outputs (the table of output topics, their resolved names and /clock: each message
encoded once, the same bytes published and recorded), control (pause, step, reset), monitor
(diagnostics), recording (the log: its metadata, the commands as received) and process (the
process, a node of the same name). Time advances in whole control periods of simulated time
with the inputs held, paced in real time, as fast as possible, or one period per command in
lockstep; every stamp and log time is simulated time.
"""
from __future__ import annotations

from rod_sim.app.blas import one_blas_thread

one_blas_thread()                           # before rclpy and rod_sim load numpy

import dataclasses  # noqa: E402 -- after one_blas_thread
import functools
import sys
import time
from pathlib import Path

from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from std_srvs.srv import SetBool, Trigger

from rod_sim.core.units import NS_PER_S
from rod_sim.ros import simulation, startup
from rod_sim.ros.command_layout import CommandLayout
from rod_sim.ros.commands import FORCES, MESSAGE_TYPES, TORQUES, CommandIntake
from rod_sim.ros.control import (STEP_SLICE_S, WAITING_LOG_PERIOD_S, WAITING_REPUBLISH_PERIOD_S,
                                 RunControl, answering, executor_turn)
from rod_sim.ros.errors import NodeConfigError, ThrottledLog
from rod_sim.ros.inputs import Inputs
from rod_sim.ros.live import NodeLiveView
from rod_sim.ros.monitor import DIAGNOSTICS_PERIOD_S, DiagnosticReport, NodeMonitor
from rod_sim.ros.outputs import (IDLE_CLOCK_PERIOD_S, Outputs, create_clock, create_publishers,
                                 has_hinge_events, rate_dividers, resolved_names)
from rod_sim.ros.pacing import Pacing
from rod_sim.ros.parameters import (NODE_NAME, PARAMETERS, build_parser, declare_settings,
                                    unknown_overrides, unknown_warning, validate_change)
from rod_sim.ros.process import (NAME_CHECK_DELAY_S, params_files, parse_cli, run_node,
                                 same_name_warning)
from rod_sim.ros.qos import COMMAND_QOS, SERVICE_QOS, SERVICE_QUEUE_DEPTH
from rod_sim.ros.recording import NodeRecording, node_log_opener
from rod_sim.ros.stepper import Stepper

__all__ = ["RodSimNode", "NodeConfigError", "main", "PARAMETERS", "SERVICE_QUEUE_DEPTH",
           "params_files", "has_hinge_events"]


class RodSimNode(Node):
    """The simulator node. ``node_kwargs`` go to :class:`rclpy.node.Node` (``context``,
    ``parameter_overrides``, ``namespace``, ...). Raises NodeConfigError for bad parameters, a
    missing or invalid scene, or a log that cannot be created.

    Embedded in a process of one's own (as ``rod_sim.ros.demo`` does), the node's parts are
    its public attributes: ``sim`` (the simulator), ``control`` (run state: ``paused``,
    ``error``), ``inputs`` (the command intakes and their counts); :attr:`sim_time`,
    :attr:`commands_rejected` and :attr:`log_path` summarise them, and
    :meth:`diagnostic_report` is what the next ``diagnostics`` message says."""

    def __init__(self, params_files: tuple[str, ...] = (), **node_kwargs):
        super().__init__(NODE_NAME, **node_kwargs)
        self._throttle = ThrottledLog(self.get_logger())
        params_files, full_name = tuple(params_files), self.get_fully_qualified_name()
        try:
            s = self.settings = declare_settings(self, params_files)
            self.add_on_set_parameters_callback(validate_change)
            self.add_post_set_parameters_callback(self._apply_parameters)
            built = simulation.build(s, full_name, params_files)
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
            self._topic_names = resolved_names(self.resolve_topic_name, self.inputs.intakes)
            self._recording = NodeRecording(node_log_opener(
                self.scene, self.model.name, self.sim.integrator.describe(), s,
                self.control.mode, full_name, self._topic_names), self.get_logger())
            self._recording.start(Path(s.record_path) if s.record_path else None)
            self._monitor = NodeMonitor(self.control, self.period, self.inputs, self._pacing,
                                        self._recording, s.rate_hz, full_name)
            self._create_interfaces()
        except BaseException:
            self.destroy_node()
            raise
        self._stepper.start()
        unknown = self._monitor.unknown_parameters = tuple(unknown_overrides(self))
        if unknown:
            self.get_logger().warning(unknown_warning(list(unknown)))
        startup.started()           # a signal after the line stops a running node
        self.get_logger().info(simulation.start_line(
            full_name, built, self.control.mode(),
            tuple(self._topic_names[t] for t in self.inputs.named_topics()), self.log_path, s))

    def _base_angle(self) -> float:
        """The base's angle psi [rad] now (turns a base-frame wrench into Oxy)."""
        return self.model.base_state(self.sim.t, self.sim.y).psi

    def _create_interfaces(self) -> None:
        s = self.settings
        self._pubs = create_publishers(self, self._topic_names, self.scene, s.sync_mode)
        self._outputs = Outputs(self.scene, self._topic_names, self._pubs, self._recording,
                                self.period_ns, s.frame_id, rate_dividers(s))
        self._sim_clock = create_clock(self, s)
        self._stepper = Stepper(self.period, self._outputs, self._sim_clock)
        for topic, intake in self.inputs.intakes.items():   # raw: length checked first
            self.create_subscription(intake.message_class, self._topic_names[topic],
                                     functools.partial(self._on_command_bytes, intake=intake),
                                     COMMAND_QOS, raw=True)
        self.create_service(Trigger, "~/reset", answering(lambda _: self.reset()),
                            qos_profile=SERVICE_QOS)
        # its own reentrant group: between the slices of a long ~/step the other callbacks
        # run (single-threaded executor: they interleave only where _on_step awaits)
        self.create_service(Trigger, "~/step", self._on_step, qos_profile=SERVICE_QOS,
                            callback_group=ReentrantCallbackGroup())
        self.create_service(SetBool, "~/pause", answering(lambda r: self.pause(r.data)),
                            qos_profile=SERVICE_QOS)
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
        """Once, after discovery: warn when another node has this node's full name (its timer
        destroyed: a cancelled one stays in the wait set of every executor wake-up)."""
        self.destroy_timer(self._name_timer)
        warning = same_name_warning(self)
        if warning:
            self._monitor.name_conflict = warning
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
                self._outputs.set_frame_id(str(p.value), self.sim.t_ns)
                self.inputs.set_inertial_frame(str(p.value))
            elif p.name == "step_count":
                self.settings = dataclasses.replace(self.settings, step_count=int(p.value))

    sim_time = property(lambda self: self.sim.t, doc="Simulated time [s].")
    commands_rejected = property(lambda self: self.inputs.total("rejected"),
                                 doc="Commands rejected so far, on every command topic.")
    log_path = property(lambda self: self._recording.path, doc="The log being written.")

    def _on_command_bytes(self, data: bytes, intake: CommandIntake | None = None) -> None:
        """A serialized command: checked, recorded, validated, held (lockstep: queued)."""
        intake = self.inputs.forces if intake is None else intake
        command, warning = self.inputs.receive(data, intake, self.sim.t_ns, functools.partial(
            self._recording.record_received, self._topic_names[intake.kind],
            MESSAGE_TYPES[intake.kind], self.sim.t_ns))
        if command is None:
            self._throttle.log(f"rejected {intake.kind}", "warning", warning)
            return
        if self.control.first_command():
            self._pacing.unanchor()
            self.get_logger().info(f"first command received: running from t = {self.sim.t:g} s")
        if self.settings.sync_mode and self.control.running():
            self.inputs.queue.append(command)
            # its period at once, in this callback: a round through the guard condition
            # costs the executor another wait (rclpy rebuilds its wait set: ~0.2-0.4 ms)
            self._on_sync_trigger()

    def _held(self, wall_age: bool):
        held, notes = self.inputs.held(self.sim.t_ns, wall_age)
        for kind, note in notes:
            self._throttle.log(f"timeout {kind}", "info", note)
        return held

    def _on_tick(self) -> None:
        """Pacing timer: advance the periods that are due (never in lockstep)."""
        if not self.control.running():
            self._pacing.unanchor()
            return
        self._pacing.tick(self.sim.t_ns, lambda wall_age: self._step_period(self._held(wall_age)),
                          self.control.running, self._budget.seconds,
                          lambda text: self._throttle.log("dropped", "warning", text))

    def _on_sync_trigger(self) -> None:
        """Lockstep: one period per queued command, a bounded batch per callback."""
        if self.inputs.drain(self._step_period, self.control.running, time.monotonic_ns()
                             + self._budget.seconds * NS_PER_S):
            self._sync_trigger.trigger()

    def _step_period(self, held) -> bool:
        """One period holding ``held`` ((n, 3) [X, Y, T], (n + 2, 3) with a free base's rows,
        or (n, 2) forces) and publish its outputs (:class:`Stepper`); False (paused,
        reported) when the integration fails."""
        if self._stepper.run(held):
            return True
        self.get_logger().error(self.control.fail(self.period.error))
        self._pacing.unanchor()
        self.publish_diagnostics()
        return False

    def _republish_waiting(self) -> None:
        """Lockstep before the first command: the waiting state again (not recorded)."""
        if not (self.inputs.any_command() or self.inputs.queue or self.control.error):
            self._outputs.state(self.sim.snapshot(), self.sim.t_ns, record=False)

    def diagnostic_report(self) -> DiagnosticReport:
        """The health of the simulation over the window since the last diagnostics."""
        return self._monitor.report()

    def publish_diagnostics(self) -> None:
        """Publish (and record) one ``diagnostics`` message and start a new window."""
        self._outputs.message("diagnostics", self.sim.t_ns, self._monitor.message())
        self._monitor.new_window()

    # ----- services (logic in rod_sim.ros.control) -----

    def reset(self) -> str:
        """``~/reset``: back to the initial state at t = 0 (commands and errors cleared); a
        ~/step in progress ends ("interrupted"); the log continues in the next file."""
        self.control.reset()
        self.period.reset()
        self.inputs.clear()
        self._pacing.unanchor()
        note = self._recording.roll()
        self._stepper.start()
        message = "reset to the initial state at t = 0 s" + note
        self.get_logger().info(message)
        return message

    async def _on_step(self, request, response):
        """``~/step``: ``step_count`` periods while paused, in slices (see RunControl.step)."""
        response.success, response.message = await self.control.step(
            self.settings.step_count, lambda: self._step_period(self._held(wall_age=False)),
            lambda: self.sim.t, executor_turn(self._step_wake),
            min(STEP_SLICE_S, self.settings.max_period_cost))
        return response

    def pause(self, pause: bool) -> str:
        """``~/pause``: True: pause; False: resume (re-anchors the real-time clock)."""
        message = self.control.pause(pause, self.sim.t)
        if not pause and self.inputs.queue:
            self._sync_trigger.trigger()  # commands received before the pause
        self._pacing.unanchor()
        self.get_logger().info(message)
        return message

    def destroy_node(self) -> None:
        """Close the log (with its summary) and the live view, then destroy the node."""
        for part in (getattr(self, "_recording", None), getattr(self, "_live", None)):
            if part is not None:
                part.close()
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
