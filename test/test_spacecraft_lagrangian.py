"""Chains on a spacecraft (issue 25, SPEC section 8) against an independent Lagrangian.

``lagrangian_base.py`` derives the exact equations of k chains on a free base with a reaction
wheel and uniform gravity from the kinematics alone (sympy + Gauss quadrature; it imports
nothing from rod_sim). The models are asked for their answers through ``make_model`` only.

What is checked (the model's contract, from the brief and SPEC section 8):

* full model, alpha = beta = 0, any rates (bending rates included): its accelerations satisfy
  the exact Lagrange equations with the base, every row (chains, x_B, y_B, psi, theta_w), to
  1e-9 relative -- the paper's mass matrix and velocity terms are exact at zero bending;
* full model at nonzero bending: the same equations with the inertial force evaluated at
  alpha = beta = 0 (the paper's L depends on q through phi only) and everything else --
  hinges, bending energy, damping, loads and gravity through the exact bent shape -- at q;
* rigid model: the exact equations restricted to alpha = beta = 0 (phi, base and wheel rows;
  the alpha/beta rows are then constraint forces);
* reduced model: the full model's equations with alpha' = beta' = 0 and zero bending
  accelerations, alpha, beta from ``model.bending`` (the paper's reduction (11)-(15)), every
  row including the alpha/beta rows (which become the quasi-static bending equations);
* prescribed base (spin_up psi(t)): the chain rows, the base's motion entering as known
  accelerations; the chains' reaction on it (``base_reaction``) is the oracle's support force;
* the oracle itself: its fixed-base limit is ``lagrangian.py``'s chain, its quadrature is
  exact, gravity is the gradient of its potential, and its own trajectories conserve
  momentum (P - M g t, H about the centre of mass) -- so the comparisons can be trusted;
* and the comparisons can fail: a wrong coefficient is detected.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from sc_common import (Layout, chain_dict, cycloidal, free_base, harmonic, needs_spacecraft,
                       oracle_from_dict, rel, scene_dict, spin_up)
from lagrangian import Lagrangian
from lagrangian_base import BaseData, BaseLagrangian, ChainData

SCENES = [((1,), 201), ((2,), 202), ((3,), 203), ((1, 2), 204), ((2, 3), 205), ((3, 3), 206)]
GRAVITY = (0.7, -9.81)


def make(name, d):
    from rod_sim.core.models import make_model
    from rod_sim.core.scene import Scene
    return make_model(name, Scene.from_dict(d))


def random_scene(ns, seed, gravity=GRAVITY, base=None, loads=True):
    """Chains with rod counts ns on a free base with a wheel, gravity on, constant scripted
    loads on chain nodes, the base and the wheel; returns (dict, rng, scripted (N + 2, 3))."""
    rng = np.random.default_rng(seed)
    chains = [chain_dict(f"c{i}", n, rng) for i, n in enumerate(ns)]
    N = sum(ns)
    scripted = np.zeros((N + 2, 3))
    ld = []
    if loads:
        off = np.cumsum([0] + list(ns))
        for i, n in enumerate(ns):
            node = int(rng.integers(1, n + 1))
            axis = "xy"[int(rng.integers(0, 2))]
            amp = float(rng.uniform(-30, 30))
            ld.append({"chain": f"c{i}", "node": node, "axis": axis, "shape": "constant",
                       "amplitude": amp, "start": 0.0})
            scripted[off[i] + node - 1, "xy".index(axis)] += amp
        if base is None or base.get("mode") == "free":
            for axis, col in (("x", 0), ("y", 1), ("moment", 2)):
                amp = float(rng.uniform(-40, 40))
                ld.append({"node": "base", "axis": axis, "shape": "constant", "amplitude": amp,
                           "start": 0.0})
                scripted[N, col] += amp
            amp = float(rng.uniform(-2, 2))
            ld.append({"node": "wheel", "axis": "moment", "shape": "constant", "amplitude": amp,
                       "start": 0.0})
            scripted[N + 1, 2] += amp
    d = scene_dict(chains, free_base() if base is None else base, gravity, ld)
    return d, rng, scripted


def random_held(N, rng, free=True):
    h = np.zeros((N + 2, 3))
    h[:N, :2] = rng.uniform(-20, 20, (N, 2))
    h[:N, 2] = rng.uniform(-5, 5, N)
    if free:
        h[N] = rng.uniform(-30, 30, 3)
        h[N + 1, 2] = rng.uniform(-1, 1)
    return h


def random_state(lay: Layout, rng, bending=0.0, bend_rate=2.0):
    N = lay.N
    q = np.zeros(3 * N + 4)
    qd = np.zeros(3 * N + 4)
    q[:N] = rng.uniform(-np.pi, np.pi, N)
    q[N:3 * N] = bending * rng.uniform(-1, 1, 2 * N)
    q[3 * N:] = [*rng.uniform(-2, 2, 2), rng.uniform(-np.pi, np.pi), rng.uniform(-3, 3)]
    qd[:N] = rng.uniform(-3, 3, N)
    qd[N:3 * N] = bend_rate * rng.uniform(-1, 1, 2 * N)
    qd[3 * N:] = [*rng.uniform(-1, 1, 2), rng.uniform(-1, 1), rng.uniform(-5, 5)]
    return lay.to_oracle(lay.from_oracle(q, qd))


def residual_scale(lag, q, qd, qdd, held, zbi=False):
    qi = lag.unbent(q) if zbi else q
    terms = [lag.inertial_force(qi, qd, qdd), lag.potential_gradient(q),
             lag.dissipation_force(q, qd), lag.load_force(q, held)]
    return max(np.max(np.abs(x)) for x in terms)


def check_rows(lag, q, qd, qdd, held, rows, zbi=False, tol=1e-9):
    r = lag.residual(q, qd, qdd, held, zero_bending_inertia=zbi)[rows]
    scale = residual_scale(lag, q, qd, qdd, held, zbi)
    err = float(np.max(np.abs(r)) / scale)
    if err >= tol:   # say how much of it is gravity acting through the bent shape
        g_bend = (lag.gravity_force(q) - lag.gravity_force(lag.unbent(q)))[rows]
        left = float(np.max(np.abs(r + g_bend)) / scale)
        raise AssertionError(
            f"residual {err:.3e} of scale {scale:.3e} (rows {list(rows)}); without gravity's "
            f"generalized force through the bending (-dV_g/dq at q minus at alpha = beta = 0: "
            f"max {np.max(np.abs(g_bend)) / scale:.3e}) it would be {left:.3e}")
    return err


# ----------------------------------------------------------------------------- the oracle alone

def small_oracle(ns=(1, 2), gravity=(0.0, 0.0), seed=2, damping=True):
    rng = np.random.default_rng(seed)
    chains = [ChainData(rng.uniform(.5, 1.5, n), rng.uniform(.5, 2, n), rng.uniform(.2, 1, n),
                        rng.uniform(50, 200, n), rng.uniform(10, 50, n),
                        rng.uniform(.05, .5, n) if damping else np.zeros(n),
                        attach=rng.uniform(-.5, .5, 2)) for n in ns]
    base = BaseData(mass=3.0, inertia=0.7, com=[0.1, -0.05], wheel=0.05)
    return BaseLagrangian(chains, base, gravity=gravity), rng


def test_oracle_fixed_limit_is_the_chain_lagrangian():
    """Base coordinates held at 0 with zero rates: the chain rows are lagrangian.py's, for a
    chain attached at the origin; a base at a pose (x, y, psi) only moves and turns the chain
    (the residual of the rotated state equals the unrotated one with loads rotated)."""
    rng = np.random.default_rng(11)
    n = 3
    c = ChainData(rng.uniform(.5, 2.5, n), rng.uniform(.5, 4, n), rng.uniform(.2, 3, n),
                  rng.uniform(1e3, 1e5, n), rng.uniform(10, 200, n), rng.uniform(.05, 2, n))
    ob = BaseLagrangian([c], BaseData())
    old = Lagrangian(c.l, c.m, c.mu, c.EI, c.kappa, c.nu)
    q = np.concatenate([rng.uniform(-3, 3, n), .3 * rng.uniform(-1, 1, 2 * n)])
    qd, qdd = rng.uniform(-2, 2, 3 * n), rng.normal(size=3 * n)
    F = rng.uniform(-10, 10, (n, 2))
    held = np.zeros((n + 2, 3))
    held[:n, :2] = F
    z = np.zeros(4)
    r_new = ob.residual(np.r_[q, z], np.r_[qd, z], np.r_[qdd, z], held)[:3 * n]
    assert rel(r_new, old.residual(q, qd, qdd, F)) < 1e-13
    assert rel(ob.mass_matrix(np.r_[q, z])[:3 * n, :3 * n], old.exact_mass_matrix(q)) < 1e-13
    assert abs(ob.potential(np.r_[q, z]) - old.potential(q)) < 1e-12 * old.potential(q)
    # base turned by psi0 and shifted: same physics with the chain angles shifted by psi0
    psi0 = 0.8
    Rm = np.array([[np.cos(psi0), -np.sin(psi0)], [np.sin(psi0), np.cos(psi0)]])
    q2 = np.r_[q[:n] + psi0, q[n:], 1.0, -2.0, psi0, 0.0]
    held2 = held.copy()
    held2[:n, :2] = F @ Rm.T
    r2 = ob.residual(q2, np.r_[qd, z], np.r_[qdd, z], held2)[:3 * n]
    assert rel(r2, r_new) < 1e-12


def test_oracle_quadrature_and_bending_energy():
    ob, rng = small_oracle((2, 3))
    ob10 = BaseLagrangian(ob.chains, ob.base, gauss_points=10)
    q = rng.uniform(-1, 1, ob.nq)
    qd, qdd = rng.uniform(-2, 2, ob.nq), rng.normal(size=ob.nq)
    assert rel(ob.mass_matrix(q), ob10.mass_matrix(q)) < 1e-13
    assert rel(ob.inertial_force(q, qd, qdd), ob10.inertial_force(q, qd, qdd)) < 1e-13
    N = ob.N
    al, be = q[N:2 * N], q[2 * N:3 * N]
    bend = float(np.sum(2 * ob.EI / ob.l * (al ** 2 + be ** 2 + al * be)))   # paper eq. (6)
    d = ob.hinge_deflections(q)
    hinge = 0.5 * float(np.sum(ob.kappa * d ** 2))
    assert abs(ob.potential(q) - bend - hinge) < 1e-12 * (bend + hinge)
    # hinge 0 of each chain measures phi_1 + alpha_1 - psi
    for first in (0, 2):
        assert abs(d[first] - (q[first] + q[N + first] - q[3 * N + 2])) < 1e-15


def test_oracle_gradients_are_finite_differences():
    """dPi/dq (hinges, bending, gravity through the bent shape) and the loads' virtual work
    against central differences of the potential and of the loaded points' positions."""
    ob, rng = small_oracle((2, 1), gravity=(1.3, -9.81))
    q = rng.uniform(-1, 1, ob.nq)
    h = 1e-6
    E = np.eye(ob.nq)
    fd = np.array([(ob.potential(q + h * e) - ob.potential(q - h * e)) / (2 * h) for e in E])
    assert rel(fd, ob.potential_gradient(q)) < 1e-7
    # gravity alone pulls on the alpha/beta rows (bent shape) and on the base rows
    g = ob.gravity_force(q)
    assert np.all(np.abs(g[ob.N:3 * ob.N]) > 0) and abs(g[3 * ob.N + 1]) > 0


