"""Closed forms and limits of the chain on a spacecraft (issue 25, SPEC section 8).

Every expected value here is computed in this file from the geometry (with the help of the
independent ``lagrangian_base`` oracle for positions, masses and momentum, which imports
nothing from rod_sim); rod_sim is asked only through ``make_model``, ``Simulator`` and the
models' public methods.

* a base of 1e12 kg / 1e12 kg m^2 reproduces the fixed base (1e-9 rad, every model);
* a prescribed zero motion is the fixed base bit for bit;
* all hinges locked (and rods rigid): one free rigid body -- the centre of mass moves
  uniformly, the body turns at omega = H_cm / I_cm;
* a reaction-wheel spin-up of a locked chain: psi'' = -T / I_sys (wheel's axial inertia
  excluded), theta_w'' = T / J_w + T / I_sys, centre of mass at rest;
* momentum: the rigid model (and the full model at zero bending) conserve P and H exactly
  without external loads (instantaneous rates exact, trajectories to integrator tolerance),
  dP/dt = applied force and dH/dt = applied moment (instantaneous; along a run under timed
  step loads, integrated in closed form);
* gravity: hanging one- and two-rod chains (equilibrium and small-swing periods from their
  linearisation, derived below), and a heavy clamped cantilever's sag against Euler-Bernoulli.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import CubicSpline
from scipy.linalg import eigh, null_space
from scipy.optimize import brentq

from sc_common import (Layout, chain_dict, free_base, needs_spacecraft, oracle_from_dict, rel,
                       scene_dict)

MODELS = ["rigid", "reduced", "full"]
SC = needs_spacecraft()     # every test that asks rod_sim; the closed forms' own checks run alone


def make(name, d):
    from rod_sim.core.models import make_model
    from rod_sim.core.scene import Scene
    return make_model(name, Scene.from_dict(d))


def run(model, t_end, rate_hz=100.0, tol=1e-12, integrator="dop853-jit"):
    from rod_sim.core.integrators import make_integrator
    from rod_sim.core.simulator import Simulator
    sim = Simulator(model, make_integrator(integrator, rtol=tol, atol=tol))
    return sim.run(t_end, rate_hz)


def layout_of(name, d):
    N = sum(c["rods"]["count"] for c in d["chains"])
    b = d.get("base") or {"mode": "fixed"}
    return Layout(name, N, b["mode"] == "free", b["mode"] == "free" and "wheel" in b)


def with_initial(c, phi, phi_rate=None):
    c = dict(c)
    c["initial"] = {"phi": [float(v) for v in np.atleast_1d(phi)]}
    if phi_rate is not None:
        c["initial"]["phi_rate"] = [float(v) for v in np.atleast_1d(phi_rate)]
    return c


def rigid_chain(c, locked=True):
    """The chain with rigid rods (and every hinge locked)."""
    c = dict(c)
    c["rods"] = dict(c["rods"], rigid=True)
    if locked:
        c["hinges"] = dict(c["hinges"], locked=True)
    return c


def two_chains(seed, rigid=False, locked=False):
    rng = np.random.default_rng(seed)
    a = with_initial(chain_dict("left", 2, rng, attach=[0.8, 0.1], EI=2e3),
                     rng.uniform(-0.5, 0.5, 2), rng.uniform(-1, 1, 2))
    b = with_initial(chain_dict("right", 3, rng, attach=[-0.7, -0.2], EI=2e3),
                     np.pi + rng.uniform(-0.5, 0.5, 3), rng.uniform(-1, 1, 3))
    if rigid:
        a, b = rigid_chain(a, locked), rigid_chain(b, locked)
    return [a, b], rng


# ------------------------------------------------------------------------- heavy base, zero motion

@SC
@pytest.mark.slow
@pytest.mark.parametrize("name", MODELS)
def test_heavy_free_base_is_the_fixed_base(name):
    """Two chains with constant nodal loads, gravity off, 0.3 s: a free base of 1e12 kg and
    1e12 kg m^2 at rest gives the fixed base's angles (and end slopes) to 1e-9 rad."""
    chains, _ = two_chains(7)
    loads = [{"chain": "left", "node": 2, "axis": "y", "shape": "constant", "amplitude": 15.0,
              "start": 0.0},
             {"chain": "right", "node": 1, "axis": "x", "shape": "constant", "amplitude": -8.0,
              "start": 0.0}]
    fixed = scene_dict(chains, {"mode": "fixed"}, None, loads)
    heavy = scene_dict(chains, free_base(mass=1e12, inertia=1e12, com=(0.0, 0.0), wheel=0.0),
                       None, loads)
    lf, lh = layout_of(name, fixed), layout_of(name, heavy)
    yf = run(make(name, fixed), 0.3).y
    yh = run(make(name, heavy), 0.3).y
    nc = lf.dof      # the chain coordinates come first in both layouts
    err = np.max(np.abs(yf[:, :nc] - yh[:, :nc]))
    base_move = np.max(np.abs(yh[:, nc:lh.dof]))
    print(f"\n[heavy base, {name}] max |chain coordinate difference| {err:.2e} rad, "
          f"base pose moved {base_move:.2e}")
    assert err < 1e-9
    assert base_move < 1e-9


