"""Chains on a base (issue 25): what the kernels' segment and base handling must preserve.

The oracles here are independent of the base code: a chain's own single-chain equations (the
paper's, checked elsewhere against the Lagrangian), the conservation laws that the derivation
in docs/spacecraft.md says each model has, and the trapezoid integral of the applied loads.
"""
from __future__ import annotations

import numpy as np
import pytest

from rod_sim.core.integrators import make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.momentum import MomentumBalance, momentum_rates
from rod_sim.core.scene import Scene
from rod_sim.core.simulator import Simulator

MODELS = ("rigid", "reduced", "full")


def _chain(n, l, m, mu, EI, kappa, nu, phi, rate):
    return {"rods": {"count": n, "length": l, "mass_per_length": m, "bending_stiffness": EI},
            "nodes": {"mass": mu}, "hinges": {"stiffness": kappa, "damping": nu},
            "initial": {"phi": phi, "phi_rate": rate}}


A = _chain(3, [1.0, 0.7, 1.3], 2.0, [0.5, 0.0, 1.0], 400.0, [30.0, 5.0, 8.0], 0.3,
           [0.2, 0.9, 1.4], [0.5, -1.0, 2.0])
B = _chain(2, 1.5, [1.0, 3.0], 0.4, [800.0, 300.0], 20.0, [0.1, 0.0], [3.0, 2.5],
           [-0.4, 0.7])


def _two_chains(base=None, gravity=None, attach=((0.0, 0.0), (0.0, 0.0))):
    chains = [dict(A, name="a", attach=list(attach[0])), dict(B, name="b", attach=list(attach[1]))]
    data = {"name": "two", "chains": chains}
    if base is not None:
        data["base"] = base
    if gravity is not None:
        data["gravity"] = gravity
    return Scene.from_dict(data)


@pytest.mark.parametrize("name", MODELS)
def test_two_chains_on_a_fixed_base_are_two_independent_chains(name):
    """Two chains hanging from the origin of a fixed base: the right-hand side of the pair is
    each chain's own (a one-chain scene of the paper), bit for bit."""
    pair = make_model(name, _two_chains())
    solo = [make_model(name, Scene.from_dict(dict(c, name=f"solo{i}"))) for i, c in
            enumerate((A, B))]
    rng = np.random.default_rng(3)
    y = pair.initial_state() + 0.05 * rng.standard_normal(pair.state_size)
    held = rng.standard_normal((pair.n + 2, 3))
    held[pair.n:] = 0.0
    dy = pair.rhs(0.2, y, held)
    per = pair.dof_per_rod
    for c, (model, (a, b)) in enumerate(zip(solo, ((0, 3), (3, 5)))):
        n = b - a
        idx = np.concatenate([np.arange(a, b) + g * pair.n for g in range(per)])
        ys = np.concatenate([y[idx], y[pair.dof + idx]])
        ds = model.rhs(0.2, ys, held[a:b])
        np.testing.assert_array_equal(dy[idx], ds[:per * n])
        np.testing.assert_array_equal(dy[pair.dof + idx], ds[per * n:])


FREE = {"mode": "free", "mass": 40.0, "inertia": 9.0, "centre_of_mass": [0.1, -0.2],
        "initial": {"psi_rate": 0.3, "x_rate": 0.2}, "wheel": {"inertia": 0.05, "rate": 4.0}}


@pytest.mark.parametrize("name", ("rigid", "reduced"))
def test_rigid_and_reduced_conserve_momentum_on_a_free_base(name):
    """No load: the chords' linear and angular momentum stay put (docs/spacecraft.md section
    6), with two chains, a wheel and an offset centre of mass; they are not linear in the
    state, so a Runge-Kutta step keeps them to its local error: at rtol 1e-13 that is within
    1e-12 of their size."""
    scene = _two_chains(FREE, attach=((0.5, 0.2), (-0.4, 0.1)))
    model = make_model(name, scene)
    sim = Simulator(model, make_integrator("dop853-jit", rtol=1e-13, atol=1e-13))
    tr = sim.run(0.5, 10)
    m0 = model.momentum(0.0, tr.y[0])
    m1 = model.momentum(tr.t[-1], tr.y[-1])
    assert abs(model.base_state(tr.t[-1], tr.y[-1]).psi) > 0.05        # the base did turn
    scale_p = float(np.max(np.abs(m0.linear))) + 1.0
    np.testing.assert_allclose(m1.linear, m0.linear, rtol=0, atol=1e-12 * scale_p)
    assert abs(m1.angular_origin - m0.angular_origin) <= 1e-12 * abs(m0.angular_origin)


@pytest.mark.parametrize("name", MODELS)
def test_momentum_ledger_closes_under_loads_and_gravity(name):
    """dP/dt = applied force + weight (+ the full model's booked defect) and dH/dt = their
    moment about O: the ledger's residual is the trapezoid rule's error, which falls as the
    square of the sample spacing."""
    data = {"name": "loaded", "base": FREE, "gravity": [0.3, -2.0],
            "chains": [dict(A, name="a", attach=[0.5, 0.2]), dict(B, name="b", attach=[-0.4, 0.1])],
            "loads": [{"chain": "a", "node": 3, "axis": "y", "shape": "raised_cosine_pulse",
                       "amplitude": 5.0, "start": 0.0, "duration": 0.2},
                      {"node": "base", "axis": "moment", "shape": "step", "amplitude": 3.0,
                       "start": 0.1, "duration": 0.1},
                      {"node": "base", "axis": "x", "shape": "constant", "amplitude": 2.0,
                       "start": 0.05},
                      {"node": "wheel", "axis": "moment", "shape": "constant", "amplitude": 0.2,
                       "start": 0.0}]}
    model = make_model(name, Scene.from_dict(data))
    residuals = []
    for rate in (200.0, 400.0):
        sim = Simulator(model, make_integrator("dop853-jit", rtol=1e-11, atol=1e-11))
        tr = sim.run(0.3, rate)
        bal = MomentumBalance()
        for t, y in zip(tr.t, tr.y):
            bal.add(t, model.momentum(t, y), momentum_rates(model, t, y))
        residuals.append((np.max(np.abs(bal.residual_linear)), abs(bal.residual_angular),
                          np.max(np.abs(bal.impulse)), abs(bal.angular_impulse)))
    (p1, h1, imp, aimp), (p2, h2, _, _) = residuals
    assert imp > 1.0 and aimp > 0.1                     # the loads did act
    assert p2 <= 1e-4 * imp and h2 <= 1e-4 * max(aimp, 1.0)
    # second order in the sample spacing (or already at round-off)
    assert p2 <= 0.35 * p1 + 1e-9 and h2 <= 0.35 * h1 + 1e-9
