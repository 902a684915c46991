"""What one wake-up of the executor costs the main thread (rclpy's and the machine's, not the
period's), with rclpy's executor and with the node's own.

    python -m rod_sim.ros.executor_cost [--seconds 2] [--rounds 2] [--domain 227]

The node's pacing timer wakes its executor at every tick, and each wake-up waits on every
entity of the node. This measures the main thread's CPU time per wake-up of a 1 ms timer whose
callback does nothing (``time.thread_time`` over ``--seconds`` of spinning, divided by the
timer's calls) for two nodes and two executors, taking turns, ``--rounds`` times:

- nodes: ``bare`` (the timer only, no parameter services) and ``rod_sim node`` (a real
  :class:`~rod_sim.ros.node.RodSimNode` on the paper's example, paused, its pacing tick at
  1 Hz, with the 1 ms timer added: every entity the node has, as it has them);
- executors: ``rclpy's`` (:class:`rclpy.executors.SingleThreadedExecutor`) and ``lean``
  (:class:`~rod_sim.ros.executor.LeanExecutor`, what ``rod-sim node`` spins).

No message is sent. ``ROS_AUTOMATIC_DISCOVERY_RANGE`` is LOCALHOST and ``ROS_DOMAIN_ID`` is
``--domain``.
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

NODES = ("bare", "rod_sim node")
EXECUTORS = ("rclpy's", "lean")
TICK_S = 0.001
"""[s] period of the timer that wakes the executor (the node's shortest pacing tick)."""
SCENE = Path(__file__).resolve().parents[2] / "config" / "paper_example.yaml"


def make_node(rclpy, kind: str):
    """A node of ``kind`` (:data:`NODES`) without its 1 ms timer."""
    if kind == NODES[0]:
        return rclpy.create_node("executor_cost_bare", start_parameter_services=False)
    from rclpy.parameter import Parameter

    from rod_sim.ros.node import RodSimNode

    return RodSimNode(parameter_overrides=[
        Parameter("scene_file", value=str(SCENE)), Parameter("rate_hz", value=1.0),
        Parameter("start_paused", value=True)])


def make_executor(kind: str):
    """An executor of ``kind`` (:data:`EXECUTORS`)."""
    from rclpy.executors import SingleThreadedExecutor

    from rod_sim.ros.executor import LeanExecutor

    return SingleThreadedExecutor() if kind == EXECUTORS[0] else LeanExecutor()


def wake_cost(node, executor, calls: list[int], seconds: float) -> tuple[int, float]:
    """(timer calls, main-thread CPU [us] per call) of ``node`` spun by ``executor`` for
    ``seconds`` after 0.3 s of warm-up; ``calls[0]`` counts the 1 ms timer's calls."""
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
    return n, (1e6 * cpu / n if n else float("nan"))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m rod_sim.ros.executor_cost",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("--seconds", type=float, default=2.0, help="[s] of spinning per turn")
    p.add_argument("--rounds", type=int, default=2, help="rounds of the four turns")
    p.add_argument("--domain", type=int, default=227,
                   help="ROS_DOMAIN_ID (Fast DDS allows 0..232)")
    args = p.parse_args(argv)
    if not args.seconds > 0 or args.rounds < 1 or not 0 <= args.domain <= 232:
        p.error("--seconds must be > 0, --rounds >= 1 and --domain in 0..232")
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ["ROS_DOMAIN_ID"] = str(args.domain)
    import rclpy

    rclpy.init()
    nodes = {}
    try:
        for kind in NODES:
            calls = [0]
            node = make_node(rclpy, kind)
            node.create_timer(TICK_S, lambda calls=calls: calls.__setitem__(0, calls[0] + 1))
            nodes[kind] = node, calls
        executors = {kind: make_executor(kind) for kind in EXECUTORS}
        for _ in range(args.rounds):
            for kind, (node, calls) in nodes.items():
                for ex in EXECUTORS:
                    n, us = wake_cost(node, executors[ex], calls, args.seconds)
                    print(f"{kind}, {ex} executor: {us:.0f} us of main-thread CPU per wake-up "
                          f"({n} wake-ups of a {TICK_S * 1e3:g} ms timer)", flush=True)
    finally:
        for node, _ in nodes.values():
            node.destroy_node()
        rclpy.shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