@SC
@pytest.mark.slow
@pytest.mark.parametrize("motion", [{"psi": {"shape": "hold"}},
                                    {"psi": {"shape": "spin_up", "rate": 0.0, "duration": 1.0}},
                                    {"psi": {"shape": "hold"}, "x": {"shape": "hold"},
                                     "y": {"shape": "hold"}}])
@pytest.mark.parametrize("name", MODELS)
def test_prescribed_zero_motion_is_the_fixed_base_bit_for_bit(name, motion):
    """Gravity on, two chains, 0.2 s (before the spin_up's breakpoint at 1 s)."""
    chains, _ = two_chains(8)
    g = (0.0, -9.81)
    fixed = scene_dict(chains, {"mode": "fixed"}, g)
    still = scene_dict(chains, {"mode": "prescribed", "motion": motion}, g)
    a, b = run(make(name, fixed), 0.2, tol=1e-9), run(make(name, still), 0.2, tol=1e-9)
    assert a.y.shape == b.y.shape
    assert np.array_equal(a.y, b.y), np.max(np.abs(a.y - b.y))


# ------------------------------------------------------------------------- locked: one rigid body

def locked_scene(seed, wheel=0.0, loads=(), base_twist=(0.3, -0.2, 0.4)):
    chains, rng = two_chains(seed, rigid=True, locked=True)
    # consistent initial rates: every rod turns with the base
    for c in chains:
        c["initial"]["phi_rate"] = [float(base_twist[2])] * c["rods"]["count"]
    base = free_base(mass=30.0, inertia=8.0, com=(0.05, 0.1), wheel=wheel,
                     initial={"x": 0.2, "y": -0.1, "psi": 0.0, "x_rate": base_twist[0],
                              "y_rate": base_twist[1], "psi_rate": base_twist[2]})
    return scene_dict(chains, base, None, loads)


def frozen_offsets(lag, lay, y):
    """phi_k - psi (N,) of a state (constant for a rigid body)."""
    q, _ = lay.to_oracle(y)
    return q[:lag.N] - q[lag.i_psi]


@SC
@pytest.mark.slow
@pytest.mark.parametrize("name", MODELS)
def test_all_locked_is_one_free_rigid_body(name):
    """Rigid rods, every hinge locked, free base with an initial twist, no loads, 1 s: the
    centre of mass moves at P/M, every angle turns at omega = H_cm / I_cm with I_cm computed
    here from the geometry (rods m l^2/12 + parallel axes, node masses, base), the shape is
    frozen."""
    d = locked_scene(21)
    lag, lay = oracle_from_dict(d), layout_of(name, d)
    tr = run(make(name, d), 1.0, rate_hz=20)
    q0, qd0 = lay.to_oracle(tr.y[0])
    M, com0, I = lag.rigid_inertia(q0)
    P, H, Hc, com_o, mass = lag.momentum(q0, qd0)
    assert abs(mass - M) < 1e-12 * M and rel(com_o, com0) < 1e-12
    omega, v = Hc / I, P / M
    assert abs(omega - qd0[lag.i_psi]) < 1e-12 * abs(omega)   # the state is a rigid motion
    off0 = frozen_offsets(lag, lay, tr.y[0])
    worst = {"com": 0.0, "psi": 0.0, "shape": 0.0}
    for t, y in zip(tr.t, tr.y):
        q, _ = lay.to_oracle(y)
        worst["com"] = max(worst["com"], np.max(np.abs(lag.rigid_inertia(q)[1] - com0 - v * t)))
        worst["psi"] = max(worst["psi"], abs(q[lag.i_psi] - q0[lag.i_psi] - omega * t))
        worst["shape"] = max(worst["shape"], np.max(np.abs(frozen_offsets(lag, lay, y) - off0)))
        if name == "full":
            worst["shape"] = max(worst["shape"], np.max(np.abs(q[lag.i_bend])))
    print(f"\n[locked rigid body, {name}] omega {omega:.6f} rad/s; max errors {worst}")
    assert worst["com"] < 1e-9 and worst["psi"] < 1e-9 and worst["shape"] < 1e-9


