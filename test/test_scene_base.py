"""Scenes on a spacecraft (SPEC section 8): base, chains, gravity, base and wheel loads, motion
profiles. Every rule and error of docs/interface.md section 1 for the new keys, the flattening
of chains into the per-rod arrays, exact round trips, and a scene without the new keys giving
the dictionary and YAML it gave before (literal expectations written out by hand below)."""
from __future__ import annotations

import copy
import math
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from rod_sim.core import scene as scene_module
from rod_sim.core.scene import (BaseSpec, ChainSpec, Load, MotionProfile, Scene, SceneError,
                                WheelSpec)
from rod_sim.io.scene_yaml import _SceneLoader, load_scene, scene_from_yaml_text, scene_to_yaml

REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / "config"
SPEC_EXAMPLE = Path(__file__).resolve().parent / "data" / "two_wings.yaml"   # SPEC section 8
PI = math.pi


def read_yaml(path: Path) -> dict:
    """Scene data as the scene loader reads it (YAML 1.2 floats such as 1.0e3)."""
    return yaml.load(path.read_text(encoding="utf-8"), Loader=_SceneLoader)


# ----- a scene without the new keys: exactly what it was (literal expectations) -----

LEGACY = {
    "name": "legacy",
    "rods": {"count": 2, "length": [1.0, 2.0], "mass_per_length": 3.0,
             "bending_stiffness": 1.0e4, "rigid": [False, True]},
    "nodes": {"mass": 0.5},
    "hinges": {"stiffness": 10.0, "damping": 0.1, "rest_angle": [0.0, 0.25],
               "locked": [True, False], "latch": [None, 0.75],
               "stop": {"angle": [None, [-1.0, 1.0]], "stiffness": 1.0e4}},
    "initial": {"phi": [0.0, 0.5]},
    "loads": [{"node": 2, "axis": "y", "shape": "step", "amplitude": 5.0, "duration": 1.0},
              {"node": 1, "axis": "x", "shape": "constant", "amplitude": -2.0, "start": 1.5}],
}

LEGACY_DICT = {
    "name": "legacy",
    "rods": {"count": 2, "length": [1.0, 2.0], "mass_per_length": [3.0, 3.0],
             "bending_stiffness": [10000.0, 10000.0], "rigid": [False, True]},
    "nodes": {"mass": [0.5, 0.5]},
    "hinges": {"stiffness": [10.0, 10.0], "damping": [0.1, 0.1], "rest_angle": [0.0, 0.25],
               "stop": {"angle": [None, [-1.0, 1.0]], "stiffness": [10000.0, 10000.0],
                        "damping": [0.0, 0.0]},
               "latch": [None, 0.75], "locked": [True, False]},
    "initial": {"phi": [0.0, 0.5], "phi_rate": [0.0, 0.0]},
    "loads": [{"node": 2, "axis": "y", "shape": "step", "amplitude": 5.0, "start": 0.0,
               "duration": 1.0},
              {"node": 1, "axis": "x", "shape": "constant", "amplitude": -2.0, "start": 1.5}],
}

LEGACY_YAML = """\
# rod_sim scene (resolved; a scalar applies to every rod, node or hinge; SI units)
name: legacy
rods:
  count: 2
  length: [1.0, 2.0]
  mass_per_length: 3.0
  bending_stiffness: 10000.0
  rigid: [false, true]
nodes: {mass: 0.5}
hinges:
  stiffness: 10.0
  damping: 0.1
  rest_angle: [0.0, 0.25]
  stop:
    angle:
    - null
    - [-1.0, 1.0]
    stiffness: 10000.0
    damping: 0.0
  latch: [null, 0.75]
  locked: [true, false]
initial:
  phi: [0.0, 0.5]
  phi_rate: 0.0
loads:
- {node: 2, axis: y, shape: step, amplitude: 5.0, start: 0.0, duration: 1.0}
- {node: 1, axis: x, shape: constant, amplitude: -2.0, start: 1.5}
"""

PLAIN_YAML = """\
# rod_sim scene (resolved; a scalar applies to every rod, node or hinge; SI units)
name: plain
rods: {count: 3, length: 2.0, mass_per_length: 3.0, bending_stiffness: 100000.0}
nodes: {mass: 3.0}
hinges: {stiffness: 100.0, damping: 0.01}
initial: {phi: 0.0, phi_rate: 0.0}
"""


def test_legacy_scene_dictionary_and_yaml_are_unchanged():
    sc = Scene.from_dict(LEGACY)
    out = sc.to_dict()
    assert out == LEGACY_DICT
    assert list(out) == list(LEGACY_DICT)
    for section in ("rods", "hinges"):
        assert list(out[section]) == list(LEGACY_DICT[section])
    assert [list(ld) for ld in out["loads"]] == [list(ld) for ld in LEGACY_DICT["loads"]]
    assert scene_to_yaml(sc) == LEGACY_YAML
    plain = Scene.from_dict({"name": "plain", "rods": {"count": 3, "length": 2.0,
                                                       "mass_per_length": 3.0,
                                                       "bending_stiffness": 1e5},
                             "nodes": {"mass": 3.0},
                             "hinges": {"stiffness": 100.0, "damping": 0.01}})
    assert scene_to_yaml(plain) == PLAIN_YAML


