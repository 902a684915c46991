"""QoS profiles of the rod_sim node's topics (and of ``/clock``, which the player shares).

Every output topic offers one QoS in every mode (real time, as fast as possible, lockstep), so
that one subscriber QoS works against any node: the state topics are **reliable and transient
local**, which both default-QoS (reliable, volatile) and transient-local subscribers match (a
transient-local publisher serves volatile subscribers too). Only the history depth differs
between modes, and depth plays no part in QoS matching: 10 at a real-time pace (a slow reliable
reader does not lose states in a burst), 1 in lockstep (a late transient-local reader gets just
the latest state, the one the simulator waits on)."""
from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy


def keep_last(depth: int, reliability: ReliabilityPolicy = ReliabilityPolicy.RELIABLE,
              durability: DurabilityPolicy = DurabilityPolicy.VOLATILE) -> QoSProfile:
    """A keep-last profile of ``depth`` messages."""
    return QoSProfile(depth=depth, history=HistoryPolicy.KEEP_LAST, reliability=reliability,
                      durability=durability)


STATE_DEPTH = 10
"""History depth of the state topics at a real-time pace (and as fast as possible)."""
LOCKSTEP_STATE_DEPTH = 1
"""History depth of the state topics in lockstep: a late joiner gets the latest state only."""
STATE_QOS = keep_last(STATE_DEPTH, durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""State topics (``joint_states``, ``rod_states``, ``bending``, ``node_poses``, ``markers``)
outside lockstep: reliable, transient local."""
LOCKSTEP_STATE_QOS = keep_last(LOCKSTEP_STATE_DEPTH, durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""Lockstep state topics: the same reliability and durability as :data:`STATE_QOS` (so the same
subscribers match), depth 1: a transient-local client gets the latest state (the t = 0 state
before the first command) and can answer it."""
DIAGNOSTICS_QOS = keep_last(10)
"""``/diagnostics``: reliable, volatile, depth 10, as diagnostic_updater publishes."""
LATCHED_QOS = keep_last(1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""``robot_description`` and ``scene``: published once (and after ``~/reset``), kept for late
subscribers, as robot_state_publisher publishes ``robot_description``."""
APPLIED_QOS = keep_last(1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""``applied_forces`` is published only when it changes: late subscribers get the latest one."""
CLOCK_QOS = keep_last(1, reliability=ReliabilityPolicy.BEST_EFFORT)
"""rclcpp's ClockQoS, which rclpy's TimeSource and rosbag2's player also use."""
CLOCK_RELIABILITY = {"reliable": ReliabilityPolicy.RELIABLE,
                     "best_effort": ReliabilityPolicy.BEST_EFFORT}
"""Values of the ``clock_reliability`` parameter. A reliable publisher reaches both reliable
(default QoS) and best-effort (ClockQoS) subscribers; a best-effort one only the latter."""
COMMAND_QOS = keep_last(10)
"""``nodal_forces`` subscription: reliable, volatile, depth 10; it matches reliable publishers,
volatile or transient local (not best-effort ones: a lockstep command must not be lost)."""
EVENTS_QOS = keep_last(100, durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""``hinge_events`` are rare and matter: kept for late subscribers (docs/hinges.md)."""


SERVICE_QUEUE_DEPTH = 10_000
SERVICE_QOS = keep_last(SERVICE_QUEUE_DEPTH)
"""``~/pause``, ``~/step``, ``~/reset``: rclpy's default service QoS keeps 10 requests, so a
burst of calls lost all but ~10 in the middleware, unanswered; a depth of 1000 still lost the
calls beyond 1000 per service in a flood of 4000 (issue 27 item 9). 10 000 outstanding
requests per service are kept (and their responses); each is answered, or refused "busy"."""


def clock_qos(reliability: str) -> QoSProfile:
    """``/clock`` (depth 1, volatile) with a :data:`CLOCK_RELIABILITY` name's reliability."""
    return keep_last(1, reliability=CLOCK_RELIABILITY[reliability])
