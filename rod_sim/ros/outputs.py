"""The rod_sim node's output topics: one table, one encoding per message, every sink the same bytes.

Each output topic is one :class:`Output` entry of :data:`OUTPUTS`: its relative name, ROS
type, QoS (a name of :data:`QOS`), the parameter whose rate [Hz] divides the control rate (None:
every period) and, for the topics a state determines, its encoder ``encode(snapshot, scene,
frame_id) -> bytes`` (:mod:`rod_sim.io.encoders`: CDR straight from numpy). :class:`Outputs`
encodes each due message **once** and hands the same bytes to every sink: the DDS publisher
(rclpy publishes serialized messages as they are: ``Publisher.publish(bytes)`` calls
``publish_raw``, no Python message object is built) and the MCAP log; snapshot taps (the live
view) get the snapshot itself. Adding a topic is one entry here and its encoder. The node's
resolved topic names (:func:`resolved_names`), the dividers of its rate parameters
(:func:`rate_dividers`) and ``/clock`` (:class:`SimClock`) are made here too.

Nothing here needs a ROS graph: publishers are anything with ``publish(bytes)``
(test/test_node_outputs.py uses lists).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Iterable, Mapping

import numpy as np

from rod_sim.core.scene import Scene
from rod_sim.core.snapshot import Snapshot
from rod_sim.io import cdr, encoders, topics
from rod_sim.io.hinge_events import HINGE_EVENTS_TOPIC, HINGE_EVENTS_TYPE, event_message, \
    event_time_ns
from rod_sim.ros.applied_base import APPLIED_BASE_LABEL, APPLIED_BASE_TOPIC, APPLIED_BASE_TYPE

DIAGNOSTICS_TOPIC = "/diagnostics"
"""Absolute, where diagnostic_aggregator listens (as diagnostic_updater publishes)."""
IDLE_CLOCK_PERIOD_S = 0.1
"""[s] wall period of ``/clock`` while no period advances (:meth:`SimClock.idle`)."""


@dataclass(frozen=True)
class Output:
    """One output topic. ``qos``: 'state', 'applied', 'latched', 'diagnostics' or 'events'
    (see :mod:`rod_sim.ros.qos`); ``rate_parameter``: the node parameter [Hz] whose rate sets
    the divider k = max(1, round(rate_hz / rate)) (every k-th period counted from t = 0; a rate
    of 0: every period); ``encode``: the snapshot encoder of a state topic (None for topics
    written from other data)."""

    name: str
    type_name: str
    qos: str
    encode: encoders.SnapshotEncoder | None = None
    rate_parameter: str | None = None
    applies: Callable[[Scene], bool] | None = None
    """Whether a scene has this topic (None: every scene)."""

    def exists_for(self, scene: Scene) -> bool:
        return self.applies is None or bool(self.applies(scene))

    @property
    def is_state(self) -> bool:
        return self.encode is not None


def _state(name: str, rate_parameter: str | None = None,
           applies: Callable[[Scene], bool] | None = None) -> Output:
    return Output(name, topics.TOPIC_TYPES[name], "state", encoders.SNAPSHOT_ENCODERS[name],
                  rate_parameter, applies)


OUTPUTS: tuple[Output, ...] = (
    _state("joint_states"),
    _state("rod_states"),
    _state("bending"),
    _state("node_poses"),
    _state("base_odometry", applies=lambda scene: scene.moving_base),
    _state("markers", "markers_rate_hz"),
    Output("applied_forces", topics.TOPIC_TYPES["applied_forces"], "applied"),
    Output("applied_torques", topics.TOPIC_TYPES["applied_torques"], "applied"),
    Output(APPLIED_BASE_TOPIC, APPLIED_BASE_TYPE, "applied",
           applies=lambda scene: scene.base.mode == "free"),
    Output("robot_description", topics.TOPIC_TYPES["robot_description"], "latched"),
    Output("scene", topics.TOPIC_TYPES["scene"], "latched"),
    Output("diagnostics", topics.TOPIC_TYPES["diagnostics"], "diagnostics"),
    Output(HINGE_EVENTS_TOPIC, HINGE_EVENTS_TYPE, "events",
           applies=lambda scene: has_hinge_events(scene)),
)
"""Every output topic of the node but ``/clock`` (docs/interface.md section 3)."""

BY_NAME = {o.name: o for o in OUTPUTS}
STATE_TOPICS = tuple(o.name for o in OUTPUTS if o.is_state)
"""Published at the end of every control period (markers: every k-th)."""

LOG_DEPTHS = {"applied": 1, "latched": 1, "events": 100}
"""History depth offered per QoS name in the log's ``offered_qos_profiles`` (transient local;
the state topics: the mode's state depth; diagnostics: the writer's default, volatile)."""


def has_hinge_events(scene: Scene) -> bool:
    """Whether the scene has latches or stops, the only sources of ``hinge_events`` (its
    publisher exists only then; events are recorded in any case)."""
    def given(values, default_test) -> bool:
        return values is not None and bool(np.any(default_test(np.asarray(values, float))))
    return (given(scene.latch_angle, lambda v: ~np.isnan(v))
            or given(scene.stop_lower, np.isfinite) or given(scene.stop_upper, np.isfinite))


def rate_dividers(settings) -> dict[str, int]:
    """Relative name -> :func:`~rod_sim.io.topics.divider` of each output with a rate
    parameter, from the node's ``settings`` (:class:`~rod_sim.ros.parameters.NodeSettings`:
    ``rate_hz`` and the topic's rate [Hz], e.g. ``markers_rate_hz``)."""
    return {o.name: topics.divider(settings.rate_hz, getattr(settings, o.rate_parameter))
            for o in OUTPUTS if o.rate_parameter}