def test_legacy_scene_is_one_unnamed_chain_on_the_fixed_base():
    sc = Scene.from_dict(LEGACY)
    assert sc.chains == (ChainSpec(None, 0, 2, (0.0, 0.0)),)
    assert not sc.has_chains and not sc.has_base and sc.gravity is None
    assert sc.base == BaseSpec(mode="fixed") and sc.base.mode == "fixed"
    assert (sc.base.x, sc.base.y, sc.base.psi) == (0.0, 0.0, 0.0)
    assert sc.chain_starts.dtype == np.int64 and sc.chain_starts.tolist() == [0, 2]
    assert sc.chain_slices() == [slice(0, 2)]
    assert sc.chain_of_rod.dtype == np.int64 and sc.chain_of_rod.tolist() == [0, 0]
    assert all(ld.chain == 0 for ld in sc.loads)
    assert [ld.row(sc) for ld in sc.loads] == [1, 0]
    assert [ld.column for ld in sc.loads] == [1, 0]
    # built directly, without the parser: the same defaults
    direct = Scene(name="d", length=[1.0], mass_per_length=[1.0], bending_stiffness=[1.0],
                   node_mass=[0.0], hinge_stiffness=[0.0], hinge_damping=[0.0], phi0=[0.0],
                   phi_rate0=[0.0])
    assert direct.chains == (ChainSpec(None, 0, 1, (0.0, 0.0)),) and not direct.has_base


def test_legacy_scene_with_base_or_gravity_writes_them_and_round_trips():
    data = copy.deepcopy(LEGACY)
    data["base"] = {"mode": "fixed"}
    sc = Scene.from_dict(data)
    assert sc.has_base and not sc.has_chains
    out = sc.to_dict()
    assert out["base"] == {"mode": "fixed", "centre_of_mass": [0.0, 0.0],
                           "initial": {"x": 0.0, "y": 0.0, "psi": 0.0, "x_rate": 0.0,
                                       "y_rate": 0.0, "psi_rate": 0.0}}
    assert {k: v for k, v in out.items() if k != "base"} == LEGACY_DICT
    data["gravity"] = [0.0, -9.81]
    sc = Scene.from_dict(data)
    assert sc.gravity == (0.0, -9.81) and sc.to_dict()["gravity"] == [0.0, -9.81]
    assert_round_trip(sc)


# ----- the example of SPEC section 8 -----

def test_spec_example_loads_flattened():
    sc = load_scene(SPEC_EXAMPLE)
    assert sc.name == "two_wings" and sc.n == 8 and sc.has_chains and sc.has_base
    assert sc.chains == (ChainSpec("left", 0, 4, (1.0, 0.0)), ChainSpec("right", 4, 4, (-1.0, 0.0)))
    assert sc.chain_starts.tolist() == [0, 4, 8]
    assert sc.chain_slices() == [slice(0, 4), slice(4, 8)]
    assert sc.chain_of_rod.tolist() == [0, 0, 0, 0, 1, 1, 1, 1]
    assert sc.chain_root.tolist() == [True, False, False, False, True, False, False, False]
    np.testing.assert_array_equal(sc.phi0, [0.0] * 4 + [3.141592653589793] * 4)
    np.testing.assert_array_equal(sc.length, np.full(8, 1.5))
    np.testing.assert_array_equal(sc.hinge_damping, np.full(8, 0.2))
    base = sc.base
    assert (base.mode, base.mass, base.inertia, base.centre_of_mass) == ("free", 750.0, 900.0,
                                                                          (0.0, 0.0))
    assert base.wheel == WheelSpec(0.05, 0.0) and dict(base.motion) == {}
    assert sc.gravity is None
    left, base_moment, wheel = sc.loads
    assert (left.chain, left.node, left.row(sc), left.column) == (0, 4, 3, 1)
    assert (base_moment.node, base_moment.row(sc), base_moment.column) == ("base", 8, 2)
    assert (wheel.node, wheel.row(sc), wheel.column) == ("wheel", 9, 2)
    table = sc.scripted_load_table(1.2)
    expected = np.zeros((10, 3))
    expected[8, 2] = 100.0                      # base moment step on [1, 1.5)
    np.testing.assert_array_equal(table, expected)
    table = sc.scripted_load_table(2.0)
    expected = np.zeros((10, 3))
    expected[9, 2] = 0.5                        # wheel torque from 2 s on
    np.testing.assert_array_equal(table, expected)
    forces = sc.scripted_forces(0.05)           # chain nodes only
    assert forces.shape == (8, 2) and forces[3, 1] == 10.0 and np.count_nonzero(forces) == 1
    assert_round_trip(sc)


def assert_round_trip(sc: Scene) -> None:
    """Scene.from_dict(to_dict) and the YAML text give the scene back exactly."""
    for back in (Scene.from_dict(sc.to_dict()), scene_from_yaml_text(scene_to_yaml(sc))):
        assert back.to_dict() == sc.to_dict()
        for name in sc.__dataclass_fields__:
            a, b = getattr(sc, name), getattr(back, name)
            if isinstance(a, np.ndarray):
                np.testing.assert_array_equal(a, b, err_msg=name)
            else:
                assert a == b, name
        assert back.has_base == sc.has_base and back.has_chains == sc.has_chains


# ----- flattening -----

TWO = {
    "name": "two",
    "base": {"mode": "free", "mass": 10.0, "inertia": 2.0, "centre_of_mass": [0.1, -0.2],
             "initial": {"x": 1.0, "psi": 0.3, "psi_rate": 0.5}},
    "gravity": [0.0, -9.81],
    "chains": [
        {"name": "a", "attach": [0.5, 0.25],
         "rods": {"count": 2, "length": [1.0, 2.0], "mass_per_length": 1.0,
                  "bending_stiffness": 1e3},
         "nodes": {"mass": [0.1, 0.2]},
         "hinges": {"stiffness": 5.0, "damping": 0.5}},
        {"name": "b_2", "attach": [-0.5, 0.0],
         "rods": {"count": 3, "length": [3.0, 4.0, 5.0], "mass_per_length": 2.0,
                  "bending_stiffness": 2e3, "rigid": [False, True, False]},
         "nodes": {"mass": 0.0},
         "hinges": {"stiffness": [6.0, 7.0, 8.0], "damping": 0.0, "rest_angle": [0.0, 0.1, 0.2],
                    "locked": [False, False, True], "latch": [None, 0.4, None],
                    "stop": {"angle": [[-1.0, 1.0], None, [-2.0, 2.0]], "stiffness": 1e4,
                             "damping": 3.0}},
         "initial": {"phi": [1.0, 1.2, 1.5], "phi_rate": [0.5, 0.5, 0.5]}},
    ],
    "loads": [{"chain": "b_2", "node": 3, "axis": "x", "shape": "constant", "amplitude": 1.0},
              {"chain": "a", "node": 1, "axis": "y", "shape": "step", "amplitude": 2.0,
               "duration": 1.0},
              {"node": "base", "axis": "y", "shape": "constant", "amplitude": 3.0}],
}


