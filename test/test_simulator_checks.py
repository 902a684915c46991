"""The cheap forms of three checks on every drive (one sim.advance of a period): the output
times' order, the non-finite state, the scene's breakpoints (found once per scene). Each must
still catch what the full form caught."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from rod_sim.core.integrators import IntegrationError
from rod_sim.core.models import make_model
from rod_sim.core.scene import Load
from rod_sim.core.simulator import Simulator
from rod_sim.io.scene_yaml import load_scene

PAPER = Path(__file__).resolve().parents[1] / "config" / "paper_example.yaml"


@pytest.fixture(scope="module")
def sim():
    return Simulator(make_model("reduced", load_scene(PAPER)))


@pytest.mark.parametrize("bad", [np.inf, -np.inf, np.nan])
def test_one_non_finite_component_is_caught(sim, bad):
    Y = np.zeros((3, sim.model.state_size))
    Y[2, 5] = bad
    with pytest.raises(IntegrationError, match="non-finite") as err:
        sim._check_finite(np.array([0.1, 0.2, 0.3]), Y)
    assert err.value.t == 0.3


def test_huge_finite_values_pass(sim):
    Y = np.full((2, sim.model.state_size), 1e308)
    sim._check_finite(np.array([0.1, 0.2]), Y)


def test_unsorted_output_times_are_refused_and_one_time_is_fine(sim):
    from rod_sim.core.integrators import drive

    with pytest.raises(ValueError, match="sorted"):
        drive(sim.model, sim.integrator, sim.y, 0.0, [0.2, 0.1])
    assert drive(sim.model, sim.integrator, sim.y, 0.0, [0.001]).Y.shape == (
        1, sim.model.state_size)


def test_breakpoints_are_each_scenes_own():
    scene = load_scene(PAPER)
    pulse = Load(node=8, axis="y", shape="raised_cosine_pulse", amplitude=1.0, start=0.5,
                 duration=0.25)
    a = dataclasses.replace(scene, loads=(pulse,))
    b = dataclasses.replace(a, loads=())
    assert a.breakpoints() == (0.5, 0.75) == a.breakpoints()
    assert b.breakpoints() == ()
    assert a.breakpoints() == (0.5, 0.75)
