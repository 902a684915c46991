"""``rod-sim replay`` of a spacecraft log: the topics a moving base adds (``/base_odometry``,
nav_msgs/Odometry; ``/diagnostics`` with the momentum keys) and the chain-prefixed states come
back on a live graph with the recorded bytes, in order. The log is written by ``rod-sim
simulate`` of the two-wing deployment (reduced, 0.2 s at 50 Hz). ROS domain ids from
ros_domains (LOCALHOST)."""
from __future__ import annotations

import numpy as np
import pytest

from rod_sim.tools import cli
from ros_domains import next_domains  # noqa: E402
from test_replay import (STARTUP_S, listener, recorded, replay,  # noqa: F401 (fixtures)
                         unpadded)

REPO = __import__("pathlib").Path(__file__).resolve().parents[1]
DOMAIN_SC, = next_domains(1)
TOPICS = {"/base_odometry": "nav_msgs/msg/Odometry",
          "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
          "/joint_states": "sensor_msgs/msg/JointState",
          "/node_poses": "geometry_msgs/msg/PoseArray"}
SAMPLES = 11


@pytest.fixture(scope="module")
def spacecraft_log(tmp_path_factory):
    out = tmp_path_factory.mktemp("replay_sc") / "two_wing.mcap"
    assert cli.main(["simulate", str(REPO / "config" / "two_wing_deployment.yaml"),
                     "--t-end", "0.2", "--rate", "50", "--out", str(out)]) == 0
    return out


@pytest.mark.ros
@pytest.mark.timeout(120)
def test_a_spacecraft_log_replays_its_base_and_diagnostics(spacecraft_log, listener, replay):
    from nav_msgs.msg import Odometry
    from rclpy.serialization import deserialize_message

    for topic in TOPICS:
        assert len(recorded(spacecraft_log, topic)) == SAMPLES, topic
    lis = listener(DOMAIN_SC, TOPICS.items())
    proc = replay(DOMAIN_SC, spacecraft_log, "--wait-for-subscribers", "--delay", "0.5",
                  "--topics", *TOPICS)
    lis.spin_until(lambda: all(len(v) >= SAMPLES for v in lis.received.values()), STARTUP_S,
                   "every message", proc.proc)
    assert proc.wait() == 0, proc.stderr
    for topic in TOPICS:
        expected = recorded(spacecraft_log, topic)
        assert unpadded(lis.received[topic], expected) == [d for _, d in expected], topic
    # the base turns while the wings deploy: the replayed odometry carries a moving base
    odo = [deserialize_message(d, Odometry) for _, d in lis.received["/base_odometry"]]
    wz = np.array([m.twist.twist.angular.z for m in odo])
    assert odo[0].header.frame_id and odo[0].child_frame_id
    assert np.max(np.abs(wz)) > 0.0