@SC
@pytest.mark.slow
def test_locking_projection_conserves_momentum():
    """Rigid model, locked hinges, chain initial rates NOT those of the base: the initial
    projection onto the constraint is an internal impulse, so the body turns at
    H_cm / I_cm and its centre of mass moves at P / M of the requested (unprojected) state."""
    d = locked_scene(22)
    for c, w in zip(d["chains"], (1.5, -0.7)):
        c["initial"]["phi_rate"] = [w] * c["rods"]["count"]
    lag, lay = oracle_from_dict(d), layout_of("rigid", d)
    model = make("rigid", d)
    N = lag.N      # the requested (unprojected) state, built here from the scene dict
    q = np.zeros(lag.nq)
    qd = np.zeros(lag.nq)
    i = 0
    for c in d["chains"]:
        n = c["rods"]["count"]
        q[i:i + n], qd[i:i + n] = c["initial"]["phi"], c["initial"]["phi_rate"]
        i += n
    b = d["base"]["initial"]
    q[3 * N:3 * N + 3] = b["x"], b["y"], b["psi"]
    qd[3 * N:3 * N + 3] = b["x_rate"], b["y_rate"], b["psi_rate"]
    M, _, I = lag.rigid_inertia(q)
    P, _, Hc, _, _ = lag.momentum(q, qd)
    tr = run(model, 0.2, rate_hz=10)
    q0, qd0 = lay.to_oracle(tr.y[0])
    P_after = lag.momentum(q0, qd0)[0]
    print(f"\n[locking projection] omega {qd0[lag.i_psi]:.12f} vs H_cm/I_cm {Hc / I:.12f}; "
          f"P after {P_after} vs requested {P}")
    assert abs(qd0[lag.i_psi] - Hc / I) < 1e-10 * abs(Hc / I)
    assert rel(P_after, P) < 1e-10


@SC
@pytest.mark.slow
@pytest.mark.parametrize("name", MODELS)
def test_wheel_spin_up_of_a_locked_chain(name):
    """A constant wheel motor torque T from t = 0 on a locked rigid spacecraft at rest:
    psi(t) = psi0 - T t^2 / (2 I_sys) (I_sys about the system's centre of mass, the wheel's
    axial inertia excluded), theta_w(t) = T t^2 / 2 (1/J_w + 1/I_sys), centre of mass fixed."""
    T, Jw = 0.8, 0.05
    d = locked_scene(23, wheel=Jw, base_twist=(0.0, 0.0, 0.0),
                     loads=[{"node": "wheel", "axis": "moment", "shape": "constant",
                             "amplitude": T, "start": 0.0}])
    lag, lay = oracle_from_dict(d), layout_of(name, d)
    tr = run(make(name, d), 1.0, rate_hz=20)
    q0, _ = lay.to_oracle(tr.y[0])
    _, com0, I = lag.rigid_inertia(q0)
    worst = np.zeros(3)
    for t, y in zip(tr.t, tr.y):
        q, qd = lay.to_oracle(y)
        worst = np.maximum(worst, [
            abs(q[lag.i_psi] - (q0[lag.i_psi] - T * t * t / (2 * I))),
            abs(q[lag.i_wheel] - T * t * t / 2 * (1 / Jw + 1 / I)) / max(1.0, T * t * t / Jw),
            np.max(np.abs(lag.rigid_inertia(q)[1] - com0))])
    print(f"\n[wheel spin-up, {name}] I_sys {I:.6f} kg m^2; max errors psi {worst[0]:.2e} rad, "
          f"theta_w {worst[1]:.2e} (rel), com {worst[2]:.2e} m")
    assert worst[0] < 1e-9 and worst[1] < 1e-9 and worst[2] < 1e-9


# ----------------------------------------------------------------------------- momentum

