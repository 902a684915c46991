"""The numpy encoders of the state topics (rod_sim.io.encoders) give exactly the bytes of the
message dicts (rod_sim.io.topics) encoded by mcap_ros2, and rclpy decodes them to the same
message objects; no ROS graph."""
from __future__ import annotations

import math

import numpy as np
import pytest
from mcap_ros2._dynamic import serialize_dynamic
from rclpy.serialization import deserialize_message, serialize_message

from rod_sim.core.kinematics import node_positions
from rod_sim.core.scene import Scene
from rod_sim.core.snapshot import Snapshot
from rod_sim.io import encoders, topics
from rod_sim.io.msgdefs import SCHEMAS
from rod_sim.ros.conversions import message_class, to_message

TOPICS = topics.SNAPSHOT_TOPICS


def make_scene(n: int, length=2.0, mass=3.0) -> Scene:
    return Scene.from_dict({
        "name": f"chain_{n}",
        "rods": {"count": n, "length": length, "mass_per_length": 3.0,
                 "bending_stiffness": 1e5},
        "nodes": {"mass": mass},
        "hinges": {"stiffness": 100.0, "damping": 0.01}})


def make_snapshot(scene: Scene, seed: int, t: float = 1.25) -> Snapshot:
    rng = np.random.default_rng(seed)
    n = scene.n
    phi = rng.uniform(-math.pi, math.pi, n)
    return Snapshot(t=t, phi=phi, phi_rate=rng.normal(size=n), alpha=0.01 * rng.normal(size=n),
                    beta=0.01 * rng.normal(size=n), hinge_angle=np.diff(phi, prepend=0.0),
                    hinge_rate=rng.normal(size=n), hinge_moment=100.0 * rng.normal(size=n),
                    nodes=node_positions(np.asarray(scene.length), phi),
                    forces=rng.normal(scale=100.0, size=(n, 2)))


def mcap_ros2_bytes(type_name: str, data: dict) -> bytes:
    """The exact CDR of mcap_ros2's dynamic serializer (independent of rod_sim.io.cdr)."""
    encode = serialize_dynamic(type_name, SCHEMAS[type_name])[type_name]
    return bytes(encode(data))


# frame ids of every length mod 8 move every later field's alignment
FRAMES = ("world", "w", "ab", "abc", "abcd", "base_link", "a/b/c/d/e/f", "")


@pytest.mark.parametrize("topic", TOPICS)
@pytest.mark.parametrize("n", [1, 2, 3, 7, topics.MARKER_MAX_STRIPS,
                               topics.MARKER_MAX_STRIPS + 1, 1024])
def test_encoded_bytes_equal_the_dict_path_and_mcap_ros2(topic, n):
    scene = make_scene(n)
    frames = FRAMES if n <= 7 else FRAMES[:2]
    for k, frame in enumerate(frames):
        snap = make_snapshot(scene, seed=n * 31 + k, t=0.001 * k + (n % 5) * 3.7)
        data = topics.snapshot_messages(snap, scene, frame, [topic])[topic]
        ours = encoders.SNAPSHOT_ENCODERS[topic](snap, scene, frame)
        assert ours == mcap_ros2_bytes(topics.TOPIC_TYPES[topic], data), (topic, n, frame)


@pytest.mark.parametrize("topic", TOPICS)
def test_rclpy_decodes_the_same_message(topic):
    """rclpy's own (Fast CDR) deserializer reads our bytes as the message object of the same
    content; its serializer agrees with them except in alignment padding, which Fast DDS
    leaves uninitialised (and it appends junk beyond the exact length)."""
    scene = make_scene(5)
    snap = make_snapshot(scene, seed=9)
    data = topics.snapshot_messages(snap, scene, "world", [topic])[topic]
    ours = encoders.SNAPSHOT_ENCODERS[topic](snap, scene, "world")
    msg = to_message(topics.TOPIC_TYPES[topic], data)
    assert deserialize_message(ours, message_class(topics.TOPIC_TYPES[topic])) == msg
    theirs = serialize_message(msg)
    assert len(theirs) >= len(ours)
    differ = [i for i in range(len(ours)) if theirs[i] != ours[i]]
    assert all(ours[i] == 0 for i in differ), "a non-padding byte differs"