def test_chains_are_concatenated_in_scene_order():
    sc = Scene.from_dict(TWO)
    assert sc.n == 5 and sc.chain_starts.tolist() == [0, 2, 5]
    assert sc.chains[1] == ChainSpec("b_2", 2, 3, (-0.5, 0.0))
    assert sc.chain_of_rod.tolist() == [0, 0, 1, 1, 1]
    np.testing.assert_array_equal(sc.length, [1.0, 2.0, 3.0, 4.0, 5.0])
    np.testing.assert_array_equal(sc.mass_per_length, [1.0, 1.0, 2.0, 2.0, 2.0])
    np.testing.assert_array_equal(sc.node_mass, [0.1, 0.2, 0.0, 0.0, 0.0])
    np.testing.assert_array_equal(sc.hinge_stiffness, [5.0, 5.0, 6.0, 7.0, 8.0])
    np.testing.assert_array_equal(sc.phi0, [0.0, 0.0, 1.0, 1.2, 1.5])
    np.testing.assert_array_equal(sc.phi_rate0, [0.0, 0.0, 0.5, 0.5, 0.5])
    # features: chain a has none (defaults), chain b its own
    np.testing.assert_array_equal(sc.hinge_rest_angle, [0.0, 0.0, 0.0, 0.1, 0.2])
    np.testing.assert_array_equal(sc.hinge_locked, [False, False, False, False, True])
    np.testing.assert_array_equal(sc.rod_rigid, [False, False, False, True, False])
    np.testing.assert_array_equal(sc.stop_lower, [-np.inf, -np.inf, -1.0, -np.inf, -2.0])
    np.testing.assert_array_equal(sc.stop_upper, [np.inf, np.inf, 1.0, np.inf, 2.0])
    np.testing.assert_array_equal(sc.stop_stiffness, [0.0, 0.0, 1e4, 1e4, 1e4])
    np.testing.assert_array_equal(sc.stop_damping, [0.0, 0.0, 3.0, 3.0, 3.0])
    np.testing.assert_array_equal(np.isnan(sc.latch_angle), [True, True, True, False, True])
    assert sc.latch_angle[3] == 0.4
    # hinge angles: each chain's hinge 0 against the base's initial psi (0.3)
    np.testing.assert_allclose(sc.initial_hinge_angles(), [-0.3, 0.0, 0.7, 0.2, 0.3],
                               rtol=0, atol=1e-15)
    assert [(ld.chain, ld.row(sc), ld.column) for ld in sc.loads] == [(1, 4, 0), (0, 0, 1),
                                                                     (0, 5, 1)]
    assert sc.gravity == (0.0, -9.81)
    base = sc.base
    assert (base.x, base.y, base.psi, base.x_rate, base.y_rate, base.psi_rate) == (
        1.0, 0.0, 0.3, 0.0, 0.0, 0.5)
    assert base.centre_of_mass == (0.1, -0.2) and base.wheel is None
    assert_round_trip(sc)


def test_chain_dictionary_spells_out_each_chain():
    out = Scene.from_dict(TWO).to_dict()
    assert list(out) == ["name", "base", "gravity", "chains", "loads"]
    a, b = out["chains"]
    assert a == {"name": "a", "attach": [0.5, 0.25],
                 "rods": {"count": 2, "length": [1.0, 2.0], "mass_per_length": [1.0, 1.0],
                          "bending_stiffness": [1000.0, 1000.0]},
                 "nodes": {"mass": [0.1, 0.2]},
                 "hinges": {"stiffness": [5.0, 5.0], "damping": [0.5, 0.5]},
                 "initial": {"phi": [0.0, 0.0], "phi_rate": [0.0, 0.0]}}
    assert b["rods"]["rigid"] == [False, True, False]
    assert b["hinges"]["stop"] == {"angle": [[-1.0, 1.0], None, [-2.0, 2.0]],
                                   "stiffness": [1e4, 1e4, 1e4], "damping": [3.0, 3.0, 3.0]}
    assert b["hinges"]["latch"] == [None, 0.4, None]
    assert b["hinges"]["locked"] == [False, False, True]
    assert out["loads"] == [
        {"chain": "b_2", "node": 3, "axis": "x", "shape": "constant", "amplitude": 1.0,
         "start": 0.0},
        {"chain": "a", "node": 1, "axis": "y", "shape": "step", "amplitude": 2.0, "start": 0.0,
         "duration": 1.0},
        {"node": "base", "axis": "y", "shape": "constant", "amplitude": 3.0, "start": 0.0}]
    assert out["base"] == {"mode": "free", "mass": 10.0, "inertia": 2.0,
                           "centre_of_mass": [0.1, -0.2],
                           "initial": {"x": 1.0, "y": 0.0, "psi": 0.3, "x_rate": 0.0,
                                       "y_rate": 0.0, "psi_rate": 0.5}}


def test_one_chain_needs_no_chain_in_its_loads_and_defaults():
    data = {"chains": [{"name": "only", "rods": {"count": 3, "length": 1.0,
                                                  "mass_per_length": 1.0,
                                                  "bending_stiffness": 1.0},
                        "nodes": {"mass": 1.0}, "hinges": {"stiffness": 1.0, "damping": 0.0}}],
            "loads": [{"node": 3, "axis": "x", "shape": "constant", "amplitude": 1.0}]}
    sc = Scene.from_dict(data)
    assert sc.name == "scene" and sc.chains == (ChainSpec("only", 0, 3, (0.0, 0.0)),)
    assert sc.has_chains and not sc.has_base and sc.base.mode == "fixed"
    assert sc.loads[0].chain == 0 and sc.loads[0].row(sc) == 2
    assert sc.to_dict()["loads"][0]["chain"] == "only"      # written explicitly
    assert_round_trip(sc)