def test_oracle_momentum_rate_is_the_applied_wrench():
    """Along the oracle's own accelerations, dP/dt and dH_O/dt (exact kinematics) equal the
    external force and moment (nodal forces, base force and moment, gravity); hinge and wheel
    motor moments are internal. A consistency check of momentum_rate and external_wrench,
    which test_spacecraft_limits uses on the models."""
    ob, rng = small_oracle((2, 1), gravity=GRAVITY)
    for _ in range(3):
        q, qd = rng.uniform(-1, 1, ob.nq), rng.uniform(-2, 2, ob.nq)
        held = rng.uniform(-10, 10, (ob.N + 2, 3))
        held[ob.N + 1, :2] = 0
        qdd = ob.accelerations(q, qd, held)
        dP, dH, sP, sH = ob.momentum_rate(q, qd, qdd, scale=True)
        F, M = ob.external_wrench(q, held)
        assert np.max(np.abs(dP - F)) < 1e-12 * sP and abs(dH - M) < 1e-12 * sH
        # and the moment check can fail: a hinge torque counted as external breaks it
        assert abs(dH - M - held[0, 2]) > 1e-6 * sH


@pytest.mark.slow
def test_oracle_trajectories_conserve_momentum():
    """Integrating the oracle's own equations (scipy DOP853, 1e-11): with internal damping,
    hinge springs and a wheel motor torque, P, H_O and H_cm are constant; under gravity
    P - M g t and H_cm are constant (uniform gravity has no moment about the centre of mass).
    The energy is conserved without damping."""
    for g in [(0.0, 0.0), (0.3, -9.81)]:
        ob, rng = small_oracle((1, 1), gravity=g, seed=3)
        nq = ob.nq
        q0 = np.r_[rng.uniform(-3, 3, 2), 0.05 * rng.uniform(-1, 1, 4), 0.1, -0.2, 0.3, 0.0]
        qd0 = rng.uniform(-1, 1, nq)
        held = np.zeros((4, 3))
        held[3, 2] = 0.3

        def f(t, y):
            return np.r_[y[nq:], ob.accelerations(y[:nq], y[nq:], held)]

        sol = solve_ivp(f, (0, 0.3), np.r_[q0, qd0], method="DOP853", rtol=1e-11, atol=1e-11,
                        dense_output=True)
        P0, H0, Hc0, _, M = ob.momentum(q0, qd0)
        for t in (0.1, 0.2, 0.3):
            y = sol.sol(t)
            P, H, Hc, _, _ = ob.momentum(y[:nq], y[nq:])
            assert np.max(np.abs(P - np.asarray(g) * M * t - P0)) < 1e-8 * max(1, np.abs(P0).max())
            assert abs(Hc - Hc0) < 1e-8 * max(1, abs(Hc0))
            if not any(g):
                assert abs(H - H0) < 1e-8 * max(1, abs(H0))
    ob, rng = small_oracle((2,), gravity=(0.0, -9.81), seed=4, damping=False)
    nq = ob.nq
    q0 = np.r_[rng.uniform(-3, 3, 2), 0.05 * rng.uniform(-1, 1, 4), 0, 0, 0.3, 0.0]
    qd0 = rng.uniform(-1, 1, nq)
    sol = solve_ivp(lambda t, y: np.r_[y[nq:], ob.accelerations(y[:nq], y[nq:])], (0, 0.3),
                    np.r_[q0, qd0], method="DOP853", rtol=1e-11, atol=1e-11)
    e = [ob.kinetic_energy(y[:nq], y[nq:]) + ob.potential(y[:nq]) for y in sol.y.T]
    assert np.ptp(e) < 1e-8 * max(abs(e[0]), 1.0)


