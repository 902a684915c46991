"""The core's seams: integrators are immutable settings whose carried state belongs to the
simulator, models are registered once and implement the whole Model protocol, and the driver
returns a named result."""
from __future__ import annotations

import dataclasses
import inspect
from pathlib import Path

import numpy as np
import pytest

from rod_sim.core import integrators, models
from rod_sim.core.integrators import DriveResult, drive, make_integrator
from rod_sim.core.models import MODELS, Model, make_model
from rod_sim.core.simulator import Simulator
from rod_sim.io.scene_yaml import load_scene

REPO = Path(__file__).resolve().parents[1]
DEPLOY = REPO / "config" / "deployment.yaml"
PAPER = REPO / "config" / "paper_example.yaml"


def _protocol_members(proto) -> set[str]:
    names = set(getattr(proto, "__annotations__", {}))
    names |= {k for k, v in vars(proto).items()
              if not k.startswith("_") and (callable(v) or isinstance(v, property))}
    return names


@pytest.mark.parametrize("name", sorted(MODELS))
def test_every_registered_model_implements_the_whole_protocol(name):
    model = make_model(name, load_scene(PAPER))
    members = _protocol_members(Model)
    assert {"rhs", "plan", "compiled", "mass_times", "powers", "snapshot"} <= members
    missing = sorted(m for m in members if not hasattr(model, m))
    assert not missing, missing
    for m in members:
        attr = getattr(type(model), m, None)
        if callable(attr) and m not in ("kernel",):
            proto = list(inspect.signature(getattr(Model, m)).parameters.values())
            mine = list(inspect.signature(attr).parameters.values())
            # the protocol's parameters, same names, kinds and order; extra ones only optional
            assert [(q.name, q.kind) for q in mine[:len(proto)]] == \
                [(q.name, q.kind) for q in proto], (name, m, proto, mine)
            assert all(q.default is not q.empty or q.kind in (q.VAR_POSITIONAL, q.VAR_KEYWORD)
                       for q in mine[len(proto):]), (name, m, mine)
    assert model.compiled.dop853 is not model.compiled.radau


@pytest.mark.parametrize("name", ["dop853-jit", "radau-jit", "rk4", "RK45"])
def test_integrators_are_immutable_settings(name):
    integ = make_integrator(name)
    with pytest.raises(dataclasses.FrozenInstanceError):
        integ.rtol = 1.0
    assert not any(f.name.startswith("_") for f in dataclasses.fields(integ))


@pytest.mark.parametrize("name", ["dop853-jit", "radau-jit", "rk4"])
def test_two_simulators_sharing_model_and_integrator_do_not_interfere(name):
    """Interleaved periods of two simulators on one model and one integrator object give
    exactly what each gives alone (the carried step, workspace and counters are theirs)."""
    model = make_model("full", load_scene(DEPLOY))
    integ = make_integrator(name, rtol=1e-7)
    alone = Simulator(model, integ)
    for _ in range(20):
        alone.advance(0.01)
    a, b = Simulator(model, integ), Simulator(model, integ)
    b.set_forces(np.full((model.n, 2), 0.5))           # a different run in between
    for _ in range(20):
        a.advance(0.01)
        b.advance(0.01)
    np.testing.assert_array_equal(a.y, alone.y)
    assert a.stats == alone.stats and a.stats is not b.stats
    assert not np.array_equal(a.y, b.y)
    assert [e.kind for e in a.events] == [e.kind for e in alone.events]


def test_drive_returns_a_named_result_and_counts_into_the_carry():
    model = make_model("reduced", load_scene(DEPLOY))
    integ = make_integrator("dop853-jit")
    carry = integ.init(model)
    out = drive(model, integ, model.initial_state(), 0.0, [0.0, 0.5, 1.0], carry=carry)
    assert isinstance(out, DriveResult)
    assert out.Y.shape == (3, model.state_size) and out.modes.shape == (3, model.n)
    np.testing.assert_array_equal(out.Y[-1], out.y)           # no latch on the last time
    assert out.contact.shape == (model.n,) and out.mode.shape == (model.n,)
    assert carry.stats.nfev > 0 and carry.h > 0
    again = drive(model, integ, model.initial_state(), 0.0, [0.0, 0.5, 1.0])
    np.testing.assert_array_equal(again.Y[:, :model.n], out.Y[:, :model.n])


def test_configure_replaces_settings_and_keeps_the_carry():
    sim = Simulator(make_model("reduced", load_scene(PAPER)), make_integrator())
    sim.advance(0.01)
    carry, h = sim.carry, sim.carry.h
    sim.configure(max_steps=7)
    assert sim.integrator.max_steps == 7 and sim.carry is carry and sim.carry.h == h
    with pytest.raises(integrators.IntegrationError, match="too many steps"):
        sim.configure(max_step=1e-6)
        sim.advance(0.01)


def test_registries_are_the_one_place_names_resolve():
    assert set(integrators.INTEGRATORS) == set(integrators.INTEGRATOR_NAMES)
    with pytest.raises(ValueError, match="unknown integrator 'nope'"):
        make_integrator("nope")
    with pytest.raises(models.ModelError, match="unknown model 'nope'"):
        make_model("nope", load_scene(PAPER))
    for name, cls in MODELS.items():
        assert cls.name == name