def test_special_values_and_stamps():
    """NaN, inf, -0.0 go through unchanged; stamps round like topics.stamp; a time beyond
    int32 seconds is refused."""
    scene = make_scene(3)
    snap = make_snapshot(scene, seed=1, t=2.0000000004999)
    phi = snap.phi.copy()
    phi[:] = [np.nan, -0.0, np.inf]
    odd = Snapshot(**{**snap.__dict__, "phi": phi})
    for topic in ("rod_states", "clock"):
        data = topics.snapshot_messages(odd, scene, "world", [topic])[topic]
        assert encoders.SNAPSHOT_ENCODERS[topic](odd, scene, "world") == \
            mcap_ros2_bytes(topics.TOPIC_TYPES[topic], data)
    late = Snapshot(**{**snap.__dict__, "t": 2.0 ** 31})
    with pytest.raises(ValueError, match="int32 seconds"):
        encoders.rod_states(late, scene, "world")


def test_applied_inputs_and_strings():
    rng = np.random.default_rng(4)
    for n in (0, 1, 5):
        f, t = rng.normal(size=(n, 2)), rng.normal(size=n)
        assert encoders.force_array(f) == mcap_ros2_bytes(
            "std_msgs/msg/Float64MultiArray", topics.force_array(f))
        assert encoders.torque_array(t) == mcap_ros2_bytes(
            "std_msgs/msg/Float64MultiArray", topics.torque_array(t))
    assert encoders.clock_ns(3_000_000_007) == mcap_ros2_bytes(
        "rosgraph_msgs/msg/Clock", {"clock": {"sec": 3, "nanosec": 7}})
    text = "name: é\n"
    assert encoders.string(text) == mcap_ros2_bytes("std_msgs/msg/String", {"data": text})


def test_snapshot_bytes_selection_and_errors():
    scene = make_scene(4)
    snap = make_snapshot(scene, seed=2)
    assert set(encoders.snapshot_bytes(snap, scene)) == set(topics.DEFAULT_TOPICS)
    with pytest.raises(ValueError, match="cannot build"):
        encoders.snapshot_bytes(snap, scene, names=["diagnostics"])
    with pytest.raises(ValueError, match="rods"):
        encoders.snapshot_bytes(snap, make_scene(5))


def test_diagnostics_bytes_are_the_dict_encoders():
    """encoders.diagnostics: the bytes of the generic encoder (and the reference one) of
    topics.diagnostics, for keys and values of every length mod 4, empty and non-ASCII
    strings, every level."""
    from rod_sim.io import cdr

    rng = np.random.default_rng(11)
    fast = cdr.encoder("diagnostic_msgs/msg/DiagnosticArray")
    ref = cdr.reference_encoder("diagnostic_msgs/msg/DiagnosticArray")
    for case in range(40):
        values = {"k" * int(rng.integers(0, 9)) + str(i): (
            "" if rng.random() < 0.1 else f"{rng.normal():.17g}" + "é" * int(rng.integers(0, 3)))
            for i in range(int(rng.integers(0, 30)))}
        kw = dict(level=case % 4, message="m" * (case % 5), frame_id="w" * (case % 3),
                  name="rod_sim: simulation" if case % 2 else "n" * (case % 7))
        t = float(rng.uniform(0, 100.0))
        msg = topics.diagnostics(t, values, "scène" * (case % 2), **kw)
        got = encoders.diagnostics(t, values, "scène" * (case % 2), **kw)
        assert got == fast(msg) == ref(msg)
    with pytest.raises(ValueError):
        encoders.diagnostics(0.0, {}, "x", level=4)


