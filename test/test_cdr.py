"""rod_sim.io.cdr: byte equality with mcap_ros2's serialize_dynamic for every type rod_sim logs,
on real and randomized messages; round trip through an independent decoder (rosbags); errors."""
from __future__ import annotations

import array
import json
import math
import random
import struct
from pathlib import Path

import numpy as np
import pytest
from mcap_ros2._dynamic import serialize_dynamic
from rosbags.typesys import Stores, get_typestore

from rod_sim.core.integrators import make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.simulator import Simulator
from rod_sim.core.snapshot import Snapshot
from rod_sim.io import cdr, msgdefs, topics
from rod_sim.io.hinge_events import event_message
from rod_sim.io.scene_yaml import load_scene
from rod_sim.ros.monitor import DiagnosticReport

REPO = Path(__file__).resolve().parents[1]
TYPES = list(msgdefs.SCHEMAS)
TYPESTORE = get_typestore(Stores.ROS2_JAZZY)


def mcap_encode(type_name: str, msg) -> bytes:
    return serialize_dynamic(type_name, msgdefs.SCHEMAS[type_name])[type_name](msg)


def fast_only(type_name: str):
    """The compiled encoder with its fallback disabled: any message it does not encode itself
    fails the test (so that equality checks the generated code, not the reference)."""
    enc = cdr.encoder(type_name)
    fresh = dict(enc.__globals__)

    def no_fallback(msg):
        raise AssertionError(f"{type_name}: the fast path gave up on {msg!r:.200}")

    fresh["_reference"] = no_fallback
    return type(enc)(enc.__code__, fresh)


@pytest.fixture(scope="module")
def real_messages() -> list[tuple[str, dict]]:
    """(type, message) as the node and `simulate` log them: every snapshot topic of the seed
    scene at a few states of the full and the reduced model, diagnostics, commands, events."""
    scene = load_scene(REPO / "config" / "paper_example.yaml")
    out = []
    for model_name in ("full", "reduced"):
        sim = Simulator(make_model(model_name, scene), make_integrator("dop853-jit"))
        traj = sim.run(0.2, 50)
        for i in (0, 3, len(traj.t) - 1):
            msgs = topics.snapshot_messages(traj.snapshot(i), scene, "world", topics.SNAPSHOT_TOPICS)
            out += [(topics.TOPIC_TYPES[name], msg) for name, msg in msgs.items()]
    report = DiagnosticReport(
        mode="real time", state="running", sim_time=1.25, rtf_target=1.0, rtf_measured=0.97,
        wall_window=1.0, step_cost_mean=0.2, step_cost_max=0.9, step_budget=1.0, steps=1000,
        dropped_periods=3, energy=1.5e-3, energy_residual=1e-9, commands_received=10,
        commands_rejected=1, last_rejection="wrong length 3 (expected 16)", command_active=True,
        max_abs_alpha=0.01, max_abs_beta=0.02, model="reduced", integrator="dop853-jit",
        extra={"scene": "paper_example", "recording": "/tmp/x.mcap"}, validity=["ok"])
    level, message, values = report.status()
    out.append(("diagnostic_msgs/msg/DiagnosticArray",
                topics.diagnostics(1.25, values, scene.name, level=level, message=message)))
    out.append(("rosgraph_msgs/msg/Clock", topics.clock(12345.678901234)))
    out.append(("std_msgs/msg/Float64MultiArray",  # a nodal_forces command as the node logs it
                {"layout": {"dim": [], "data_offset": 0}, "data": [0.5, -1.0] * scene.n}))
    out.append(("std_msgs/msg/Float64MultiArray", topics.force_array(np.ones((scene.n, 2)))))
    out.append(("nav_msgs/msg/Odometry", topics.base_odometry(  # a free base's odometry
        Snapshot(t=1.5, phi=np.zeros(1), phi_rate=np.zeros(1), alpha=np.zeros(1),
                 beta=np.zeros(1), hinge_angle=np.zeros(1), hinge_rate=np.zeros(1),
                 hinge_moment=np.zeros(1), nodes=np.zeros((2, 2)), forces=np.zeros((1, 2)),
                 base=np.array([0.5, -0.25, 2.0, 0.1, 0.2, -0.3])), "world")))
    out.append(("geometry_msgs/msg/WrenchStamped",   # a base_wrench command as logged
                {"header": {"stamp": {"sec": 1, "nanosec": 5}, "frame_id": "base"},
                 "wrench": {"force": {"x": 1.0, "y": -2.0, "z": 0.0},
                            "torque": {"x": 0.0, "y": 0.0, "z": 0.5}}}))
    out.append(("std_msgs/msg/String", event_message(
        {"t": 0.125, "event": "latch", "hinge": 2, "angle": 0.1, "rate": -0.5,
         "kinetic_energy_loss": 1e-4})))
    return out


