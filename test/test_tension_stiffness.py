"""radau-jit's Newton matrix carries the tension stiffness of a limp line (core/newton.py).

A limp chain under load (a tether spun by its base, a cable hanging under gravity) is held
straight by its tension: T_k l_k on rod k's angle. Without it the O(n) Newton matrix had no
stiffness at all for such a chain, and on config/tether_pair.yaml with 512 rods a tether
radau-jit rejected 135 steps for 54 it kept (reduced model, 0.5 s, rtol 1e-10), where the
dense finite-difference Jacobian took 3 steps and none rejected.

Oracles: the tensions of a hanging chain at rest and of a chain spun rigidly about a fixed
hinge, by statics written out here; the trajectories of dop853-jit at rtol 1e-12.
"""
from __future__ import annotations

import numpy as np
import pytest

from rod_sim.core import kernels, newton
from rod_sim.core.integrators import make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.scene import Scene
from rod_sim.core.simulator import Simulator

N, L, RHO, MU, G, OMEGA = 6, 0.5, 0.4, 0.03, 9.81, 3.0


def chain_scene(**extra) -> Scene:
    return Scene.from_dict({
        "name": "limp", "rods": {"count": N, "length": L, "mass_per_length": RHO,
                                 "bending_stiffness": 50.0},
        "nodes": {"mass": MU}, "hinges": {"stiffness": 0.0, "damping": 0.0},
        **extra})


def stiffness_of(model, t, y):
    data = model.new_data()
    plan = data.plan()
    held = np.zeros((model.n + 2, 3))
    out = np.zeros(model.n)
    f = np.empty(y.size)
    problem = kernels.Problem(model.chain, plan.extra, model.loads, held)
    model.kernel(t, y, *problem, t, f)
    newton.tension_stiffness(problem, t, t, y, f, out)
    return out


def end_tensions(force_beyond_tip_node, rod_force):
    """Tensions at the near and far end of each rod from the chain's tip: the far end carries
    the node beyond it and everything after, the near end also the rod's own share."""
    far, near, acc = np.zeros(N), np.zeros(N), 0.0
    for k in range(N - 1, -1, -1):
        acc += force_beyond_tip_node[k]
        far[k] = acc
        acc += rod_force[k]
        near[k] = acc
    return near, far


@pytest.mark.parametrize("model_name", ["rigid", "reduced", "full"])
def test_a_hanging_chain_at_rest_has_its_weights_tension(model_name):
    model = make_model(model_name, chain_scene(gravity=[0.0, -G],
                                               initial={"phi": -np.pi / 2}))
    y = model.initial_state()
    near, far = end_tensions(np.full(N, MU * G), np.full(N, RHO * L * G))
    expected = L * 0.5 * (near + far)              # = d^2 V / d phi_k^2 at the hanging rest
    assert np.allclose(stiffness_of(model, 0.0, y), expected, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("model_name", ["rigid", "reduced"])
def test_a_chain_spun_rigidly_has_its_centripetal_tension(model_name):
    model = make_model(model_name, chain_scene(initial={"phi": 0.0, "phi_rate": OMEGA}))
    y = model.initial_state()
    tips = L * np.arange(1, N + 1)                  # node k's radius
    centres = tips - 0.5 * L
    near, far = end_tensions(MU * OMEGA ** 2 * tips, RHO * L * OMEGA ** 2 * centres)
    assert np.allclose(stiffness_of(model, 0.0, y), L * 0.5 * (near + far), rtol=1e-12)


def test_a_compressed_rod_adds_no_stiffness():
    # standing on its hinge, upright: every rod is compressed by the weight above it
    model = make_model("rigid", chain_scene(gravity=[0.0, -G], initial={"phi": np.pi / 2}))
    assert np.all(stiffness_of(model, 0.0, model.initial_state()) == 0.0)


def long_tethers(rods: int) -> Scene:
    chain = {"rods": {"count": rods, "length": 0.1, "mass_per_length": 0.02,
                      "bending_stiffness": 0.05},
             "nodes": {"mass": 0.001}, "hinges": {"stiffness": 0.0, "damping": 1.0e-4}}
    return Scene.from_dict({
        "name": "tethers", "base": {"mode": "free", "mass": 100.0, "inertia": 50.0,
                                    "initial": {"psi_rate": 0.1}},
        "chains": [{"name": "east", "attach": [1.0, 0.0], **chain,
                    "initial": {"phi": 0.0, "phi_rate": 0.1}},
                   {"name": "west", "attach": [-1.0, 0.0], **chain,
                    "initial": {"phi": float(np.pi), "phi_rate": 0.1}}]})


def test_spun_tethers_take_a_few_implicit_steps_and_stay_accurate():
    model = make_model("reduced", long_tethers(512))
    sim = Simulator(model, make_integrator("radau-jit", rtol=1e-10, atol=1e-12))
    got = sim.run(0.5, 10.0)
    assert sim.stats.steps <= 6 and sim.stats.rejected <= 2, sim.stats   # was 54 and 135
    ref = Simulator(model, make_integrator("dop853-jit", rtol=1e-12, atol=1e-14)).run(0.5, 10.0)
    assert np.max(np.abs(got.y - ref.y)) < 1e-9


def test_a_swinging_cable_under_gravity_stays_accurate():
    # 60 rods released 0.3 rad from hanging, one lock between rods 20 and 21: the tension
    # stiffness in the Newton matrix (and in the lock's split-off rigid turn) keeps radau-jit
    # on dop853-jit's trajectory
    scene = Scene.from_dict({
        "name": "cable", "rods": {"count": 60, "length": 0.05, "mass_per_length": 0.4,
                                  "bending_stiffness": 5.0},
        "nodes": {"mass": 0.002},
        "hinges": {"stiffness": 0.0, "damping": 1e-4,
                   "locked": [k == 20 for k in range(60)]},
        "gravity": [0.0, -G], "initial": {"phi": -np.pi / 2 + 0.3}})
    for model_name in ("reduced", "full"):
        model = make_model(model_name, scene)
        ref = Simulator(model, make_integrator("dop853-jit", rtol=1e-12, atol=1e-14)).run(
            0.5, 20.0)
        for rtol, bound in ((1e-6, 1e-4), (1e-10, 1e-8)):
            sim = Simulator(model, make_integrator("radau-jit", rtol=rtol))
            got = sim.run(0.5, 20.0)
            err = np.max(np.abs(model.phi(got.y) - model.phi(ref.y)))
            assert err < bound, (model_name, rtol, err, sim.stats)