def test_prescribed_base_round_trips_and_evaluates_its_pose():
    data = copy.deepcopy(TWO)
    data["base"] = {"mode": "prescribed", "initial": {"psi": 0.3, "x": 2.0},
                    "motion": {"x": {"shape": "cycloidal", "amplitude": 1.5, "duration": 2.0,
                                     "start": 1.0},
                               "psi": {"shape": "spin_up", "rate": 6.0, "duration": 15.0}}}
    data["loads"] = data["loads"][:2]
    sc = Scene.from_dict(data)
    base = sc.base
    assert list(base.motion) == ["psi", "x"]            # psi, x, y order
    assert base.motion["psi"] == MotionProfile("spin_up", rate=6.0, duration=15.0)
    assert math.isnan(base.mass) and math.isnan(base.inertia)
    assert sc.motion_breakpoints() == (0.0, 1.0, 3.0, 15.0)
    q, dq, ddq = base.pose(2.0)               # x: half-way through the cycloidal move
    assert q[0] == pytest.approx(2.0 + 0.75, abs=1e-15) and q[1] == 0.0
    assert dq[0] == pytest.approx(2 * 1.5 / 2.0, rel=1e-15) and ddq[0] == pytest.approx(0, abs=1e-14)
    # psi at 7.5 s = T/2 of the spin-up: 0.3 + r T (1/8 - 1/(2 pi^2)), rate r/2, acc 2 r/T
    q, dq, ddq = base.pose(7.5)
    assert q[:2] == (2.0 + 1.5, 0.0) and dq[:2] == (0.0, 0.0)
    assert q[2] == pytest.approx(0.3 + 6.0 * 15.0 * (1 / 8 - 1 / (2 * PI ** 2)), rel=1e-14)
    assert dq[2] == pytest.approx(3.0, rel=1e-14) and ddq[2] == pytest.approx(0.8, rel=1e-14)
    assert sc.to_dict()["base"]["motion"] == {
        "psi": {"shape": "spin_up", "rate": 6.0, "duration": 15.0, "start": 0.0},
        "x": {"shape": "cycloidal", "amplitude": 1.5, "duration": 2.0, "start": 1.0}}
    assert_round_trip(sc)


# ----- errors: one line, keyed by the entry -----

def _two(path: str, value):
    """TWO with the entry at ``path`` (``chains[1].name``, ``base.mode``) set (``...`` removes it)."""
    data = copy.deepcopy(TWO)
    *parents, last = re.findall(r"[^.\[\]]+", path)
    target = data
    for part in parents:
        target = target[int(part)] if part.isdigit() else target[part]
    key = int(last) if last.isdigit() else last
    if value is ...:
        del target[key]
    else:
        target[key] = value
    return data


BAD = [
    ("base.mode", "floating", "base.mode", r"must be one of fixed, free, prescribed \(got 'floating'\)"),
    ("base.mode", ..., "base.mode", r"missing \(one of fixed, free, prescribed\)"),
    ("base.mass", ..., "base.mass", r"missing \(a free base needs its mass"),
    ("base.inertia", ..., "base.inertia", r"missing \(a free base needs its inertia"),
    ("base.mass", 0.0, "base.mass", r"must be > 0"),
    ("base.inertia", -1.0, "base.inertia", r"must be > 0"),
    ("base.mass", math.nan, "base.mass", r"must be finite"),
    ("base.centre_of_mass", [math.inf, 0.0], "base.centre_of_mass", r"must be finite at index 0"),
    ("base.centre_of_mass", [0.0, 2e12], "base.centre_of_mass", r"magnitude must be <= 1e\+12"),
    ("base.centre_of_mass", 0.0, "base.centre_of_mass", r"must be a pair \[x, y\]"),
    ("base.initial.psi", math.nan, "base.initial.psi", r"must be finite"),
    ("base.initial.z", 1.0, "base.initial.z", r"unknown key"),
    ("base.colour", 1.0, "base.colour", r"unknown key"),
    ("base.wheel", {"inertia": 0.0}, "base.wheel.inertia", r"must be > 0"),
    ("base.wheel", {"rate": 1.0}, "base.wheel.inertia", r"missing"),
    ("base.wheel", {"inertia": 1.0, "spin": 1.0}, "base.wheel.spin", r"unknown key"),
    ("base.motion", {"psi": {"shape": "spin_up", "rate": 1.0, "duration": 1.0}}, "base.motion",
     r"only a prescribed base has a motion \(the mode is free\)"),
    ("gravity", [0.0, math.nan], "gravity", r"must be finite at index 1"),
    ("gravity", [0.0, 1e13], "gravity", r"magnitude must be <= 1e\+12 at index 1"),
    ("gravity", [0.0, -9.81, 0.0], "gravity", r"must be a pair"),
    ("gravity", "down", "gravity", r"must be a pair"),
    ("chains", [], "chains", r"must be a non-empty list of chains"),
    ("chains", {"name": "a"}, "chains", r"must be a non-empty list of chains"),
    ("chains[1].name", "a", "chains[1].name", r"duplicate chain name 'a' \(also chains\[0\]\)"),
    ("chains[1].name", "2b", "chains[1].name", r"must match \[A-Za-z\]\[A-Za-z0-9_\]\*"),
    ("chains[1].name", "left/wing", "chains[1].name", r"must match"),
    ("chains[1].name", "x" * 65, "chains[1].name", r"must match .* with at most 64 characters"),
    ("chains[1].name", "", "chains[1].name", r"must match"),
    ("chains[1].name", 7, "chains[1].name", r"must match"),
    ("chains[1].name", ..., "chains[1].name", r"missing"),
    ("chains[0].attach", [math.nan, 0.0], "chains[0].attach", r"must be finite at index 0"),
    ("chains[0].attach", [0.0, math.inf], "chains[0].attach", r"must be finite at index 1"),
    ("chains[0].attach", [2e12, 0.0], "chains[0].attach", r"magnitude must be <= 1e\+12"),
    ("chains[0].attach", [1.0], "chains[0].attach", r"must be a pair"),
    ("chains[0].colour", 1, "chains[0].colour", r"unknown key"),
    ("chains[0].rods.count", 0, "chains[0].rods.count", r"must be a whole number"),
    ("chains[1].rods.length", [1.0, 2.0], "chains[1].rods.length", r"expected a scalar or a list of 3"),
    ("chains[1].hinges", ..., "chains[1].hinges", r"missing section"),
    ("chains[1].rods.mass_per_length", 0.0, "chains[1].nodes.mass",
     r"the chain has no inertia: rod 3 and node 3 are both massless"),
    ("chains[1].hinges.stop.angle", [[-0.1, 0.1], None, None], "chains[1].hinges.stop.angle",
     r"hinge 0: the initial hinge angle 0.7 rad lies outside its stops \[-0.1, 0.1\]"),
    ("chains[1].hinges.latch", [None, None, 3.0], "chains[1].hinges.latch",
     r"hinge 2: the latch angle 3 rad lies outside its stops \[-2, 2\], so it can never latch"),
    ("loads[0].chain", "c", "loads[0].chain", r"unknown chain 'c' \(chains: a, b_2\)"),
    ("loads[0].chain", ..., "loads[0].chain", r"missing: the scene has 2 chains \(a, b_2\)"),
    ("loads[0].node", 4, "loads[0].node", r"must be a node number 1..3 of chain b_2 \(got 4\)"),
    ("loads[0].node", 0, "loads[0].node", r"must be a node number 1..3"),
    ("loads[0].node", "hub", "loads[0].node", r"must be a node number 1..3 of chain b_2, 'base' or 'wheel' \(got 'hub'\)"),
    ("loads[1].axis", "moment", "loads[1].axis", r"must be 'x' or 'y'"),
    ("loads[2].axis", "z", "loads[2].axis", r"must be x, y or moment for a base load"),
    ("loads[2].chain", "a", "loads[2].chain", r"not allowed in a base load"),
    ("loads[2].node", "wheel", "loads[2].node", r"a wheel load needs base.wheel"),
]


