"""One encoding, every sink: for every output topic of the node (a separate process, lockstep,
recording), the bytes a subscriber receives over DDS are the bytes in the log, and they are
the exact CDR of the message (mcap_ros2's encoder of the decoded message, and rclpy's own
serializer up to the alignment padding Fast DDS leaves uninitialised). ROS_DOMAIN_ID 216."""
from __future__ import annotations

import time
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from mcap.reader import make_reader  # noqa: E402
from mcap_ros2._dynamic import serialize_dynamic  # noqa: E402
from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402
from std_msgs.msg import Float64MultiArray  # noqa: E402

from procs import REPO  # noqa: E402
from ros_graph import Client, NodeProcess, unique_namespace  # noqa: E402
from rod_sim.io.msgdefs import SCHEMAS  # noqa: E402
from rod_sim.ros.conversions import message_class  # noqa: E402
from rod_sim.ros.qos import keep_last  # noqa: E402
from rclpy.qos import DurabilityPolicy  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]

DOMAIN = 216
PERIODS = 60
TOPICS = {"joint_states": "sensor_msgs/msg/JointState",
          "rod_states": "sensor_msgs/msg/JointState",
          "bending": "sensor_msgs/msg/JointState",
          "node_poses": "geometry_msgs/msg/PoseArray",
          "markers": "visualization_msgs/msg/MarkerArray",
          "applied_forces": "std_msgs/msg/Float64MultiArray",
          "applied_torques": "std_msgs/msg/Float64MultiArray",
          "robot_description": "std_msgs/msg/String",
          "scene": "std_msgs/msg/String",
          "hinge_events": "std_msgs/msg/String"}
"""Output topics (relative) and their types, written out here (not imported from the node)."""


def as_dict(msg):
    """An rclpy message as the nested dicts and lists mcap_ros2 encodes (written here, not
    the project's conversions)."""
    if hasattr(msg, "get_fields_and_field_types"):
        return {name: (getattr(msg, name)[0] if kind == "octet" else as_dict(getattr(msg, name)))
                for name, kind in msg.get_fields_and_field_types().items()}
    if isinstance(msg, (bytes, bytearray)):
        return list(msg)
    if hasattr(msg, "tolist"):
        return msg.tolist()
    if isinstance(msg, (list, tuple)) or type(msg).__name__ == "array":
        return [as_dict(m) for m in msg]
    return msg


def exact_cdr(type_name: str, data: bytes) -> tuple[bytes, object]:
    """mcap_ros2's encoding of the message rclpy decodes from ``data`` (and that message)."""
    msg = deserialize_message(data, message_class(type_name))
    return bytes(serialize_dynamic(type_name, SCHEMAS[type_name])[type_name](as_dict(msg))), msg


def padded_to(data: bytes, candidates: list[bytes]) -> bytes:
    """``data`` without the 0..3 zero bytes the transport appended to reach a multiple of 4,
    if that gives one of ``candidates`` (else ``data`` as received)."""
    known = set(candidates)
    for extra in range(4):
        head, tail = data[:len(data) - extra], data[len(data) - extra:]
        if tail == bytes(extra) and len(data) % 4 == 0 and head in known:
            return head
    return data


def logged(path: Path) -> dict[str, list[bytes]]:
    out = defaultdict(list)
    with open(path, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
            out[channel.topic].append(message.data)
    return out


def test_published_bytes_are_the_logged_bytes_and_exact_cdr(tmp_path, monkeypatch):
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setenv("ROS_DOMAIN_ID", str(DOMAIN))
    ns = unique_namespace()
    log = tmp_path / "run.mcap"
    node = NodeProcess(tmp_path, DOMAIN, extra=["-r", f"__ns:={ns}"],
                       scene_file=str(REPO / "config" / "deployment.yaml"), sync_mode=True,
                       record_path=str(log), markers_rate_hz=20.0, rate_hz=100.0)
    client = Client(DOMAIN, namespace=ns)
    received = defaultdict(list)
    try:
        qos = keep_last(1000, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        for topic, type_name in TOPICS.items():
            client.node.create_subscription(
                message_class(type_name), topic,
                lambda data, topic=topic: received[topic].append(data), qos, raw=True)
        client.node.create_subscription(
            message_class("diagnostic_msgs/msg/DiagnosticArray"), "/diagnostics",
            lambda data: received["diagnostics"].append(data), keep_last(100), raw=True)
        pub = client.node.create_publisher(Float64MultiArray, "nodal_forces", keep_last(100))
        torques = client.node.create_publisher(Float64MultiArray, "hinge_torques",
                                               keep_last(100))
        client.spin_until(lambda: received["rod_states"] and pub.get_subscription_count()
                          and torques.get_subscription_count(), 60.0,
                          "the t = 0 state and the command subscriptions", node)
        n = 5
        for k in range(PERIODS):
            msg = Float64MultiArray()
            msg.data = [0.01 * np.sin(k + j) for j in range(2 * n)]
            (torques if k % 7 == 3 else pub).publish(
                msg if k % 7 != 3 else Float64MultiArray(data=[0.001 * k] * n))
            count = len({bytes(b) for b in received["rod_states"]})
            client.spin_until(lambda: len({bytes(b) for b in received["rod_states"]}) > count,
                              30.0, f"the state of period {k + 1}", node)
        client.spin_until(lambda: received["diagnostics"], 5.0, "diagnostics", node)
        client.spin_for(0.3)
    finally:
        client.close()
        assert node.stop() == 0, node.stderr
    log_bytes = logged(log)
    assert not [t for t in TOPICS if t != "hinge_events" and not received[t]]
    for topic, type_name in {**TOPICS, "diagnostics": "diagnostic_msgs/msg/DiagnosticArray"
                             }.items():
        name = "/diagnostics" if topic == "diagnostics" else f"{ns}/{topic}"
        got = [bytes(b) for b in received[topic]]
        in_log = log_bytes[name]
        # every message received is in the log, the same bytes (the lockstep node publishes
        # its waiting state again, unrecorded: equal bytes; applied_* only on change). The
        # DDS transport pads a payload to a multiple of 4 bytes with zeros: strip that.
        unpadded = [padded_to(data, in_log) for data in got]
        assert set(unpadded) <= set(in_log), topic
        got = unpadded
        if topic in ("joint_states", "rod_states", "bending", "node_poses", "markers"):
            assert list(dict.fromkeys(got)) == in_log, topic
        for data in set(in_log):
            exact, msg = exact_cdr(type_name, data)
            assert data == exact, topic
            theirs = serialize_message(msg)
            assert len(theirs) >= len(data) and all(
                data[i] == 0 for i in range(len(data)) if theirs[i] != data[i]), topic
    assert len(log_bytes[f"{ns}/rod_states"]) == PERIODS + 1