def test_oracle_detects_a_wrong_coefficient():
    """The oracle's own accelerations fail a perturbed oracle (base inertia 1% off, attach
    point mirrored, hinge 0 measured without psi): the residual check can fail."""
    ob, rng = small_oracle((2, 1), gravity=GRAVITY)
    q, qd = rng.uniform(-1, 1, ob.nq), rng.uniform(-2, 2, ob.nq)
    q[ob.i_bend] = 0
    qdd = ob.accelerations(q, qd)
    assert np.max(np.abs(ob.residual(q, qd, qdd))) < 1e-10 * residual_scale(ob, q, qd, qdd, None)
    for base, chains in [
            (BaseData(ob.base.mass, ob.base.inertia * 1.01, ob.base.com, ob.base.wheel), ob.chains),
            (ob.base, [ChainData(c.l, c.m, c.mu, c.EI, c.kappa, c.nu, attach=c.attach * [-1, 1])
                       for c in ob.chains])]:
        bad = BaseLagrangian(chains, base, gravity=GRAVITY)
        err = np.max(np.abs(bad.residual(q, qd, qdd))) / residual_scale(bad, q, qd, qdd, None)
        assert err > 1e-5, err


# ----------------------------------------------------------------------------- the models

@needs_spacecraft()
@pytest.mark.parametrize("ns,seed", SCENES)
def test_full_model_exact_at_zero_bending(ns, seed):
    """Free base + wheel + gravity + loads: full.rhs satisfies every exact row at alpha = beta
    = 0, random rates (bending rates included) and random held inputs."""
    d, rng, scripted = random_scene(ns, seed)
    model = make("full", d)
    lag = oracle_from_dict(d)
    lay = Layout("full", lag.N, True, True)
    errs = []
    for _ in range(3):
        q, qd = random_state(lay, rng, bending=0.0)
        held = random_held(lag.N, rng)
        t = float(rng.uniform(0, 2))
        dy = model.rhs(t, lay.from_oracle(q, qd), held)
        assert np.array_equal(dy[:lay.dof], lay.from_oracle(q, qd)[lay.dof:])
        qdd = lay.qdd_to_oracle(dy)
        errs.append(check_rows(lag, q, qd, qdd, held + scripted, lay.idx))
    print(f"\n[full, zero bending, ns={ns}] max residual {max(errs):.2e}")


