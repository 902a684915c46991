"""Every service call to the node is answered (issue 19 item 4): a flood of ~/pause, ~/step
and ~/reset calls sent without waiting gets one answer each (done or refused "busy"), and a
~/step of many periods runs in bounded slices: the node answers ~/pause and publishes
diagnostics meanwhile, a second ~/step is refused "busy", the first answers when done.
ROS domain ids from ros_domains (LOCALHOST)."""
from __future__ import annotations

import time

import pytest

pytest.importorskip("rclpy")

import test_node_ros as base  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from std_srvs.srv import SetBool, Trigger  # noqa: E402

import rod_sim.ros.node as node_module  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]


harness = base.harness_fixture()


def ready_client(h, srv_type, name):
    client = h.client.create_client(srv_type, name)
    h.spin_until(client.service_is_ready, what=f"service {name}")
    return client


def test_a_flood_of_service_calls_is_answered_every_one(harness):
    """400 calls sent without waiting (the audit: 31 of 400 answered)."""
    h = harness(scene_file=str(base.SMALL), start_paused=True)
    pause = ready_client(h, SetBool, "/rod_sim/pause")
    step = ready_client(h, Trigger, "/rod_sim/step")
    reset = ready_client(h, Trigger, "/rod_sim/reset")
    futures = []
    for k in range(400):
        if k % 4 == 0:
            futures.append(pause.call_async(SetBool.Request(data=True)))
        elif k % 4 == 3:
            futures.append(reset.call_async(Trigger.Request()))
        else:
            futures.append(step.call_async(Trigger.Request()))
    h.spin_until(lambda: all(f.done() for f in futures), timeout=60.0,
                 what=f"answers ({sum(f.done() for f in futures)} of 400 so far)")
    answers = [f.result() for f in futures]
    assert all(a.success or a.message.startswith("busy") for a in answers), \
        [a.message for a in answers if not a.success][:3]
    assert 400 <= getattr(node_module, "SERVICE_QUEUE_DEPTH", 0)      # the stated limit


@pytest.mark.slow
def test_a_long_step_runs_in_slices_and_the_node_keeps_answering(harness):
    h = harness(scene_file=str(base.SMALL), start_paused=True, rate_hz=10000.0,
                step_count=10000)
    h.subscribe("/diagnostics", DiagnosticArray)
    pause = ready_client(h, SetBool, "/rod_sim/pause")
    step = ready_client(h, Trigger, "/rod_sim/step")
    started = time.monotonic()
    stepping = step.call_async(Trigger.Request())
    h.spin_until(lambda: h.node.sim.t_ns > 0, what="the step call to start")
    busy = step.call_async(Trigger.Request())
    paused = pause.call_async(SetBool.Request(data=True))
    h.spin_until(lambda: busy.done() and paused.done(), timeout=5.0,
                 what="answers during the step")
    assert not stepping.done(), ("~/pause and a second ~/step were answered only after the "
                                 "step call: the node was blocked while it stepped")
    assert paused.result().success
    assert not busy.result().success and busy.result().message.startswith("busy")
    seen = len(h.received["/diagnostics"])
    h.spin_until(stepping.done, timeout=60.0, what="the step call's answer")
    took = time.monotonic() - started
    done = stepping.result()
    assert done.success, done.message
    assert h.node.sim.t_ns == 10000 * 100_000                  # 10000 periods of 0.1 ms
    if took > 2.5:                          # diagnostics at 1 Hz went on during the step
        assert len(h.received["/diagnostics"]) > seen
