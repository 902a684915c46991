"""Issue 27 item 9: a flood of 4000 concurrent service calls to the node (a separate process)
gets one answer each -- done, or refused "busy" -- within a bounded time; none is lost in the
node's middleware queues (depth 10 000 per service, rod_sim.ros.qos.SERVICE_QOS). The caller
keeps as many calls as it has outstanding too: with rclpy's default client QoS (depth 10) a
flood loses requests and responses in the caller's own queues (measured: 2448 of 4000 answered
in 150 s with a default-QoS client; all 4000 in ~25 s with a deep one). ROS_DOMAIN_ID 218."""
from __future__ import annotations

import time

import pytest

pytest.importorskip("rclpy")

from std_srvs.srv import SetBool, Trigger  # noqa: E402

from procs import REPO  # noqa: E402
from rod_sim.ros.qos import keep_last  # noqa: E402
from ros_graph import Client, NodeProcess, unique_namespace  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.slow, pytest.mark.timeout(300)]
DOMAIN = 218
CALLS = 4000
BOUND_S = 150.0
"""[s] for every answer (measured: 4000 in 36 s with the node and the caller in one process
on a loaded 2-core machine, load ~6)."""


def test_4000_concurrent_calls_each_get_an_answer(tmp_path, monkeypatch):
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setenv("ROS_DOMAIN_ID", str(DOMAIN))
    ns = unique_namespace()
    node = NodeProcess(tmp_path, DOMAIN, extra=["-r", f"__ns:={ns}"],
                       scene_file=str(REPO / "config" / "small_chain.yaml"), start_paused=True)
    client = Client(DOMAIN)
    try:
        services = {name: client.node.create_client(kind, f"{ns}/rod_sim/{name}",
                                                    qos_profile=keep_last(CALLS))
                    for name, kind in (("pause", SetBool), ("step", Trigger),
                                       ("reset", Trigger))}
        for name, c in services.items():
            client.spin_until(c.service_is_ready, 60.0, f"service {name}", node)
        started = time.monotonic()
        futures = []
        for k in range(CALLS):
            if k % 4 == 0:
                futures.append(services["pause"].call_async(SetBool.Request(data=True)))
            elif k % 4 == 3:
                futures.append(services["reset"].call_async(Trigger.Request()))
            else:
                futures.append(services["step"].call_async(Trigger.Request()))
        client.spin_until(lambda: all(f.done() for f in futures), BOUND_S,
                          lambda: f"answers ({sum(f.done() for f in futures)} of {CALLS})",
                          node)
        elapsed = time.monotonic() - started
    finally:
        client.close()
        node.stop()
    answers = [f.result() for f in futures]
    refused = [a.message for a in answers if not a.success]
    assert all(m.startswith("busy") for m in refused), refused[:3]
    assert elapsed < BOUND_S