@pytest.mark.parametrize("path, value, key, match", BAD, ids=[f"{b[0]}={b[1]!r:.20}" for b in BAD])
def test_bad_entry_is_refused_with_its_key(path, value, key, match):
    with pytest.raises(SceneError, match=re.escape(key) + ": " + (match or "")) as err:
        Scene.from_dict(_two(path, value))
    assert err.value.key == key and "\n" not in str(err.value)


def test_top_level_chain_sections_beside_chains_are_refused():
    for section in ("rods", "nodes", "hinges", "initial"):
        data = copy.deepcopy(TWO)
        data[section] = {}
        with pytest.raises(SceneError, match=rf"^{section}: not allowed beside chains:"):
            Scene.from_dict(data)


def test_mode_rules():
    base = copy.deepcopy(TWO["base"])
    fixed = dict(base, mode="fixed")
    with pytest.raises(SceneError, match=r"^base.initial.psi_rate: must be 0 for a fixed base"):
        Scene.from_dict(_two("base", fixed))
    del fixed["initial"]["psi_rate"]
    with pytest.raises(SceneError, match=r"^loads\[2\].node: a base load needs a free base "
                                         r"\(a fixed base absorbs it\)"):
        Scene.from_dict(_two("base", fixed))
    sc = Scene.from_dict(dict(_two("base", fixed), loads=TWO["loads"][:2]))
    assert sc.base.mass == 10.0 and sc.base.inertia == 2.0    # optional, kept
    with pytest.raises(SceneError, match=r"^base.wheel: only a free base has a wheel \(the mode "
                                         r"is fixed\)"):
        Scene.from_dict(_two("base", dict(fixed, wheel={"inertia": 1.0})))
    prescribed = {"mode": "prescribed", "initial": {"psi_rate": 1.0},
                  "motion": {"psi": {"shape": "hold"}}}
    with pytest.raises(SceneError, match=r"^base.initial.psi_rate: must be 0 for a prescribed "
                                         r"base: the rates of a prescribed base come from"):
        Scene.from_dict(_two("base", prescribed))
    with pytest.raises(SceneError, match=r"^base.motion: missing \(a prescribed base needs a "
                                         r"motion for psi, x or y\)"):
        Scene.from_dict(_two("base", {"mode": "prescribed"}))
    with pytest.raises(SceneError, match=r"^base.motion.z: unknown key \(allowed: psi, x, y\)"):
        Scene.from_dict(_two("base", {"mode": "prescribed", "motion": {"z": {"shape": "hold"}}}))
    with pytest.raises(SceneError, match=r"^base.wheel: only a free base has a wheel \(the mode "
                                         r"is prescribed\)"):
        Scene.from_dict(_two("base", {"mode": "prescribed", "motion": {"x": {"shape": "hold"}},
                                      "wheel": {"inertia": 1.0}}))
    with pytest.raises(SceneError, match=r"^loads\[2\].node: a base load needs a free base \(a "
                                         r"prescribed base absorbs it\)"):
        Scene.from_dict(_two("base", {"mode": "prescribed", "motion": {"x": {"shape": "hold"}}}))
    with pytest.raises(SceneError, match=r"^base: must be a mapping"):
        Scene.from_dict(_two("base", None))


