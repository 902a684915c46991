"""The rod_sim ROS 2 node (docs/interface.md section 3): a chain of elastic rods driven by nodal forces.

Run it as ``sim_node`` / ``rod-sim node`` / ``python -m rod_sim.ros.node``, e.g.::

    python -m rod_sim.ros.node --ros-args --params-file config/sim_node.params.yaml \\
        -p scene_file:=config/paper_example.yaml -p sync_mode:=true

This module holds the node class: its interfaces, timers, pacing, stepping and publishing. The
rest lives in :mod:`rod_sim.ros.parameters` (declarations, settings and their checks),
:mod:`rod_sim.ros.commands` (command intake: length check, decoding, validation, rejection
counts, zero-order hold and timeout), :mod:`rod_sim.ros.recording` (the log and its rolling after
``~/reset``), :mod:`rod_sim.ros.qos` (QoS profiles) and :mod:`rod_sim.ros.process` (a ROS
process: arguments, signals, spin loop, exit codes); :func:`main` at the end wires the node
into it (``--help`` lists the parameters).

How time advances
-----------------
The node owns a :class:`~rod_sim.core.simulator.Simulator` and advances it only in whole
control periods dt = 1/rate_hz of simulated time, holding the command force constant over each
period (zero-order hold). The subscription callback never integrates: it validates and stores.

- Real time (``real_time_factor`` > 0, ``sync_mode`` false): a steady wall-clock timer ticks;
  at each tick a :class:`~rod_sim.ros.pacing.RealTimePacer` compares the simulated time with
  ``real_time_factor`` x the wall time since the clock was anchored and the node advances the
  whole periods it is behind (a tick is not assumed to be one period). A backlog is caught up
  as far as the measured wall cost of a period affords it (median of recent ticks, see
  :meth:`~rod_sim.ros.pacing.RealTimePacer.decide`); only what cannot be caught up is dropped
  (the clock is re-anchored): the ``diagnostics`` then show a measured real-time factor below
  the target instead of the executor stalling.
- As fast as possible (``real_time_factor`` 0): a zero-period timer advances periods for a
  bounded wall-time budget per tick, so commands and services are still served between ticks.
- Lockstep (``sync_mode`` true): exactly one period per received valid command, then the
  outputs are published. Before the first command nothing advances (no freewheeling: the chain
  stays at its initial state at t = 0); a command received while paused is held but does not
  step. The same sequence of commands gives bit-for-bit the same states and log.

Each period: the held command is chosen (the latest valid one, or zero once it is older than
``command_timeout``: wall time at a real-time pace, simulated time when running as fast as
possible and for ``~/step``; in lockstep every period applies the command that triggered it),
``applied_forces`` = scripted scene loads + held command is published at the start time of the
period (on the topic only when it changes; in the log every period, so a log alone replays the
run), the simulator advances, and the states are published stamped at the end of the period.
Every header stamp and log time is simulated time.

Outputs nobody subscribes to are only built when a log is being recorded (``markers`` is the
costly one). The state topics are reliable and transient local in every mode (depth 10, in
lockstep 1; :mod:`rod_sim.ros.qos`), so default-QoS and transient-local subscribers both match;
in lockstep they are always published, the t = 0 state included, so a client can start from
the state callback, and until the first command the waiting state is published again every
0.5 s (not recorded) for volatile subscribers that joined later. ``/clock`` (depth 1,
volatile, ``clock_reliability``: reliable by default, which both default-QoS and ClockQoS
subscribers receive) is published for every period *before* that period's outputs and, while
nothing advances (paused, waiting,
failed), repeats the frozen time every 0.1 s; it is not recorded: log times already are
simulated times and players publish their own clock. ``/diagnostics`` is absolute (status
``rod_sim: simulation``). ``start_paused`` holds the node at t = 0 until ``~/pause`` false or
the first valid command; ``~/step`` advances ``step_count`` periods.

Work per period is bounded (:mod:`rod_sim.ros.budget`): the integrator's steps per
``Simulator.advance`` are capped from ``max_period_cost`` and the measured cost of a step, so
a period that would take seconds (a 1e12 N command) fails fast with a named cause. Commands
are taken as serialized bytes and refused by their length before they are decoded.

Commands: ``nodal_forces`` (2n values [N]) and ``hinge_torques`` (n values [N m], joint order
hinge_0..hinge_{n-1}), one :class:`~rod_sim.ros.commands.CommandIntake` each (validation,
counts, hold, timeout per topic); the held input of a period is (n, 3) = [X, Y, T]. In
lockstep a valid command on either topic advances one period with the other topic's last
valid command held; ``applied_torques`` (the held torques) is published on change and
recorded every period beside ``applied_forces``.

Recording (``record_path``): the log of docs/interface.md section 4 with the commands as received (``/nodal_forces``,
``/hinge_torques`` at the simulated time of reception, rejected ones included), ``/applied_forces``,
``/applied_torques``, every output
topic and ``/diagnostics`` (which carries wall-clock measurements and so differs between
otherwise identical runs), under their resolved names (namespace and remappings applied, as
rosbag2 records). ``~/reset`` sends simulated time back to 0, so the recording goes on in the
next free file ``<stem>_<k><suffix>`` next to the first; a log that cannot be opened or written
is an ERROR on diagnostics. The log is closed with its summary on
SIGINT, SIGTERM and shutdown; after SIGKILL it stays readable up to its last complete chunk.

Integration failures pause the simulation, are logged and reported with level ERROR on
``diagnostics``; ``~/reset`` (or resuming with ``~/pause`` false) continues.
"""
from __future__ import annotations

import argparse
import functools
import sys
import textwrap
import time
from collections import deque
from pathlib import Path

import numpy as np
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import QoSProfile
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import SetBool, Trigger

from rod_sim import __version__
from rod_sim.core.integrators import IntegrationError, make_integrator
from rod_sim.core.models import ModelError, make_model
from rod_sim.core.scene import SceneError
from rod_sim.core.simulator import Simulator
from rod_sim.core.units import NS_PER_S
from rod_sim.core.validity import ValidityMonitor, balance_sample
from rod_sim.io import topics
from rod_sim.io.hinge_events import (HINGE_EVENTS_TOPIC, HINGE_EVENTS_TYPE, event_message,
                                     event_time_ns)
