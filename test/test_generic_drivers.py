"""Integrators generic over the model's compiled right-hand side: one compiled driver per
integrator serves every model through one dispatch (kernels.model_rhs on the plan's
``extra.rhs``), so adding a model adds a kernel and a branch, not drivers."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rod_sim.core import erk, jit, kernels, radau
from rod_sim.core.integrators import make_integrator
from rod_sim.core.models import DRIVERS, MODELS, make_model
from rod_sim.core.simulator import Simulator
from rod_sim.io.scene_yaml import load_scene

CONFIG = Path(__file__).resolve().parents[1] / "config"


def test_every_model_has_the_same_drivers_and_its_own_rhs_code():
    scene = load_scene(CONFIG / "paper_example.yaml")
    codes = set()
    for name in MODELS:
        model = make_model(name, scene)
        assert model.compiled is DRIVERS
        assert model.plan().extra.rhs == model.rhs_code
        codes.add(model.rhs_code)
    assert len(codes) == len(MODELS)
    assert DRIVERS == (erk.dop853_model, erk.fixed_model, radau.radau_model)


@pytest.mark.parametrize("scene", ["paper_example", "two_wing_deployment", "spin_up_beam"])
def test_the_dispatch_is_each_models_kernel_bit_for_bit(scene):
    sc = load_scene(CONFIG / f"{scene}.yaml")
    rng = np.random.default_rng(3)
    for name in MODELS:
        model = make_model(name, sc)
        sim = Simulator(model)
        sim.advance(0.02)
        extra = sim.data.plan(sim.mode, sim.contact).extra
        held = model._held(rng.normal(size=(model.n, 2)))
        for _ in range(3):
            y = sim.y + 1e-3 * rng.normal(size=sim.y.size)
            a, b = np.empty(y.size), np.empty(y.size)
            model.kernel(0.3, y, model.chain, extra, model.loads, held, 0.3, a)
            kernels.model_rhs(0.3, y, model.chain, extra, model.loads, held, 0.3, b)
            np.testing.assert_array_equal(a, b)


@pytest.mark.skipif(not jit.HAVE_NUMBA, reason="numba not installed")
def test_one_compiled_specialisation_per_integrator_serves_every_model():
    for scene in (load_scene(CONFIG / f"{s}.yaml") for s in ("paper_example", "deployment")):
        for integ in ("dop853-jit", "radau-jit", "rk4"):
            for name in MODELS:
                try:
                    Simulator(make_model(name, scene), make_integrator(integ)).advance(1e-3)
                except ValueError:                # a combination the library refuses
                    pass
    for driver in DRIVERS:
        assert len(driver.signatures) == 1, (driver, driver.signatures)
