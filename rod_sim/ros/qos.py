"""QoS profiles of the rod_sim node's topics (and of ``/clock``, which the player shares)."""
from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy


def keep_last(depth: int, reliability: ReliabilityPolicy = ReliabilityPolicy.RELIABLE,
              durability: DurabilityPolicy = DurabilityPolicy.VOLATILE) -> QoSProfile:
    """A keep-last profile of ``depth`` messages."""
    return QoSProfile(depth=depth, history=HistoryPolicy.KEEP_LAST, reliability=reliability,
                      durability=durability)


STATE_QOS = keep_last(10)
APPLIED_QOS = keep_last(1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""``applied_forces`` is published only when it changes: late subscribers get the latest one."""
CLOCK_QOS = keep_last(1, reliability=ReliabilityPolicy.BEST_EFFORT)
"""rclcpp's ClockQoS, which rclpy's TimeSource and rosbag2's player also use."""
CLOCK_RELIABILITY = {"reliable": ReliabilityPolicy.RELIABLE,
                     "best_effort": ReliabilityPolicy.BEST_EFFORT}
"""Values of the ``clock_reliability`` parameter. A reliable publisher reaches both reliable
(default QoS) and best-effort (ClockQoS) subscribers; a best-effort one only the latter."""
LOCKSTEP_STATE_QOS = keep_last(1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""Lockstep state topics: a client that subscribes transient local gets the latest state
(the t = 0 state before the first command) and can answer it."""
COMMAND_QOS = STATE_QOS
EVENTS_QOS = keep_last(100, durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""``hinge_events`` are rare and matter: kept for late subscribers (docs/hinges.md)."""


SERVICE_QUEUE_DEPTH = 1000
SERVICE_QOS = keep_last(SERVICE_QUEUE_DEPTH)
"""``~/pause``, ``~/step``, ``~/reset``: rclpy's default service QoS keeps 10 requests, so a
burst of calls lost all but ~10 in the middleware, unanswered. 1000 outstanding requests per
service are kept (and their responses); each is answered, or refused "busy"."""


def clock_qos(reliability: str) -> QoSProfile:
    """``/clock`` (depth 1, volatile) with a :data:`CLOCK_RELIABILITY` name's reliability."""
    return keep_last(1, reliability=CLOCK_RELIABILITY[reliability])