def test_real_messages_match_mcap_ros2_byte_for_byte(real_messages):
    assert {t for t, _ in real_messages} == set(TYPES)
    for type_name, msg in real_messages:
        expected = mcap_encode(type_name, msg)
        assert fast_only(type_name)(msg) == expected, type_name
        assert cdr.encoder(type_name)(msg) == expected, type_name
        assert cdr.reference_encoder(type_name)(msg) == expected, type_name


def _plain(value):
    """rosbags' decoded message as plain Python (numpy arrays -> lists, structs -> dicts)."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, list):
        return [_plain(v) for v in value]
    if hasattr(value, "__dataclass_fields__"):
        return {k: _plain(getattr(value, k)) for k in value.__dataclass_fields__
                if k != "__msgtype__"}
    return value


def _contains(decoded, sent, path=""):
    """Every field ``sent`` gives has that value in ``decoded`` (the others are defaults)."""
    if isinstance(sent, dict):
        for key, value in sent.items():
            _contains(decoded[key], value, f"{path}.{key}")
    elif isinstance(sent, (list, tuple)):
        assert len(decoded) == len(sent), path
        for i, (d, s) in enumerate(zip(decoded, sent)):
            _contains(d, s, f"{path}[{i}]")
    elif isinstance(sent, float):
        assert decoded == sent or (math.isnan(sent) and math.isnan(decoded)), path
    else:
        assert decoded == sent, path


def test_round_trip_through_rosbags(real_messages):
    for type_name, msg in real_messages:
        data = cdr.encoder(type_name)(msg)
        decoded = _plain(TYPESTORE.deserialize_cdr(data, type_name))
        _contains(decoded, msg)
        # and rosbags' own encoding of what it decoded is the same bytes
        assert bytes(TYPESTORE.serialize_cdr(TYPESTORE.deserialize_cdr(data, type_name),
                                             type_name)) == data, type_name
    markers = next(m for t, m in real_messages if t.endswith("MarkerArray"))
    decoded = TYPESTORE.deserialize_cdr(cdr.encoder("visualization_msgs/msg/MarkerArray")(markers),
                                        "visualization_msgs/msg/MarkerArray")
    assert decoded.markers[0].points[3].x == markers["markers"][0]["points"][3]["x"]
    assert decoded.markers[0].texture.format == "" and decoded.markers[-1].ns == "nodes"


# ----- randomized messages -----

_INT_RANGES = {"byte": (0, 255), "char": (-128, 127), "int8": (-128, 127), "uint8": (0, 255),
               "int16": (-2**15, 2**15 - 1), "uint16": (0, 2**16 - 1),
               "int32": (-2**31, 2**31 - 1), "uint32": (0, 2**32 - 1),
               "int64": (-2**63, 2**63 - 1), "uint64": (0, 2**64 - 1)}
_TEXTS = ["", "a", "world", "ab", "abc", "abcd", "Стержень ϕ₁ — 🙂", "x" * 37, "tab\tnew\nline"]


def _random_value(rng: random.Random, ftype: str):
    if ftype in ("float64", "float32"):
        v = rng.choice([0.0, -0.0, 1.5, -2.25, rng.uniform(-1e3, 1e3), 1e-300, math.inf, -math.inf])
        return float(np.float32(v)) if ftype == "float32" and math.isfinite(v) else v
    if ftype == "bool":
        return rng.random() < 0.5
    if ftype == "string":
        return rng.choice(_TEXTS)
    lo, hi = _INT_RANGES[ftype]
    return rng.choice([lo, hi, 0, rng.randint(lo, hi)])


def _random_message(rng: random.Random, table, tname: str, p_missing: float):
    msg = {}
    for f in table[tname]:
        if rng.random() < p_missing and f.name != "values" and f.array != "fixed":
            continue  # absent: the default (DiagnosticStatus.values: see the test below; a
            # missing fixed-size array the fast path leaves to the reference encoder)
        n = f.size if f.array == "fixed" else rng.choice([0, 1, 2, 3, 5]) if f.array else None
        if f.is_struct:
            msg[f.name] = (_random_message(rng, table, f.type, p_missing) if n is None else
                           [_random_message(rng, table, f.type, p_missing) for _ in range(n)])
        elif n is None:
            msg[f.name] = _random_value(rng, f.type)
        else:
            msg[f.name] = [_random_value(rng, f.type) for _ in range(n)]
    return msg


@pytest.mark.parametrize("type_name", TYPES)
@pytest.mark.parametrize("p_missing", [0.0, 0.3, 0.8])
def test_random_messages_match_mcap_ros2(type_name, p_missing):
    table = cdr.parse_definition(type_name, msgdefs.SCHEMAS[type_name])
    root = next(iter(table))
    rng = random.Random(f"{type_name}/{p_missing}")
    fast = fast_only(type_name)
    for _ in range(40):
        msg = _random_message(rng, table, root, p_missing)
        expected = mcap_encode(type_name, msg)
        assert fast(msg) == expected, msg
        assert cdr.reference_encoder(type_name)(msg) == expected, msg


def test_defaults_nones_and_conversions_as_mcap_ros2():
    enc = cdr.encoder
    cases = [
        ("visualization_msgs/msg/MarkerArray", {}),
        ("visualization_msgs/msg/MarkerArray", {"markers": [{}, {"pose": {}}, {"pose": None}]}),
        ("visualization_msgs/msg/MarkerArray",  # Quaternion.w defaults to 1.0
         {"markers": [{"pose": {"orientation": {"x": 0.5}}, "points": [{"x": 1.0}, {}]}]}),
        ("sensor_msgs/msg/JointState", {"header": None, "name": None, "position": None}),
        ("sensor_msgs/msg/JointState", {"header": {"stamp": {"sec": None, "nanosec": 7}},
                                        "position": [1, 2, None], "name": ["a", None, 5]}),
        ("geometry_msgs/msg/PoseArray", {"poses": [{"position": {"x": 1, "y": True}}]}),
        ("std_msgs/msg/Float64MultiArray",  # floats in int fields truncate, str numbers parse
         {"layout": {"dim": [{"label": 7, "size": 2.9, "stride": "3"}], "data_offset": 1.2},
          "data": ("1.5", 2, 3.0)}),
        ("std_msgs/msg/String", {"data": None}),
        ("std_msgs/msg/String", {"data": 42}),
        ("rosgraph_msgs/msg/Clock", {"clock": {"sec": 2**31 - 1, "nanosec": 999_999_999}}),
        ("diagnostic_msgs/msg/DiagnosticArray",
         {"status": [{"level": b"\x02"[0], "values": [{"key": "k"}, {}]}, {"values": []}]}),
        ("visualization_msgs/msg/MarkerArray",
         {"markers": [{"texture": {"data": b"\x00\x01\xff", "format": "png"},
                       "mesh_file": {"data": array.array("B", [1, 2, 3])}}]}),
    ]
    for type_name, msg in cases:
        assert enc(type_name)(msg) == mcap_encode(type_name, msg), msg


def test_numpy_arrays_and_tuples_encode_as_lists():
    enc = cdr.encoder("sensor_msgs/msg/JointState")
    as_list = {"name": ["a", "b", "c"], "position": [0.1, -2.0, 3.5],
               "velocity": [1.0, 2.0, 3.0], "effort": []}
    expected = mcap_encode("sensor_msgs/msg/JointState", as_list)
    as_numpy = {"name": ("a", "b", "c"), "position": np.array([0.1, -2.0, 3.5]),
                "velocity": np.array([1, 2, 3]), "effort": np.zeros(0)}
    assert fast_only("sensor_msgs/msg/JointState")(as_numpy) == expected
    assert enc({**as_numpy, "position": np.array([0.1, -2.0, 3.5], dtype=">f8")}) == expected
    strided = np.array([[0.1, 9.0], [-2.0, 9.0], [3.5, 9.0]])[:, 0]
    assert enc({**as_numpy, "position": strided}) == expected
    assert enc({**as_numpy, "position": np.array([0.1, -2.0, 3.5], dtype=np.float32)}) == \
        mcap_encode("sensor_msgs/msg/JointState",
                    {**as_list, "position": np.array([0.1, -2.0, 3.5], np.float32).tolist()})
    assert cdr.reference_encoder("sensor_msgs/msg/JointState")(as_numpy) == expected


def test_missing_diagnostic_values_encode_as_empty():
    """mcap_ros2 reads a missing ``values`` key as the dict's .values method and fails; the
    field's default (an empty sequence) is what rclpy and rosbags give."""
    enc = cdr.encoder("diagnostic_msgs/msg/DiagnosticArray")
    with_values = {"status": [{"name": "x", "values": []}]}
    assert enc({"status": [{"name": "x"}]}) == mcap_encode(
        "diagnostic_msgs/msg/DiagnosticArray", with_values)


