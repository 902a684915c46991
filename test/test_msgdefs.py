"""The embedded ros2msg schemas match ROS 2 Jazzy: its .msg files and the rosbags typestore."""
from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from rod_sim.io import cdr, msgdefs
from rod_sim.io.msgdefs import SCHEMAS, SEPARATOR, TYPE_HASHES, TYPE_NAMES

JAZZY = get_typestore(Stores.ROS2_JAZZY)


def _share_dirs() -> list[Path]:
    """Candidate ``share`` directories of an installed ROS 2 (the venv wheels, AMENT_PREFIX_PATH)."""
    prefixes = [Path(sys.prefix)]
    prefixes += [Path(p) for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    return [p / "share" for p in prefixes]


def _share_for(type_name: str) -> Path | None:
    """A share directory holding every .msg file ``type_name`` needs, or None."""
    for share in _share_dirs():
        try:
            msgdefs.full_definition(type_name, msgdefs.share_source(share))
        except OSError:
            continue
        return share
    return None


def test_the_logged_types_have_schemas_and_hashes():
    assert set(SCHEMAS) == set(TYPE_NAMES) == set(TYPE_HASHES)
    assert {"sensor_msgs/msg/JointState", "geometry_msgs/msg/PoseArray",
            "std_msgs/msg/Float64MultiArray", "visualization_msgs/msg/MarkerArray",
            "diagnostic_msgs/msg/DiagnosticArray", "rosgraph_msgs/msg/Clock",
            "std_msgs/msg/String"} <= set(SCHEMAS)


@pytest.mark.parametrize("type_name", TYPE_NAMES)
def test_schema_equals_the_concatenated_msg_files(type_name):
    share = _share_for(type_name)
    if share is None:
        pytest.skip(f"no ROS 2 share directory with the .msg files of {type_name}")
    assert SCHEMAS[type_name] == msgdefs.full_definition(type_name, msgdefs.share_source(share))
    package, name = type_name.split("/msg/")
    info = json.loads((share / package / "msg" / f"{name}.json").read_text())
    hashes = {h["type_name"]: h["hash_string"] for h in info["type_hashes"]}
    assert TYPE_HASHES[type_name] == hashes[type_name]


def test_the_ros_extra_ships_every_msg_file_the_schemas_copy():
    """Where the ROS 2 interface wheels are installed (the ``ros`` extra), the comparison above
    runs for every type: a missing .msg file fails here instead of skipping there."""
    import importlib.util

    if importlib.util.find_spec("sensor_msgs") is None:
        pytest.skip("the ROS 2 interface packages (rod_sim[ros]) are not installed")
    assert [t for t in TYPE_NAMES if _share_for(t) is None] == []


@pytest.mark.parametrize("type_name", TYPE_NAMES)
def test_schema_layout_is_rosbag2s(type_name):
    text = SCHEMAS[type_name]
    parts = text.split("\n" + SEPARATOR)
    headers = [p.split("\n", 1)[0] for p in parts[1:]]
    assert all(h.startswith("MSG: ") and h.count("/") == 1 for h in headers), headers
    assert len(headers) == len(set(headers)), "each dependency appears once"
    # every separator line is exactly 80 '=' and sits between two definitions
    for line in text.splitlines():
        if set(line) == {"="}:
            assert len(line) == 80
    assert not parts[0].startswith("MSG: ")
    # the root text is the .msg file itself, comments included (first line of JointState)
    if type_name == "sensor_msgs/msg/JointState":
        assert text.startswith("# This is a message that holds data to describe the state")


@pytest.mark.parametrize("type_name", TYPE_NAMES)
def test_schema_fields_match_the_jazzy_typestore(type_name):
    parsed = get_types_from_msg(SCHEMAS[type_name], type_name)
    assert type_name in parsed
    for name, (consts, fields) in parsed.items():
        ref_consts, ref_fields = JAZZY.fielddefs[name]
        assert fields == ref_fields, name
        assert sorted(consts) == sorted(ref_consts), name
    # the whole closure of the type is present
    closure, todo = set(), [type_name]
    while todo:
        name = todo.pop()
        if name in closure:
            continue
        closure.add(name)
        for _, desc in JAZZY.fielddefs[name][1]:
            todo += _nested_names(desc)
    assert closure == set(parsed)


def _nested_names(desc) -> list[str]:
    kind, arg = desc
    if kind.name == "NAME":
        return [arg]
    if kind.name in ("ARRAY", "SEQUENCE"):
        return _nested_names(arg[0])
    return []


@pytest.mark.parametrize("type_name", TYPE_NAMES)
def test_type_hash_matches_the_typestore_and_our_text(type_name):
    assert TYPE_HASHES[type_name] == JAZZY.hash_rihs01(type_name)
    store = get_typestore(Stores.EMPTY)
    store.register(get_types_from_msg(SCHEMAS[type_name], type_name))
    assert store.hash_rihs01(type_name) == TYPE_HASHES[type_name]


@pytest.mark.parametrize("type_name", TYPE_NAMES)
def test_field_table_matches_the_typestore(type_name):
    table = cdr.parse_definition(type_name, SCHEMAS[type_name])
    for name, fields in table.items():
        assert [f.name for f in fields] == [f for f, _ in JAZZY.fielddefs[name][1]], name


def test_encoders_reject_misspelled_nested_fields():
    encode = cdr.encoder("visualization_msgs/msg/MarkerArray")
    ok = {"markers": [{"header": {"stamp": {"sec": 1, "nanosec": 2}, "frame_id": "w"},
                       "points": [{"x": 1.0, "y": 2.0}], "color": {"r": 1.0}}]}
    encode(ok)
    bad = {"markers": [{"points": [{"x": 1.0}, {"x": 1.0, "yy": 2.0}]}]}
    with pytest.raises(msgdefs.MessageFieldError, match=r"markers\[0\]\.points\[1\]\.yy"):
        encode(bad)
    with pytest.raises(msgdefs.MessageFieldError, match="stamp.secs"):
        cdr.encoder("sensor_msgs/msg/JointState")({"header": {"stamp": {"secs": 1}}})


def test_full_definition_follows_rosbag2s_order_and_dedup():
    files = {
        ("p", "Root"): "q/B b\nA a  # comment\nint32 X=1\nq/B[] more\n",
        ("p", "A"): "q/B inner\nstring s\n",
        ("q", "B"): "float64 v\n",
    }
    text = msgdefs.full_definition("p/msg/Root", lambda pkg, name: files[(pkg, name)])
    assert text == (files[("p", "Root")] + "\n" + SEPARATOR + "MSG: p/A\n" + files[("p", "A")]
                    + "\n" + SEPARATOR + "MSG: q/B\n" + files[("q", "B")])