@needs_spacecraft()
@pytest.mark.parametrize("ns,seed", SCENES)
def test_full_model_at_bending_is_zero_bending_inertia_plus_exact_forces(ns, seed):
    """Nonzero alpha, beta: full.rhs satisfies the equations whose inertial force is the exact
    one at alpha = beta = 0 (the paper's approximation) and whose potential (hinges, bending,
    gravity through the bent shape), damping and loads are exact at q."""
    d, rng, scripted = random_scene(ns, seed + 50)
    model = make("full", d)
    lag = oracle_from_dict(d)
    lay = Layout("full", lag.N, True, True)
    for _ in range(3):
        q, qd = random_state(lay, rng, bending=0.02)
        held = random_held(lag.N, rng)
        qdd = lay.qdd_to_oracle(model.rhs(0.3, lay.from_oracle(q, qd), held))
        check_rows(lag, q, qd, qdd, held + scripted, lay.idx, zbi=True)
        # and the exact inertia at that bending would NOT be satisfied (the test can tell)
        r = lag.residual(q, qd, qdd, held + scripted)[lay.idx]
        assert np.max(np.abs(r)) > 1e-7 * residual_scale(lag, q, qd, qdd, held + scripted)


@needs_spacecraft()
@pytest.mark.parametrize("ns,seed", SCENES)
def test_rigid_model_is_the_exact_lagrangian_without_bending(ns, seed):
    d, rng, scripted = random_scene(ns, seed + 100)
    model = make("rigid", d)
    lag = oracle_from_dict(d)
    lay = Layout("rigid", lag.N, True, True)
    for _ in range(3):
        q, qd = random_state(lay, rng)
        held = random_held(lag.N, rng)
        qdd = lay.qdd_to_oracle(model.rhs(0.1, lay.from_oracle(q, qd), held))
        check_rows(lag, q, qd, qdd, held + scripted, lay.idx)