def random_free(seed, ns=(2, 1, 3), gravity=None, loads=()):
    rng = np.random.default_rng(seed)
    chains = [with_initial(chain_dict(f"c{i}", n, rng, EI=3e3), rng.uniform(-3, 3, n),
                           rng.uniform(-1, 1, n)) for i, n in enumerate(ns)]
    base = free_base(mass=25.0, inertia=6.0, com=(0.1, 0.05), wheel=0.2,
                     initial={"x": 0.0, "y": 0.0, "psi": 0.3, "x_rate": 0.1, "y_rate": -0.2,
                              "psi_rate": 0.5})
    base["wheel"]["rate"] = 3.0
    return scene_dict(chains, base, gravity, loads), rng


def random_model_state(lag, lay, rng, bending=0.0):
    q, qd = np.zeros(lag.nq), np.zeros(lag.nq)
    q[:lag.N] = rng.uniform(-3, 3, lag.N)
    q[lag.i_bend] = bending * rng.uniform(-1, 1, 2 * lag.N)
    q[3 * lag.N:] = rng.uniform(-1, 1, 4)
    qd[:lag.N] = rng.uniform(-2, 2, lag.N)
    qd[lag.i_bend] = rng.uniform(-1, 1, 2 * lag.N)
    qd[3 * lag.N:] = rng.uniform(-2, 2, 4)
    return lay.to_oracle(lay.from_oracle(q, qd))


@SC
@pytest.mark.parametrize("name", ["rigid", "full"])
def test_momentum_rate_is_the_applied_wrench(name):
    """Instantaneous and exact: with random held nodal forces, hinge motor moments, base force
    and moment, wheel torque and gravity, the model's accelerations give (oracle's exact
    kinematics) dP/dt = sum F + M g and dH_O/dt = sum r x F + M_base + moment of gravity; with
    nothing external (gravity off, only hinge and wheel motor moments) both are 0 to
    round-off. Full model at zero bending (where it is exact). Also model.momentum agrees
    with the oracle's momentum."""
    for g, external in (((0.4, -9.81), True), (None, False)):
        d, rng = random_free(31 if external else 32, gravity=g)
        model = make(name, d)
        lag, lay = oracle_from_dict(d), layout_of(name, d)
        for _ in range(3):
            q, qd = random_model_state(lag, lay, rng)
            held = np.zeros((lag.N + 2, 3))
            held[:lag.N, 2] = rng.uniform(-5, 5, lag.N)
            held[lag.N + 1, 2] = rng.uniform(-1, 1)
            if external:
                held[:lag.N, :2] = rng.uniform(-20, 20, (lag.N, 2))
                held[lag.N] = rng.uniform(-30, 30, 3)
            y = lay.from_oracle(q, qd)
            qdd = lay.qdd_to_oracle(model.rhs(0.0, y, held))
            dP, dH, sP, sH = lag.momentum_rate(q, qd, qdd, scale=True)
            F, Mo = lag.external_wrench(q, held)
            P, H, Hc, com, mass = lag.momentum(q, qd)
            eP, eH = np.max(np.abs(dP - F)) / sP, abs(dH - Mo) / sH
            print(f"\n[{name}, external={external}] |dP/dt - F| {eP:.1e}, |dH/dt - M| {eH:.1e} "
                  f"(of sum |dm a|, sum |r x dm a|)")
            assert eP < 1e-11 and eH < 1e-11, (dP, F, dH, Mo)
            m = model.momentum(0.0, y, held)
            assert rel(m.linear, P) < 1e-12 and abs(m.angular_origin - H) < 1e-12 * max(1, abs(H))
            assert abs(m.angular_com - Hc) < 1e-12 * max(1, abs(Hc))
            assert rel(m.com, com) < 1e-12 and abs(m.mass - mass) < 1e-12 * mass


@SC
@pytest.mark.slow
def test_rigid_model_conserves_momentum_along_a_run():
    """Three chains with springs, dampers and a wheel motor torque (all internal), gravity off,
    1 s at rtol 1e-12: P, H_O, H_cm from model.momentum stay constant to 1e-10 relative."""
    d, _ = random_free(33, loads=[{"node": "wheel", "axis": "moment", "shape": "constant",
                                   "amplitude": 0.7, "start": 0.0}])
    model = make("rigid", d)
    tr = run(model, 1.0, rate_hz=50)
    m = [model.momentum(t, y) for t, y in zip(tr.t, tr.y)]
    P = np.array([x.linear for x in m])
    H = np.array([x.angular_origin for x in m])
    Hc = np.array([x.angular_com for x in m])
    dP = np.max(np.abs(P - P[0])) / np.max(np.abs(P[0]))
    dH = np.max(np.abs(H - H[0])) / abs(H[0])
    dHc = np.max(np.abs(Hc - Hc[0])) / abs(Hc[0])
    print(f"\n[rigid, no external load, 1 s] drift P {dP:.2e}, H_O {dH:.2e}, H_cm {dHc:.2e}")
    assert dP < 1e-10 and dH < 1e-10 and dHc < 1e-10