from rod_sim.io.log_writer import LogWriter
from rod_sim.io.scene_yaml import load_scene, scene_to_yaml
from rod_sim.io.urdf import scene_urdf
from rod_sim.tools.common import UsageError
from rod_sim.tools.limits import check_model_memory
from rod_sim.ros import budget
from rod_sim.ros.commands import FORCES, TORQUES, Command, CommandIntake
from rod_sim.ros.conversions import message_class, message_to_dict, to_message
from rod_sim.ros.errors import NodeConfigError, one_line
from rod_sim.ros.monitor import DiagnosticReport, EnergyLedger
from rod_sim.ros.pacing import RateMeter, RealTimePacer, period_ns, tick_period_s
from rod_sim.ros.parameters import (NODE_NAME, PARAMETERS, NodeSettings, declare_settings,
                                    unknown_overrides, validate_change)
from rod_sim.ros.process import params_files, parse_cli, run_node
from rod_sim.ros.qos import (APPLIED_QOS, COMMAND_QOS, DIAGNOSTICS_QOS, EVENTS_QOS, LATCHED_QOS,
                             LOCKSTEP_STATE_DEPTH, LOCKSTEP_STATE_QOS, SERVICE_QOS, STATE_DEPTH,
                             STATE_QOS, clock_qos)
from rod_sim.ros.qos import SERVICE_QUEUE_DEPTH  # noqa: F401  (the node's stated limit)
from rod_sim.ros.recording import NodeRecording, create_log, offered_qos
from rod_sim.ros.scene_path import ScenePathError, resolve_scene_file

COMMAND_TOPIC = FORCES
"""``nodal_forces``: [X_1, Y_1, ..., X_n, Y_n] [N]."""
TORQUE_TOPIC = TORQUES
"""``hinge_torques``: [T_0, ..., T_{n-1}] [N m] in joint order hinge_0..hinge_{n-1}."""
COMMAND_TOPICS = (COMMAND_TOPIC, TORQUE_TOPIC)
COMMAND_TYPE = "std_msgs/msg/Float64MultiArray"
APPLIED_TOPICS = {COMMAND_TOPIC: "applied_forces", TORQUE_TOPIC: "applied_torques"}
"""Command topic -> the output topic of what is applied (recorded every period)."""
STATE_TOPICS = ("joint_states", "rod_states", "bending", "node_poses", "markers")
"""Published at the end of every control period (if subscribed or recorded)."""
DESCRIPTION_TOPICS = ("robot_description", "scene")
"""Published once, transient local, and recorded at t = 0 of every log: the chain as URDF
(:mod:`rod_sim.io.urdf`) and the resolved scene as YAML (a converted log stays
self-contained)."""

DIAGNOSTICS_TOPIC = "/diagnostics"
"""Absolute, where diagnostic_aggregator listens (as diagnostic_updater publishes)."""
DIAGNOSTICS_STATUS_NAME = "rod_sim: simulation"
DIAGNOSTICS_PERIOD_S = 1.0
"""[s] wall period of the ``diagnostics`` messages."""
IDLE_CLOCK_PERIOD_S = 0.1
"""[s] wall period of ``/clock`` while no period advances (paused, waiting, failed)."""
WAITING_LOG_PERIOD_S = 3.0
"""[s] wall period of the "waiting for ..." log line at t = 0."""
WAITING_REPUBLISH_PERIOD_S = 0.5
"""[s] wall period at which a lockstep node that waits for its first command publishes the
waiting state again (not recorded), so that a volatile (default-QoS) controller that connects
later receives a state to answer."""
NAME_CHECK_DELAY_S = 2.0
"""[s] after start at which the graph is checked for another node of the same name."""
FAST_TICK_BUDGET_NS = 20_000_000
"""[ns] wall time one tick may spend stepping when running as fast as possible."""
PERIOD_COST_TICKS = 50
"""Ticks whose wall cost per period the pacer's estimate is the median of."""
SYNC_BATCH = 16
"""Lockstep commands processed per executor callback before yielding to other callbacks."""
THROTTLE_S = 2.0
"""[s] minimum interval between repeated warnings of one kind."""


def has_hinge_events(scene) -> bool:
    """Whether the scene has latches or stops, the only sources of ``hinge_events``."""
    def given(values, default_test) -> bool:
        return values is not None and bool(np.any(default_test(np.asarray(values, float))))
    return (given(scene.latch_angle, lambda v: ~np.isnan(v))
            or given(scene.stop_lower, np.isfinite) or given(scene.stop_upper, np.isfinite))


# ----- the node -----

STEP_SLICE_S = 0.1
"""[s] wall time a ~/step call steps before the executor serves other callbacks (at most
max_period_cost)."""


class _NextTurn:
    """Awaited in a service coroutine: hands control back to rclpy's executor once (the
    task stays pending and is resumed on the executor's next turn)."""

    def __await__(self):
        yield