def test_wheel_loads():
    data = _two("base.wheel", {"inertia": 0.05, "rate": 2.0})
    data["loads"].append({"node": "wheel", "axis": "moment", "shape": "step", "amplitude": 0.5,
                          "start": 1.0, "duration": 2.0})
    sc = Scene.from_dict(data)
    assert sc.base.wheel == WheelSpec(0.05, 2.0)
    assert sc.loads[3].row(sc) == 6 and sc.loads[3].column == 2
    assert sc.scripted_load_table(1.5)[6].tolist() == [0.0, 0.0, 0.5]
    assert_round_trip(sc)
    data["loads"][3]["axis"] = "x"
    with pytest.raises(SceneError, match=r"^loads\[3\].axis: must be moment for a wheel load"):
        Scene.from_dict(data)


def test_loads_on_legacy_scene_name_no_chain_and_no_base():
    data = copy.deepcopy(LEGACY)
    data["loads"][0]["chain"] = "a"
    with pytest.raises(SceneError, match=r"^loads\[0\].chain: unknown chain 'a' \(the scene has "
                                         r"no chains: list\)"):
        Scene.from_dict(data)
    data = copy.deepcopy(LEGACY)
    data["loads"][0]["node"] = "base"
    with pytest.raises(SceneError, match=r"^loads\[0\].node: a base load needs a free base"):
        Scene.from_dict(data)
    data["base"] = {"mode": "free", "mass": 1.0, "inertia": 1.0}
    data["loads"][0]["axis"] = "moment"
    sc = Scene.from_dict(data)                       # a legacy chain on a free base
    assert sc.loads[0].row(sc) == 2 and sc.has_base and not sc.has_chains
    assert_round_trip(sc)


def test_total_rod_count_is_limited(monkeypatch):
    monkeypatch.setattr(scene_module, "MAX_RODS", 4)
    with pytest.raises(SceneError, match=r"^chains\[1\].rods.count: the chains have 5 rods up to "
                                         r"this one; at most 4 in all"):
        Scene.from_dict(TWO)


def test_initial_hinge_angle_check_measures_hinge_0_against_base_psi():
    data = _two("chains[1].hinges.stop", {"angle": [[-0.1, 0.1], None, [-2.0, 2.0]],
                                          "stiffness": 1e4})
    data["chains"][1]["initial"]["phi"] = [1.0, 1.0, 1.0]
    with pytest.raises(SceneError, match=r"^chains\[1\].hinges.stop.angle: hinge 0: the initial "
                                         r"hinge angle 0.7 rad"):
        Scene.from_dict(data)                    # phi_1 - psi_0 = 1.0 - 0.3
    data["base"]["initial"]["psi"] = 0.95
    sc = Scene.from_dict(data)                   # 0.05: inside
    assert sc.initial_hinge_angles()[2] == pytest.approx(0.05, abs=1e-15)


def test_direct_construction_is_checked():
    sc = Scene.from_dict(TWO)
    with pytest.raises(SceneError, match=r"^chains: the chains have 4 rods, the arrays 5"):
        sc.with_changes(chains=(ChainSpec("a", 0, 2), ChainSpec("b", 2, 2)))
    with pytest.raises(SceneError, match=r"^chains\[1\]: must start at rod index 2"):
        sc.with_changes(chains=(ChainSpec("a", 0, 2), ChainSpec("b", 1, 3)))
    with pytest.raises(SceneError, match=r"^chains: only a scene's single chain may be unnamed"):
        sc.with_changes(chains=(ChainSpec(None, 0, 2), ChainSpec("b", 2, 3)))
    with pytest.raises(SceneError, match=r"^chains\[0\].attach: must be finite"):
        sc.with_changes(chains=(ChainSpec("a", 0, 2, (math.nan, 0.0)), ChainSpec("b", 2, 3)))
    with pytest.raises(SceneError, match=r"^loads\[0\]: chain 1, node 4"):
        sc.with_changes(loads=(Load(node=4, axis="x", shape="constant", amplitude=1.0, chain=1),))
    with pytest.raises(SceneError, match=r"^loads\[0\]: a wheel load needs base.wheel"):
        sc.with_changes(loads=(Load(node="wheel", axis="moment", shape="constant", amplitude=1.0),))
    with pytest.raises(SceneError, match=r"^gravity: must be finite"):
        sc.with_changes(gravity=(0.0, math.inf))
    with pytest.raises(SceneError, match=r"^base.mass: missing"):
        BaseSpec(mode="free", inertia=1.0)
    with pytest.raises(SceneError, match=r"^base.motion: only a prescribed base"):
        BaseSpec(mode="fixed", motion={"psi": MotionProfile("hold")})
    with pytest.raises(SceneError, match=r"^inertia: must be > 0"):
        WheelSpec(inertia=0.0)


# ----- motion profiles: closed forms, derivatives, continuity, refusals -----

def spin_up_oracle(t, r, big_t, t0=0.0):
    """The spin-up profile written out from its definition (rate ramp, integrated by hand)."""
    tau = t - t0
    if tau <= 0:
        return 0.0, 0.0, 0.0
    if tau < big_t:
        w = 2 * PI / big_t
        return ((r / big_t) * (tau ** 2 / 2 + (math.cos(w * tau) - 1) / w ** 2),
                (r / big_t) * (tau - math.sin(w * tau) / w),
                (r / big_t) * (1 - math.cos(w * tau)))
    return r * big_t / 2 + r * (tau - big_t), r, 0.0


PROFILES = [MotionProfile("spin_up", rate=6.0, duration=15.0),
            MotionProfile("spin_up", rate=-0.4, duration=2.0, start=0.5),
            MotionProfile("cycloidal", amplitude=1.5, duration=2.0, start=1.0),
            MotionProfile("harmonic", amplitude=0.2, frequency=0.5, start=0.25),
            MotionProfile("hold")]


