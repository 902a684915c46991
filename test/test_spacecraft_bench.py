"""The spacecraft bench's correctness (issue 25; no speed is asserted, the figures are in
docs/bench.md) and two properties the bench relies on:

- radau-jit, dop853-jit and rk4 agree on a free base with a wheel and timed base and wheel
  loads, in every model (each against dop853-jit at rtol 1e-11);
- a free base's run is O(n) in memory: the peak resident memory a run of 2 x 4096 rods adds,
  measured in a fresh process, is far below one dense (dof x dof) matrix;
- the bench's scenes say what they claim (free and fixed base: the same chains), its Basilisk
  peer is the same spacecraft as rod_sim's rigid model (skipped without Basilisk), and its
  micro-benchmark returns the documented keys.
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rod_sim.core.integrators import make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.scene import Scene
from rod_sim.core.simulator import Simulator
from rod_sim.bench import basilisk_peer, spacecraft

ROOT = Path(__file__).resolve().parents[1]


def _free_scene():
    """Two 4-rod chains on a free base with a wheel, a base moment pulse and a wheel torque."""
    chain = {"rods": {"count": 4, "length": 0.5, "mass_per_length": 2.0,
                      "bending_stiffness": 50.0},
             "nodes": {"mass": 0.1}, "hinges": {"stiffness": 20.0, "damping": 0.05}}
    return Scene.from_dict({
        "name": "free_agree",
        "base": {"mode": "free", "mass": 20.0, "inertia": 5.0, "centre_of_mass": [0.1, -0.05],
                 "initial": {"psi_rate": 0.3, "x_rate": 0.1},
                 "wheel": {"inertia": 0.02, "rate": 1.0}},
        "chains": [{"name": "a", "attach": [0.5, 0.0], **chain,
                    "initial": {"phi": [0.1, 0.3, 0.2, -0.1], "phi_rate": 0.5}},
                   {"name": "b", "attach": [-0.5, 0.1], **chain,
                    "initial": {"phi": 3.0, "phi_rate": -0.2}}],
        "loads": [{"node": "base", "axis": "moment", "shape": "step", "amplitude": 2.0,
                   "start": 0.05, "duration": 0.1},
                  {"node": "wheel", "axis": "moment", "shape": "constant", "amplitude": 0.1,
                   "start": 0.1},
                  {"chain": "b", "node": 4, "axis": "y", "shape": "step", "amplitude": 1.0,
                   "start": 0.0, "duration": 0.05}]})


def _angles(model, integrator, **kw):
    traj = Simulator(model, make_integrator(integrator, **kw)).run(0.3, 100.0)
    i = model.base_index
    return np.column_stack([traj.phi, traj.y[:, i:i + 3]])      # phi, x_B, y_B, psi


@pytest.mark.parametrize("model_name", ["rigid", "reduced", "full"])
def test_integrators_agree_on_a_free_base(model_name):
    model = make_model(model_name, _free_scene())
    ref = _angles(model, "dop853-jit", rtol=1e-11, atol=1e-11)
    assert np.max(np.abs(ref[-1, -1] - ref[0, -1])) > 0.05          # the base turns
    for integrator, kw, tol in (("radau-jit", {"rtol": 1e-9, "atol": 1e-9}, 1e-6),
                                ("rk4", {"step": 2e-5}, 1e-6),
                                ("dop853-jit", {"rtol": 1e-8, "atol": 1e-8}, 1e-6)):
        got = _angles(model, integrator, **kw)
        err = float(np.max(np.abs(got - ref)))
        assert err < tol, (model_name, integrator, err)


_MEMORY_PROBE = r"""
import json, resource, sys
from rod_sim.core.integrators import make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.simulator import Simulator
from rod_sim.bench.spacecraft import two_chain_scene
model_name, integrator, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
kw = {"step": 1e-5} if integrator == "rk4" else {"rtol": 1e-6, "atol": 1e-6}
small = make_model(model_name, two_chain_scene(8, "free"))        # load the kernels
Simulator(small, make_integrator(integrator, **kw)).advance(1e-4)
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
model = make_model(model_name, two_chain_scene(n, "free"))
sim = Simulator(model, make_integrator(integrator, **kw))
sim.advance(2e-4)
after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"dof": model.dof, "state": model.state_size,
                  "added_bytes": (after - before) * 1024}))
"""


@pytest.mark.parametrize("model_name,integrator", [("full", "radau-jit"), ("reduced", "radau-jit"),
                                                   ("full", "dop853-jit")])
def test_a_free_base_run_is_linear_in_memory(model_name, integrator):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-c", _MEMORY_PROBE, model_name, integrator, "4096"],
                         capture_output=True, text=True, env=env, timeout=600, check=True)
    res = json.loads(out.stdout.strip().splitlines()[-1])
    dense = 8 * res["dof"] ** 2                        # one dense dof x dof matrix [bytes]
    # 2 x 4096 rods: the full model's dof is 24579, a dense matrix 4.8 GB (reduced 0.5 GB);
    # the O(n) run keeps a few dozen vectors of the state's size
    assert res["added_bytes"] < 64 << 20, res
    assert res["added_bytes"] < dense / 8, (res, dense)


def test_bench_scenes_free_and_fixed_hold_the_same_chains():
    free, fixed = spacecraft.two_chain_scene(16, "free"), spacecraft.two_chain_scene(16, "fixed")
    assert free.n == fixed.n == 32 and len(free.chains) == len(fixed.chains) == 2
    for key in ("length", "mass_per_length", "bending_stiffness", "node_mass",
                "hinge_stiffness", "hinge_damping", "phi0", "phi_rate0"):
        assert np.array_equal(getattr(free, key), getattr(fixed, key)), key
    assert free.base.mode == "free" and fixed.base.mode == "fixed"
    assert make_model("full", free).nb == 3 and make_model("full", fixed).nb == 0


def test_rhs_ratio_returns_every_model_with_its_figures():
    res = spacecraft.base_rhs_ratio(n=8, rounds=1, span_s=1e-4)
    assert set(res) == {"rigid", "reduced", "full"}
    for r in res.values():
        assert r["free_s"] > 0 and r["fixed_s"] > 0 and r["n_total"] == 16
        assert math.isclose(r["ratio"], r["free_s"] / r["fixed_s"])


@pytest.mark.skipif(not basilisk_peer.available(), reason="Basilisk (pip bsk) not installed")
def test_basilisk_peer_is_the_same_spacecraft_as_the_rigid_model():
    craft = spacecraft.peer_spacecraft(5)
    ours = make_model("rigid", spacecraft.peer_scene(craft))
    _, psi, theta, _ = spacecraft._rod_sim_final(ours, 1e-12, 2.0, 1)
    theirs = basilisk_peer.time_run(craft, 2.0, 1e-3, repeats=1)
    assert abs(psi) > 0.1                                    # the hub turns (0.1 rad/s)
    assert abs(spacecraft._wrap(psi - theirs.psi)) < 1e-9
    assert np.max(np.abs(theta - theirs.theta)) < 1e-9
    assert np.max(np.abs(theta)) > 1e-3                      # the panels swing
