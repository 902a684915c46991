"""rod_sim.core.stability: linear stability of the models and of the explicit integrators.

Checked against independent facts: RK4's stability limits (2 sqrt 2 on the imaginary axis,
2.7853 on the negative real axis, textbook values), DOP853's stability polynomial agreeing
with exp(z) to order 8 (and not 9), a one-rod rigid chain's eigenvalues from its own
characteristic equation, and the full model's step limit predicting where fixed-step RK4
turns unstable on the paper's example.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from rod_sim.core import erk, stability
from rod_sim.core.integrators import IntegrationError, make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.scene import Scene
from rod_sim.core.simulator import Simulator
from rod_sim.io.scene_yaml import load_scene
from rod_sim.app.common import PAPER_EXAMPLE

RK4_A = np.array([[0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 1, 0]], dtype=float)
RK4_B = np.array([1, 2, 2, 1], dtype=float) / 6.0


def test_rk4_limits_are_the_textbook_values():
    assert stability.stability_limit(RK4_A, RK4_B, 1j) == pytest.approx(2 * math.sqrt(2),
                                                                         abs=1e-8)
    assert stability.stability_limit(RK4_A, RK4_B, -1.0) == pytest.approx(2.785293563, abs=1e-7)


def test_dop853_polynomial_is_exp_to_order_8():
    s = erk.B_DOP.shape[0]
    R = stability.stability_polynomial(erk.A_DOP[:s, :s], erk.B_DOP)
    for z in (0.4, 0.4j, 0.24 - 0.32j):
        zz = np.array([z, z / 2])
        err = np.abs(R(zz) - np.exp(zz))
        # local error ~ C z^9 (order 8): halving z divides it by ~2^9, not 2^8 or 2^10
        assert 2**8.5 < err[0] / err[1] < 2**9.5


def test_explicit_limit_of_dop853_on_the_imaginary_axis():
    s = erk.B_DOP.shape[0]
    x = stability.stability_limit(erk.A_DOP[:s, :s], erk.B_DOP, 1j)
    R = stability.stability_polynomial(erk.A_DOP[:s, :s], erk.B_DOP)
    assert abs(R(1j * x * 0.999)) <= 1.0 + 1e-12 < abs(R(1j * x * 1.001))
    assert 5.0 < x < 7.0


def test_one_rod_eigenvalues_from_its_characteristic_equation():
    # one rigid rod on a hinge: (m l^3 / 3 + mu l^2) phi'' + nu phi' + kappa phi = 0 at rest
    m, l, mu, kappa, nu = 3.0, 2.0, 1.5, 400.0, 0.7
    scene = Scene.from_dict({"name": "one", "rods": {"count": 1, "length": l,
                                                     "mass_per_length": m,
                                                     "bending_stiffness": 1e5},
                             "nodes": {"mass": mu}, "hinges": {"stiffness": kappa,
                                                               "damping": nu},
                             "initial": {"phi": 0.0, "phi_rate": 0.0}, "loads": []})
    model = make_model("rigid", scene)
    inertia = m * l**3 / 3.0 + mu * l**2
    expected = np.roots([inertia, nu, kappa])
    radius, lam = stability.spectral_radius(model, 0.0, model.initial_state())
    assert radius == pytest.approx(abs(expected[0]), rel=1e-6)
    assert lam.real == pytest.approx(expected[0].real, rel=1e-5)


@pytest.fixture(scope="module")
def paper_full():
    return make_model("full", load_scene(str(PAPER_EXAMPLE)))


def test_full_model_step_limit_predicts_rk4(paper_full):
    """h_max = 2 sqrt 2 / max |lambda|: RK4 at 0.9 h_max runs, at 1.3 h_max it blows up."""
    traj = Simulator(paper_full, make_integrator("dop853-jit", rtol=1e-8)).run(0.3, 100.0)
    radius = max(stability.spectral_radius(paper_full, float(t), y)[0]
                 for t, y in zip(traj.t[::5], traj.y[::5]))
    assert 2000.0 < radius < 4000.0          # the bending vibrations, far above the hinges'
    h_max = stability.stability_limit(RK4_A, RK4_B, 1j) / radius
    ok = Simulator(paper_full, make_integrator("rk4", step=0.9 * h_max)).run(0.3, 100.0)
    assert np.all(np.isfinite(ok.y)) and np.max(np.abs(ok.phi - traj.phi)) < 1e-3
    with pytest.raises(IntegrationError):
        Simulator(paper_full, make_integrator("rk4", step=1.3 * h_max)).run(0.3, 100.0)