def _step_integral(t, start, duration):
    """int_0^t of a unit step on [start, start + duration)."""
    return np.clip(t - start, 0.0, duration)


@SC
@pytest.mark.slow
def test_momentum_follows_timed_loads():
    """Rigid model, gravity off, timed step loads: nodal forces and a base force change P by
    their closed-form impulse; a base moment step changes H_O by its angular impulse (a
    second scene with moments only, so r x F does not enter)."""
    loads_P = [
        {"chain": "c0", "node": 2, "axis": "x", "shape": "step", "amplitude": 12.0,
         "start": 0.1, "duration": 0.3},
        {"chain": "c2", "node": 3, "axis": "y", "shape": "step", "amplitude": -7.0,
         "start": 0.25, "duration": 0.4},
        {"node": "base", "axis": "y", "shape": "step", "amplitude": 20.0, "start": 0.5,
         "duration": 0.2}]
    d, _ = random_free(34, loads=loads_P)
    model = make("rigid", d)
    tr = run(model, 1.0, rate_hz=20)
    P0 = model.momentum(0.0, tr.y[0]).linear
    errs = []
    for t, y in zip(tr.t, tr.y):
        imp = np.array([12.0 * _step_integral(t, 0.1, 0.3),
                        -7.0 * _step_integral(t, 0.25, 0.4) + 20.0 * _step_integral(t, 0.5, 0.2)])
        errs.append(np.max(np.abs(model.momentum(t, y).linear - P0 - imp)))
    loads_H = [{"node": "base", "axis": "moment", "shape": "step", "amplitude": 9.0,
                "start": 0.2, "duration": 0.5},
               {"node": "wheel", "axis": "moment", "shape": "constant", "amplitude": 0.4,
                "start": 0.0}]
    d, _ = random_free(35, loads=loads_H)
    model = make("rigid", d)
    tr = run(model, 1.0, rate_hz=20)
    m0 = model.momentum(0.0, tr.y[0])
    errH = []
    for t, y in zip(tr.t, tr.y):
        m = model.momentum(t, y)
        ang = 9.0 * _step_integral(t, 0.2, 0.5)
        errH.append(max(abs(m.angular_origin - m0.angular_origin - ang),
                        np.max(np.abs(m.linear - m0.linear))))
    print(f"\n[timed loads] max |P - P0 - impulse| {max(errs):.2e} kg m/s, "
          f"max |H - H0 - angular impulse| {max(errH):.2e} kg m^2/s")
    assert max(errs) < 1e-9 and max(errH) < 1e-9


# ----------------------------------------------------------------------------- gravity

def hanging_chain(n, rng, rest, kappa, name="h"):
    c = chain_dict(name, n, rng, attach=[0.0, 0.0], nu=0.0, kappa=kappa)
    c["hinges"]["rest_angle"] = [float(v) for v in rest]
    return c


def pendulum_1(c, g):
    """One rod (l, m per length, tip mass mu), hinge spring kappa with rest angle 0 at the
    fixed base, gravity (0, -g): potential kappa phi^2/2 + g G sin(phi), G = m l^2/2 + mu l;
    equilibrium kappa phi + g G cos(phi) = 0; linearised I phi'' = -(kappa - g G sin phi*)
    (phi - phi*), I = m l^3/3 + mu l^2."""
    l, m, mu = c["rods"]["length"][0], c["rods"]["mass_per_length"][0], c["nodes"]["mass"][0]
    k = c["hinges"]["stiffness"][0]
    G = m * l * l / 2 + mu * l
    phi = brentq(lambda p: k * p + g * G * np.cos(p), -np.pi / 2, 0.0)
    I = m * l ** 3 / 3 + mu * l * l
    return phi, np.sqrt((k - g * G * np.sin(phi)) / I)