def test_joint_state_layout_memo_is_for_its_own_names_only():
    """The per-sample layout lookup keyed by the names' id (no hashing of n names) takes an
    entry only for the very tuple it was made for: a tuple at a reused id gets its own
    layout (fails if the identity check goes)."""
    scene = make_scene(4)
    snap = make_snapshot(scene, 3)
    names_a = tuple(f"a_{k}" for k in range(4))
    names_b = tuple(f"b_{k}" for k in range(4))
    arrays = (snap.hinge_angle, snap.hinge_rate, snap.hinge_moment)
    first = encoders._joint_state(snap, "world", names_a, *arrays)
    assert b"a_0" in first
    key = ("world", id(names_a), (4, 4, 4))
    encoders._LAYOUT_BY_NAMES[("world", id(names_b), (4, 4, 4))] = \
        encoders._LAYOUT_BY_NAMES[key]                  # as if names_b had names_a's id
    second = encoders._joint_state(snap, "world", names_b, *arrays)
    assert b"b_0" in second and b"a_0" not in second
    assert second == encoders._joint_state_layout("world", names_b, (4, 4, 4)).fill(
        stamp=encoders._stamp(snap), position=arrays[0], velocity=arrays[1], effort=arrays[2])


def test_layout_fill_refuses_a_slot_of_the_wrong_size():
    """A slot filled with too few or too many bytes is an error (the per-message bytearray
    would silently change length: every later field shifted)."""
    from rod_sim.io.cdr_layout import LayoutWriter

    w = LayoutWriter()
    w.header("world")
    w.f64_seq("data", 3)
    layout = w.layout()
    stamp = np.array([1, 2], dtype="<u4")
    good = layout.fill(stamp=stamp, data=np.arange(3.0))
    assert good[-24:] == np.arange(3.0).tobytes() and len(good) == len(layout.template)
    for wrong in (np.arange(2.0), np.arange(4.0)):
        with pytest.raises(ValueError):
            layout.fill(stamp=stamp, data=wrong)


def test_layout_filler_gives_the_dict_path_bytes_in_any_argument_order():
    """``Layout.filler`` (values by position, the message joined from the template's constant
    runs and the slots' bytes): the bytes of the project's dict encoder for the same
    JointState whatever order the slots are named in, from any array (strided, a list, read
    only); a slot of the wrong size is an error, as with ``fill``."""
    from rod_sim.io import cdr
    from rod_sim.io.cdr_layout import LayoutWriter

    names = ("j_0", "j_1", "j_2")
    w = LayoutWriter()
    w.header("world")
    w.string_seq(names)
    for field in ("position", "velocity", "effort"):
        w.f64_seq(field, 3)
    layout = w.layout()
    pos, vel = np.array([0.5, -0.0, 1e-300]), np.arange(6.0)[::2]       # vel: strided
    eff = [math.inf, -2.5, 3.0]
    stamp = np.array([7, 123456789], dtype="<u4")
    ro = pos.copy()
    ro.flags.writeable = False
    want = cdr.encoder("sensor_msgs/msg/JointState")({
        "header": {"stamp": {"sec": 7, "nanosec": 123456789}, "frame_id": "world"},
        "name": list(names), "position": pos.tolist(), "velocity": vel.tolist(),
        "effort": eff})
    values = {"stamp": stamp, "position": ro, "velocity": vel, "effort": eff}
    for order in (("stamp", "position", "velocity", "effort"),
                  ("effort", "stamp", "velocity", "position")):
        fill = layout.filler(order)
        assert fill(*(values[k] for k in order)) == want
        assert layout.filler(order) is fill                     # made once per order
    fill = layout.filler(("stamp", "position", "velocity", "effort"))
    for wrong in (np.arange(2.0), np.arange(4.0)):
        with pytest.raises(ValueError):
            fill(stamp, wrong, vel, eff)
    with pytest.raises(ValueError):
        layout.filler(("stamp", "position"))                    # every slot, once
