"""Message conversions and the demo controller's force law (rclpy messages, no ROS graph)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, MultiArrayLayout

from rod_sim.core.kinematics import node_positions
from rod_sim.core.scene import Scene
from rod_sim.core.snapshot import Snapshot
from rod_sim.io import topics
from rod_sim.ros.controller import hinge_forces, hinge_moments, pd_forces
from rod_sim.ros.conversions import (CommandError, command_forces, message_class,
                                     message_to_dict, to_message)


def make_scene(n: int = 4) -> Scene:
    return Scene.from_dict({"name": "t", "rods": {"count": n, "length": 1.5,
                                                   "mass_per_length": 2.0,
                                                   "bending_stiffness": 1e4},
                            "nodes": {"mass": 1.0},
                            "hinges": {"stiffness": 10.0, "damping": 0.1}})


def make_snapshot(scene: Scene, seed: int = 3) -> Snapshot:
    rng = np.random.default_rng(seed)
    n = scene.n
    phi = rng.uniform(-1, 1, n)
    return Snapshot(t=1.25, phi=phi, phi_rate=rng.normal(size=n), alpha=0.01 * rng.normal(size=n),
                    beta=0.01 * rng.normal(size=n), hinge_angle=np.diff(phi, prepend=0.0),
                    hinge_rate=rng.normal(size=n), hinge_moment=rng.normal(size=n),
                    nodes=node_positions(np.asarray(scene.length), phi),
                    forces=rng.normal(size=(n, 2)))


def assert_same(data, msg_dict, path="msg"):
    """Every value of ``data`` is in ``msg_dict`` (floats exactly)."""
    if isinstance(data, dict):
        for key, value in data.items():
            assert_same(value, msg_dict[key], f"{path}.{key}")
    elif isinstance(data, list):
        assert len(data) == len(msg_dict), path
        for i, (a, b) in enumerate(zip(data, msg_dict)):
            assert_same(a, b, f"{path}[{i}]")
    else:
        assert data == msg_dict, path


@pytest.mark.parametrize("topic", topics.DEFAULT_TOPICS + ("clock",))
def test_topic_dicts_become_equal_rclpy_messages(topic):
    scene = make_scene()
    data = topics.snapshot_messages(make_snapshot(scene), scene, "world", [topic])[topic]
    msg = to_message(topics.TOPIC_TYPES[topic], data)
    assert type(msg).__name__ == topics.TOPIC_TYPES[topic].rsplit("/", 1)[1]
    assert_same(data, message_to_dict(msg))


def test_joint_state_values_and_stamp():
    scene = make_scene()
    snap = make_snapshot(scene)
    msg = to_message("sensor_msgs/msg/JointState", topics.rod_states(snap, "world"))
    assert isinstance(msg, JointState)
    assert list(msg.name) == ["rod_1", "rod_2", "rod_3", "rod_4"]
    assert list(msg.position) == list(snap.phi)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1, 250_000_000)
    assert msg.header.frame_id == "world"


def test_diagnostics_level_becomes_a_byte():
    data = topics.diagnostics(2.0, {"a": 1.5}, "scene", level=topics.DIAGNOSTIC_ERROR,
                              message="broken")
    msg = to_message("diagnostic_msgs/msg/DiagnosticArray", data)
    assert isinstance(msg, DiagnosticArray)
    assert msg.status[0].level == b"\x02" and msg.status[0].values[0].value == "1.5"


def test_unknown_field_and_type_are_rejected():
    with pytest.raises(ValueError, match="no field 'positions'"):
        to_message("sensor_msgs/msg/JointState", {"positions": [1.0]})
    with pytest.raises(ValueError, match="not installed"):
        message_class("nope_msgs/msg/Nothing")
    with pytest.raises(ValueError, match="not a ROS message type"):
        message_class("JointState")
    assert message_class("std_msgs/Float64MultiArray") is Float64MultiArray


def command(values, offset: int = 0) -> Float64MultiArray:
    msg = Float64MultiArray()
    msg.layout = MultiArrayLayout(data_offset=offset)
    msg.data = [float(v) for v in values]
    return msg


def test_command_forces_valid_layout():
    f = command_forces(command([1, 2, 3, 4, 5, 6]), 3)
    assert f.shape == (3, 2) and f[0].tolist() == [1.0, 2.0] and f[2].tolist() == [5.0, 6.0]
    f = command_forces(command([99, 1, 2, 3, 4], offset=1), 2)
    assert f.tolist() == [[1.0, 2.0], [3.0, 4.0]]


@pytest.mark.parametrize("values, match", [
    ([1, 2, 3], "expected 4 values .* got 3"),
    ([], "got 0"),
    ([1, 2, 3, 4, 5], "got 5"),
    ([1, math.nan, 3, 4], r"non-finite value nan at data\[1\]"),
    ([1, 2, math.inf, 4], r"non-finite value inf at data\[2\]"),
])
def test_command_forces_rejects_bad_commands(values, match):
    with pytest.raises(CommandError, match=match):
        command_forces(command(values), 2)


def generalized_forces(forces, phi, lengths):
    """Q_k = sum_j F_j . d p_j / d phi_k for the chain's node positions p_j (j = 1..n)."""
    n = len(phi)
    q = np.zeros(n)
    for k in range(n):
        dp = lengths[k] * np.array([-math.sin(phi[k]), math.cos(phi[k])])
        q[k] = sum(forces[j] @ dp for j in range(k, n))
    return q