def resolved_names(resolve: Callable[[str], str], commands: Iterable[str] = ()
                   ) -> dict[str, str]:
    """Relative -> resolved name of every output topic and of the ``commands`` topics,
    ``resolve`` being the node's ``resolve_topic_name`` (namespace, remappings);
    ``diagnostics`` is resolved from the absolute :data:`DIAGNOSTICS_TOPIC`."""
    names = {t: resolve(t) for t in (*(o.name for o in OUTPUTS), *commands)}
    names["diagnostics"] = resolve(DIAGNOSTICS_TOPIC)
    return names


def log_depths(sync_mode: bool, scene: Scene) -> dict[str, int]:
    """Relative topic -> history depth of the scene's transient-local topics, as offered in a
    log (``hinge_events`` in any case: events are recorded whatever the scene)."""
    from rod_sim.ros.qos import LOCKSTEP_STATE_DEPTH, STATE_DEPTH

    depths = {**LOG_DEPTHS, "state": LOCKSTEP_STATE_DEPTH if sync_mode else STATE_DEPTH}
    return {o.name: depths[o.qos] for o in OUTPUTS
            if o.qos in depths and (o.qos == "events" or o.exists_for(scene))}


def quiet_events():
    """The event callbacks of the node's output publishers: none. rclpy's defaults give every
    publisher two QoS event handlers (incompatible QoS, incompatible type: a warning on the
    publisher's side when a subscriber asks for what it does not offer), and its executor polls
    each of them at every wake-up: 24 handlers for the node's 12 publishers cost ~0.12 ms of
    the ~0.2 ms an executor wake-up takes (measured: 200 -> 85 us CPU per spin_once), at every
    tick of a 2 kHz node and every lockstep round trip. The subscriber's side still warns (its
    own defaults); the node's command subscriptions keep theirs."""
    from rclpy.event_handler import PublisherEventCallbacks

    return PublisherEventCallbacks(use_default_callbacks=False)


def create_clock(node, settings) -> "SimClock":
    """The ``/clock`` of ``node`` (:class:`SimClock`): published if ``settings.publish_clock``,
    with the QoS of ``settings.clock_reliability`` and no QoS event handlers
    (:func:`quiet_events`)."""
    from rod_sim.ros.conversions import message_class
    from rod_sim.ros.qos import clock_qos

    return SimClock(node.create_publisher(
        message_class(topics.TOPIC_TYPES["clock"]), "/clock",
        clock_qos(settings.clock_reliability), event_callbacks=quiet_events())
        if settings.publish_clock else None, IDLE_CLOCK_PERIOD_S)