def test_spin_up_matches_its_closed_form():
    p = MotionProfile("spin_up", rate=6.0, duration=15.0)
    for t in (-1.0, 0.0, 1.0, 3.75, 7.5, 14.9, 15.0, 20.0):
        np.testing.assert_allclose(p.evaluate(t), spin_up_oracle(t, 6.0, 15.0), rtol=1e-12,
                                   atol=1e-12, err_msg=str(t))
    v, r, a = p.evaluate(7.5)                  # tau = T/2
    assert v == pytest.approx(6.0 * 15.0 * (1 / 8 - 1 / (2 * PI ** 2)), rel=1e-14)
    assert r == pytest.approx(3.0, rel=1e-14) and a == pytest.approx(2 * 6.0 / 15.0, rel=1e-14)
    v, r, a = p.evaluate(3.75)                 # tau = T/4: (r/T)(T/4 - T/(2 pi)), r/T
    assert r == pytest.approx(6.0 * (1 / 4 - 1 / (2 * PI)), rel=1e-14)
    assert a == pytest.approx(6.0 / 15.0, rel=1e-14)
    assert p.evaluate(15.0) == (45.0, 6.0, 0.0) and p.evaluate(25.0) == (105.0, 6.0, 0.0)
    assert p.breakpoints() == (0.0, 15.0)
    assert MotionProfile("spin_up", rate=1.0, duration=2.0, start=0.5).breakpoints() == (0.5, 2.5)


def test_cycloidal_and_harmonic_match_their_closed_forms():
    p = MotionProfile("cycloidal", amplitude=1.5, duration=2.0, start=1.0)
    assert p.evaluate(0.5) == (0.0, 0.0, 0.0)
    v, r, a = p.evaluate(2.0)                  # tau = T/2: D/2, 2 D/T, 0
    assert (v, r) == (pytest.approx(0.75, rel=1e-15), pytest.approx(1.5, rel=1e-15))
    assert a == pytest.approx(0.0, abs=1e-15)
    v, r, a = p.evaluate(1.5)                  # tau = T/4: D (1/4 - 1/(2 pi)), D/T, (D/T)(2 pi/T)
    assert v == pytest.approx(1.5 * (0.25 - 1 / (2 * PI)), rel=1e-14)
    assert r == pytest.approx(0.75, rel=1e-14) and a == pytest.approx(0.75 * PI, rel=1e-14)
    assert p.evaluate(3.0) == (1.5, 0.0, 0.0) and p.evaluate(9.0) == (1.5, 0.0, 0.0)
    assert p.breakpoints() == (1.0, 3.0)
    h = MotionProfile("harmonic", amplitude=0.2, frequency=0.5, start=0.25)
    v, r, a = h.evaluate(0.25 + 0.5)           # a quarter period: A, 2 pi f A, 0
    assert v == pytest.approx(0.2, rel=1e-15) and r == pytest.approx(PI * 0.2, rel=1e-15)
    assert a == pytest.approx(0.0, abs=1e-15)
    v, r, a = h.evaluate(0.25 + 1.0)           # half a period: 2 A, 0, -(2 pi f)^2 A
    assert v == pytest.approx(0.4, rel=1e-15) and r == pytest.approx(0.0, abs=1e-15)
    assert a == pytest.approx(-PI ** 2 * 0.2, rel=1e-14)
    assert h.breakpoints() == (0.25,)
    hold = MotionProfile("hold")
    assert hold.evaluate(3.0) == (0.0, 0.0, 0.0) and hold.breakpoints() == ()


@pytest.mark.parametrize("p", PROFILES, ids=[p.shape for p in PROFILES])
def test_rate_and_acceleration_are_the_derivatives(p):
    h = 1e-5
    for t in np.linspace(-0.5, 18.0, 157):
        if any(abs(t - b) < 2 * h for b in p.breakpoints()):
            continue
        v_lo, r_lo, _ = p.evaluate(t - h)
        v_hi, r_hi, _ = p.evaluate(t + h)
        _, r, a = p.evaluate(t)
        scale = 1.0 + abs(r) + abs(a)
        assert (v_hi - v_lo) / (2 * h) == pytest.approx(r, abs=1e-7 * scale), t
        assert (r_hi - r_lo) / (2 * h) == pytest.approx(a, abs=1e-6 * scale), t


@pytest.mark.parametrize("p", PROFILES[:3], ids=[p.shape for p in PROFILES[:3]])
def test_value_rate_and_acceleration_are_continuous_at_breakpoints(p):
    eps = 1e-9
    for b in p.breakpoints():
        before, after = p.evaluate(b - eps), p.evaluate(b + eps)
        for x, y in zip(before, after):
            assert abs(x - y) < 1e-7, (b, before, after)


def test_harmonic_jumps_only_in_its_acceleration_at_its_breakpoint():
    p = MotionProfile("harmonic", amplitude=0.2, frequency=0.5, start=0.25)
    before, after = p.evaluate(0.25 - 1e-9), p.evaluate(0.25 + 1e-9)
    assert abs(before[0] - after[0]) < 1e-12 and abs(before[1] - after[1]) < 1e-8
    assert after[2] == pytest.approx(PI ** 2 * 0.2, rel=1e-6) and before[2] == 0.0


