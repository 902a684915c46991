"""Basilisk itself as an external peer (issue 25): a hub with two hinged rigid panels.

Basilisk (pip ``bsk``): ``spacecraft.Spacecraft`` + two ``HingedRigidBodyStateEffector``,
no gravity, no orbit, planar: the hinge axes along the body z axis, the hub turning about z.
rod_sim: the rigid model on a free base, each panel a one-rod rigid chain.

The mapping (read from Basilisk's hingedRigidBodyStateEffector.cpp): a panel's centre of mass
is r_S = r_H - d s1 with s1 the first row of dcm_SH dcm_HB, dcm_SH = M2(theta) (rotation
about the hinge frame's axis h2). With dcm_HB rows h1 = (-1, 0, 0), h2 = (0, 0, 1),
h3 = h1 x h2 = (0, 1, 0) the panel points along +x of the body at theta = 0 and along
(cos theta, sin theta): rod angle phi = psi + theta. With h1 = (1, 0, 0), h3 = (0, -1, 0) it
points along -x: phi = psi + pi + theta (rod_sim rest angle pi). A uniform rod of length l
and mass m: d = l / 2, inertia about the hinge axis through S m l^2 / 12 (IPntS_S[1][1]),
node mass 0, mass per length m / l; Basilisk's spring and damper -k theta - c theta' are
rod_sim's hinge 0 (kappa = k, nu = c, measured from the rest angle). The hub: m_B = mHub,
J_B = IHubPntBc_B[2][2], centre of mass r_BcB_B. psi = 4 atan(sigma_3) (MRP, unwrapped).
The centre of mass's uniform motion does not enter the attitude and hinge dynamics, so the
translational initial conditions need not match.

The independent oracle (``lagrangian_base``) integrated by scipy is compared too: it ties
the oracle used by the other spacecraft tests to an external code.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from lagrangian_base import BaseData, BaseLagrangian, ChainData
from sc_common import needs_spacecraft

bsk = pytest.importorskip("Basilisk",
                          reason="Basilisk (pip bsk, the 'peer' extra) is not installed")

T_END, DT_OUT, DT_BSK = 10.0, 0.1, 1e-3
HUB = dict(mass=750.0, inertia=600.0, com=(0.1, 0.05), omega=0.1)
PANELS = [   # attach (base frame), side (+1: along +x, -1: along -x), theta0, theta_dot0
    dict(attach=(1.0, 0.2), side=+1, theta=np.radians(5.0), theta_dot=0.0),
    dict(attach=(-1.0, -0.1), side=-1, theta=np.radians(-3.0), theta_dot=0.2)]
PANEL = dict(mass=100.0, length=3.0, k=100.0, c=2.0)


def run_basilisk():
    """(t, psi, psi_rate, theta (N, 2), theta_dot (N, 2)) from Basilisk (RK4 at 1 ms)."""
    from Basilisk.simulation import hingedRigidBodyStateEffector, spacecraft
    from Basilisk.utilities import SimulationBaseClass, macros
    sim = SimulationBaseClass.SimBaseClass()
    proc = sim.CreateNewProcess("proc")
    proc.addTask(sim.CreateNewTask("task", macros.sec2nano(DT_BSK)))
    sc = spacecraft.Spacecraft()
    sc.ModelTag = "hub"
    sc.hub.mHub = HUB["mass"]
    sc.hub.r_BcB_B = [[HUB["com"][0]], [HUB["com"][1]], [0.0]]
    J = HUB["inertia"]
    sc.hub.IHubPntBc_B = [[J + 300.0, 0, 0], [0, J + 200.0, 0], [0, 0, J]]
    sc.hub.r_CN_NInit = [[0.0], [0.0], [0.0]]
    sc.hub.v_CN_NInit = [[0.0], [0.0], [0.0]]
    sc.hub.sigma_BNInit = [[0.0], [0.0], [0.0]]
    sc.hub.omega_BN_BInit = [[0.0], [0.0], [HUB["omega"]]]
    m, l = PANEL["mass"], PANEL["length"]
    effectors = []
    for i, p in enumerate(PANELS):
        e = hingedRigidBodyStateEffector.HingedRigidBodyStateEffector()
        e.ModelTag = f"panel{i}"
        e.mass = m
        e.IPntS_S = [[m * l * l / 12, 0, 0], [0, m * l * l / 12, 0], [0, 0, m * l * l / 12]]
        e.d, e.k, e.c = l / 2, PANEL["k"], PANEL["c"]
        e.r_HB_B = [[p["attach"][0]], [p["attach"][1]], [0.0]]
        s = p["side"]
        e.dcm_HB = [[-s, 0, 0], [0, 0, 1], [0, s, 0]]
        e.thetaInit, e.thetaDotInit = p["theta"], p["theta_dot"]
        e.nameOfThetaState, e.nameOfThetaDotState = f"theta{i}", f"thetaDot{i}"
        sc.addStateEffector(e)
        sim.AddModelToTask("task", e)
        effectors.append(e)
    sim.AddModelToTask("task", sc)
    rec = sc.scStateOutMsg.recorder(macros.sec2nano(DT_OUT))
    sim.AddModelToTask("task", rec)
    precs = [e.hingedRigidBodyOutMsg.recorder(macros.sec2nano(DT_OUT)) for e in effectors]
    for r in precs:
        sim.AddModelToTask("task", r)
    sim.InitializeSimulation()
    sim.ConfigureStopTime(macros.sec2nano(T_END))
    sim.ExecuteSimulation()
    sigma, omega = np.asarray(rec.sigma_BN), np.asarray(rec.omega_BN_B)
    assert np.max(np.abs(sigma[:, :2])) == 0 and np.max(np.abs(omega[:, :2])) == 0   # planar
    psi = np.unwrap(4 * np.arctan(sigma[:, 2]))
    theta = np.column_stack([np.asarray(r.theta) for r in precs])
    theta_dot = np.column_stack([np.asarray(r.thetaDot) for r in precs])
    return np.asarray(rec.times()) * 1e-9, psi, omega[:, 2], theta, theta_dot


def offsets():
    return np.array([0.0 if p["side"] > 0 else np.pi for p in PANELS])


def scene():
    """The same spacecraft as a rod_sim scene (SPEC section 8)."""
    m, l = PANEL["mass"], PANEL["length"]
    chains = []
    for i, (p, off) in enumerate(zip(PANELS, offsets())):
        chains.append({
            "name": f"panel{i}", "attach": list(p["attach"]),
            "rods": {"count": 1, "length": l, "mass_per_length": m / l,
                     "bending_stiffness": 1.0e6},
            "nodes": {"mass": 0.0},
            "hinges": {"stiffness": PANEL["k"], "damping": PANEL["c"], "rest_angle": float(off)},
            "initial": {"phi": [float(off + p["theta"])],
                        "phi_rate": [HUB["omega"] + p["theta_dot"]]}})
    base = {"mode": "free", "mass": HUB["mass"], "inertia": HUB["inertia"],
            "centre_of_mass": list(HUB["com"]), "initial": {"psi_rate": HUB["omega"]}}
    return {"name": "basilisk_peer", "base": base, "chains": chains}


def compare(t, psi, rate, theta, theta_dot, ref):
    tb, psi_b, rate_b, th_b, thd_b = ref
    assert np.allclose(t, tb, atol=1e-9)
    return {"psi": np.max(np.abs(psi - psi_b)), "psi_rate": np.max(np.abs(rate - rate_b)),
            "theta": np.max(np.abs(theta - th_b)), "theta_dot": np.max(np.abs(theta_dot - thd_b))}


@pytest.fixture(scope="module")
def basilisk():
    return run_basilisk()


def test_oracle_matches_basilisk(basilisk):
    """The independent Lagrangian (rigid rods: alpha = beta = 0 held, no wheel), integrated by
    scipy DOP853 at 1e-12, against Basilisk over 10 s."""
    m, l = PANEL["mass"], PANEL["length"]
    chains = [ChainData([l], [m / l], [0.0], [1e6], [PANEL["k"]], [PANEL["c"]],
                        attach=p["attach"], rest=[off]) for p, off in zip(PANELS, offsets())]
    ob = BaseLagrangian(chains, BaseData(HUB["mass"], HUB["inertia"], HUB["com"], 0.0))
    free = np.array([0, 1, 6, 7, 8])     # phi_1, phi_2, x_B, y_B, psi

    def f(t, y):
        q, qd = np.zeros(ob.nq), np.zeros(ob.nq)
        q[free], qd[free] = y[:5], y[5:]
        return np.r_[y[5:], ob.accelerations(q, qd, free=free)[free]]

    w = HUB["omega"]
    y0 = np.r_[offsets() + [p["theta"] for p in PANELS], 0, 0, 0,
               [w + p["theta_dot"] for p in PANELS], 0, 0, w]
    t = basilisk[0]
    sol = solve_ivp(f, (0, t[-1]), y0, method="DOP853", rtol=1e-12, atol=1e-12, t_eval=t)
    psi = sol.y[4]
    err = compare(t, psi, sol.y[9], sol.y[:2].T - psi[:, None] - offsets(),
                  sol.y[5:7].T - sol.y[9][:, None], basilisk)
    print(f"\n[oracle vs Basilisk, 10 s] max |difference| {err}")
    assert max(err.values()) < 1e-8, err


@needs_spacecraft()
@pytest.mark.slow
def test_rod_sim_rigid_model_matches_basilisk(basilisk):
    """rod_sim's rigid model on a free base (dop853-jit, rtol = atol = 1e-12) against Basilisk
    over 10 s: hub attitude and rate, both panel angles and rates."""
    from rod_sim.core.integrators import make_integrator
    from rod_sim.core.models import make_model
    from rod_sim.core.scene import Scene
    from rod_sim.core.simulator import Simulator
    model = make_model("rigid", Scene.from_dict(scene()))
    sim = Simulator(model, make_integrator("dop853-jit", rtol=1e-12, atol=1e-12))
    tr = sim.run(T_END, 1.0 / DT_OUT)
    y = tr.y
    assert y.shape[1] == 10       # [phi_1, phi_2, x_B, y_B, psi] and their rates
    psi, rate = y[:, 4], y[:, 9]
    err = compare(tr.t, psi, rate, y[:, :2] - psi[:, None] - offsets(),
                  y[:, 5:7] - rate[:, None], basilisk)
    print(f"\n[rod_sim rigid vs Basilisk, 10 s] max |difference| {err}")
    assert max(err.values()) < 1e-8, err