def test_layout_alignment_and_header_by_hand():
    """A few encodings written out by hand from the CDR rules (not from any encoder)."""
    clock = cdr.encoder("rosgraph_msgs/msg/Clock")({"clock": {"sec": 1, "nanosec": 2}})
    assert clock == b"\x00\x01\x00\x00" + struct.pack("<iI", 1, 2)
    string = cdr.encoder("std_msgs/msg/String")({"data": "ab"})
    assert string == b"\x00\x01\x00\x00" + b"\x03\x00\x00\x00ab\x00"  # no trailing padding
    js = cdr.encoder("sensor_msgs/msg/JointState")(
        {"header": {"frame_id": "w"}, "name": ["ab"], "position": [1.0]})
    body = (struct.pack("<iI", 0, 0) + b"\x02\x00\x00\x00w\x00" + b"\x00\x00"  # pad to 4
            + struct.pack("<I", 1) + b"\x03\x00\x00\x00ab\x00" + b"\x00"  # name; pad to 4
            + struct.pack("<I", 1) + struct.pack("<d", 1.0)  # offset 32: 8-aligned, no pad
            + struct.pack("<I", 0) + struct.pack("<I", 0))  # velocity, effort empty
    assert js == b"\x00\x01\x00\x00" + body
    js = cdr.encoder("sensor_msgs/msg/JointState")({"name": [], "velocity": [2.0]})
    body = (struct.pack("<iI", 0, 0) + b"\x01\x00\x00\x00\x00" + b"\x00\x00\x00"  # to 16
            + struct.pack("<I", 0) + struct.pack("<I", 0)  # name, position empty (offset 24)
            + struct.pack("<I", 1) + b"\x00" * 4 + struct.pack("<d", 2.0)  # 28: pad to 32
            + struct.pack("<I", 0))
    assert js == b"\x00\x01\x00\x00" + body