@needs_spacecraft()
@pytest.mark.parametrize("ns,seed", SCENES)
def test_reduced_model_is_the_full_equations_without_bending_rates(ns, seed):
    """(phi'' from reduced.rhs, alpha, beta from reduced.bending, alpha' = beta' = alpha'' =
    beta'' = 0) satisfies every row of the full model's equations (zero-bending inertia, exact
    forces at the quasi-static bending), the alpha/beta rows included."""
    d, rng, scripted = random_scene(ns, seed + 200)
    model = make("reduced", d)
    lag = oracle_from_dict(d)
    lay = Layout("reduced", lag.N, True, True)
    N = lag.N
    for _ in range(3):
        q, qd = random_state(lay, rng)
        held = random_held(N, rng)
        y = lay.from_oracle(q, qd)
        qdd = lay.qdd_to_oracle(model.rhs(0.4, y, held))
        al, be = model.bending(0.4, y, held)
        q[N:2 * N], q[2 * N:3 * N] = al, be
        assert np.max(np.abs(np.r_[al, be])) > 0
        rows = np.r_[lay.idx, np.arange(N, 3 * N)]
        check_rows(lag, q, qd, qdd, held + scripted, rows, zbi=True)


# ----------------------------------------------------------------------------- prescribed base

RATE, T_SPIN, D_X, T_X, A_Y, F_Y = 2.5, 3.0, 0.5, 2.0, 0.3, 0.7
BASE0 = (0.2, -0.1, 0.3)      # x_0, y_0, psi_0 of the prescribed motions q = q_0 + p(t)