def pendulum_2(c, g):
    """Two rods hanging straight down (rest angles: hinge 0 -pi/2, hinge 1 0, so phi = -pi/2
    is the equilibrium), angles from the vertical theta_k = phi_k + pi/2. With M_k = m_k l_k,
    node masses mu_1 (joint), mu_2 (tip), the kinetic energy at theta = 0 is theta'^T A theta'/2:
      A11 = M1 l1^2/3 + (mu1 + M2 + mu2) l1^2,  A12 = l1 l2 (M2/2 + mu2),
      A22 = M2 l2^2/3 + mu2 l2^2,
    the potential -g [(M1/2 + mu1 + M2 + mu2) l1 cos th1 + (M2/2 + mu2) l2 cos th2] + springs
    k0 th1^2/2 + k1 (th2 - th1)^2/2, so K = g diag((M1/2 + mu1 + M2 + mu2) l1, (M2/2 + mu2) l2)
    + [[k0 + k1, -k1], [-k1, k1]]; omega^2 = eigenvalues of (K, A)."""
    l1, l2 = c["rods"]["length"]
    m1, m2 = c["rods"]["mass_per_length"]
    mu1, mu2 = c["nodes"]["mass"]
    k0, k1 = c["hinges"]["stiffness"]
    M1, M2 = m1 * l1, m2 * l2
    A = np.array([[M1 * l1 ** 2 / 3 + (mu1 + M2 + mu2) * l1 ** 2, l1 * l2 * (M2 / 2 + mu2)],
                  [l1 * l2 * (M2 / 2 + mu2), M2 * l2 ** 2 / 3 + mu2 * l2 ** 2]])
    K = g * np.diag([(M1 / 2 + mu1 + M2 + mu2) * l1, (M2 / 2 + mu2) * l2]) \
        + np.array([[k0 + k1, -k1], [-k1, k1]])
    w2, V = eigh(K, A)
    return np.sqrt(w2), V


def measured_period(t, x):
    """Mean period from the upward zero crossings of x(t) (cubic spline roots)."""
    roots = CubicSpline(t, x).roots(extrapolate=False)
    up = [r for r in roots if CubicSpline(t, x)(r, 1) > 0]
    return float(np.mean(np.diff(up)))


@SC
@pytest.mark.slow
@pytest.mark.parametrize("name", MODELS)
def test_hanging_rod_equilibrium_and_period(name):
    """n = 1 (rigid rod in the reduced and full models): the model's accelerations vanish at
    the closed-form equilibrium (and not 1e-3 rad away); a 1e-4 rad swing about it has the
    compound pendulum's period to 1e-6."""
    g = 9.81
    rng = np.random.default_rng(41)
    c = hanging_chain(1, rng, [0.0], 20.0)
    if name != "rigid":
        c = rigid_chain(c, locked=False)
    phi, w = pendulum_1(c, g)
    d = scene_dict([with_initial(c, phi + 1e-4)], None, (0.0, -g))
    model = make(name, d)
    lay = layout_of(name, d)
    y_eq = np.zeros(2 * lay.dof)
    y_eq[0] = phi
    acc = model.rhs(0.0, y_eq)[lay.dof]
    y_off = y_eq.copy()
    y_off[0] += 1e-3
    acc_off = model.rhs(0.0, y_off)[lay.dof]
    assert abs(acc) < 1e-9 * abs(acc_off) * 1e3, (acc, acc_off)
    assert abs(acc_off + w * w * 1e-3) < 1e-2 * w * w * 1e-3     # linearised stiffness
    T = 2 * np.pi / w
    tr = run(model, 3.2 * T, rate_hz=400 / T)
    Tm = measured_period(tr.t, tr.y[:, 0] - phi)
    print(f"\n[hanging rod, {name}] phi* {phi:.9f} rad, period {Tm:.9f} s vs {T:.9f} s "
          f"(rel {abs(Tm - T) / T:.1e})")
    assert abs(Tm - T) < 1e-6 * T


