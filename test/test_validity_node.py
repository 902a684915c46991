"""The node reports validity warnings (WARN) and integration failures naming the cause (ERROR)
on diagnostics, and its log stays readable. ROS domain ids from ros_domains (LOCALHOST)."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("rclpy")

import test_node_ros as base  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402

from rod_sim.io.log_reader import LogReader  # noqa: E402
from rod_sim.io.series import read_rod_states  # noqa: E402
from rod_sim.io.scene_yaml import scene_to_yaml  # noqa: E402
from rod_sim.tools.hard_cases import chain  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(60)]


@pytest.fixture
def harness(monkeypatch):
    made = []

    def make(**kwargs):
        h = base.Harness(monkeypatch, **kwargs)
        made.append(h)
        return h

    yield made, make
    for h in made:
        h.close()


def statuses(h, level: bytes):
    return [m.status[0] for m in h.received["diagnostics"] if m.status[0].level == level]


def test_soft_chain_warns_about_the_quasi_static_reduction(harness, tmp_path):
    _, make = harness
    scene = tmp_path / "soft.yaml"
    scene.write_text(scene_to_yaml(chain(EI=1e3, name="soft")))
    h = make(scene_file=str(scene), model="reduced", real_time_factor=0.0)
    h.subscribe("diagnostics", DiagnosticArray)
    h.wait_matched("diagnostics")
    h.spin_until(lambda: h.node.sim_time > 1.6, what="1.6 s of simulated time")
    h.spin_until(lambda: any("bending mode" in s.message for s in statuses(h, b"\x01")),
                 what="a WARN naming the bending mode")
    values = {kv.key: kv.value for kv in statuses(h, b"\x01")[-1].values}
    assert "bending mode" in values["validity"]


def test_diverging_integrator_pauses_with_named_cause_and_closes_the_log(harness, tmp_path):
    made, make = harness
    log = tmp_path / "diverge.mcap"
    h = make(scene_file=str(base.PAPER), model="full", integrator="euler",
             real_time_factor=0.0, record_path=str(log))
    h.subscribe("diagnostics", DiagnosticArray)
    h.wait_matched("diagnostics")
    h.commands.publish(base.force_command([1e9] * 16))
    h.spin_until(lambda: h.node.control.error is not None, what="the integration failure")
    assert " of rod " in h.node.control.error and "t = " in h.node.control.error
    assert h.node.control.paused and np.all(np.isfinite(h.node.sim.y))
    h.spin_until(lambda: statuses(h, b"\x02"), what="an ERROR diagnostic")
    assert " of rod " in statuses(h, b"\x02")[0].message
    h.close()
    made.clear()
    t, phi, _ = read_rod_states(log)
    assert t.size > 0 and np.all(np.isfinite(phi))
    assert LogReader(log).metadata()["model"] == "full"
