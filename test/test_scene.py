"""Scene files (SPEC section 2): every validation rule, broadcasting, the paper's example, round trip."""
from __future__ import annotations

import copy
import math
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from rod_sim.core.scene import Load, Scene, SceneError
from rod_sim.io.scene_yaml import load_scene, scene_from_yaml_text, scene_to_yaml

REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / "config"

ARRAY_FIELDS = ("length", "mass_per_length", "bending_stiffness", "node_mass",
                "hinge_stiffness", "hinge_damping", "phi0", "phi_rate0")

BASE = {
    "name": "base",
    "rods": {"count": 3, "length": 1.0, "mass_per_length": 2.0, "bending_stiffness": 1.0e4},
    "nodes": {"mass": 0.5},
    "hinges": {"stiffness": 10.0, "damping": 0.1},
    "initial": {"phi": 0.0, "phi_rate": 0.0},
    "loads": [{"node": 3, "axis": "y", "shape": "raised_cosine_pulse", "amplitude": 5.0,
               "start": 0.0, "duration": 1.0}],
}


def write(tmp_path: Path, text: str, name: str = "scene.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def load_data(tmp_path: Path, data) -> Scene:
    return load_scene(write(tmp_path, yaml.safe_dump(data, sort_keys=False)))


DELETE = object()


def changed(path: str, value):
    """BASE with the entry at dotted ``path`` (``loads[0].node``) set, or removed if value is DELETE."""
    data = copy.deepcopy(BASE)
    *parents, last = re.findall(r"[^.\[\]]+", path)
    target = data
    for part in parents:
        target = target[int(part)] if part.isdigit() else target[part]
    if value is DELETE:
        del target[int(last) if last.isdigit() else last]
    else:
        target[int(last) if last.isdigit() else last] = value
    return data


def assert_scene_error(err: SceneError, key: str) -> None:
    assert err.key == key
    text = str(err)
    assert "\n" not in text and "\r" not in text, text
    assert text.startswith(f"{key}: "), text


def scenes_equal(a: Scene, b: Scene) -> None:
    assert a.name == b.name
    assert a.n == b.n
    for name in ARRAY_FIELDS:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert a.loads == b.loads


# ----- validation: every rule names the entry -----------------------------------------------

INVALID = [
    # unknown keys, at the top level, in every section and in a load entry
    ("unknown top-level key", "gravity", 9.81, "gravity"),
    ("unknown rods key", "rods.width", 0.1, "rods.width"),
    ("unknown nodes key", "nodes.radius", 0.1, "nodes.radius"),
    ("unknown hinges key", "hinges.friction", 0.1, "hinges.friction"),
    ("unknown initial key", "initial.theta", 0.0, "initial.theta"),
    ("unknown load key", "loads[0].phase", 0.0, "loads[0].phase"),
    # wrong list lengths (n = 3)
    ("short rods list", "rods.length", [1.0, 1.0], "rods.length"),
    ("long rods list", "rods.bending_stiffness", [1.0] * 4, "rods.bending_stiffness"),
    ("short nodes list", "nodes.mass", [1.0], "nodes.mass"),
    ("long hinges list", "hinges.damping", [0.1] * 4, "hinges.damping"),
    ("empty initial list", "initial.phi", [], "initial.phi"),
    ("long initial list", "initial.phi_rate", [0.0] * 5, "initial.phi_rate"),
    # non-physical values
    ("zero length", "rods.length", 0.0, "rods.length"),
    ("negative length in a list", "rods.length", [1.0, -1.0, 1.0], "rods.length"),
    ("negative mass per length", "rods.mass_per_length", -2.0, "rods.mass_per_length"),
    ("zero EI", "rods.bending_stiffness", 0.0, "rods.bending_stiffness"),
    ("negative EI", "rods.bending_stiffness", [1.0, 1.0, -5.0], "rods.bending_stiffness"),
    ("negative kappa", "hinges.stiffness", -1.0, "hinges.stiffness"),
    ("negative nu", "hinges.damping", [0.1, -0.1, 0.1], "hinges.damping"),
    ("negative node mass", "nodes.mass", -0.5, "nodes.mass"),
    # wrong types
    ("string for a number", "rods.length", "long", "rods.length"),
    ("mapping for a number", "hinges.stiffness", {"a": 1}, "hinges.stiffness"),
    ("string in a list", "initial.phi", [0.0, "x", 0.0], "initial.phi"),
    ("bool for a number", "rods.length", True, "rods.length"),
    ("bool in a list", "nodes.mass", [1.0, False, 1.0], "nodes.mass"),
    ("zero count", "rods.count", 0, "rods.count"),
    ("fractional count", "rods.count", 2.5, "rods.count"),
    ("bool count", "rods.count", True, "rods.count"),
    ("empty name", "name", "", "name"),
    ("numeric name", "name", 12, "name"),
    ("section not a mapping", "hinges", [1, 2], "hinges"),
    ("loads not a list", "loads", {"node": 3}, "loads"),
    ("load not a mapping", "loads[0]", "pulse", "loads[0]"),
    # bad loads
    ("load node 0", "loads[0].node", 0, "loads[0].node"),
    ("load node past the tip", "loads[0].node", 4, "loads[0].node"),
    ("fractional load node", "loads[0].node", 1.5, "loads[0].node"),
    ("bool load node", "loads[0].node", True, "loads[0].node"),
    ("load axis z", "loads[0].axis", "z", "loads[0].axis"),
    ("load shape unknown", "loads[0].shape", "sawtooth", "loads[0].shape"),
    ("load duration zero", "loads[0].duration", 0.0, "loads[0].duration"),
    ("load duration negative", "loads[0].duration", -1.0, "loads[0].duration"),
    ("load start negative", "loads[0].start", -0.5, "loads[0].start"),
    ("load amplitude string", "loads[0].amplitude", "big", "loads[0].amplitude"),
    ("bool load amplitude", "loads[0].amplitude", False, "loads[0].amplitude"),
    # missing entries
    ("missing rods", "rods", DELETE, "rods"),
    ("missing nodes", "nodes", DELETE, "nodes"),
    ("missing hinges", "hinges", DELETE, "hinges"),
    ("missing count", "rods.count", DELETE, "rods.count"),
    ("missing length", "rods.length", DELETE, "rods.length"),
    ("missing mass per length", "rods.mass_per_length", DELETE, "rods.mass_per_length"),
    ("missing EI", "rods.bending_stiffness", DELETE, "rods.bending_stiffness"),
    ("missing node mass", "nodes.mass", DELETE, "nodes.mass"),
    ("missing kappa", "hinges.stiffness", DELETE, "hinges.stiffness"),
    ("missing nu", "hinges.damping", DELETE, "hinges.damping"),
    ("pulse without duration", "loads[0].duration", DELETE, "loads[0].duration"),
    ("load without node", "loads[0].node", DELETE, "loads[0].node"),
    ("load without axis", "loads[0].axis", DELETE, "loads[0].axis"),
    ("load without shape", "loads[0].shape", DELETE, "loads[0].shape"),
    ("load without amplitude", "loads[0].amplitude", DELETE, "loads[0].amplitude"),
]


@pytest.mark.parametrize("path, value, key", [c[1:] for c in INVALID], ids=[c[0] for c in INVALID])
def test_invalid_entry_is_rejected_naming_its_key(tmp_path, path, value, key):
    with pytest.raises(SceneError) as info:
        load_data(tmp_path, changed(path, value))
    assert_scene_error(info.value, key)


@pytest.mark.parametrize("rod_mass, node_mass", [(0.0, 0.0), (0.0, [1.0, 1.0, 0.0])],
                         ids=["all massless", "massless tip"])
def test_chain_without_inertia_is_rejected(tmp_path, rod_mass, node_mass):
    data = changed("rods.mass_per_length", rod_mass)
    data["nodes"]["mass"] = node_mass
    with pytest.raises(SceneError, match="no inertia") as info:
        load_data(tmp_path, data)
    assert_scene_error(info.value, "nodes.mass")


def test_massless_rods_with_node_masses_are_fine(tmp_path):
    scene = load_data(tmp_path, changed("rods.mass_per_length", 0.0))
    assert np.all(scene.mass_per_length == 0.0)


NON_FINITE = [
    ("rods.length", ".nan"), ("rods.length", ".inf"), ("rods.mass_per_length", ".inf"),
    ("rods.bending_stiffness", ".inf"), ("hinges.stiffness", "-.inf"), ("hinges.damping", ".NaN"),
    ("nodes.mass", "[1.0, .nan, 1.0]"), ("initial.phi", ".nan"), ("initial.phi_rate", "[0, 0, .inf]"),
]


def base_text(**overrides: str) -> str:
    """YAML text of a valid 3-rod scene; ``overrides`` replace entries by section__key."""
    values = {"rods__length": "1.0", "rods__mass_per_length": "2.0",
              "rods__bending_stiffness": "1.0e4", "nodes__mass": "0.5",
              "hinges__stiffness": "10.0", "hinges__damping": "0.1",
              "initial__phi": "0.0", "initial__phi_rate": "0.0",
              "load__amplitude": "5.0", "load__start": "0.0", "load__duration": "1.0"}
    values.update(overrides)
    v = values
    return (
        "name: text\n"
        "rods:\n"
        "  count: 3\n"
        f"  length: {v['rods__length']}\n"
        f"  mass_per_length: {v['rods__mass_per_length']}\n"
        f"  bending_stiffness: {v['rods__bending_stiffness']}\n"
        "nodes:\n"
        f"  mass: {v['nodes__mass']}\n"
        "hinges:\n"
        f"  stiffness: {v['hinges__stiffness']}\n"
        f"  damping: {v['hinges__damping']}\n"
        "initial:\n"
        f"  phi: {v['initial__phi']}\n"
        f"  phi_rate: {v['initial__phi_rate']}\n"
        "loads:\n"
        "  - node: 3\n"
        "    axis: y\n"
        "    shape: raised_cosine_pulse\n"
        f"    amplitude: {v['load__amplitude']}\n"
        f"    start: {v['load__start']}\n"
        f"    duration: {v['load__duration']}\n"
    )


def test_base_text_is_valid():
    scene = scene_from_yaml_text(base_text())
    assert scene.n == 3 and scene.bending_stiffness[0] == 1.0e4


@pytest.mark.parametrize("key, literal", NON_FINITE, ids=[f"{k}={v}" for k, v in NON_FINITE])
def test_non_finite_value_is_rejected(tmp_path, key, literal):
    path = write(tmp_path, base_text(**{key.replace(".", "__"): literal}))
    with pytest.raises(SceneError, match="finite") as info:
        load_scene(path)
    assert_scene_error(info.value, key)


@pytest.mark.parametrize("field, literal", [("amplitude", ".nan"), ("start", ".inf"),
                                            ("duration", ".inf"), ("duration", ".nan")])
def test_non_finite_load_number_is_rejected(field, literal):
    with pytest.raises(SceneError, match="finite") as info:
        scene_from_yaml_text(base_text(**{f"load__{field}": literal}))
    assert_scene_error(info.value, f"loads[0].{field}")


@pytest.mark.parametrize("key, literal", [
    ("rods.length", "yes"), ("rods.bending_stiffness", "true"), ("nodes.mass", "[1, on, 1]"),
    ("hinges.damping", "off"), ("initial.phi", "No"), ("loads[0].amplitude", "TRUE"),
])
def test_yaml_booleans_are_not_numbers(key, literal):
    override = "load__amplitude" if key.startswith("loads") else key.replace(".", "__")
    with pytest.raises(SceneError) as info:
        scene_from_yaml_text(base_text(**{override: literal}))
    assert_scene_error(info.value, key)


DUPLICATES = [
    ("top level", "name: a\nname: b\n", "name"),
    ("section", base_text() + "rods:\n  count: 3\n", "rods"),
    ("inside a section", base_text().replace("  count: 3\n", "  count: 3\n  count: 4\n"), "rods.count"),
    ("quoted duplicate", base_text().replace("  count: 3\n", "  count: 3\n  'count': 3\n"), "rods.count"),
    ("load entry", base_text().replace("    axis: y\n", "    axis: y\n    axis: x\n"), "loads[0].axis"),
    ("flow mapping", "loads:\n  - {node: 1, node: 2}\n", "loads[0].node"),
]


@pytest.mark.parametrize("text, key", [d[1:] for d in DUPLICATES], ids=[d[0] for d in DUPLICATES])
def test_duplicate_key_is_rejected(tmp_path, text, key):
    with pytest.raises(SceneError, match="duplicate key") as info:
        load_scene(write(tmp_path, text))
    assert_scene_error(info.value, key)


def test_duplicate_key_message_gives_both_lines():
    with pytest.raises(SceneError) as info:
        scene_from_yaml_text("name: a\nrods: {}\nname: b\n")
    assert str(info.value) == "name: duplicate key (first at line 1, again at line 3)"


def test_merge_key_override_is_not_a_duplicate():
    text = base_text().replace(
        "hinges:\n  stiffness: 10.0\n",
        "hinges:\n  <<: {stiffness: 1.0, damping: 7.0}\n  stiffness: 10.0\n")
    scene = scene_from_yaml_text(text)
    assert scene.hinge_stiffness.tolist() == [10.0] * 3
    assert scene.hinge_damping.tolist() == [0.1] * 3


@pytest.mark.parametrize("text, line, column", [
    ("name: x\nrods: count: 3\n", 2, 12),
    ("rods:\n  count: 3\n  length: [1.0, 2.0\nnodes: {}\n", 4, 6),
    ("rods:\n  count: 3\n\tlength: 1\n", 3, 1),
    ("name: 'open\n", 2, 1),
], ids=["mapping value", "unclosed list", "tab indent", "unclosed quote"])
def test_yaml_syntax_error_is_one_line_with_position(tmp_path, text, line, column):
    with pytest.raises(SceneError) as info:
        load_scene(write(tmp_path, text))
    assert_scene_error(info.value, "scene")
    assert re.match(rf"^scene: YAML error at line {line} column {column}: \S", str(info.value)), \
        str(info.value)


def test_unsafe_tag_is_a_yaml_error():
    with pytest.raises(SceneError, match=r"^scene: YAML error at line 1 column \d+: ") as info:
        scene_from_yaml_text("name: !!python/object/apply:os.system ['true']\n")
    assert_scene_error(info.value, "scene")


def test_several_documents_are_a_yaml_error():
    with pytest.raises(SceneError, match="YAML error") as info:
        scene_from_yaml_text(base_text() + "---\n" + base_text())
    assert_scene_error(info.value, "scene")


def test_missing_file_is_named(tmp_path):
    missing = tmp_path / "nowhere" / "scene.yaml"
    with pytest.raises(SceneError) as info:
        load_scene(missing)
    assert_scene_error(info.value, "scene")
    assert "not found" in str(info.value) and str(missing) in str(info.value)


def test_directory_is_not_a_scene(tmp_path):
    with pytest.raises(SceneError, match="directory") as info:
        load_scene(tmp_path)
    assert_scene_error(info.value, "scene")


def test_binary_file_is_rejected(tmp_path):
    path = tmp_path / "scene.yaml"
    path.write_bytes(b"name: \xff\xfe\n")
    with pytest.raises(SceneError, match="UTF-8") as info:
        load_scene(path)
    assert_scene_error(info.value, "scene")


@pytest.mark.parametrize("text", ["", "# only a comment\n", "- rods\n- nodes\n", "42\n", "just text\n"],
                         ids=["empty", "comment", "list", "number", "string"])
def test_top_level_must_be_a_mapping(tmp_path, text):
    with pytest.raises(SceneError) as info:
        load_scene(write(tmp_path, text))
    assert_scene_error(info.value, "scene")


def test_recursive_alias_terminates():
    with pytest.raises(SceneError) as info:
        scene_from_yaml_text("extra: &a [1, *a]\n" + base_text())
    assert_scene_error(info.value, "extra")


# ----- values: broadcasting, lists, number forms, defaults ----------------------------------

def test_scalars_broadcast_to_every_rod_node_and_hinge(tmp_path):
    scene = load_data(tmp_path, BASE)
    expected = {"length": 1.0, "mass_per_length": 2.0, "bending_stiffness": 1.0e4,
                "node_mass": 0.5, "hinge_stiffness": 10.0, "hinge_damping": 0.1,
                "phi0": 0.0, "phi_rate0": 0.0}
    for name, value in expected.items():
        arr = getattr(scene, name)
        assert arr.shape == (3,), name
        assert arr.dtype == np.float64, name
        assert arr.tolist() == [value] * 3, name


def test_lists_are_taken_per_rod(tmp_path):
    data = copy.deepcopy(BASE)
    data["rods"].update(length=[1.0, 2.0, 3.0], mass_per_length=[0.5, 0, 1],
                        bending_stiffness=[1e3, 2e3, 3e3])
    data["nodes"]["mass"] = [0.1, 0.2, 0.3]
    data["hinges"].update(stiffness=[0, 5, 6], damping=[0.0, 0.5, 0.6])
    data["initial"].update(phi=[0.1, -0.2, 0.3], phi_rate=[1, 2, 3])
    scene = load_data(tmp_path, data)
    assert scene.length.tolist() == [1.0, 2.0, 3.0]
    assert scene.mass_per_length.tolist() == [0.5, 0.0, 1.0]
    assert scene.bending_stiffness.tolist() == [1e3, 2e3, 3e3]
    assert scene.node_mass.tolist() == [0.1, 0.2, 0.3]
    assert scene.hinge_stiffness.tolist() == [0.0, 5.0, 6.0]
    assert scene.hinge_damping.tolist() == [0.0, 0.5, 0.6]
    assert scene.phi0.tolist() == [0.1, -0.2, 0.3]
    assert scene.phi_rate0.tolist() == [1.0, 2.0, 3.0]


@pytest.mark.parametrize("literal, value", [
    ("1e5", 1e5), ("1.0e5", 1e5), ("1.0e+5", 1e5), ("2E-3", 2e-3), ("+1.5e2", 150.0),
    ("100000", 1e5), ("1_000.5", 1000.5), (".5", 0.5), ("3.", 3.0),
])
def test_number_forms(literal, value):
    scene = scene_from_yaml_text(base_text(rods__bending_stiffness=literal))
    assert scene.bending_stiffness.tolist() == [value] * 3


def test_optional_sections_default(tmp_path):
    data = copy.deepcopy(BASE)
    del data["initial"], data["loads"], data["name"]
    scene = load_scene(write(tmp_path, yaml.safe_dump(data), name="my_chain.yaml"))
    assert scene.phi0.tolist() == [0.0] * 3 and scene.phi_rate0.tolist() == [0.0] * 3
    assert scene.loads == ()
    assert scene.name == "my_chain"  # named after the file
    assert scene_from_yaml_text(yaml.safe_dump(data)).name == "scene"


def test_arrays_are_read_only(tmp_path):
    scene = load_data(tmp_path, BASE)
    for name in ARRAY_FIELDS:
        arr = getattr(scene, name)
        assert not arr.flags.writeable, name
        with pytest.raises(ValueError):
            arr[0] = 1.0
    with pytest.raises(AttributeError):
        scene.name = "other"


# ----- the paper's example (seed, section 3) ------------------------------------------------

def test_paper_example_has_the_seed_numbers():
    scene = load_scene(CONFIG / "paper_example.yaml")
    assert scene.name == "paper_example"
    assert scene.n == 8
    assert scene.length.tolist() == [2.0] * 8               # l_k = 2 m
    assert scene.mass_per_length.tolist() == [3.0] * 8      # m_k = 3 kg/m
    assert scene.node_mass.tolist() == [3.0] * 8            # mu_k = 3 kg
    assert scene.bending_stiffness.tolist() == [1e5] * 8    # EI_k = 1e5
    assert scene.hinge_stiffness.tolist() == [100.0] * 8    # kappa_k = 100, k = 0..7
    assert scene.hinge_damping.tolist() == [0.01] * 8       # nu_k = 0.01
    assert scene.phi0.tolist() == [0.0] * 8
    assert scene.phi_rate0.tolist() == [0.0] * 8
    assert scene.loads == (
        Load(node=8, axis="x", shape="raised_cosine_pulse", amplitude=-150.0, start=0.0, duration=0.5),
        Load(node=8, axis="y", shape="raised_cosine_pulse", amplitude=1200.0, start=0.0, duration=1.0),
    )


# F(t) = A (1/2 - 1/2 cos(2 pi (t - start) / duration)), worked by hand:
# X_8: A = -150, duration 0.5 (the paper's cos(4 pi t / T), T = 1); Y_8: A = 1200, duration 1.
PAPER_FORCES = [
    # t,     X_8,                      Y_8
    (0.0,    0.0,                      0.0),
    (0.125,  -75.0,                    1200 * (0.5 - 0.5 * math.sqrt(0.5))),  # cos(pi/2)=0; cos(pi/4)
    (0.25,   -150.0,                   600.0),                                 # cos(pi) = -1; cos(pi/2) = 0
    (0.5,    0.0,                      1200.0),                                # cos(2 pi) = 1; cos(pi) = -1
    (0.6,    0.0,                      1200 * (0.5 - 0.5 * math.cos(1.2 * math.pi))),
    (0.75,   0.0,                      600.0),
    (1.0,    0.0,                      0.0),
    (1.5,    0.0,                      0.0),
]


@pytest.mark.parametrize("t, x8, y8", PAPER_FORCES)
def test_paper_example_loads(t, x8, y8):
    scene = load_scene(CONFIG / "paper_example.yaml")
    forces = scene.scripted_forces(t)
    assert forces.shape == (8, 2)
    assert forces[7, 0] == pytest.approx(x8, abs=1e-9)
    assert forces[7, 1] == pytest.approx(y8, abs=1e-9)
    assert np.all(forces[:7] == 0.0)  # X_k = Y_k = 0 for k = 1..7


def test_small_chain_loads_quickly():
    scene = load_scene(CONFIG / "small_chain.yaml")
    assert scene.n == 3
    assert scene.loads and scene.loads[0].shape == "constant"
    assert scene.scripted_forces(0.0)[2, 1] == 0.0
    assert scene.scripted_forces(1.0)[2, 1] == scene.loads[0].amplitude


def test_node_params_file_names_a_loadable_scene():
    params = yaml.safe_load((CONFIG / "sim_node.params.yaml").read_text())
    p = params["/**"]["ros__parameters"]       # any namespace (issue 13)
    assert p["model"] in ("reduced", "full", "rigid")
    assert p["rate_hz"] > 0 and p["frame_id"] == "world"
    assert load_scene(CONFIG / p["scene_file"]).n == 8   # relative to the params file


# ----- round trip ---------------------------------------------------------------------------

ROUND_TRIP = {
    "paper": lambda: load_scene(CONFIG / "paper_example.yaml"),
    "small_chain": lambda: load_scene(CONFIG / "small_chain.yaml"),
    "awkward": lambda: Scene.from_dict({
        "name": "yes",  # a string that YAML 1.1 would read as a bool unless quoted
        "rods": {"count": 4, "length": [0.1, 1 / 3, 2.5e-7, 1e12],
                 "mass_per_length": [0, 1.1, 2.2, 3.3], "bending_stiffness": [1e-3, 7, 1e12, 0.5]},
        "nodes": {"mass": [0.0, 0.0, 0.0, 1e-9]},
        "hinges": {"stiffness": [0, 1, 2, 3], "damping": 0.0},
        "initial": {"phi": [math.pi, -math.pi / 7, 0.1, -0.0], "phi_rate": [1e-300, 0, 0, -5]},
        "loads": [
            {"node": 1, "axis": "x", "shape": "constant", "amplitude": -2.5, "start": 0.3},
            {"node": 4, "axis": "y", "shape": "step", "amplitude": 1e6, "start": 0.0,
             "duration": 0.1},
            {"node": 4, "axis": "y", "shape": "raised_cosine_pulse", "amplitude": 0.1,
             "start": 1.0, "duration": 0.7},
        ],
    }),
}


@pytest.mark.parametrize("make", ROUND_TRIP.values(), ids=ROUND_TRIP.keys())
def test_round_trip(tmp_path, make):
    scene = make()
    text = scene_to_yaml(scene)
    again = scene_from_yaml_text(text)
    scenes_equal(scene, again)
    assert scene_to_yaml(again) == text
    path = write(tmp_path, text, name="other_name.yaml")
    scenes_equal(scene, load_scene(path))  # the written name wins over the file name


def test_dump_is_resolved_and_safe():
    text = scene_to_yaml(load_scene(CONFIG / "small_chain.yaml"))
    data = yaml.safe_load(text)
    assert data["rods"]["mass_per_length"] == 2.0      # the same for every rod: written once
    assert data["initial"]["phi"] == [0.0, 0.1, 0.2]    # per-rod values spelled out
    assert "!!" not in text  # no Python-specific tags
    # a uniform 100000-rod chain stays small, and reads back the same
    big = load_scene(CONFIG / "small_chain.yaml").to_dict()
    big["rods"]["count"] = 100_000
    for section, key in (("rods", "length"), ("rods", "mass_per_length"),
                         ("rods", "bending_stiffness"), ("nodes", "mass"), ("hinges", "stiffness"),
                         ("hinges", "damping"), ("initial", "phi"), ("initial", "phi_rate")):
        big[section][key] = big[section][key][0]
    big["loads"] = []
    scene = Scene.from_dict(big)
    text = scene_to_yaml(scene)
    assert len(text) < 2000
    again = scene_from_yaml_text(text)
    assert again.n == 100_000 and np.array_equal(again.length, scene.length)
