"""rod_sim.ros.executor.LeanExecutor against rclpy's SingleThreadedExecutor (the oracle): the
same callbacks run, in the same order, for the entities and patterns the node uses (timers
destroyed and re-created, raw subscriptions, services with a coroutine callback awaiting a
guard condition's turn, mutually exclusive and reentrant groups, timeouts, shutdown), with
nothing asserted about time but bounds no load reaches."""
from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
from ros_domains import next_domain  # noqa: E402

rclpy = pytest.importorskip("rclpy")
from rclpy.callback_groups import ReentrantCallbackGroup  # noqa: E402
from rclpy.clock import Clock, ClockType  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from std_msgs.msg import Int32  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from ros_graph import Client  # noqa: E402
from rod_sim.ros.executor import LeanExecutor  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]

EXECUTORS = {"rclpy": SingleThreadedExecutor, "lean": LeanExecutor}
LIMIT_S = 30.0
"""[s] for anything the executor is to run: a bound no load reaches."""


@pytest.fixture
def domain(monkeypatch):
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    domain = next_domain()
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    return domain


def scripted_run(kind: str, domain: int) -> list:
    """A script of entity events on one node, spun by ``kind``: returns the callbacks' log."""
    log = []
    graph = Client(domain, "lean_script", executor_class=EXECUTORS[kind])
    node, executor = graph.node, graph.executor
    steady = Clock(clock_type=ClockType.STEADY_TIME)
    try:
        # a guard condition triggered before spinning, twice: one call
        gc = node.create_guard_condition(lambda: log.append("guard"))
        gc.trigger()
        gc.trigger()
        graph.spin_until(lambda: "guard" in log, LIMIT_S, "the guard condition's callback")
        # a raw subscription gets the bytes of each message, in order
        sub_msgs = []
        node.create_subscription(Int32, "lean_topic", lambda data: sub_msgs.append(bytes(data)),
                                 10, raw=True)
        pub = node.create_publisher(Int32, "lean_topic", 10)
        graph.spin_until(lambda: pub.get_subscription_count() > 0, LIMIT_S, "the subscription's discovery")
        for k in range(3):
            pub.publish(Int32(data=k))
        graph.spin_until(lambda: len(sub_msgs) == 3, LIMIT_S, "3 messages")
        log.append(("sub", [m[-4:] for m in sub_msgs]))
        # a timer destroyed from its own callback, another created in its place
        fired = []

        def first():
            fired.append("first")
            node.destroy_timer(timers[0])
            timers[0] = node.create_timer(0.001, lambda: fired.append("second"), clock=steady)
        timers = [node.create_timer(0.001, first, clock=steady)]
        graph.spin_until(lambda: fired.count("second") >= 3, LIMIT_S, "the re-created timer")
        log.append(("timers", fired.count("first"), fired[:2]))
        node.destroy_timer(timers[0])
        # a coroutine service callback in a reentrant group that yields the executor between
        # its slices (as the node's ~/step): a plain service of the default group runs between
        wake = node.create_guard_condition(lambda: None)

        class NextTurn:
            def __await__(self):
                yield

        async def sliced(request, response):
            for k in range(3):
                log.append(f"slice {k}")
                wake.trigger()
                await NextTurn()
            response.success = True
            return response

        def plain(request, response):
            log.append("plain")
            response.success = True
            return response

        node.create_service(Trigger, "lean_sliced", sliced,
                            callback_group=ReentrantCallbackGroup())
        node.create_service(Trigger, "lean_plain", plain)
        client_s = node.create_client(Trigger, "lean_sliced")
        client_p = node.create_client(Trigger, "lean_plain")
        graph.spin_until(lambda: client_s.service_is_ready() and client_p.service_is_ready(), LIMIT_S, "the services")
        fs = client_s.call_async(Trigger.Request())
        graph.spin_until(lambda: "slice 0" in log, LIMIT_S, "the sliced service's first slice")
        fp = client_p.call_async(Trigger.Request())
        graph.spin_until(lambda: fs.done() and fp.done(), LIMIT_S, "both responses")
        log.append(("responses", fs.result().success, fp.result().success))
        # a task created on the executor runs, its result is the callback's
        task = executor.create_task(lambda: 42)
        graph.spin_until(task.done, LIMIT_S, "the task")
        log.append(("task", task.result()))
        # nothing ready: spin_once(timeout) returns (no wait without end)
        start = time.monotonic()
        executor.spin_once(timeout_sec=0.05)
        log.append(("timeout returned", time.monotonic() - start < 20.0))
    finally:
        graph.close()
    return log