def prescribed_scene(ns, seed, translate, model_gravity=GRAVITY):
    motion = {"psi": {"shape": "spin_up", "rate": RATE, "duration": T_SPIN}}
    base = {"mode": "prescribed", "motion": motion}
    if translate:
        motion["x"] = {"shape": "cycloidal", "amplitude": D_X, "duration": T_X}
        motion["y"] = {"shape": "harmonic", "amplitude": A_Y, "frequency": F_Y}
        base["initial"] = dict(zip(("x", "y", "psi"), BASE0))
    d, rng, scripted = random_scene(ns, seed, gravity=model_gravity, base=base)
    return d, rng, scripted


def prescribed_base(t, translate):
    """(q, q', q'') (3,) of the base (x_B, y_B, psi) at t, in closed form (sc_common)."""
    parts = [(0.0, 0.0, 0.0), (0.0, 0.0, 0.0), spin_up(t, RATE, T_SPIN)]
    q0 = np.zeros(3)
    if translate:
        parts[0], parts[1] = cycloidal(t, D_X, T_X), harmonic(t, A_Y, F_Y)
        q0 = np.array(BASE0)
    p = np.array(parts).T
    return q0 + p[0], p[1], p[2]


@needs_spacecraft()
@pytest.mark.parametrize("name", ["full", "rigid", "reduced"])
@pytest.mark.parametrize("ns,seed,translate", [((2,), 301, False), ((1, 3), 302, False),
                                               ((2, 1), 303, True)])