@SC
@pytest.mark.slow
@pytest.mark.parametrize("name", MODELS)
def test_hanging_double_pendulum_modes(name):
    """n = 2 hanging straight down: accelerations vanish there; started (1e-4 rad) along each
    eigenvector of the 2x2 problem (pendulum_2) it swings at that eigenfrequency (1e-6)."""
    g = 9.81
    rng = np.random.default_rng(42)
    c = hanging_chain(2, rng, [-np.pi / 2, 0.0], 15.0)
    if name != "rigid":
        c = rigid_chain(c, locked=False)
    w, V = pendulum_2(c, g)
    d0 = scene_dict([with_initial(c, [-np.pi / 2] * 2)], None, (0.0, -g))
    model = make(name, d0)
    lay = layout_of(name, d0)
    y = np.zeros(2 * lay.dof)
    y[:2] = -np.pi / 2
    assert np.max(np.abs(model.rhs(0.0, y)[lay.dof:lay.dof + 2])) < 1e-9
    for j in range(2):
        v = V[:, j] / np.max(np.abs(V[:, j]))
        d = scene_dict([with_initial(c, -np.pi / 2 + 1e-4 * v)], None, (0.0, -g))
        T = 2 * np.pi / w[j]
        tr = run(make(name, d), 3.2 * T, rate_hz=400 / T)
        theta = tr.y[:, :2] + np.pi / 2
        modal = np.linalg.solve(V, theta.T).T        # theta = V a
        Tm = measured_period(tr.t, modal[:, j])
        other = modal[:, 1 - j] / np.max(np.abs(modal[:, j]))    # the other mode stays unexcited
        print(f"\n[double pendulum, {name}] mode {j + 1}: period {Tm:.9f} s vs {T:.9f} s "
              f"(rel {abs(Tm - T) / T:.1e}), other mode {np.max(np.abs(other)):.1e} rad")
        assert abs(Tm - T) < 1e-6 * T
        assert np.max(np.abs(other)) < 1e-6


def cantilever_sag(n, L=2.0, EI=1.0e4, m=1.0, g=0.01):
    """Full model, n equal elastic rods, every hinge locked (hinge 0 clamps rod 1's slope to
    the fixed base), horizontal, node masses 0, gravity (0, -g): the static equilibrium, found
    here by Newton on the model's accelerations restricted to the constraint's null space.
    Returns (x nodes, model deflection at nodes, model deflection at rod midpoints)."""
    l = L / n
    c = {"name": "beam", "attach": [0.0, 0.0],
         "rods": {"count": n, "length": l, "mass_per_length": m, "bending_stiffness": EI},
         "nodes": {"mass": 0.0}, "hinges": {"stiffness": 1.0, "damping": 0.0, "locked": True},
         "initial": {"phi": [0.0] * n}}
    d = scene_dict([c], None, (0.0, -g))
    model = make("full", d)
    # constraint rows dDelta_h/dq on q = [phi, alpha, beta]: Delta_0 = phi_1 + alpha_1,
    # Delta_h = phi_{h+1} + alpha_{h+1} - phi_h - beta_h
    C = np.zeros((n, 3 * n))
    for h in range(n):
        C[h, h] += 1.0
        C[h, n + h] += 1.0
        if h:
            C[h, h - 1] -= 1.0
            C[h, 2 * n + h - 1] -= 1.0
    T = null_space(C)

    def res(z):
        y = np.zeros(6 * n)
        y[:3 * n] = T @ z
        return T.T @ model.rhs(0.0, y)[3 * n:]

    z = np.zeros(T.shape[1])
    for _ in range(3):
        r0 = res(z)
        h = 1e-9
        J = np.column_stack([(res(z + h * e) - r0) / h for e in np.eye(len(z))])
        z = z - np.linalg.solve(J, r0)
    q = T @ z
    assert np.max(np.abs(res(z))) < 1e-9 * g
    phi, al, be = q[:n], q[n:2 * n], q[2 * n:]
    w_nodes = np.cumsum(l * np.sin(phi))
    s = l / 2
    sigma, tau = s * (l - s) ** 2 / l ** 2, -s ** 2 * (l - s) / l ** 2
    w_mid = np.r_[0.0, w_nodes[:-1]] + s * np.sin(phi) + (al * sigma + be * tau) * np.cos(phi)
    return l * np.arange(1, n + 1), w_nodes, w_mid


