"""The node's outputs on a free base (issue 28 items 2-3), from a ROS graph: the node recording
config/two_wing_deployment.yaml in its own process publishes and records base_odometry every
period, node_poses with both chains and the base, chain-prefixed joint names with the base's
joints, and the momentum ledger on /diagnostics; `rod-sim compare` re-runs the node's log (its
/applied_base re-applied) and passes. ROS domain id from ros_domains."""
from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("rclpy")

from ros_domains import next_domain  # noqa: E402
from procs import ros_env  # noqa: E402
from ros_graph import Client, NodeProcess, unique_namespace  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
TWO_WING = REPO / "config" / "two_wing_deployment.yaml"
DOMAIN = next_domain()


def decoded(path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    out: dict[str, list] = {}
    with open(path, "rb") as f:
        for _, channel, message, msg in make_reader(
                f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            out.setdefault(channel.topic.rsplit("/", 1)[-1], []).append((message.log_time, msg))
    return out


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.timeout(900)
def test_node_publishes_and_records_the_base_and_the_ledger(tmp_path, monkeypatch):
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setenv("ROS_DOMAIN_ID", str(DOMAIN))
    ns = unique_namespace()
    log = tmp_path / "node.mcap"
    node = NodeProcess(tmp_path, DOMAIN, extra=["-r", f"__ns:={ns}"], scene_file=TWO_WING,
                       record_path=log, start_paused=True, step_count=300)
    try:
        node.wait_for_output("recording to", timeout=300)
        step = subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", "ctl", "--ns", ns,
                               "--timeout", "120", "step"], cwd=REPO, env=ros_env(DOMAIN),
                              capture_output=True, text=True, timeout=300)
        assert step.returncode == 0, step.stdout + step.stderr
        # a /diagnostics message after the steps (1 Hz of wall time: whenever it comes)
        from diagnostic_msgs.msg import DiagnosticArray

        client = Client(DOMAIN, name="diag_watch")
        seen = []
        client.node.create_subscription(DiagnosticArray, "/diagnostics", seen.append, 10)
        try:
            client.spin_until(lambda: any(
                kv.key == "sim_time_s" and float(kv.value) == 3.0
                for m in seen for st in m.status for kv in st.values), 120,
                "diagnostics at t = 3 s", node)
        finally:
            client.close()
        assert node.stop(signal.SIGINT) == 0, node.stderr
    finally:
        node.kill()
    msgs = decoded(log)
    states, odo = msgs["rod_states"], msgs["base_odometry"]
    assert len(states) == 301 and [t for t, _ in odo] == [t for t, _ in states]   # 0..3 s
    assert odo[-1][1].child_frame_id == "base"
    n, chains = 10, 2
    assert all(len(m.poses) == n + chains + 1 for _, m in msgs["node_poses"])
    names = list(msgs["joint_states"][-1][1].name)
    assert names[0] == "left/hinge_0" and names[5] == "right/hinge_0"
    assert names[-3:] == ["base_x", "base_y", "base_psi"]
    diag = [{kv.key: kv.value for kv in m.status[0].values} for _, m in msgs["diagnostics"]]
    last = diag[-1]
    for key in ("linear_momentum_x_kg_m_s", "angular_momentum_com_kg_m2_s",
                "centre_of_mass_y_m", "energy_wheel_kinetic_J", "work_injected_J",
                "momentum_balance_residual_x_kg_m_s",
                "angular_momentum_balance_residual_kg_m2_s"):
        assert key in last, sorted(last)
    # no load: the ledger's residual is the momentum itself, both round-off
    assert abs(float(last["angular_momentum_balance_residual_kg_m2_s"])) < 1e-6
    assert float(last["base_psi_rad"]) != 0.0               # the bus turns
    # the reduced model departs from the full one by ~0.02 rad in 3 s of this deployment
    compared = subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", "compare", str(log),
                               "--json", "--tolerance", "0.1"], cwd=REPO, env=ros_env(DOMAIN), capture_output=True,
                              text=True, timeout=600)
    assert compared.returncode == 0, compared.stdout + compared.stderr
    report = json.loads(compared.stdout)
    assert report["spacecraft"]["base"]["samples"] == len(odo)
    assert report["forces"]["segments"] >= 1