MOTION_BAD = [
    ({"shape": "sine", "amplitude": 1.0, "frequency": 1.0}, "shape",
     r"'sine' is not smooth enough for the integrator: its rate jumps at start"),
    ({"shape": "step", "amplitude": 1.0}, "shape", r"'step' is not smooth enough for the integrator"),
    ({"shape": "constant", "amplitude": 1.0}, "shape", r"'constant' is not smooth enough.*its value jumps"),
    ({"shape": "ramp", "rate": 1.0}, "shape", r"'ramp' is not smooth enough.*use spin_up"),
    ({"shape": "spin_up", "rate": 6.0, "duration": 0.0}, "duration",
     r"must be > 0 \(got 0\): a zero duration makes the rate jump, not smooth enough for the "
     r"integrator"),
    ({"shape": "cycloidal", "amplitude": 1.0, "duration": -1.0}, "duration",
     r"must be > 0 \(got -1\).*not smooth enough"),
    ({"shape": "spin_up", "rate": 6.0, "duration": 1e-13}, "duration", r"must be >= 1e-12"),
    ({"shape": "spin_up", "duration": 15.0}, "rate", r"missing \(shape spin_up needs rate, duration\)"),
    ({"shape": "harmonic", "amplitude": 1.0}, "frequency", r"missing"),
    ({"shape": "harmonic", "amplitude": 1.0, "frequency": 0.0}, "frequency", r"must be > 0"),
    ({"shape": "spin_up", "rate": math.inf, "duration": 1.0}, "rate", r"must be finite"),
    ({"shape": "spin_up", "rate": 1.0, "duration": 1.0, "start": -1.0}, "start", r"must be >= 0"),
    ({"shape": "spin_up", "rate": 1.0, "duration": 1.0, "amplitude": 1.0}, "amplitude",
     r"unknown key \(allowed: duration, rate, shape, start\)"),
    ({"shape": "hold", "value": 1.0}, "value", r"unknown key \(allowed: shape\)"),
    ({"shape": "wobble"}, "shape", r"must be one of hold, spin_up, cycloidal, harmonic \(got 'wobble'\)"),
    ({"shape": ["spin_up"]}, "shape", r"must be one of hold"),
    ({"rate": 1.0}, "shape", r"missing"),
]


@pytest.mark.parametrize("entry, key, match", MOTION_BAD, ids=[str(m[0])[:40] for m in MOTION_BAD])
def test_motion_that_is_not_smooth_or_malformed_is_refused(entry, key, match):
    data = _two("base", {"mode": "prescribed", "motion": {"psi": entry}})
    data["loads"] = data["loads"][:2]
    full = f"base.motion.psi.{key}"
    with pytest.raises(SceneError, match="^" + re.escape(full) + ": " + match) as err:
        Scene.from_dict(data)
    assert err.value.key == full


def test_motion_profile_constructor_checks_too():
    with pytest.raises(SceneError, match=r"^shape: 'sine' is not smooth enough"):
        MotionProfile("sine", amplitude=1.0, frequency=1.0)
    with pytest.raises(SceneError, match=r"^duration: must be > 0"):
        MotionProfile("spin_up", rate=1.0)
    with pytest.raises(SceneError, match=r"^rate: not a parameter of shape hold"):
        MotionProfile("hold", rate=1.0)
    assert MotionProfile("spin_up", rate=6, duration=15).to_dict() == {
        "shape": "spin_up", "rate": 6.0, "duration": 15.0, "start": 0.0}


# ----- shipped scenes -----

def test_shipped_two_wing_deployment():
    sc = load_scene(CONFIG / "two_wing_deployment.yaml")
    assert sc.n == 10 and [c.name for c in sc.chains] == ["left", "right"]
    assert sc.chain_starts.tolist() == [0, 5, 10]
    assert sc.base.mode == "free" and sc.base.wheel is not None and sc.gravity is None
    assert sc.base.mass == 750.0 and sc.base.inertia == 900.0
    theta = sc.initial_hinge_angles()
    np.testing.assert_allclose(theta, [0.0, 2.99, -2.99, 2.99, -2.99, PI, 2.99, -2.99, 2.99, -2.99],
                               atol=1e-12)
    assert sc.hinge_locked.tolist() == [True, False, False, False, False] * 2
    np.testing.assert_array_equal(sc.latch_angle[[1, 2, 3, 4, 6, 7, 8, 9]], 0.0)
    assert not sc.loads
    assert_round_trip(sc)


def test_shipped_spin_up_beam():
    sc = load_scene(CONFIG / "spin_up_beam.yaml")
    assert sc.base.mode == "prescribed" and list(sc.base.motion) == ["psi"]
    assert sc.base.motion["psi"] == MotionProfile("spin_up", rate=6.0, duration=15.0)
    assert sc.n == 10 and float(np.sum(sc.length)) == 10.0
    assert np.all(sc.bending_stiffness == 1.4e4) and np.all(sc.mass_per_length == 1.2)
    assert sc.hinge_locked.all() and sc.chains[0].attach == (0.0, 0.0)
    assert_round_trip(sc)


def test_shipped_tether_pair():
    sc = load_scene(CONFIG / "tether_pair.yaml")
    assert sc.n == 2048 and sc.chain_starts.tolist() == [0, 1024, 2048]
    assert sc.base.mode == "free" and sc.base.psi_rate == 0.1
    assert np.all(sc.phi_rate0 == 0.1)
    np.testing.assert_array_equal(sc.initial_hinge_angles()[[0, 1, 1024, 1025]], [0.0, 0.0, PI, 0.0])
    text = scene_to_yaml(sc)
    assert len(text) < 2000                     # uniform chains stay scalars
    assert_round_trip(sc)


def test_compiled_profile_is_the_same_law():
    numba = pytest.importorskip("numba")
    from rod_sim.core.motion import profile_at
    compiled = numba.njit(profile_at)
    for p in PROFILES:
        for t in (-1.0, 0.0, 0.3, 1.0, 2.2, 7.5, 14.999, 15.0, 40.0):
            assert compiled(p.code, *p.parameters, t) == p.evaluate(t), (p, t)


def test_scenes_pickle_and_copy():
    import pickle
    for name in ("spin_up_beam", "two_wing_deployment"):
        sc = load_scene(CONFIG / f"{name}.yaml")
        for back in (pickle.loads(pickle.dumps(sc)), copy.deepcopy(sc)):
            assert back.to_dict() == sc.to_dict() and back.base == sc.base
    with pytest.raises(TypeError):
        load_scene(CONFIG / "spin_up_beam.yaml").base.motion["x"] = MotionProfile("hold")
