"""Hinge motor moments (``Simulator.set_hinge_torques``, the kernels' held column 3).

- a constant moment T at a hinge of spring kappa is the same load as a rest angle T / kappa
  (both are the generalized force kappa theta_rest dDelta/dq): trajectories agree in every
  model (the rest angle is checked against the Lagrangian elsewhere);
- static deflection by hand: one damped rod settles at phi_1 = T / kappa_0 (its bending
  vanishes: no moment along a free rod); two rods with T at hinge 1: theta_1 = T / kappa_1,
  phi_1 = 0;
- energy balance: E(t) - E(0) = T . (theta(t) - theta(0)) - integral P_damper dt, the motor's
  work computed here from the trajectory, not from the model's ``powers``.
"""
from __future__ import annotations

import numpy as np
import pytest

from rod_sim.core.integrators import make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.scene import Scene
from rod_sim.core.simulator import Simulator

MODELS = ("rigid", "reduced", "full")


def chain(n=3, **over):
    d = {"rods": {"count": n, "length": 1.0, "mass_per_length": 2.0,
                  "bending_stiffness": 2e3},
         "nodes": {"mass": 0.5}, "hinges": {"stiffness": 40.0, "damping": 0.5},
         "initial": {"phi": 0.0, "phi_rate": 0.0}}
    for path, value in over.items():
        section, key = path.split("__")
        d[section][key] = value
    return Scene.from_dict(d)


def run(scene, model, torques, t_end, rate=50.0, rtol=1e-10):
    sim = Simulator(make_model(model, scene), make_integrator("dop853-jit", rtol=rtol,
                                                              atol=rtol))
    sim.set_hinge_torques(torques)
    return sim.run(t_end, rate), sim


@pytest.mark.parametrize("model", MODELS)
def test_a_constant_moment_is_a_rest_angle_of_t_over_kappa(model):
    T = np.array([3.0, -2.0, 1.5])
    sc = chain()
    with_motor, _ = run(sc, model, T, 1.0)
    shifted = sc.with_changes(hinge_rest_angle=T / 40.0)
    with_rest, _ = run(shifted, model, np.zeros(3), 1.0)
    assert np.max(np.abs(with_motor.y - with_rest.y)) < 1e-8
    assert np.max(np.abs(with_motor.phi)) > 0.05          # the motor moved the chain


@pytest.mark.parametrize("model", MODELS)
def test_static_deflection_by_hand(model):
    """At the hand-computed equilibrium every acceleration vanishes (one rod: phi_1 =
    T / kappa_0; two rods, T at hinge 1: phi_1 = 0, theta_1 = T / kappa_1; no bending: a free
    rod carries no moment); 10 % off it, they do not."""
    for n, kappa, T, phi in ((1, [40.0], [2.0], [2.0 / 40.0]),
                             (2, [40.0, 10.0], [0.0, 1.0], [0.0, 0.1])):
        m = make_model(model, chain(n, hinges__stiffness=kappa))
        held = np.zeros((n, 3))
        held[:, 2] = T
        y = np.zeros(m.state_size)
        y[:n] = phi
        acc = m.rhs(0.0, y, held)[m.dof:]
        assert np.max(np.abs(acc)) < 1e-12, acc
        a, b = m.bending(0.0, y, held)
        assert np.max(np.abs(np.concatenate([a, b]))) < 1e-15
        y[n - 1] *= 1.1
        assert np.max(np.abs(m.rhs(0.0, y, held)[m.dof:])) > 1e-3
    # and a damped rigid rod settles there
    traj, _ = run(chain(1, hinges__damping=20.0), "rigid", [2.0], 8.0)
    assert abs(traj.phi[-1, 0] - 2.0 / 40.0) < 1e-6


@pytest.mark.parametrize("model", MODELS)
def test_energy_balance_counts_the_motor_power(model):
    T = np.array([4.0, 0.0, -3.0])
    sc = chain()
    traj, sim = run(sc, model, T, 1.0, rate=2000.0, rtol=1e-11)
    m = sim.model
    held = sim.held
    E = np.array([m.energies(t, y, held).total for t, y in zip(traj.t, traj.y)])
    damper = np.array([m.powers(t, y, held)[1] for t, y in zip(traj.t, traj.y)])
    theta = np.array([m.hinge_deflection(t, y, held)[0] for t, y in zip(traj.t, traj.y)])
    motor_work = (theta - theta[0]) @ T                     # constant T: work = T . dtheta
    dissipated = np.concatenate([[0.0], np.cumsum(0.5 * (damper[1:] + damper[:-1])
                                                  * np.diff(traj.t))])
    residual = E - E[0] - motor_work + dissipated
    assert abs(motor_work[-1]) > 0.1
    # the rigid model conserves exactly (to the integrator and the quadrature); the bending
    # models to first order in the bending (test_physics): here 2e-5 (full) and 1.6e-3
    # (reduced) of the work
    bound = 1e-6 if model == "rigid" else 1e-2
    assert np.max(np.abs(residual)) < bound * np.max(np.abs(motor_work))
    # and without the motor's work the balance is off by that work
    assert np.max(np.abs(E - E[0] + dissipated)) > 0.5 * np.max(np.abs(motor_work))


def test_bad_torques_are_refused_and_forces_are_kept():
    sim = Simulator(make_model("reduced", chain()), make_integrator("rk4", step=1e-3))
    sim.set_forces(np.ones((3, 2)))
    sim.set_hinge_torques([1.0, 2.0, 3.0])
    np.testing.assert_array_equal(sim.held[:, :2], 1.0)
    np.testing.assert_array_equal(sim.held[:, 2], [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="torques: non-finite"):
        sim.set_hinge_torques([1.0, np.nan, 0.0])
    with pytest.raises(ValueError):
        sim.set_hinge_torques([1.0, 2.0])
    np.testing.assert_array_equal(sim.held[:, 2], [1.0, 2.0, 3.0])