@pytest.mark.parametrize("kind", ["rclpy", "lean"])
def test_the_script_runs_each_callback_once(kind, domain):
    log = scripted_run(kind, domain)
    assert log.count("guard") == 1
    assert ("sub", [(0).to_bytes(4, "little"), (1).to_bytes(4, "little"),
                    (2).to_bytes(4, "little")]) in log
    timers = next(item for item in log if item[0] == "timers")
    assert timers[1] == 1 and timers[2] == ["first", "second"]
    assert [x for x in log if isinstance(x, str) and x.startswith("slice")] == \
        ["slice 0", "slice 1", "slice 2"]
    assert "plain" in log
    assert ("responses", True, True) in log and ("task", 42) in log
    assert ("timeout returned", True) in log


def test_lean_runs_the_script_as_rclpy_does(domain):
    """The oracle is rclpy's executor: the same log, entry for entry (the plain service's
    place among the slices included: the order in which ready callbacks run)."""
    assert scripted_run("lean", domain) == scripted_run("rclpy", domain)


def test_a_busy_mutually_exclusive_group_keeps_its_other_callbacks_out(domain):
    """While a coroutine callback of the default (mutually exclusive) group is suspended, a
    timer of that group does not run; it runs once the coroutine has finished."""
    graph = Client(domain, "lean_group", executor_class=LeanExecutor)
    node, executor = graph.node, graph.executor
    log = []
    gate = rclpy.task.Future()

    async def holds():
        log.append("hold start")
        await gate
        log.append("hold end")

    try:
        timer = node.create_timer(0.001, lambda: log.append("timer"),
                                  clock=Clock(clock_type=ClockType.STEADY_TIME))
        timer.cancel()
        task_gc = node.create_guard_condition(holds)
        task_gc.trigger()
        graph.spin_until(lambda: "hold start" in log, LIMIT_S, "the coroutine's start")
        timer.reset()
        for _ in range(40):
            executor.spin_once(timeout_sec=0.005)
        assert "timer" not in log           # the group is busy with the suspended coroutine
        gate.set_result(None)
        graph.spin_until(lambda: "timer" in log, LIMIT_S, "the timer after the coroutine")
        assert log.index("hold end") < log.index("timer")
    finally:
        graph.close()


def test_shutdown_ends_spinning(domain):
    graph = Client(domain, "lean_shutdown", executor_class=LeanExecutor)
    graph.executor.shutdown()
    graph.executor.spin_once(timeout_sec=None)        # returns at once: shut down
    graph.close()


@pytest.mark.parametrize("kind", ["rclpy", "lean"])
def test_an_exception_in_a_plain_callback_comes_out_of_spin_once_and_frees_its_group(
        kind, domain):
    """A timer callback (a plain function, of the default mutually exclusive group) that
    raises: spin_once raises it, as rclpy's executor does, and the group runs the next
    callbacks (the timer's own and a raw subscription's) afterwards."""
    graph = Client(domain, f"lean_raise_{kind}", executor_class=EXECUTORS[kind])
    node, executor = graph.node, graph.executor
    calls, got = [], []

    def tick():
        calls.append(len(calls))
        if len(calls) == 1:
            raise ValueError("first tick")

    try:
        node.create_timer(0.001, tick, clock=Clock(clock_type=ClockType.STEADY_TIME))
        with pytest.raises(ValueError, match="first tick"):
            deadline = time.monotonic() + LIMIT_S
            while not calls and time.monotonic() < deadline:
                executor.spin_once(timeout_sec=0.05)
        graph.spin_until(lambda: len(calls) >= 3, LIMIT_S, "the timer after its exception")
        node.create_subscription(Int32, "lean_raise", lambda data: got.append(bytes(data)), 10,
                                 raw=True)
        pub = node.create_publisher(Int32, "lean_raise", 10)
        graph.spin_until(lambda: pub.get_subscription_count() > 0, LIMIT_S, "discovery")
        pub.publish(Int32(data=7))
        graph.spin_until(lambda: got, LIMIT_S, "the message")
        assert got[0][-4:] == (7).to_bytes(4, "little")
    finally:
        graph.close()
