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

from rod_sim.ros.executor import LeanExecutor  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]

EXECUTORS = {"rclpy": SingleThreadedExecutor, "lean": LeanExecutor}


@pytest.fixture
def context(monkeypatch):
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    domain = next_domain()
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain)
    yield ctx
    rclpy.try_shutdown(context=ctx)


def spin_until(executor, done, limit_s: float = 30.0) -> None:
    end = time.monotonic() + limit_s
    while not done():
        assert time.monotonic() < end, "the executor never ran what was due"
        executor.spin_once(timeout_sec=0.05)


def scripted_run(kind: str, ctx) -> list:
    """A script of entity events on one node, spun by ``kind``: returns the callbacks' log."""
    log = []
    node = rclpy.create_node("lean_script", context=ctx)
    executor = EXECUTORS[kind](context=ctx)
    executor.add_node(node)
    steady = Clock(clock_type=ClockType.STEADY_TIME)
    try:
        # a guard condition triggered before spinning, twice: one call
        gc = node.create_guard_condition(lambda: log.append("guard"))
        gc.trigger()
        gc.trigger()
        spin_until(executor, lambda: "guard" in log)
        # a raw subscription gets the bytes of each message, in order
        sub_msgs = []
        node.create_subscription(Int32, "lean_topic", lambda data: sub_msgs.append(bytes(data)),
                                 10, raw=True)
        pub = node.create_publisher(Int32, "lean_topic", 10)
        spin_until(executor, lambda: pub.get_subscription_count() > 0)
        for k in range(3):
            pub.publish(Int32(data=k))
        spin_until(executor, lambda: len(sub_msgs) == 3)
        log.append(("sub", [m[-4:] for m in sub_msgs]))
        # a timer destroyed from its own callback, another created in its place
        fired = []

        def first():
            fired.append("first")
            node.destroy_timer(timers[0])
            timers[0] = node.create_timer(0.001, lambda: fired.append("second"), clock=steady)
        timers = [node.create_timer(0.001, first, clock=steady)]
        spin_until(executor, lambda: fired.count("second") >= 3)
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
        spin_until(executor, lambda: client_s.service_is_ready() and client_p.service_is_ready())
        fs = client_s.call_async(Trigger.Request())
        spin_until(executor, lambda: "slice 0" in log)
        fp = client_p.call_async(Trigger.Request())
        spin_until(executor, lambda: fs.done() and fp.done())
        log.append(("responses", fs.result().success, fp.result().success))
        # a task created on the executor runs, its result is the callback's
        task = executor.create_task(lambda: 42)
        spin_until(executor, task.done)
        log.append(("task", task.result()))
        # nothing ready: spin_once(timeout) returns (no wait without end)
        start = time.monotonic()
        executor.spin_once(timeout_sec=0.05)
        log.append(("timeout returned", time.monotonic() - start < 20.0))
    finally:
        executor.shutdown()
        node.destroy_node()
    return log


@pytest.mark.parametrize("kind", ["rclpy", "lean"])
def test_the_script_runs_each_callback_once(kind, context):
    log = scripted_run(kind, context)
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


def test_lean_runs_the_script_as_rclpy_does(context):
    """The oracle is rclpy's executor: the same log, entry for entry (the plain service's
    place among the slices included: the order in which ready callbacks run)."""
    assert scripted_run("lean", context) == scripted_run("rclpy", context)


def test_a_busy_mutually_exclusive_group_keeps_its_other_callbacks_out(context):
    """While a coroutine callback of the default (mutually exclusive) group is suspended, a
    timer of that group does not run; it runs once the coroutine has finished."""
    node = rclpy.create_node("lean_group", context=context)
    executor = LeanExecutor(context=context)
    executor.add_node(node)
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
        spin_until(executor, lambda: "hold start" in log)
        timer.reset()
        for _ in range(40):
            executor.spin_once(timeout_sec=0.005)
        assert "timer" not in log           # the group is busy with the suspended coroutine
        gate.set_result(None)
        spin_until(executor, lambda: "timer" in log)
        assert log.index("hold end") < log.index("timer")
    finally:
        executor.shutdown()
        node.destroy_node()


def test_shutdown_ends_spinning(context):
    node = rclpy.create_node("lean_shutdown", context=context)
    executor = LeanExecutor(context=context)
    executor.add_node(node)
    executor.shutdown()
    executor.spin_once(timeout_sec=None)        # returns at once: shut down
    node.destroy_node()
