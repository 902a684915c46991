"""What one wake-up of rclpy's executor costs the main thread (rclpy's and the machine's, not
the period's).

    python -m rod_sim.ros.executor_cost [--seconds 2] [--rounds 2] [--domain 227]

The node's pacing timer wakes rclpy's ``SingleThreadedExecutor`` at every tick, and each
wake-up rebuilds the wait set from every entity of the node, in Python. This measures the main
thread's CPU time per wake-up of a 1 ms timer whose callback does nothing (``time.thread_time``
over ``--seconds`` of spinning, divided by the timer's calls), on two nodes taking turns,
``--rounds`` times: a ``bare`` node (the timer only, no parameter services) and one with the
``node's entities`` (the timer, 5 more timers, 3 services, 3 command subscriptions and the
parameter services, as :class:`~rod_sim.ros.node.RodSimNode` has them). No message is sent.
``ROS_AUTOMATIC_DISCOVERY_RANGE`` is LOCALHOST and ``ROS_DOMAIN_ID`` is ``--domain``.
"""
from __future__ import annotations

import argparse
import os
import time

KINDS = ("bare", "node's entities")
TICK_S = 0.001
"""[s] period of the timer that wakes the executor (the node's shortest pacing tick)."""


def wake_cost(rclpy, kind: str, seconds: float) -> tuple[int, float]:
    """(timer calls, main-thread CPU [us] per call) of one node of ``kind`` (:data:`KINDS`)
    spun for ``seconds`` after 0.3 s of warm-up."""
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import Float64MultiArray
    from std_srvs.srv import Trigger

    full = kind == KINDS[1]
    node = rclpy.create_node(f"executor_cost_{KINDS.index(kind)}",
                             start_parameter_services=full)
    calls = [0]
    node.create_timer(TICK_S, lambda: calls.__setitem__(0, calls[0] + 1))
    if full:
        for i in range(5):
            node.create_timer(1.0 + i, lambda: None)
        for name in ("reset", "step", "pause"):
            node.create_service(Trigger, f"~/{name}", lambda request, response: response)
        for i in range(3):
            node.create_subscription(Float64MultiArray, f"~/command_{i}", lambda m: None, 10)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        warm_end = time.monotonic() + 0.3
        while time.monotonic() < warm_end:
            executor.spin_once(timeout_sec=0.01)
        cpu0, calls0, end = time.thread_time(), calls[0], time.monotonic() + seconds
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.01)
        cpu, n = time.thread_time() - cpu0, calls[0] - calls0
    finally:
        executor.remove_node(node)
        node.destroy_node()
    return n, (1e6 * cpu / n if n else float("nan"))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m rod_sim.ros.executor_cost",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("--seconds", type=float, default=2.0, help="[s] of spinning per node")
    p.add_argument("--rounds", type=int, default=2, help="rounds of the two nodes")
    p.add_argument("--domain", type=int, default=227,
                   help="ROS_DOMAIN_ID (Fast DDS allows 0..232)")
    args = p.parse_args(argv)
    if not args.seconds > 0 or args.rounds < 1 or not 0 <= args.domain <= 232:
        p.error("--seconds must be > 0, --rounds >= 1 and --domain in 0..232")
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ["ROS_DOMAIN_ID"] = str(args.domain)
    import rclpy

    rclpy.init()
    try:
        for _ in range(args.rounds):
            for kind in KINDS:
                n, us = wake_cost(rclpy, kind, args.seconds)
                print(f"{kind}: {us:.0f} us of main-thread CPU per wake-up ({n} wake-ups of a "
                      f"{TICK_S * 1e3:g} ms timer)", flush=True)
    finally:
        rclpy.shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