# ----- types with fixed/bounded arrays, defaults and every primitive (not in SCHEMAS) -----

SYNTHETIC = """\
# every primitive, defaults, fixed and bounded arrays
bool flag true
byte b
char c
int8 i8 -3
uint8 u8
int16 i16
uint16 u16 7
int32 i32
uint32 u32
int64 i64
uint64 u64
float32 f32 0.5
float64 f64 -1.25
string s "hi" # a comment
string t "a#b"
string<=5 short
int32 LIMIT=4
float64[3] fixed
uint8[2] pair
int16[<=3] bounded
pkg/Inner[2] inners
Inner single
Empty nothing
string[] words
bool[] flags
================================================================================
MSG: pkg/Inner
uint8 a
float64 x
================================================================================
MSG: pkg/Empty
"""


def test_synthetic_type_matches_mcap_ros2():
    name = "pkg/msg/Synthetic"
    enc = cdr.compile_encoder(name, SYNTHETIC)
    reference = serialize_dynamic(name, SYNTHETIC)[name]
    full = {"flag": False, "b": 200, "c": -5, "i8": 1, "u8": 2, "i16": -300, "u16": 60000,
            "i32": -7, "u32": 7, "i64": -2**40, "u64": 2**63, "f32": 1.5, "f64": math.pi,
            "s": "x", "short": "abc", "fixed": [1.0, 2.0, 3.0], "pair": [1, 2],
            "bounded": [1, -2], "inners": [{"a": 1, "x": 2.0}, {"a": 3}], "single": {"x": 5.0},
            "nothing": {}, "words": ["", "é"], "flags": [True, False, True]}
    for msg in (full, {"fixed": (4, 5, 6), "pair": b"\x07\x08", "inners": [{}, {}]},
                {**full, "flag": None, "words": [], "bounded": [1, 2, 3]}):
        assert enc(msg) == reference(msg), msg
    assert enc({**full, "bounded": np.array([1, 2, 3], dtype=np.int16),
                "fixed": np.array([1.0, 2.0, 3.0])}) == reference({**full, "bounded": [1, 2, 3]})
    # absent fixed arrays take defaults as in mcap_ros2 (zeros, or empty structs)
    assert enc({}) == reference({})
    # the generated code handles all of these itself
    fast = type(enc)(enc.__code__, {**enc.__globals__, "_reference": None})
    fast(full)