def create_publishers(node, names: Mapping[str, str], scene: Scene, sync_mode: bool) -> dict:
    """A publisher on ``node`` for each output of :data:`OUTPUTS` that the scene has, under
    its resolved name (``hinge_events`` only for a scene with latches or stops,
    ``applied_base`` only for a free base), with the QoS of its entry and no QoS event
    handlers (:func:`quiet_events`)."""
    from rod_sim.ros import qos as profiles
    from rod_sim.ros.conversions import message_class

    qos = {"state": profiles.LOCKSTEP_STATE_QOS if sync_mode else profiles.STATE_QOS,
           "applied": profiles.APPLIED_QOS, "latched": profiles.LATCHED_QOS,
           "diagnostics": profiles.DIAGNOSTICS_QOS, "events": profiles.EVENTS_QOS}
    return {o.name: node.create_publisher(message_class(o.type_name), names[o.name], qos[o.qos],
                                          event_callbacks=quiet_events())
            for o in OUTPUTS if o.exists_for(scene)}


class Outputs:
    """Encodes and sends the outputs of a node. ``names``: relative -> resolved topic names;
    ``publishers``: relative name -> publisher (``publish(bytes)``; a topic without one is
    only recorded); ``recording``: a :class:`~rod_sim.ros.recording.NodeRecording`;
    ``dividers``: relative name -> period divider (default 1); ``period_ns`` [ns]: the control
    period, on whose grid the dividers count."""

    def __init__(self, scene: Scene, names: Mapping[str, str], publishers: Mapping,
                 recording, period_ns: int, frame_id: str,
                 dividers: Mapping[str, int] | None = None):
        self.scene = scene
        self.names = dict(names)
        self.publishers = dict(publishers)
        self.recording = recording
        self.period_ns = int(period_ns)
        self.frame_id = frame_id
        self.dividers = dict(dividers or {})
        self.taps: list[Callable[[Snapshot, int, dict], None]] = []
        """Called with every published state: ``tap(snapshot, t_ns, encoded)``, ``encoded``
        the bytes of the topics sent (e.g. the live view)."""
        self._exists: dict = {}
        self._applied_last: dict[str, tuple[tuple, bytes]] = {}
        """Per applied topic: (shape, raw bytes) of the values last published, and their
        encoding."""

    def _existing(self, names) -> tuple[Output, ...]:
        """The outputs of ``names`` the scene has (:meth:`Output.exists_for`), kept per
        ``names`` (the scene does not change)."""
        if type(names) is not tuple:
            names = tuple(names)
        found = self._exists.get(names)
        if found is None:
            found = self._exists[names] = tuple(
                BY_NAME[name] for name in names if BY_NAME[name].exists_for(self.scene))
        return found

    def encode(self, name: str, snapshot: Snapshot) -> bytes:
        """The CDR bytes of state topic ``name`` for ``snapshot``."""
        return BY_NAME[name].encode(snapshot, self.scene, self.frame_id)

    def due(self, name: str, t_ns: int) -> bool:
        """Whether the state at ``t_ns`` (on the control-period grid) carries topic ``name``."""
        return (t_ns // self.period_ns) % self.dividers.get(name, 1) == 0

    def send(self, name: str, t_ns: int, data: bytes, *, record: bool = True,
             publish: bool = True) -> None:
        """The encoded message ``data`` of topic ``name``: recorded at ``t_ns`` [ns] and
        published, the same bytes."""
        if record:
            self.recording.record_cdr(self.names[name], BY_NAME[name].type_name, t_ns, data)
        pub = self.publishers.get(name)
        if publish and pub is not None:
            pub.publish(data)

    def state(self, snapshot: Snapshot, t_ns: int, *, record: bool = True,
              names: Iterable[str] = STATE_TOPICS) -> None:
        """Every state topic due at ``t_ns`` [ns], each encoded once from ``snapshot``:
        published (always: the transient-local store then holds the latest state for a
        subscriber that joins later), then recorded (if ``record``), the same bytes; then the
        taps get the snapshot and the bytes. Publishing first lets a lockstep controller work
        on its next command while the node writes the log (measured: ~0.15 ms of recording
        per n = 8 period)."""
        encoded = {}
        scene, frame_id = self.scene, self.frame_id
        for output in self._existing(names):
            name = output.name
            if self.due(name, t_ns):
                data = encoded[name] = output.encode(snapshot, scene, frame_id)
                pub = self.publishers.get(name)
                if pub is not None:
                    pub.publish(data)
        if record:
            for name, data in encoded.items():
                self.recording.record_cdr(self.names[name], BY_NAME[name].type_name, t_ns, data)
        for tap in self.taps:
            tap(snapshot, t_ns, encoded)

    def applied(self, t_ns: int, forces: np.ndarray, torques: np.ndarray,
                base: np.ndarray | None = None) -> None:
        """The applied forces (n, 2) [N] and hinge torques (n,) [N m] from ``t_ns`` on, and on
        a free base ``base`` (4,) = [Fx, Fy, M, T_w] (:mod:`rod_sim.ros.applied_base`): each
        recorded every period, published when it changes (and the first time; compared bit
        for bit)."""
        sent = [("applied_forces", forces, encoders.force_array),
                ("applied_torques", torques, encoders.torque_array)]
        if base is not None:
            sent.append((APPLIED_BASE_TOPIC, base,
                         lambda v: encoders.labelled_array(v, APPLIED_BASE_LABEL)))
        for name, values, encode in sent:
            values = np.ascontiguousarray(values, dtype=float)
            raw = (values.shape, values.tobytes())
            last = self._applied_last.get(name)
            # compared bit for bit (-0.0 is not 0.0: its bytes differ); unchanged values are
            # recorded as the same bytes again, not encoded again
            changed = last is None or raw != last[0]
            if changed:
                last = self._applied_last[name] = (raw, encode(values))
            self.send(name, t_ns, last[1], publish=changed)

    def set_frame_id(self, frame_id: str, t_ns: int) -> None:
        """The ``frame_id`` parameter changed: the outputs from now on name it, and
        ``robot_description`` (its root link) is published again at ``t_ns``, not recorded."""
        self.frame_id = frame_id
        self.descriptions(t_ns, record=False, which=("robot_description",))

    def forget_applied(self) -> None:
        """After a reset: the next applied inputs are published whatever they are."""
        self._applied_last = {}

    def message(self, name: str, t_ns: int, data: Mapping, *, record: bool = True) -> None:
        """A message dict (descriptions, diagnostics, events) encoded once by
        :mod:`rod_sim.io.cdr`, recorded and published."""
        self.send(name, t_ns, cdr.encoder(BY_NAME[name].type_name)(data), record=record)

    def descriptions(self, t_ns: int, *, record: bool = True, which=("robot_description",
                                                                      "scene")) -> None:
        """``robot_description`` (URDF, root link = ``frame_id``) and ``scene`` (YAML) at
        ``t_ns``: published (transient local) and recorded."""
        from rod_sim.io.scene_yaml import scene_to_yaml
        from rod_sim.io.urdf import scene_urdf

        texts = {"robot_description": lambda: scene_urdf(self.scene, self.frame_id),
                 "scene": lambda: scene_to_yaml(self.scene)}
        for name in which:
            self.message(name, t_ns, {"data": texts[name]()}, record=record)

    def events(self, events) -> None:
        """Hinge events (objects with ``to_dict``), each stamped at its simulated time."""
        for event in events:
            d = event.to_dict()
            self.message(HINGE_EVENTS_TOPIC, event_time_ns(d), event_message(d))


class SimClock:
    """``/clock`` through ``publisher`` (None: not published): the simulated time of every
    period before that period's outputs, and while nothing advances the frozen time again every
    ``idle_s`` [s] of wall time; sent only while someone listens. Not recorded."""

    def __init__(self, publisher, idle_s: float):
        self.publisher = publisher
        self.idle_ns = int(idle_s * 1e9)
        self._wall_ns = 0

    def publish(self, t_ns: int) -> None:
        if self.publisher is not None and self.publisher.get_subscription_count() > 0:
            self.publisher.publish(encoders.clock_ns(t_ns))
            self._wall_ns = time.monotonic_ns()

    def idle(self, t_ns: int) -> None:
        """A timer's call: publish ``t_ns`` again if no period published for ``idle_s``."""
        if time.monotonic_ns() - self._wall_ns >= self.idle_ns:
            self.publish(t_ns)
