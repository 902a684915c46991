"""Replay of a log on a live ROS graph: the :class:`Player` node behind ``rod-sim replay``.

Every selected topic gets a publisher of its recorded type with the QoS its recorders offered
(the channel's ``offered_qos_profiles``, adapted as rosbag2's player does: our logs offer
``/applied_forces`` reliable, transient_local, depth 1). Messages go out as the recorded CDR
bytes (``Publisher.publish(bytes)``, no decoding), in log-time order, each when the wall time
since the start reaches its log-time offset divided by ``rate``.

``/clock`` (rosgraph_msgs/Clock, best effort, depth 1: rclcpp's ClockQoS) carries the log time:
at a steady wall-clock frequency between messages (the log time the wall clock corresponds
to, never past the next message) and just before every message with that message's log time,
so a node with ``use_sim_time`` sees its clock at a message's time when the message arrives.
With ``loop`` the log starts again after its end and the clock jumps back.

Paused (``start_paused`` or the ``~/pause`` service, std_srvs/SetBool) nothing is published;
resuming continues from the next message, the clock re-anchored. ``~/toggle_paused``
(std_srvs/Trigger) toggles.
"""
from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from std_srvs.srv import SetBool, Trigger

from rod_sim.core.units import NS_PER_S
from rod_sim.io.playback import PlaybackSource, QosSpec, Timeline
from rod_sim.ros.conversions import message_class
from rod_sim.ros.process import StopRequest, spin_until
from rod_sim.ros.qos import CLOCK_QOS

NODE_NAME = "rod_sim_replay"
MAX_WAIT_S = 0.05
"""[s] longest single wait, so that a stop request or a service call is served promptly."""


def qos_profile(spec: QosSpec) -> QoSProfile:
    """The rclpy QoSProfile of a :class:`~rod_sim.io.playback.QosSpec`."""
    history = (HistoryPolicy.KEEP_ALL if spec.history == "keep_all" else HistoryPolicy.KEEP_LAST)
    return QoSProfile(
        history=history, depth=max(1, spec.depth),
        reliability=(ReliabilityPolicy.BEST_EFFORT if spec.reliability == "best_effort"
                     else ReliabilityPolicy.RELIABLE),
        durability=(DurabilityPolicy.TRANSIENT_LOCAL if spec.durability == "transient_local"
                    else DurabilityPolicy.VOLATILE))


def clock_message(t_ns: int) -> Clock:
    msg = Clock()
    msg.clock.sec, msg.clock.nanosec = divmod(int(t_ns), NS_PER_S)
    return msg


@dataclass
class PlayStats:
    """What a :meth:`Player.play` did: messages published, clock messages, loops started,
    log span of the last pass [ns], wall time from the first message on [s], and whether it
    was stopped before the end."""

    messages: int = 0
    clock_messages: int = 0
    passes: int = 0
    first_ns: int | None = None
    last_ns: int | None = None
    wall_s: float = 0.0
    stopped: bool = False
    max_late_s: float = 0.0
    """[s] largest delay of a publication after its due wall time (player side)."""