def test_synthetic_defaults_are_parsed():
    table = cdr.parse_definition("pkg/msg/Synthetic", SYNTHETIC)
    fields = {f.name: f for f in table["pkg/msg/Synthetic"]}
    assert "LIMIT" not in fields and list(table) == ["pkg/msg/Synthetic", "pkg/msg/Inner",
                                                     "pkg/msg/Empty"]
    assert fields["flag"].default is True and fields["u16"].default == 7
    assert fields["s"].default == "hi" and fields["f64"].default == -1.25
    assert fields["t"].default == '"a'  # '#' starts a comment even in quotes, as in rosidl
    assert (fields["fixed"].array, fields["fixed"].size) == ("fixed", 3)
    assert (fields["bounded"].array, fields["bounded"].size) == ("bounded", 3)
    assert fields["inners"].type == "pkg/msg/Inner" and fields["nothing"].type == "pkg/msg/Empty"
    assert table["pkg/msg/Empty"] == []


# ----- errors -----

def test_unknown_fields_are_rejected_with_their_path():
    enc = cdr.encoder("visualization_msgs/msg/MarkerArray")
    good = {"markers": [{"points": [{"x": 1.0}, {"x": 2.0, "y": 1.0, "z": 0.0}]}]}
    enc(good)
    bad = {"markers": [{"points": [{"x": 1.0}, {"x": 2.0, "yy": 1.0, "z": 0.0}]}]}
    with pytest.raises(msgdefs.MessageFieldError, match=r"'markers\[0\]\.points\[1\]\.yy'"):
        enc(bad)
    with pytest.raises(msgdefs.MessageFieldError, match=r"'markers\[0\]\.header\.stamp\.secs'"):
        enc({"markers": [{"header": {"stamp": {"secs": 1}}}]})
    with pytest.raises(msgdefs.MessageFieldError, match="'positions'"):
        cdr.encoder("sensor_msgs/msg/JointState")({"positions": [1.0]})


@pytest.mark.parametrize("type_name, msg, error, match", [
    ("sensor_msgs/msg/JointState", {"position": [1.0, "x"]}, ValueError, r"position\[1\]"),
    ("sensor_msgs/msg/JointState", {"position": 1.0}, TypeError, "position"),
    ("sensor_msgs/msg/JointState", {"position": np.zeros((2, 2))}, ValueError, "position"),
    ("sensor_msgs/msg/JointState", {"position": b"\x00"}, ValueError, "position"),
    ("sensor_msgs/msg/JointState", {"header": ["x"]}, TypeError, "header"),
    ("sensor_msgs/msg/JointState", {"header": {"stamp": {"sec": 2**31}}}, struct.error,
     r"header\.stamp\.sec"),
    ("rosgraph_msgs/msg/Clock", {"clock": {"nanosec": -1}}, struct.error, r"clock\.nanosec"),
    ("std_msgs/msg/String", {"data": "\ud800"}, ValueError, "data"),
    ("geometry_msgs/msg/PoseArray", {"poses": {"position": {}}}, TypeError, "poses"),
    ("geometry_msgs/msg/PoseArray", {"poses": [{"position": {"x": {}}}]}, TypeError,
     r"poses\[0\]\.position\.x"),
    ("visualization_msgs/msg/MarkerArray", {"markers": [{"color": {"r": 1e300}}]}, ValueError,
     r"markers\[0\]\.color\.r"),
    ("std_msgs/msg/String", ["data"], TypeError, "the message"),
])
def test_bad_values_raise_naming_the_field(type_name, msg, error, match):
    with pytest.raises(error, match=match):
        cdr.encoder(type_name)(msg)


def test_fixed_and_bounded_lengths_are_checked():
    enc = cdr.compile_encoder("pkg/msg/Synthetic", SYNTHETIC)
    with pytest.raises(ValueError, match=r"fixed: fixed-size array needs 3 elements \(got 2\)"):
        enc({"fixed": [1.0, 2.0]})
    with pytest.raises(ValueError, match="inners: fixed-size array needs 2"):
        enc({"inners": [{}]})
    with pytest.raises(ValueError, match="bounded: bounded array takes at most 3"):
        enc({"bounded": [1, 2, 3, 4]})
    with pytest.raises(NotImplementedError, match="wstring"):
        cdr.compile_encoder("pkg/msg/W", "wstring w\n")({"w": "x"})