@SC
@pytest.mark.slow
def test_heavy_cantilever_sag():
    """Against Euler-Bernoulli w(x) = q x^2 (6 L^2 - 4 L x + x^2) / (24 EI), q = m g (downward).
    With locked hinges the paper's cubic rods (eq. (1): end slopes phi + alpha, phi + beta)
    are Hermite beam elements, and gravity's generalized forces the consistent loads: for a
    uniform load the Hermite solution is exact AT THE NODES (the classic nodal exactness of
    cubic beam elements) in the linear limit (here w/L ~ 1e-6, geometric terms ~ 1e-12), for
    every n; between the nodes the cubic misses the quartic by O(h^4): the rod-midpoint error
    falls ~16x per halving of the rods."""
    L, EI, m, g = 2.0, 1.0e4, 1.0, 0.01
    q = m * g
    wEB = lambda x: -q * x ** 2 * (6 * L * L - 4 * L * x + x * x) / (24 * EI)   # noqa: E731
    tip = abs(wEB(L))
    mids = []
    for n in (1, 2, 4):
        x, wn, wm = cantilever_sag(n, L, EI, m, g)
        node_err = np.max(np.abs(wn - wEB(x))) / tip
        mid_err = np.max(np.abs(wm - wEB(x - L / n / 2))) / tip
        mids.append(mid_err)
        print(f"\n[cantilever n={n}] tip {wn[-1]:.9e} m vs {wEB(L):.9e} m; node error "
              f"{node_err:.1e}, midpoint error {mid_err:.1e} (of the tip deflection)")
        assert node_err < 1e-6
    assert mids[0] > 1e-4                      # the cubic is not the quartic between nodes
    assert mids[1] < mids[0] / 8 and mids[2] < mids[1] / 8


# --------------------------------------------------------------------- the closed forms themselves

def test_pendulum_closed_forms_are_the_oracles_linearisation():
    """pendulum_1's equilibrium and frequency and pendulum_2's A and K are the independent
    oracle's phi-phi mass matrix and potential Hessian (central differences) at the
    equilibrium: the derivations above are checked without rod_sim."""
    g = 9.81
    for n, rest, kappa, seed in ((1, [0.0], 20.0, 41), (2, [-np.pi / 2, 0.0], 15.0, 42)):
        c = hanging_chain(n, np.random.default_rng(seed), rest, kappa)
        lag = oracle_from_dict(scene_dict([c], None, (0.0, -g)))
        q = np.zeros(lag.nq)
        if n == 1:
            phi, w = pendulum_1(c, g)
            q[0] = phi
        else:
            w, V = pendulum_2(c, g)
            q[:2] = -np.pi / 2
        idx = np.arange(n)
        assert np.max(np.abs(lag.potential_gradient(q)[idx])) < 1e-9
        h = 1e-5
        grad = lag.potential_gradient
        K = np.array([(grad(q + h * e)[idx] - grad(q - h * e)[idx]) / (2 * h)
                      for e in np.eye(lag.nq)[idx]])
        A = lag.mass_matrix(q)[np.ix_(idx, idx)]
        w_oracle = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(A, K)).real))
        assert np.allclose(w_oracle, np.atleast_1d(w), rtol=1e-8), (w_oracle, w)


def test_cantilever_closed_form_is_the_oracles_statics():
    """The oracle's static equilibrium (exact potential with gravity through the bent shape,
    locked-hinge constraints, linear limit) has Euler-Bernoulli's deflection at the nodes for
    n = 1, 2, 3 -- the Hermite nodal exactness that test_heavy_cantilever_sag relies on."""
    L, EI, m, g = 2.0, 1.0e4, 1.0, 0.01
    for n in (1, 2, 3):
        l = L / n
        c = {"name": "beam", "attach": [0.0, 0.0],
             "rods": {"count": n, "length": l, "mass_per_length": m, "bending_stiffness": EI},
             "nodes": {"mass": 0.0}, "hinges": {"stiffness": 1.0, "damping": 0.0}}
        lag = oracle_from_dict(scene_dict([c], None, (0.0, -g)))
        C = np.zeros((n, 3 * n))
        for h in range(n):
            C[h, h] = C[h, n + h] = 1.0
            if h:
                C[h, h - 1] = C[h, 2 * n + h - 1] = -1.0
        T = null_space(C)

        def grad(z):
            q = np.zeros(lag.nq)
            q[:3 * n] = T @ z
            return T.T @ lag.potential_gradient(q)[:3 * n]

        z = np.zeros(T.shape[1])
        for _ in range(3):
            r0 = grad(z)
            J = np.column_stack([(grad(z + 1e-8 * e) - r0) / 1e-8 for e in np.eye(len(z))])
            z = z - np.linalg.solve(J, r0)
        q = T @ z
        x = l * np.arange(1, n + 1)
        w = np.cumsum(l * np.sin(q[:n]))
        wEB = -m * g * x ** 2 * (6 * L * L - 4 * L * x + x * x) / (24 * EI)
        assert np.max(np.abs(w - wEB)) < 1e-7 * abs(wEB[-1]), (n, w, wEB)
