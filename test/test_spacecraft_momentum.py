"""The models' momentum and the booked momentum balance (issue 25 item 3) against the
independent oracle (``lagrangian_base``: exact kinematics of the bent rods, eq. (4)).

rod_sim's claim (rod_sim/core/momentum.py, docs/spacecraft.md): rigid and reduced models
conserve the chords' momentum exactly (dP/dt = F, dH_O/dt = M_O); the full model's exact
momentum of the bent rods changes by F plus a booked defect D (``defect_rates``). Checked here:

* ``model.momentum`` of the full model is the exact momentum of the bent rods (positions and
  bending rates), of the rigid/reduced models the chords' (oracle at alpha = beta = 0 with no
  bending rates);
* instantaneously, with the model's own accelerations and the oracle's exact kinematics:
  dP/dt = force + defect_force and dH_O/dt = moment + defect_moment, and force, moment are the
  applied loads plus gravity (oracle ``external_wrench``);
* along a run, the ledger ``MomentumBalance`` closes with the trapezoid rule's error (it falls
  ~4x when the sampling is halved), and without the booked defect it would not close.
"""
from __future__ import annotations

import numpy as np
import pytest

from sc_common import Layout, chain_dict, free_base, needs_spacecraft, oracle_from_dict, scene_dict

pytestmark = needs_spacecraft()
GRAVITY = (0.4, -9.81)
RATE = 2000.0     # [Hz] the ledger samples at RATE and 2 RATE: well above the bending frequencies


def make(name, d):
    from rod_sim.core.models import make_model
    from rod_sim.core.scene import Scene
    return make_model(name, Scene.from_dict(d))


def scene(seed, gravity=GRAVITY, loads=True, ns=(2, 1, 3), EI=(2e2, 1e3)):
    rng = np.random.default_rng(seed)
    chains = []
    for i, n in enumerate(ns):
        c = chain_dict(f"c{i}", n, rng, EI=rng.uniform(*EI, n))
        c["initial"] = {"phi": [float(v) for v in rng.uniform(-3, 3, n)],
                        "phi_rate": [float(v) for v in rng.uniform(-1, 1, n)]}
        chains.append(c)
    ld = []
    scripted = None
    N = sum(ns)
    if loads:
        ld = [{"chain": "c0", "node": 2, "axis": "y", "shape": "constant", "amplitude": 6.0,
               "start": 0.0},
              {"node": "base", "axis": "x", "shape": "constant", "amplitude": -9.0, "start": 0.0},
              {"node": "base", "axis": "moment", "shape": "constant", "amplitude": 4.0,
               "start": 0.0},
              {"node": "wheel", "axis": "moment", "shape": "constant", "amplitude": 0.5,
               "start": 0.0}]
        scripted = np.zeros((N + 2, 3))
        scripted[1, 1] += 6.0
        scripted[N, 0] += -9.0
        scripted[N, 2] += 4.0
        scripted[N + 1, 2] += 0.5
    base = free_base(mass=25.0, inertia=6.0, com=(0.1, 0.05), wheel=0.2,
                     initial={"x": 0.0, "y": 0.0, "psi": 0.3, "x_rate": 0.1, "y_rate": -0.2,
                              "psi_rate": 0.5})
    return scene_dict(chains, base, gravity, ld), rng, scripted


def random_state(lag, lay, rng, bending):
    q, qd = np.zeros(lag.nq), np.zeros(lag.nq)
    q[:lag.N] = rng.uniform(-3, 3, lag.N)
    q[lag.i_bend] = bending * rng.uniform(-1, 1, 2 * lag.N)
    q[3 * lag.N:] = rng.uniform(-1, 1, 4)
    qd[:lag.N] = rng.uniform(-2, 2, lag.N)
    qd[lag.i_bend] = 0.5 * rng.uniform(-1, 1, 2 * lag.N)
    qd[3 * lag.N:] = rng.uniform(-2, 2, 4)
    return lay.to_oracle(lay.from_oracle(q, qd))


def random_held(lag, rng):
    h = np.zeros((lag.N + 2, 3))
    h[:lag.N, :2] = rng.uniform(-20, 20, (lag.N, 2))
    h[:lag.N, 2] = rng.uniform(-5, 5, lag.N)
    h[lag.N] = rng.uniform(-30, 30, 3)
    h[lag.N + 1, 2] = rng.uniform(-1, 1)
    return h


@pytest.mark.parametrize("name,bending", [("full", 0.0), ("full", 0.02), ("reduced", 0.0),
                                          ("rigid", 0.0)])
def test_model_momentum_is_the_exact_momentum(name, bending):
    """full: the bent rods' exact P, H_O, H_cm, com, mass (bending rates included); rigid and
    reduced: the chords' (their states have no bending)."""
    d, rng, _ = scene(51)
    model, lag = make(name, d), oracle_from_dict(d)
    lay = Layout(name, lag.N, True, True)
    worst = 0.0
    for _ in range(3):
        q, qd = random_state(lag, lay, rng, bending)
        m = model.momentum(0.0, lay.from_oracle(q, qd))
        P, H, Hc, com, mass = lag.momentum(q, qd)
        errs = [np.max(np.abs(m.linear - P)) / np.max(np.abs(P)),
                abs(m.angular_origin - H) / abs(H), abs(m.angular_com - Hc) / abs(Hc),
                np.max(np.abs(m.com - com)), abs(m.mass - mass) / mass]
        worst = max(worst, max(errs))
        assert max(errs) < 1e-12, errs
    print(f"\n[momentum, {name}, bending {bending}] worst relative difference {worst:.1e}")