def test_prescribed_base_chain_rows(name, ns, seed, translate):
    """A spin_up psi(t) base (and, translating, a cycloidal x(t) and a harmonic y(t) from an
    initial pose): the chain rows with the base's q, q', q'' known in closed form."""
    d, rng, scripted = prescribed_scene(ns, seed, translate)
    model = make(name, d)
    lag = oracle_from_dict(d)
    lay = Layout(name, lag.N, False, False)
    N = lag.N
    for t in (0.7, 1.9, 4.0):
        bq, bqd, bqdd = prescribed_base(t, translate)
        q, qd = random_state(lay, rng)
        q, qd = lay.to_oracle(lay.from_oracle(q, qd), bq, bqd)
        held = random_held(N, rng, free=False)
        y = lay.from_oracle(q, qd)
        qdd = lay.qdd_to_oracle(model.rhs(t, y, held), bqdd)
        rows = lay.idx
        zbi = False
        if name == "reduced":
            al, be = model.bending(t, y, held)
            q[N:2 * N], q[2 * N:3 * N] = al, be
            rows, zbi = np.r_[lay.idx, np.arange(N, 3 * N)], True
        check_rows(lag, q, qd, qdd, held + scripted, rows, zbi=zbi)
        if np.any(bqdd):   # the base's acceleration matters: dropping it breaks the rows
            qdd0 = qdd.copy()
            qdd0[lag.i_base] = 0
            r = lag.residual(q, qd, qdd0, held + scripted, zbi)[lay.idx]
            assert np.max(np.abs(r)) > 1e-6 * residual_scale(lag, q, qd, qdd, held + scripted)


@needs_spacecraft()
@pytest.mark.parametrize("name", ["full", "rigid", "reduced"])
@pytest.mark.parametrize("ns,seed,translate", [((2,), 311, False), ((1, 3), 312, True),
                                               ((3, 1, 2), 313, True)])
def test_base_reaction_is_the_support_force_of_the_oracle(name, ns, seed, translate):
    """What the prescribed base gives each chain (rod_sim.core.momentum.base_reaction: the
    force F_c at the chain's node 0 r0_c, the moment M_c the chain puts on the base through
    its hinge 0), summed on the massless base, is the support's generalized force: the
    oracle's residual in the base rows, x_B, y_B: sum F_c, psi: sum (r0_c - r_B) x F_c - M_c
    (the chains' accelerations from the model, the base's from its motion; gravity, nodal
    loads and hinge motors on)."""
    from rod_sim.core.momentum import base_reaction

    d, rng, scripted = prescribed_scene(ns, seed, translate)
    model = make(name, d)
    lag = oracle_from_dict(d)
    lay = Layout(name, lag.N, False, False)
    N = lag.N
    attach = np.array([c["attach"] for c in d["chains"]])
    for t in (0.7, 1.9):
        bq, bqd, bqdd = prescribed_base(t, translate)
        q, qd = random_state(lay, rng, bending=0.05 if name == "full" else 0.0)
        q, qd = lay.to_oracle(lay.from_oracle(q, qd), bq, bqd)
        held = random_held(N, rng, free=False)
        y = lay.from_oracle(q, qd)
        qdd = lay.qdd_to_oracle(model.rhs(t, y, held), bqdd)
        zbi = name != "rigid"
        if name == "reduced":
            q[N:2 * N], q[2 * N:3 * N] = model.bending(t, y, held)
        force, moment = base_reaction(model, t, y, held)
        assert force.shape == (len(ns), 2) and moment.shape == (len(ns),)
        c, s = np.cos(bq[2]), np.sin(bq[2])
        arm = np.c_[c * attach[:, 0] - s * attach[:, 1], s * attach[:, 0] + c * attach[:, 1]]
        got = np.r_[force.sum(axis=0),
                    np.sum(arm[:, 0] * force[:, 1] - arm[:, 1] * force[:, 0]) - moment.sum()]
        want = lag.residual(q, qd, qdd, held + scripted, zero_bending_inertia=zbi)[lag.i_base]
        scale = residual_scale(lag, q, qd, qdd, held + scripted, zbi)
        assert np.max(np.abs(got - want)) < 1e-9 * scale, (got, want, scale)
        assert np.max(np.abs(want)) > 1e-3 * scale      # the support carries something