class RodSimNode(Node):
    """The simulator node. ``node_kwargs`` go to :class:`rclpy.node.Node` (``context``,
    ``parameter_overrides``, ``namespace``, ...). Raises NodeConfigError for bad parameters, a
    missing or invalid scene, or a log that cannot be created."""

    def __init__(self, params_files: tuple[str, ...] = (), **node_kwargs):
        super().__init__(NODE_NAME, **node_kwargs)
        self._recording = NodeRecording(lambda path: self._open_log(path), self.get_logger())
        self._throttle_until: dict[str, int] = {}
        self._params_files = tuple(params_files)
        self.name_conflict = False
        """True once another node with this node's full name was seen on the graph."""
        try:
            self.settings = self._declare_parameters()
            self._build_simulation()
            self._start_checked()
            self._topic_names = self._resolve_topic_names()
            self._log_path = Path(self.settings.record_path) if self.settings.record_path else None
            self._recording.start(self._log_path)
            self._create_interfaces()
        except BaseException:
            self.destroy_node()
            raise
        self._publish_descriptions()
        self._publish_state(self.sim.snapshot(), force=self.settings.sync_mode)
        self._warn_unknown_parameters()
        self.get_logger().info(
            f"{self.get_fully_qualified_name()}: scene {self.scene.name!r} (n = {self.scene.n}), "
            f"model {self.model.name}, {self.sim.integrator.describe()}, "
            f"{self.settings.rate_hz:g} Hz, {self._mode()}, work budget "
            f"{self._budget.describe()}; commands on {self._topic_names[COMMAND_TOPIC]} and "
            f"{self._topic_names[TORQUE_TOPIC]}"
            + (f", recording to {self._log_path}" if self._log_path else "")
            + (", paused until ~/pause false or the first command"
               if self.settings.start_paused else ""))

    # ----- construction -----

    def _declare_parameters(self) -> NodeSettings:
        settings = declare_settings(self, self._params_files)
        self.add_on_set_parameters_callback(validate_change)
        self.add_post_set_parameters_callback(self._apply_parameters)
        return settings

    def _build_simulation(self) -> None:
        s = self.settings
        try:
            path, note = resolve_scene_file(s.scene_file, self.get_fully_qualified_name(),
                                            self._params_files)
        except ScenePathError as exc:
            raise NodeConfigError(f"scene_file {exc}") from None
        if note:
            self.get_logger().warning(note)
        self.scene_path = path
        """The scene file found for ``scene_file`` (:mod:`rod_sim.ros.scene_path`)."""
        try:
            self.scene = load_scene(path)
            check_model_memory(self.scene.n)      # simulate's estimate, before allocating
            self.model = make_model(s.model, self.scene)
            integrator = make_integrator(s.integrator, rtol=s.rtol)
            self.period_ns = period_ns(s.rate_hz)
        except SceneError as exc:
            raise NodeConfigError(f"scene_file {s.scene_file}: {one_line(exc)}") from None
        except (ModelError, ValueError, UsageError) as exc:
            raise NodeConfigError(one_line(exc)) from None
        except MemoryError:          # beyond the estimate: still one line, not a traceback
            raise NodeConfigError(f"scene_file {s.scene_file}: out of memory building the "
                                  f"{s.model} model of {self.scene.n} rods") from None
        self.sim = Simulator(self.model, integrator)

    def _start_checked(self) -> None:
        """Warm up and set up the run state; a scene that cannot even start (e.g. phi =
        1e308: non-finite linearization) is a NodeConfigError naming the cause."""
        try:
            self._warm_up()
            self._init_state()
        except NodeConfigError:
            raise
        except (ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
            raise NodeConfigError(
                f"scene_file {self.settings.scene_file}: the scene cannot be simulated from its "
                f"initial state ({type(exc).__name__}: {one_line(exc)[:200]})") from None

    def _warm_up(self) -> None:
        """Load the compiled kernels and message types once, before the clock starts, so that
        the first real period does not pay for them, and measure the work budget."""
        scratch = Simulator(self.model, self.sim.integrator)   # same settings, its own Carry
        period_s = self.period_ns / NS_PER_S
        try:
            self._budget = budget.measure(scratch, period_s, self.settings.max_period_cost)
        except (IntegrationError, ArithmeticError):
            self._budget = budget.fallback(self.sim.integrator, self.settings.max_period_cost)
        self._budget.apply(self.sim)
        if scratch.t_ns == 0:
            return  # the first period failed: the real run reports it
        snap = scratch.snapshot()
        self.model.energies(snap.t, scratch.y, scratch.held)
        self.model.powers(snap.t, scratch.y, scratch.held)
        for name, data in topics.snapshot_messages(snap, self.scene, "world",
                                                   STATE_TOPICS).items():
            to_message(topics.TOPIC_TYPES[name], data)

    def _init_state(self) -> None:
        n = self.scene.n
        self._paused = self.settings.start_paused
        self._start_hold = self.settings.start_paused
        """Paused by start_paused only: the first valid command resumes."""
        self._step_count = self.settings.step_count
        self._stepping = False
        """A ~/step call is in progress (between its slices)."""
        self._resets = 0
        self._clock_wall_ns = 0
        self._error: str | None = None
        self._sync_queue: deque[Command] = deque()
        self._commands = CommandIntake(n, self.settings.command_timeout, FORCES)
        self._torques = CommandIntake(n, self.settings.command_timeout, TORQUES)
        self._intakes = {FORCES: self._commands, TORQUES: self._torques}
        self._rejection = ""
        """The latest rejection of either command topic, prefixed with the topic."""
        self._sync_held = np.zeros((n, 3))
        """Lockstep: the held inputs [X, Y, T] as of the last queued command processed (a
        command of one topic keeps the other topic's last command)."""
        self._dropped = 0
        self._applied_last: dict[str, np.ndarray] = {}
        self._ledger = EnergyLedger.for_model(self.model, self._energy(self.sim.held))
        self._balance_end = None
        """(t_ns, held, BalanceSample) at the end of the last period (the ledger's next start
        when the held inputs did not change)."""
        self._validity = ValidityMonitor(self.model)
        self._meter = RateMeter(time.monotonic_ns())
        self._max_alpha = 0.0
        self._max_beta = 0.0
        self._pacer: RealTimePacer | None = None
        self._period_cost_ns: float | None = None
        """[ns] estimate of the wall cost of one period (None until measured)."""
        self._period_costs: deque[float] = deque(maxlen=PERIOD_COST_TICKS)
        self._tick_timer = None
        self._frame_id = self.settings.frame_id
        self._rtf = self.settings.real_time_factor
        rate = self.settings.markers_rate_hz
        self._markers_every = max(1, round(self.settings.rate_hz / rate)) if rate > 0 else 1

    def _resolve_topic_names(self) -> dict[str, str]:
        """Relative topic name -> the resolved name it is published and recorded under
        (namespace and remappings applied, as rosbag2 records)."""
        names = {name: self.resolve_topic_name(name)
                 for name in STATE_TOPICS + DESCRIPTION_TOPICS
                 + ("applied_forces", "applied_torques", HINGE_EVENTS_TOPIC)
                 + COMMAND_TOPICS}
        names["diagnostics"] = self.resolve_topic_name(DIAGNOSTICS_TOPIC)
        return names

    def _create_interfaces(self) -> None:
        state_qos = LOCKSTEP_STATE_QOS if self.settings.sync_mode else STATE_QOS
        self._pubs = {name: self._publisher(
            topics.TOPIC_TYPES[name], self._topic_names[name],
            APPLIED_QOS if name in ("applied_forces", "applied_torques") else
            DIAGNOSTICS_QOS if name == "diagnostics" else state_qos)
            for name in STATE_TOPICS + ("applied_forces", "applied_torques", "diagnostics")}
        self._pubs.update({name: self._publisher(topics.TOPIC_TYPES[name],
                                                 self._topic_names[name], LATCHED_QOS)
                           for name in DESCRIPTION_TOPICS})
        self._clock_pub = (self._publisher(topics.TOPIC_TYPES["clock"], "/clock",
                                           clock_qos(self.settings.clock_reliability))
                           if self.settings.publish_clock else None)
        self._events_pub = (self._publisher(HINGE_EVENTS_TYPE,
                                            self._topic_names[HINGE_EVENTS_TOPIC], EVENTS_QOS)
                            if has_hinge_events(self.scene) else None)
        self._events_sent = 0
        # raw: the length of a command is checked before it is deserialized
        for topic, intake in self._intakes.items():
            self.create_subscription(Float64MultiArray, self._topic_names[topic],
                                     lambda data, intake=intake: self._on_command_bytes(
                                         data, intake), COMMAND_QOS, raw=True)
        self.create_service(Trigger, "~/reset", self._on_reset, qos_profile=SERVICE_QOS)
        # Its own reentrant group: between the slices of a long call the node's other
        # callbacks (default, mutually exclusive group) run, and a second call is answered
        # "busy". The node is spun by a single-threaded executor (rod_sim.ros.process), so callbacks
        # never run at the same time; they interleave only where _on_step awaits.
        self.create_service(Trigger, "~/step", self._on_step, qos_profile=SERVICE_QOS,
                            callback_group=ReentrantCallbackGroup())
        self.create_service(SetBool, "~/pause", self._on_pause, qos_profile=SERVICE_QOS)
        # wakes the executor to resume a ~/step call between its slices
        self._step_wake = self.create_guard_condition(lambda: None)
        self._sync_trigger = self.create_guard_condition(self._on_sync_trigger)
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._diag_timer = self.create_timer(DIAGNOSTICS_PERIOD_S, self.publish_diagnostics,
                                             clock=self._steady)
        if self._clock_pub is not None:
            self.create_timer(IDLE_CLOCK_PERIOD_S, self._on_idle_clock, clock=self._steady)
        self.create_timer(WAITING_LOG_PERIOD_S, self._log_waiting, clock=self._steady)
        if self.settings.sync_mode:
            self.create_timer(WAITING_REPUBLISH_PERIOD_S, self._republish_waiting,
                              clock=self._steady)
        self._name_timer = self.create_timer(NAME_CHECK_DELAY_S, self._check_name_unique,
                                             clock=self._steady)
        self._configure_pacing()

    def _publisher(self, type_name: str, topic: str, qos: QoSProfile):
        """A publisher of messages of ``type_name`` (e.g. 'sensor_msgs/msg/JointState')."""
        return self.create_publisher(message_class(type_name), topic, qos)

    def _warn_unknown_parameters(self) -> None:
        """Warn about overrides (-p, params files) that name no parameter of this node."""
        unknown = unknown_overrides(self)
        self.unknown_parameters = unknown
        if unknown:
            self.get_logger().warning(
                f"unknown parameter(s) ignored: {', '.join(unknown)} (parameters of this node: "
                f"{', '.join(spec.name for spec in PARAMETERS)})")

    def _check_name_unique(self) -> None:
        """Once, a little after start (discovery needs time): warn when another node with
        this node's full name is on the graph (services would reach only one of them)."""
        self._name_timer.cancel()
        full = self.get_fully_qualified_name()
        same = sum(1 for name, ns in self.get_node_names_and_namespaces()
                   if f"{ns.rstrip('/')}/{name}" == full)
        if same > 1:
            self.name_conflict = True
            self.get_logger().warning(
                f"{same} nodes named {full} are on the graph (ROS_DOMAIN_ID "
                f"{self.context.get_domain_id()}): services and parameters reach only one of "
                "them; give this one another name (-r __node:=NAME) or namespace "
                "(-r __ns:=/NS)")

    def _log_waiting(self) -> None:
        """Every few seconds while the simulation waits at its start: say what it waits for."""
        if self._start_hold:
            self.get_logger().info(
                f"paused at t = {self.sim.t:g} s (start_paused): waiting for ~/pause false or "
                f"the first {self._topic_names[COMMAND_TOPIC]} or "
                f"{self._topic_names[TORQUE_TOPIC]} command")
        elif self.settings.sync_mode and not self._any_command() and self._running():
            self.get_logger().info(
                f"lockstep: waiting for the first nodal_forces command on "
                f"{self._topic_names[COMMAND_TOPIC]} (or hinge_torques on "
                f"{self._topic_names[TORQUE_TOPIC]}; the t = {self.sim.t:g} s state is "
                "published transient local)")

    def _on_idle_clock(self) -> None:
        """/clock keeps the (frozen) simulated time while no period advances."""
        if time.monotonic_ns() - self._clock_wall_ns >= IDLE_CLOCK_PERIOD_S * NS_PER_S:
            self._publish_clock()

    def _configure_pacing(self) -> None:
        """(Re)create the pacing timer for the current mode and real-time factor."""
        if self._tick_timer is not None:
            self.destroy_timer(self._tick_timer)
            self._tick_timer = None
        self._pacer = None
        if self.settings.sync_mode:
            return
        if self._rtf > 0.0:
            self._pacer = RealTimePacer(self.period_ns, self._rtf)
            period = tick_period_s(self.period_ns, self._rtf)
        else:
            period = 0.0
        self._tick_timer = self.create_timer(period, self._on_tick, clock=self._steady)

    # ----- parameters at run time -----

    def _apply_parameters(self, params) -> None:
        for p in params:
            if p.name == "real_time_factor":
                self._rtf = float(p.value)
                self._configure_pacing()
                self._meter.restart(time.monotonic_ns())
            elif p.name == "command_timeout":
                for intake in self._intakes.values():
                    intake.set_timeout(float(p.value))
            elif p.name == "frame_id":
                self._frame_id = str(p.value)
                self._pubs["robot_description"].publish(to_message(
                    topics.TOPIC_TYPES["robot_description"],
                    {"data": scene_urdf(self.scene, self._frame_id)}))
            elif p.name == "step_count":
                self._step_count = int(p.value)

    # ----- state queries -----

    @property
    def sim_time(self) -> float:
        """Simulated time [s]."""
        return self.sim.t

    @property
    def paused(self) -> bool:
        return self._paused

    @property
    def error(self) -> str | None:
        """The cause of the last integration failure (None when running normally)."""
        return self._error

    @property
    def commands_rejected(self) -> int:
        return self._commands.rejected

    @property
    def log_path(self) -> Path | None:
        """The log being written (None when not recording)."""
        return self._recording.path

    def matched_subscribers(self, topic: str) -> int:
        """Subscriptions matched to our publisher of ``topic`` (a name of STATE_TOPICS,
        ``applied_forces`` or ``diagnostics``)."""
        return self._pubs[topic].get_subscription_count()

    def _mode(self) -> str:
        if self.settings.sync_mode:
            return "lockstep"
        return "as fast as possible" if self._rtf == 0.0 else f"real time x{self._rtf:g}"

    def _state(self) -> str:
        if self._error:
            return "error"
        if self._start_hold:
            return "paused at start (start_paused): waiting for ~/pause false or a command"
        if self._paused:
            return "paused"
        if self.settings.sync_mode and not self._any_command():
            return "waiting for the first command"
        return "running"

    # ----- commands -----

    def _any_command(self) -> bool:
        """Whether a valid command (either topic) is held since the start or the last reset."""
        return any(intake.latest is not None for intake in self._intakes.values())

    def _on_command_bytes(self, data: bytes, intake: CommandIntake | None = None) -> None:
        """A serialized command (of ``intake``'s topic, default ``nodal_forces``): refuse it by
        its length before any decoding (an 80 MB message must not stall the node), else
        decode and handle it."""
        intake = self._commands if intake is None else intake
        msg = intake.decode(data)
        if msg is None:
            self._warn_rejected(intake)
            return
        self._on_command(msg, intake)

    def _warn_rejected(self, intake: CommandIntake | None = None) -> None:
        intake = self._commands if intake is None else intake
        self._rejection = f"{intake.kind}: {intake.last_rejection}"
        self._log_throttled(
            f"rejected {intake.kind}", "warning",
            f"rejected a {intake.kind} command: {intake.last_rejection} "
            f"({intake.rejected} rejected so far); keeping the last valid command")

    def _on_command(self, msg: Float64MultiArray, intake: CommandIntake | None = None) -> None:
        """Validate and store a command of ``intake``'s topic (default ``nodal_forces``);
        never integrates."""
        intake = self._commands if intake is None else intake
        if self._recording.writer is not None:
            self._recording.record(self._topic_names[intake.kind], COMMAND_TYPE, self.sim.t_ns,
                                   message_to_dict(msg))
        command = intake.accept(msg, self.sim.t_ns)
        if command is None:
            self._warn_rejected(intake)
            return
        if self._start_hold:
            self._start_hold = self._paused = False
            if self._pacer is not None:
                self._pacer.unanchor()
            self.get_logger().info(f"first command received: running from t = {self.sim.t:g} s")
        if self.settings.sync_mode and not self._paused and self._error is None:
            self._sync_queue.append(command)
            self._sync_trigger.trigger()

    def _held_command(self, wall_age: bool) -> np.ndarray:
        """The inputs to hold over the next period, (n, 3) [X, Y, T]: per command topic the
        latest valid command, or zero once it is older than ``command_timeout`` (wall age if
        ``wall_age``, else simulated)."""
        held = np.empty((self.scene.n, 3))
        for intake, columns in ((self._commands, slice(0, 2)), (self._torques, 2)):
            was_active = intake.active
            held[:, columns] = intake.held(self.sim.t_ns, wall_age)
            if was_active and not intake.active:
                what = "command force" if intake.kind == FORCES else "hinge torques"
                self._log_throttled(
                    f"timeout {intake.kind}", "info",
                    f"no valid {intake.kind} command for "
                    f"{intake.timeout_ns / NS_PER_S:g} s: {what} set to zero")
        return held

    # the command state under the names it had before it moved to CommandIntake (tests)
    @property
    def _latest(self) -> Command | None:
        return self._commands.latest

    @property
    def _last_rejection(self) -> str:
        return self._commands.last_rejection

    @property
    def _command_active(self) -> bool:
        return self._commands.active

    def _log_throttled(self, key: str, level: str, text: str) -> None:
        """Log ``text`` at ``level`` ('info', 'warning' or 'error') at most once per
        :data:`THROTTLE_S` per ``key``. rclpy's own ``throttle_duration_sec`` inspects the
        caller's frame and module on every call, milliseconds each: too slow on a 1 kHz path.
        rclpy refuses a call site that changes severity (ValueError), so each level has its
        own call below; and a log line never stops the node."""
        now = time.monotonic_ns()
        if now < self._throttle_until.get(key, 0):
            return
        self._throttle_until[key] = now + int(THROTTLE_S * NS_PER_S)
        logger = self.get_logger()
        try:
            if level == "error":
                logger.error(text)
            elif level == "warning":
                logger.warning(text)
            else:
                logger.info(text)
        except Exception:  # noqa: BLE001 -- logging must never take the simulation down
            pass

    # ----- stepping -----

    def _running(self) -> bool:
        return not self._paused and self._error is None

    def _on_tick(self) -> None:
        """Pacing timer: advance the periods that are due (never in lockstep)."""
        if not self._running():
            if self._pacer is not None:
                self._pacer.unanchor()
            return
        if self._pacer is None:
            deadline = time.monotonic_ns() + FAST_TICK_BUDGET_NS
            while self._running() and time.monotonic_ns() < deadline:
                self._step_period(self._held_command(wall_age=False))
            return
        decision = self._pacer.decide(time.monotonic_ns(), self.sim.t_ns, self._period_cost_ns)
        if decision.dropped:
            self._dropped += decision.dropped
            self._log_throttled(
                "dropped", "warning",
                f"cannot keep up with real time x{self._rtf:g}: dropped {decision.dropped} "
                f"period(s) of backlog ({self._dropped} in all; a period costs "
                f"{(self._period_cost_ns or 0) / 1e6:.3g} ms of wall time)")
        start = time.monotonic_ns()
        deadline = start + self._budget.seconds * NS_PER_S
        stepped = 0
        for _ in range(decision.periods):       # the rest of a slow tick waits for the next
            ok = self._step_period(self._held_command(wall_age=True))
            stepped += ok
            if not ok or time.monotonic_ns() > deadline:
                break
        if stepped:
            self._note_period_cost((time.monotonic_ns() - start) / stepped)

    def _note_period_cost(self, cost_ns: float) -> None:
        """Add one tick's wall cost per period [ns] (stepping, publishing, recording) to the
        estimate the pacer catches up with: the median of the last :data:`PERIOD_COST_TICKS`
        ticks (a tick that was itself preempted by another process does not inflate it; when
        every tick is slow, the median is slow too)."""
        self._period_costs.append(cost_ns)
        self._period_cost_ns = float(np.median(self._period_costs))

    def _on_sync_trigger(self) -> None:
        """Lockstep: one period per queued command, a bounded batch per callback."""
        deadline = time.monotonic_ns() + self._budget.seconds * NS_PER_S
        for _ in range(SYNC_BATCH):
            if not self._sync_queue or not self._running() or time.monotonic_ns() > deadline:
                break
            command = self._sync_queue.popleft()
            self._intakes[command.kind].active = True
            held = self._sync_held.copy()
            if command.kind == TORQUES:
                held[:, 2] = command.forces
            else:
                held[:, :2] = command.forces
            self._sync_held = held
            self._step_period(held)
        if self._sync_queue and self._running():
            self._sync_trigger.trigger()

    def _step_period(self, held: np.ndarray) -> bool:
        """Advance one control period holding ``held`` plus the scripted loads, and publish:
        (n, 3) = nodal forces X, Y [N] and hinge torques T [N m], or (n, 2) forces only (zero
        torques). Returns False (and pauses) when the integration fails."""
        sim = self.sim
        held = np.asarray(held, dtype=float)
        if held.shape != (self.scene.n, 3):
            full = np.zeros((self.scene.n, 3))
            full[:, :2] = held.reshape(self.scene.n, 2)
            held = full
        sim.set_forces(held[:, :2])
        sim.set_hinge_torques(held[:, 2])
        self._publish_applied(sim.t_ns)
        last = self._balance_end          # the previous period's end, if it starts this one
        if last is not None and last[0] == sim.t_ns and np.array_equal(last[1], held):
            start_sample = last[2]
        else:
            start_sample = balance_sample(self.model, sim.t, sim.y, held, sim.mode)
        work = self._budget.work(sim)
        start = time.perf_counter_ns()
        try:
            # advance() never hands out a non-finite state and, when it raises, leaves the
            # simulator at the period's start (hinge latches and events included)
            sim.advance(self.period_ns / NS_PER_S)
        except (IntegrationError, ArithmeticError) as exc:
            if self._budget.exceeded(sim, work):
                exc = IntegrationError(
                    f"work budget exceeded: the period needs more than {self._budget.limit} "
                    f"{self._budget.unit} (~{self._budget.seconds:g} s of wall time, "
                    f"max_period_cost; took {(time.perf_counter_ns() - start) / 1e9:.3g} s); "
                    + (exc.reason if isinstance(exc, IntegrationError) else one_line(exc)),
                    exc.t if isinstance(exc, IntegrationError) else sim.t)
            self._fail(exc)
            return False
        self._meter.add_step(self.period_ns, time.perf_counter_ns() - start)
        snap = sim.snapshot()
        end_sample = balance_sample(self.model, sim.t, sim.y, held, sim.mode,
                                    (snap.alpha, snap.beta))
        self._ledger.add(start_sample, end_sample, sim.events[self._events_sent:])
        self._balance_end = (sim.t_ns, held.copy(), end_sample)
        self._validity.update(sim.t, sim.y, held, snap.alpha, snap.beta)
        self._validity.update_energy(sim.t, self._ledger.residual, self._ledger.scale,
                                     self._ledger.unresolved)
        self._publish_state(snap)
        self._publish_events()
        return True

    def _publish_events(self) -> None:
        """Hinge events (latch, stop contact; docs/hinges.md) since the last period, stamped
        at their simulated times: recorded and published."""
        for event in self.sim.events[self._events_sent:]:
            data = event_message(event.to_dict())
            self._recording.record(self._topic_names[HINGE_EVENTS_TOPIC], HINGE_EVENTS_TYPE,
                                   event_time_ns(event.to_dict()), data)
            if self._events_pub is not None:
                self._events_pub.publish(to_message(HINGE_EVENTS_TYPE, data))
        self._events_sent = len(self.sim.events)

    def _energy(self, held: np.ndarray, bending=None) -> float:
        return self.model.energies(self.sim.t, self.sim.y, held, bending=bending,
                                   mode=self.sim.mode).total

    def _fail(self, exc: Exception) -> None:
        """Pause after a failed period (the state stays at the period's start), log the cause
        and report it on diagnostics."""
        if isinstance(exc, IntegrationError):
            reason, t = exc.reason, exc.t
        else:  # an arithmetic failure inside the stepper, e.g. a division by zero
            reason, t = f"{type(exc).__name__}: {one_line(exc)}", self.sim.t
        self._paused = True
        self._error = (f"{reason} at t = {t:.6g} s "
                       f"({self.model.name} model, {self.sim.integrator.describe()})")
        self.get_logger().error(f"integration failed: {self._error}; simulation paused "
                                "(call ~/reset, or ~/pause false to retry)")
        if self._pacer is not None:
            self._pacer.unanchor()
        self.publish_diagnostics()

    # ----- publishing -----

    def _wants(self, name: str) -> bool:
        return self._recording.writer is not None or self._listened(name)

    def _listened(self, name: str) -> bool:
        """Publish ``name``: someone listens, or lockstep (its transient-local state topics
        keep the latest state for a client that joins later)."""
        return ((self.settings.sync_mode and name in STATE_TOPICS)
                or self._pubs[name].get_subscription_count() > 0)

    def _emit(self, name: str, t_ns: int, data: dict, force: bool = False) -> None:
        """Record ``data`` on the resolved topic ``name`` at ``t_ns`` and publish it if anyone
        listens (or ``force``)."""
        type_name = topics.TOPIC_TYPES[name]
        self._recording.record(self._topic_names[name], type_name, t_ns, data)
        if force or self._listened(name):
            self._pubs[name].publish(to_message(type_name, data))

    def _publish_applied(self, t_ns: int) -> None:
        """Applied forces (scripted + held) and hinge torques (held) from ``t_ns`` on: each
        recorded every period, published when it changes (and the first time)."""
        values = {"applied_forces": self.model.forces(t_ns / NS_PER_S, self.sim.held),
                  "applied_torques": self.sim.held[:, 2].copy()}
        for name, applied in values.items():
            data = (topics.force_array(applied) if name == "applied_forces" else
                    topics.torque_array(applied))
            self._recording.record(self._topic_names[name], topics.TOPIC_TYPES[name], t_ns, data)
            last = self._applied_last.get(name)
            if last is None or not np.array_equal(applied, last):
                self._applied_last[name] = applied
                self._pubs[name].publish(to_message(topics.TOPIC_TYPES[name], data))

    def _publish_state(self, snap, force: bool = False) -> None:
        """Everything a state determines, stamped at its simulated time (``force``: publish
        every state topic even without subscribers, e.g. lockstep's t = 0 state)."""
        t_ns = self.sim.t_ns
        self._max_alpha = max(self._max_alpha, float(np.max(np.abs(snap.alpha), initial=0.0)))
        self._max_beta = max(self._max_beta, float(np.max(np.abs(snap.beta), initial=0.0)))
        self._publish_clock()       # /clock first: no output is stamped later than it
        wanted = [name for name in STATE_TOPICS if (force or self._wants(name))
                  and (name != "markers" or self._markers_due(t_ns))]
        if wanted:
            for name, data in topics.snapshot_messages(snap, self.scene, self._frame_id,
                                                       wanted).items():
                self._emit(name, t_ns, data, force)

    def _publish_descriptions(self) -> None:
        """``robot_description`` (URDF, root link = ``frame_id``) and ``scene`` (YAML): published
        (transient local) and recorded at the current simulated time (t = 0 at start and after
        ``~/reset``)."""
        texts = {"robot_description": scene_urdf(self.scene, self._frame_id),
                 "scene": scene_to_yaml(self.scene)}
        for name, text in texts.items():
            self._recording.record(self._topic_names[name], topics.TOPIC_TYPES[name],
                                   self.sim.t_ns, {"data": text})
            self._pubs[name].publish(to_message(topics.TOPIC_TYPES[name], {"data": text}))

    def _republish_waiting(self) -> None:
        """Lockstep, before the first valid command (at start and after ``~/reset``): publish
        the waiting state again, not recorded, for volatile subscribers that joined since."""
        if self._any_command() or self._sync_queue or self._error is not None:
            return
        wanted = [name for name in STATE_TOPICS
                  if name != "markers" or self._markers_due(self.sim.t_ns)]
        for name, data in topics.snapshot_messages(self.sim.snapshot(), self.scene,
                                                   self._frame_id, wanted).items():
            self._pubs[name].publish(to_message(topics.TOPIC_TYPES[name], data))

    def _publish_clock(self) -> None:
        """Simulated time on /clock (if enabled and someone listens)."""
        if self._clock_pub is not None and self._clock_pub.get_subscription_count() > 0:
            self._clock_pub.publish(to_message(topics.TOPIC_TYPES["clock"],
                                               {"clock": topics.stamp_from_ns(self.sim.t_ns)}))
            self._clock_wall_ns = time.monotonic_ns()

    def _markers_due(self, t_ns: int) -> bool:
        """Whether the state at ``t_ns`` (on the control-period grid) gets markers."""
        return (t_ns // self.period_ns) % self._markers_every == 0

    def diagnostic_report(self) -> DiagnosticReport:
        """The health of the simulation over the window since the last diagnostics."""
        wall = time.monotonic_ns()
        mean_ms, max_ms = self._meter.step_cost_ms()
        rtf_target = None if self.settings.sync_mode else self._rtf
        budget = (self.period_ns / 1e6 / self._rtf) if rtf_target else None
        return DiagnosticReport(
            mode=self._mode(), state=self._state(), sim_time=self.sim.t,
            rtf_target=rtf_target, rtf_measured=self._meter.real_time_factor(wall),
            wall_window=self._meter.window_s(wall),
            step_cost_mean=mean_ms, step_cost_max=max_ms, step_budget=budget,
            steps=self._meter.steps, dropped_periods=self._dropped,
            energy=self._ledger.energy, energy_residual=self._ledger.residual,
            commands_received=self._commands.received + self._torques.received,
            commands_rejected=self._commands.rejected + self._torques.rejected,
            last_rejection=self._rejection,
            command_active=self._commands.active or self._torques.active,
            max_abs_alpha=self._max_alpha, max_abs_beta=self._max_beta,
            model=self.model.name, integrator=self.sim.integrator.describe(), error=self._error,
            recording_error=self._recording.error,
            validity=[f.message for f in self._validity.findings() if f.kind != "bending"],
            extra={"scene": self.scene.name, "rate_hz": f"{self.settings.rate_hz:g}",
                   "recording": str(self.log_path) if self.log_path else "off",
                   "work_budget": self._budget.describe(), "node": self.get_fully_qualified_name(),
                   **{f"{kind}_{what}": str(getattr(intake, what))
                      for kind, intake in self._intakes.items()
                      for what in ("received", "rejected")},
                   **{f"{kind}_active": "true" if intake.active else "false"
                      for kind, intake in self._intakes.items()}})

    def publish_diagnostics(self) -> None:
        """Publish (and record) one ``diagnostics`` message and start a new window."""
        level, message, values = self.diagnostic_report().status()
        data = topics.diagnostics(self.sim.t, values, self.scene.name, level=level,
                                  message=message, frame_id="", name=DIAGNOSTICS_STATUS_NAME)
        self._emit("diagnostics", self.sim.t_ns, data)
        self._meter.restart(time.monotonic_ns())
        self._max_alpha = self._max_beta = 0.0

    # ----- services -----

    def _on_reset(self, request, response):
        """Back to the scene's initial state at t = 0 (commands and errors cleared); a
        ~/step call in progress ends (answered "interrupted")."""
        self._resets += 1
        self.sim.reset()
        self._events_sent = 0
        for intake in self._intakes.values():
            intake.clear()
        self._sync_queue.clear()
        self._sync_held = np.zeros((self.scene.n, 3))
        self._error = None
        self._applied_last = {}
        self._ledger.start(self._energy(self.sim.held))
        self._balance_end = None
        self._validity = ValidityMonitor(self.model)
        self._meter.restart(time.monotonic_ns())
        if self._pacer is not None:
            self._pacer.unanchor()
        note = self._recording.roll()
        self._publish_descriptions()
        self._publish_state(self.sim.snapshot())
        response.success = True
        response.message = "reset to the initial state at t = 0 s" + note
        self.get_logger().info(response.message)
        return response

    async def _on_step(self, request, response):
        """``step_count`` control periods, only while paused, in slices of at most
        STEP_SLICE_S (or max_period_cost) of wall time: between slices the executor serves
        the other callbacks (~/pause, ~/reset, diagnostics, commands), and the call is
        answered when its periods are done. A second call meanwhile is refused "busy";
        ~/pause false or ~/reset end the call early (answered "interrupted")."""
        if self._stepping:
            response.success = False
            response.message = (f"busy: a ~/step call is in progress (t = {self.sim.t:.9g} s); "
                                "call again when it has answered")
            return response
        if not self._paused:
            response.success = False
            response.message = ("~/step works only while paused: call ~/pause with data: true "
                                "first")
            return response
        self._stepping = True
        try:
            return await self._step_sliced(response)
        finally:
            self._stepping = False

    async def _step_sliced(self, response):
        remaining, resets = self._step_count, self._resets
        slice_s = min(STEP_SLICE_S, self.settings.max_period_cost)
        ok = True
        while remaining and ok:
            started = time.monotonic()
            while remaining and ok and time.monotonic() - started < slice_s:
                ok = self._step_period(self._held_command(wall_age=False))
                remaining -= 1
            if remaining and ok:
                self._step_wake.trigger()
                await _NextTurn()                # the executor runs what is ready, then us
                if self._resets != resets or not self._paused:
                    why = "~/reset" if self._resets != resets else "~/pause false"
                    response.success = False
                    response.message = (f"interrupted by {why} after "
                                        f"{self._step_count - remaining} of {self._step_count} "
                                        f"periods (t = {self.sim.t:.9g} s)")
                    return response
        response.success = ok
        response.message = (f"stepped to t = {self.sim.t:.9g} s" if ok else
                            f"step failed: {self._error}")
        return response

    def _on_pause(self, request, response):
        """data true: pause; false: resume (re-anchors the real-time clock)."""
        self._start_hold = False
        if request.data:
            self._paused = True
            response.message = f"paused at t = {self.sim.t:.9g} s"
        else:
            note = f" (after the integration error: {self._error})" if self._error else ""
            self._paused = False
            self._error = None
            response.message = f"resumed at t = {self.sim.t:.9g} s{note}"
            if self._sync_queue:
                self._sync_trigger.trigger()  # commands received before the pause
        if self._pacer is not None:
            self._pacer.unanchor()
        response.success = True
        self.get_logger().info(response.message)
        return response

    # ----- recording -----

    def _open_log(self, path: Path) -> LogWriter:
        """A new log at ``path`` with this run's metadata (raises NodeConfigError)."""
        s = self.settings
        metadata = {"scene": scene_to_yaml(self.scene), "model": self.model.name,
                    "integrator": self.sim.integrator.describe(), "version": __version__,
                    "rtol": repr(s.rtol), "rate_hz": repr(s.rate_hz),
                    "source": "rod_sim node", "mode": self._mode(),
                    "node": self.get_fully_qualified_name()}
        state_depth = LOCKSTEP_STATE_DEPTH if s.sync_mode else STATE_DEPTH
        latched = {"applied_forces": 1, "applied_torques": 1, HINGE_EVENTS_TOPIC: 100,
                   **{name: 1 for name in DESCRIPTION_TOPICS},
                   **{name: state_depth for name in STATE_TOPICS}}
        return create_log(path, metadata, offered_qos(self._topic_names, latched))

    @property
    def _log(self) -> LogWriter | None:
        """The log being written (None when not recording)."""
        return self._recording.writer

    def destroy_node(self) -> None:
        """Close the log (with its summary), then destroy the node."""
        self._recording.close()
        super().destroy_node()


# ----- the node as a process (sim_node, rod-sim node, python -m rod_sim.ros.node)
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


def main(argv: list[str] | None = None, prog: str = "sim_node") -> int:
    """Run the node until SIGINT/SIGTERM. Returns 0, or 2 (with a one-line reason on stderr)
    for bad arguments, parameters or scenes. ``prog`` names the command in messages."""
    args = list(sys.argv[1:] if argv is None else argv)
    parse_cli(build_parser(prog), args)
    return run_node(prog, functools.partial(RodSimNode, params_files=params_files(args)),
                    args, NodeConfigError)


if __name__ == "__main__":
    sys.exit(main())