def test_hinge_forces_do_the_work_of_hinge_moments():
    rng = np.random.default_rng(11)
    n = 6
    phi = rng.uniform(-2, 2, n)
    lengths = rng.uniform(0.5, 2.0, n)
    moments = rng.normal(scale=50.0, size=n)
    forces = hinge_forces(moments, phi, lengths)
    q_phi = generalized_forces(forces, phi, lengths)
    # on the rod angles: M_{k-1} - M_k; on the hinge angles (phi_k = sum_{h<k} q_h): M_h
    np.testing.assert_allclose(q_phi, moments - np.append(moments[1:], 0.0), atol=1e-9)
    np.testing.assert_allclose(np.cumsum(q_phi[::-1])[::-1], moments, atol=1e-9)


def test_pd_law_signs_and_limit():
    m = hinge_moments([0.1, -0.2], [0.0, 1.0], [0.0, 0.0], kp=10.0, kd=2.0)
    np.testing.assert_allclose(m, [-1.0, 2.0 - 2.0])
    lengths = np.array([1.0, 1.0])
    f = pd_forces([0.0, 0.0], [0.0, 0.0], [1.0, 1.0], lengths, kp=1e3, kd=0.0, max_moment=10.0)
    # both hinges ask for +10 N m: rod 1 gets no net couple, rod 2 gets +10 N m at its tip
    np.testing.assert_allclose(f, [[0.0, -10.0], [0.0, 10.0]], atol=1e-12)


def test_a_long_chain_is_drawn_as_one_strip_through_its_nodes():
    """Above MARKER_MAX_STRIPS rods one LINE_STRIP through nodes 0..n replaces the per-rod
    strips (building 1024 per-rod markers took longer than a 10 ms period)."""
    import numpy as np

    from rod_sim.core.models import make_model
    from rod_sim.io import topics
    from rod_sim.bench.long_chains import uniform_chain

    for n, strips in ((topics.MARKER_MAX_STRIPS, topics.MARKER_MAX_STRIPS), (300, 1)):
        scene = uniform_chain(n)
        model = make_model("rigid", scene)
        y = model.initial_state()
        y[:n] = np.linspace(0.0, 1.0, n)
        snap = model.snapshot(0.0, y)
        items = topics.markers(snap, scene)["markers"]
        rods = [m for m in items if m["ns"] == "rods"]
        assert len(rods) == strips
        if strips == 1:
            pts = np.array([[p["x"], p["y"]] for p in rods[0]["points"]])
            np.testing.assert_allclose(pts, snap.nodes, atol=1e-12)