@needs_spacecraft()
@pytest.mark.parametrize("name", ["rigid", "reduced"])
@pytest.mark.parametrize("ns,seed,translate", [((2,), 321, False), ((1, 3), 322, True)])
def test_balance_pair_on_a_prescribed_base_is_the_oracles_energy_rate(name, ns, seed,
                                                                      translate):
    """A balance sample's two moved states y +- h f on a prescribed base, in one compiled call
    (State.moved_net_powers): each is the rate of the oracle's mechanical energy there, the
    power of the loads, motors and dampers on every coordinate's rate plus the support's
    generalized force (the residual's base rows, with the model's accelerations and the
    motion's) on the base's rates (gravity, nodal loads and hinge motors on)."""
    from rod_sim.core.validity import RATE_STEP as h

    d, rng, scripted = prescribed_scene(ns, seed, translate)
    model = make(name, d)
    assert model.paired_balance
    lag = oracle_from_dict(d)
    lay = Layout(name, lag.N, False, False)
    N = lag.N
    zbi = name != "rigid"
    for t in (0.7, 1.9):
        bq, bqd, _ = prescribed_base(t, translate)
        q, qd = random_state(lay, rng)
        q, qd = lay.to_oracle(lay.from_oracle(q, qd), bq, bqd)
        held = random_held(N, rng, free=False)
        y = lay.from_oracle(q, qd)
        s = model.state(t, y, held)
        hf = h * s.f
        pair = s.moved_net_powers(t + h, t - h, hf)
        assert pair is not None
        for got, tm, ym in zip(pair, (t + h, t - h), (y + hf, y - hf)):
            bq, bqd, bqdd = prescribed_base(tm, translate)
            qm, qdm = lay.to_oracle(ym, bq, bqd)
            qdd = lay.qdd_to_oracle(model.rhs(tm, ym, held), bqdd)
            if name == "reduced":
                qm[N:2 * N], qm[2 * N:3 * N] = model.bending(tm, ym, held)
            loads = held + scripted
            support = lag.residual(qm, qdm, qdd, loads, zero_bending_inertia=zbi)[lag.i_base]
            want = float((lag.load_force(qm, loads) - lag.dissipation_force(qm, qdm)) @ qdm
                         + support @ qdm[lag.i_base])
            scale = residual_scale(lag, qm, qdm, qdd, loads, zbi) * np.max(np.abs(qdm))
            assert abs(got - want) < 1e-9 * scale, (got, want, scale)
            assert abs(support @ qdm[lag.i_base]) > 1e-3 * scale   # the base delivers power


# ----------------------------------------------------------------------------- the check can fail

@needs_spacecraft()
def test_comparison_detects_a_wrong_coefficient():
    """The model's answer passes the oracle to 1e-9 and fails it by far when one coefficient
    of the oracle is wrong: base inertia +1%, wheel inertia +1%, base centre of mass moved by
    1 cm, one attach point mirrored."""
    d, rng, scripted = random_scene((2, 1), 404)
    model = make("full", d)
    lag = oracle_from_dict(d)
    lay = Layout("full", lag.N, True, True)
    q, qd = random_state(lay, rng)
    held = random_held(lag.N, rng)
    qdd = lay.qdd_to_oracle(model.rhs(0.0, lay.from_oracle(q, qd), held))
    check_rows(lag, q, qd, qdd, held + scripted, lay.idx)
    b = lag.base
    variants = [
        (BaseData(b.mass, b.inertia * 1.01, b.com, b.wheel), lag.chains),
        (BaseData(b.mass, b.inertia, b.com, b.wheel * 1.01), lag.chains),
        (BaseData(b.mass, b.inertia, b.com + [0.01, 0.0], b.wheel), lag.chains),
        (b, [lag.chains[0]] + [ChainData(c.l, c.m, c.mu, c.EI, c.kappa, c.nu,
                                         attach=c.attach * [-1, 1]) for c in lag.chains[1:]]),
    ]
    for base, chains in variants:
        bad = BaseLagrangian(chains, base, gravity=lag.g)
        r = bad.residual(q, qd, qdd, held + scripted)[lay.idx]
        err = np.max(np.abs(r)) / residual_scale(bad, q, qd, qdd, held + scripted)
        assert err > 1e-6, err