def test_unknown_types_and_bad_definitions():
    with pytest.raises(KeyError, match="no schema"):
        cdr.encoder("std_msgs/msg/Int32")
    with pytest.raises(ValueError, match="no definition of pkg/msg/Missing"):
        cdr.compile_encoder("pkg/msg/T", "Missing m\n")


def test_generated_source_is_readable():
    source = cdr.compile_encoder("rosgraph_msgs/msg/Clock",
                                 msgdefs.SCHEMAS["rosgraph_msgs/msg/Clock"], source=True)
    assert source.startswith("def encode(m):") and "_reference(m)" in source
    json.dumps(source)  # plain text


def test_struct_sequences_padded_after_their_count():
    """A sequence of 8-aligned structs whose count ends at offset 4 mod 8: the first element
    is padded (never the case in SCHEMAS, where such counts end 8-aligned)."""
    text = ("uint32 a\nuint32 b\nVec[] v\nuint8 c\nVec[] w\nPoseLike[] p\n" + "=" * 80 +
            "\nMSG: pkg/Vec\nfloat64 x\nfloat64 y\n" + "=" * 80 +
            "\nMSG: pkg/PoseLike\nuint8 tag\nfloat64 x\n")
    name = "pkg/msg/T"
    enc = cdr.compile_encoder(name, text)
    fast = type(enc)(enc.__code__, {**enc.__globals__, "_reference": None})
    reference = serialize_dynamic(name, text)[name]
    for msg in ({"v": [{"x": 1.0, "y": 2.0}, {"x": 3.0}], "c": 1, "w": [{"y": 4.0}],
                 "p": [{"tag": 1, "x": 1.0}, {"x": 2.0}]},
                {"v": [], "w": [{"x": 1.0, "y": 2.0}], "p": []}, {}):
        assert fast(msg) == reference(msg), msg
    assert fast({"v": [{"x": 1.0, "y": 2.0}]})[4 + 12:4 + 16] == b"\x00" * 4  # the pad


def test_cdr_bench_runs_and_every_encoder_agrees(capsys):
    """The benchmark quoted in rod_sim/io/cdr.py's docstring: mcap_ros2, rod_sim and (when
    installed) rosbags give the same bytes for every topic (else it returns 1)."""
    from rod_sim.io import cdr_bench

    assert cdr_bench.main(["--repeat", "1"]) == 0
    out = capsys.readouterr().out
    assert "6 per period" in out and "markers" in out
    pytest.importorskip("rosbags")
    assert "rosbags dict [us]" in out


def test_long_name_sequences_are_cached_but_never_stale():
    """Joint names of a long chain are encoded once and reused while equal; a different or
    mutated list of the same length, or another alignment, is encoded afresh (byte-equal to
    mcap_ros2 every time)."""
    enc = fast_only("sensor_msgs/msg/JointState")
    names = [f"rod_{k}" for k in range(1, 41)]
    msg = {"header": {"stamp": {"sec": 1, "nanosec": 2}, "frame_id": "world"}, "name": names,
           "position": [0.5] * 40, "velocity": [], "effort": []}
    first = enc(msg)
    assert first == mcap_encode("sensor_msgs/msg/JointState", msg)
    assert enc(msg) == first
    names[7] = "rod_x"                                        # same object, mutated
    assert enc(msg) == mcap_encode("sensor_msgs/msg/JointState", msg) != first
    other = dict(msg, name=[f"hinge_{k}" for k in range(40)])  # same length, other names
    assert enc(other) == mcap_encode("sensor_msgs/msg/JointState", other)
    shifted = dict(msg, header={"stamp": {"sec": 1, "nanosec": 2}, "frame_id": "w"})
    assert enc(shifted) == mcap_encode("sensor_msgs/msg/JointState", shifted)


def test_node_poses_are_the_nodes_with_their_rods_yaw():
    rng = np.random.default_rng(3)
    n = 300
    phi = rng.uniform(-3.0, 3.0, n)
    length = rng.uniform(0.5, 2.0, n)
    from rod_sim.core.kinematics import node_positions

    snap = type("S", (), {"t": 0.25, "phi": phi, "nodes": node_positions(length, phi)})()
    msg = topics.node_poses(snap)
    assert len(msg["poses"]) == n + 1
    for k, pose in enumerate(msg["poses"]):
        q = topics.yaw_quaternion(phi[max(k, 1) - 1])
        assert pose["orientation"] == pytest.approx(q, abs=1e-15)
        assert (pose["position"]["x"], pose["position"]["y"]) == tuple(snap.nodes[k])
        assert pose["position"]["z"] == 0.0