@pytest.mark.parametrize("name,bending", [("full", 0.0), ("full", 0.02), ("reduced", 0.0),
                                          ("rigid", 0.0)])
def test_booked_rates_are_the_exact_momentum_rates(name, bending):
    """With the model's accelerations (bending rates and accelerations included for the full
    model), the oracle's exact dP/dt, dH_O/dt equal the booked force + defect_force,
    moment + defect_moment; the booked force and moment are the applied loads with gravity.
    The defect must matter at bending: force alone does not close there."""
    from rod_sim.core.momentum import momentum_rates
    d, rng, scripted = scene(52)
    model, lag = make(name, d), oracle_from_dict(d)
    lay = Layout(name, lag.N, True, True)
    for _ in range(3):
        q, qd = random_state(lag, lay, rng, bending)
        held = random_held(lag, rng)
        y = lay.from_oracle(q, qd)
        qdd = lay.qdd_to_oracle(model.rhs(0.0, y, held))
        rates = momentum_rates(model, 0.0, y, held)
        dP, dH, sP, sH = lag.momentum_rate(q, qd, qdd, scale=True)
        F, M = lag.external_wrench(q, held + scripted)
        eF = np.max(np.abs(rates.force - F)) / sP
        eM = abs(rates.moment - M) / sH
        eP = np.max(np.abs(dP - rates.force - rates.defect_force)) / sP
        eH = abs(dH - rates.moment - rates.defect_moment) / sH
        print(f"\n[booked rates, {name}, bending {bending}] applied F {eF:.1e}, M {eM:.1e}; "
              f"closure dP/dt {eP:.1e}, dH/dt {eH:.1e} (of sum |dm a|, sum |r x dm a|); "
              f"defect {np.max(np.abs(rates.defect_force)) / sP:.1e}, "
              f"{abs(rates.defect_moment) / sH:.1e}")
        assert eF < 1e-12 and eM < 1e-12
        assert eP < 1e-11 and eH < 1e-11
        if bending:
            assert np.max(np.abs(dP - rates.force)) / sP > 1e-6


@pytest.mark.slow
@pytest.mark.parametrize("name", ["full", "reduced", "rigid"])
def test_momentum_ledger_closes_along_a_run(name):
    """0.5 s with gravity, scripted loads and a wheel torque, soft rods; the ledger (trapezoid
    rule over the samples at 2 and 4 kHz). The trapezoid error is second order, so the signed
    residuals R_200, R_400 extrapolate (Richardson, (4 R_400 - R_200) / 3) to ~0 when the
    booking is right; a missing or wrong booked term leaves a residual that does not fall
    with the sampling. Asserted: each residual is round-off (< 1e-11 of the momentum scale)
    or falls by 3.5 .. 4.6 when the spacing is halved, and is < 1e-5 at 4 kHz.
    (A first version asserted |R_400| < 1e-6 at 200/400 Hz: the trapezoid error of H there is
    ~8e-6 for the rigid model, measured, below the quadrature's own error; and with stiff rods
    (bending near 700 Hz) the full model's samples were not in the asymptotic regime.)"""
    from rod_sim.core.integrators import make_integrator
    from rod_sim.core.momentum import MomentumBalance, momentum_rates
    from rod_sim.core.simulator import Simulator
    d, _, _ = scene(53, EI=(50.0, 200.0))   # bending frequencies ~ 10 .. 200 Hz << RATE
    model = make(name, d)
    res = []
    for rate in (RATE, 2 * RATE):
        sim = Simulator(model, make_integrator("dop853-jit", rtol=1e-12, atol=1e-12))
        tr = sim.run(0.5, rate)
        bal = MomentumBalance()
        for t, y in zip(tr.t, tr.y):
            bal.add(float(t), model.momentum(float(t), y), momentum_rates(model, float(t), y))
        res.append((bal.residual_linear / bal.scale_p, bal.residual_angular / bal.scale_h))
    extP = np.max(np.abs(4 * res[1][0] - res[0][0])) / 3
    extH = abs(4 * res[1][1] - res[0][1]) / 3
    print(f"\n[momentum ledger, {name}] relative residual at {RATE:g} Hz "
          f"{np.max(np.abs(res[0][0])):.1e} (P), {abs(res[0][1]):.1e} (H); at {2 * RATE:g} Hz "
          f"{np.max(np.abs(res[1][0])):.1e}, {abs(res[1][1]):.1e}; extrapolated {extP:.1e}, "
          f"{extH:.1e}")
    for coarse, fine in ((np.max(np.abs(res[0][0])), np.max(np.abs(res[1][0]))),
                         (abs(res[0][1]), abs(res[1][1]))):
        # round-off, or the trapezoid's second order: halving the spacing divides by ~4
        assert fine < 1e-11 or 3.5 < coarse / fine < 4.6, (coarse, fine)
        assert fine < 1e-5