class Player(Node):
    """Publishes ``topics`` (absolute names of ``source.tracks``) of ``source``.

    ``rate``: log seconds per wall second (> 0). ``clock_hz``: /clock frequency [Hz of wall
    time]; 0 = no /clock at all. ``start_offset_s``: skip the first seconds of the log (log
    time, from its first selected message). ``node_kwargs`` go to :class:`rclpy.node.Node`.
    Raises ValueError for a type that is not installed.
    """

    def __init__(self, source: PlaybackSource, topics: Sequence[str], *, rate: float = 1.0,
                 clock_hz: float = 100.0, loop: bool = False, start_paused: bool = False,
                 start_offset_s: float = 0.0, live_view=None, **node_kwargs):
        super().__init__(NODE_NAME, **node_kwargs)
        try:
            self.source = source
            self.topics = list(topics)
            self.timeline = Timeline(rate)
            self.clock_period_ns = round(NS_PER_S / clock_hz) if clock_hz > 0 else 0
            self.loop = loop
            self.start_offset_ns = round(start_offset_s * NS_PER_S)
            self.paused = start_paused
            self.live_view = live_view
            """A :class:`~rod_sim.io.live_view.LiveView` shown what is replayed (or None)."""
            self._pubs = {}
            for topic in self.topics:
                track = source.tracks[topic]
                self._pubs[topic] = self.create_publisher(
                    message_class(track.type_name), topic, qos_profile(track.qos))
            self._clock_pub = (self.create_publisher(Clock, "/clock", CLOCK_QOS)
                               if self.clock_period_ns else None)
            self.create_service(SetBool, "~/pause", self._on_pause)
            self.create_service(Trigger, "~/toggle_paused", self._on_toggle)
        except BaseException:
            self.destroy_node()
            raise
        self._pause_changed = False
        self._next_clock_wall = 0
        self._last_clock: int | None = None
        self.stats = PlayStats()

    # ----- services -----

    def _set_paused(self, paused: bool) -> str:
        if paused != self.paused:
            self.paused = paused
            self._pause_changed = True
        state = "paused" if paused else "playing"
        self.get_logger().info(state)
        return state

    def _on_pause(self, request, response):
        """data true: pause; false: resume."""
        response.message = self._set_paused(bool(request.data))
        response.success = True
        return response

    def _on_toggle(self, request, response):
        response.message = self._set_paused(not self.paused)
        response.success = True
        return response

    # ----- playing -----

    def subscribers_matched(self) -> bool:
        """Every replayed topic has at least one matched subscription."""
        return all(pub.get_subscription_count() > 0 for pub in self._pubs.values())

    def _publish_clock(self, t_ns: int) -> None:
        if self._clock_pub is None or t_ns == self._last_clock:
            return
        self._clock_pub.publish(clock_message(t_ns))
        self._last_clock = t_ns
        self.stats.clock_messages += 1

    def _wait_until_due(self, executor, stop: StopRequest, t_ns: int) -> bool:
        """Serve callbacks and publish /clock until log time ``t_ns`` is due (False when a stop
        is requested first). While paused the timeline is re-anchored at ``t_ns``. Records
        how late the due time is met in ``stats.max_late_s``."""
        period = self.clock_period_ns
        while True:
            if stop.requested or not executor.context.ok():
                return False
            now = time.monotonic_ns()
            if self._pause_changed:
                self._pause_changed = False
                if not self.paused:                         # resume at the next message
                    self.timeline.anchor(t_ns, now)
                    self._next_clock_wall = now
            if self.paused:
                executor.spin_once(timeout_sec=MAX_WAIT_S)
                continue
            due = self.timeline.wall_at(t_ns)
            if now >= due:
                self.stats.max_late_s = max(self.stats.max_late_s, (now - due) / NS_PER_S)
                return True
            wake = due
            if period:
                if now >= self._next_clock_wall:
                    self._publish_clock(min(self.timeline.log_at(now), t_ns))
                    self._next_clock_wall += period
                    if self._next_clock_wall <= now:         # fell behind: do not burst
                        self._next_clock_wall = now + period
                wake = min(wake, self._next_clock_wall)
            executor.spin_once(timeout_sec=min(MAX_WAIT_S, max(0, wake - now) / NS_PER_S))

    def play(self, executor, stop: StopRequest) -> PlayStats:
        """Publish the log (again and again with ``loop``) until its end or a stop request.
        ``executor`` must hold this node (it serves the pause services while waiting)."""
        stats = self.stats
        started_wall = None
        while True:
            first = None
            for topic, t_ns, data in self.source.messages(self.topics):
                if first is None:
                    first = t_ns
                    start = first + self.start_offset_ns
                    self.timeline.anchor(start, time.monotonic_ns())
                    self._next_clock_wall = self.timeline.wall_ns
                    stats.passes += 1
                    stats.first_ns = start
                if t_ns < start:
                    continue
                if not self._wait_until_due(executor, stop, t_ns):
                    stats.stopped = True
                    break
                if started_wall is None:
                    started_wall = time.monotonic_ns()
                self._publish_clock(t_ns)
                self._pubs[topic].publish(data)
                if self.live_view is not None:
                    self.live_view.forward(topic, t_ns, data)
                stats.messages += 1
                stats.last_ns = t_ns
            if started_wall is not None:
                stats.wall_s = (time.monotonic_ns() - started_wall) / NS_PER_S
            if stats.stopped or not self.loop or first is None:
                return stats
            executor.spin_once(timeout_sec=0)


    def flush(self, timeout_s: float = 2.0) -> bool:
        """Wait (at most ``timeout_s`` in all) until the matched subscribers acknowledged
        every reliable message, so that exiting right after the last one loses none."""
        from rclpy.duration import Duration

        deadline = time.monotonic() + timeout_s
        acked = True
        for pub in self._pubs.values():
            left = max(0.0, deadline - time.monotonic())
            acked = pub.wait_for_all_acked(Duration(nanoseconds=int(left * NS_PER_S))) and acked
        return acked


def wait_for_subscribers(player: Player, executor, stop: StopRequest) -> bool:
    """Spin until every replayed topic has a subscriber (False when stopped first)."""
    waiting = [t for t, pub in player._pubs.items() if pub.get_subscription_count() == 0]
    if waiting:
        player.get_logger().info(f"waiting for a subscriber on {', '.join(waiting)}")
    spin_until(executor, stop, player.subscribers_matched)
    return player.subscribers_matched()
