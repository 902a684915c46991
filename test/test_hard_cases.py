"""Hard cases with the DEFAULT integrator (dop853-jit, rtol 1e-8), never a silent NaN, the
validity monitor and ``rod-sim advise``. References are independent of the run under test:
a much tighter run, scipy's Radau, a known limit (EI -> inf, a locked chain as one rigid body),
conservation laws."""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rod_sim.core import validity
from rod_sim.core.integrators import IntegrationError, make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.simulator import Simulator
from rod_sim.io.scene_yaml import load_scene, scene_to_yaml
from rod_sim.tools import advise
from rod_sim.tools.hard_cases import chain, folded, run_case, step_forces_case
from untimed import untimed_lines

REPO = Path(__file__).resolve().parents[1]
PAPER = REPO / "config" / "paper_example.yaml"


def run(scene, model, t_end, rtol=None, integrator="dop853-jit", rate=100.0, **kw):
    sim = Simulator(make_model(model, scene), make_integrator(integrator, rtol=rtol, **kw))
    return sim.run(t_end, rate), sim.stats


def max_err(a, b) -> float:
    return float(np.max(np.abs(a.phi - b.phi)))


# ----- hard cases, default settings -----

@pytest.mark.slow
@pytest.mark.parametrize("model", ["rigid", "reduced"])
def test_256_rods(model):
    scene = chain(256)
    traj, _ = run(scene, model, 0.1)
    ref, _ = run(scene, model, 0.1, rtol=1e-11)
    assert np.all(np.isfinite(traj.y))
    assert max_err(traj, ref) < 1e-6


@pytest.mark.slow
def test_64_rods_full_model():
    scene = chain(64)
    traj, stats = run(scene, "full", 0.01)
    ref, _ = run(scene, "full", 0.01, rtol=1e-11)
    assert max_err(traj, ref) < 1e-6
    assert stats.rejected < stats.steps          # stability-limited, but it gets through


@pytest.mark.slow
def test_stiff_bending_full_model_meets_radau_and_the_rigid_limit():
    """EI = 1e8: kHz bending modes. Checked against scipy's implicit Radau and against the
    rigid model (the limit EI -> inf): the gap to the rigid model falls ~1/EI."""
    stiff = chain(EI=1e8)
    traj, _ = run(stiff, "full", 1.0)
    radau, _ = run(stiff, "full", 1.0, rtol=1e-10, integrator="Radau")
    assert max_err(traj, radau) < 1e-6
    rigid, _ = run(stiff, "rigid", 1.0)
    softer, _ = run(chain(EI=1e7), "full", 1.0)
    gap8, gap7 = max_err(traj, rigid), max_err(softer, rigid)
    assert 5.0 < gap7 / gap8 < 20.0, (gap7, gap8)


def test_stiff_bending_reduced_model_tends_to_rigid():
    r7, _ = run(chain(EI=1e7), "reduced", 2.0)
    r8, _ = run(chain(EI=1e8), "reduced", 2.0)
    rigid, _ = run(chain(EI=1e8), "rigid", 2.0)
    assert 5.0 < max_err(r7, rigid) / max_err(r8, rigid) < 20.0


def test_locked_hinges_move_like_one_rigid_body():
    """Hinges 1..7 at kappa 1e6 (the seed's locking): the rigid chain turns like one 16 m
    rigid rod on hinge 0 -- a 1-DOF pendulum integrated here with scipy."""
    scene = chain(kappa=[100.0] + [1e6] * 7)
    traj, _ = run(scene, "rigid", 2.0)
    l, m, mu = 2.0, 3.0, 3.0
    s = l * np.arange(1, 9)                                   # node distances from the origin
    inertia = m * 16.0**3 / 3.0 + mu * np.sum(s**2)

    def rhs(t, y):
        fx, fy = scene.scripted_forces(t)[-1]
        torque = 16.0 * (-np.sin(y[0]) * fx + np.cos(y[0]) * fy)
        return [y[1], (torque - 100.0 * y[0] - 0.01 * y[1]) / inertia]

    sol = solve_ivp(rhs, (0, 2), [0.0, 0.0], t_eval=traj.t, rtol=1e-11, atol=1e-12,
                    max_step=0.01)
    theta = sol.y[0]
    gap6 = np.max(np.abs(traj.phi - theta[:, None]))
    # the locked hinges still yield by moment / kappa: at most sum_h F_max (16 - 2h) / kappa
    assert gap6 < 1200.0 * np.sum(16.0 - 2.0 * np.arange(1, 8)) / 1e6
    stiffer, _ = run(chain(kappa=[100.0] + [1e7] * 7), "rigid", 2.0)
    gap7 = np.max(np.abs(stiffer.phi - theta[:, None]))
    assert 5.0 < gap6 / gap7 < 20.0, (gap6, gap7)          # the limit kappa -> inf
    for model in ("reduced", "full"):
        tr, _ = run(scene, model, 2.0)
        ref, _ = run(scene, model, 2.0, rtol=1e-11)
        assert max_err(tr, ref) < 1e-6


def angular_momentum(model, y) -> float:
    """L_z about the origin [kg m^2/s] of the rigid chain, by Gauss quadrature along each rod
    (independent of the model's mass matrix)."""
    p = model.params
    phi, dphi = model.phi(y), model.phi_rate(y)
    u = np.stack([np.cos(phi), np.sin(phi)], 1)
    w = np.stack([-np.sin(phi), np.cos(phi)], 1) * dphi[:, None]
    x = np.vstack([[0, 0], np.cumsum(p.l[:, None] * u, 0)])
    v = np.vstack([[0, 0], np.cumsum(p.l[:, None] * w, 0)])
    L = float(np.sum(p.mu * (x[1:, 0] * v[1:, 1] - x[1:, 1] * v[1:, 0])))
    g, gw = np.polynomial.legendre.leggauss(3)
    for k in range(model.n):
        for xi, wi in zip(0.5 * (g + 1), 0.5 * gw):
            r = x[k] + xi * p.l[k] * u[k]
            vel = v[k] + xi * p.l[k] * w[k]
            L += p.m[k] * p.l[k] * wi * (r[0] * vel[1] - r[1] * vel[0])
    return L


def test_free_hinges_conserve_energy_and_angular_momentum():
    scene = chain(kappa=0.0, nu=0.0, loads=[], phi=[0.0, 0.3, -0.2, 0.5, 0.1, -0.4, 0.2, 0.0],
                  phi_rate=[1.0, -0.5, 0.8, 0.2, -1.0, 0.4, 0.6, -0.3])
    traj, _ = run(scene, "rigid", 20.0)
    model = traj.model
    L = np.array([angular_momentum(model, y) for y in traj.y[::50]])
    E = np.array([model.energies(t, y).total for t, y in zip(traj.t[::50], traj.y[::50])])
    assert abs(L[0]) > 1.0
    assert np.max(np.abs(L - L[0])) < 1e-5 * abs(L[0])
    assert np.max(np.abs(E - E[0])) < 1e-5 * E[0]
    for model_name in ("reduced", "full"):
        tr, _ = run(chain(kappa=0.0, nu=0.0), model_name, 2.0)
        ref, _ = run(chain(kappa=0.0, nu=0.0), model_name, 2.0, rtol=1e-11)
        assert max_err(tr, ref) < 1e-6


def energy_gradient(model, y, eps=1e-6):
    g = np.empty(y.size)
    for i in range(y.size):
        yp, ym = y.copy(), y.copy()
        yp[i] += eps
        ym[i] -= eps
        g[i] = (model.energies(0, yp).total - model.energies(0, ym).total) / (2 * eps)
    return g


def test_1000_s_undamped_energy_drift_within_the_tolerance_bound():
    """Each accepted DOP853 step has a scaled RMS error estimate < 1, i.e. |e_i / sc_i|_2 <=
    sqrt(N) with sc_i = atol + rtol |y_i|; so |dE| <= |grad E * sc|_2 sqrt(N) per step
    (Cauchy-Schwarz, first order) and the drift over S steps is at most S times the largest
    such bound. The rigid model conserves energy exactly, so this must hold."""
    scene = chain(nu=0.0, loads=[], phi_rate=[0.5, -0.3, 0.2, 0.1, -0.4, 0.3, 0.2, -0.1])
    traj, stats = run(scene, "rigid", 1000.0, rate=10.0)
    model = traj.model
    E = np.array([model.energies(t, y).total for t, y in zip(traj.t, traj.y)])
    drift = float(np.max(np.abs(E - E[0])))
    rtol = make_integrator().rtol
    per_step = max(np.linalg.norm(energy_gradient(model, y) * (rtol + rtol * np.abs(y)))
                   for y in traj.y[::100]) * math.sqrt(traj.y.shape[1])
    bound = stats.steps * per_step
    assert drift < bound, (drift, bound)
    assert drift > 0.0          # measured, not vacuous
    print(f"1000 s rigid: drift {drift:.3g} J, bound {bound:.3g} J, E0 {E[0]:.3g} J")


@pytest.mark.slow
@pytest.mark.parametrize("model", ["reduced", "full"])
def test_long_undamped_runs_agree_with_tight_runs(model):
    scene = chain(nu=0.0, loads=[], phi_rate=[0.5, -0.3, 0.2, 0.1, -0.4, 0.3, 0.2, -0.1])
    t_end = 1000.0 if model == "reduced" else 30.0
    traj, _ = run(scene, model, t_end, rate=10.0)
    ref, _ = run(scene, model, t_end, rate=10.0, rtol=1e-11)
    # an undamped oscillation accumulates phase error linearly in time: about 1e-3 rad per
    # 1000 s at rtol 1e-8 (docs/hard_cases.md); a tenfold tighter rtol must shrink it
    err = max_err(traj, ref)
    assert err < 1e-2
    tighter, _ = run(scene, model, t_end, rate=10.0, rtol=1e-9)
    assert max_err(tighter, ref) < 0.3 * err or err < 1e-8


@pytest.mark.parametrize("model", ["reduced", "full"])
def test_whipping_tip_is_fast_and_accurate(model):
    scene = chain(scale=4.0, kappa=10.0)
    traj, _ = run(scene, model, 2.0)
    ref, _ = run(scene, model, 2.0, rtol=1e-11)
    assert np.max(np.abs(traj.phi_rate)) > 30.0                 # really violent
    assert max_err(traj, ref) < 1e-5


@pytest.mark.parametrize("scene, model, t_end", [
    (chain(mu=[3.0] * 7 + [3000.0], scale=10.0), "full", 1.0),
    (chain(m=1e-6), "reduced", 2.0),
    (chain(m=1e-3), "full", 0.1),
    (folded(), "full", 2.0),
    (folded(), "reduced", 2.0),
], ids=["heavy-tip-full", "massless-rods-reduced", "light-rods-full", "folded-full",
        "folded-reduced"])
def test_mass_extremes_and_folded_chains(scene, model, t_end):
    traj, _ = run(scene, model, t_end)
    ref, _ = run(scene, model, t_end, rtol=1e-11)
    assert max_err(traj, ref) < 1e-5


def test_folded_rigid_chain_matches_radau():
    traj, _ = run(folded(), "rigid", 2.0)
    radau, _ = run(folded(), "rigid", 2.0, rtol=1e-11, integrator="Radau")
    assert max_err(traj, radau) < 1e-6


@pytest.mark.parametrize("model", ["reduced", "full"])
def test_step_changes_of_commanded_forces(model):
    """set_forces mid-run equals the same forces as scripted step loads (restarts at the
    breakpoints are exercised by a different code path)."""
    case = step_forces_case(model)
    traj, _, _, _, error = run_case(case)
    assert error is None
    loads = [{"node": 8, "axis": "y", "shape": "step", "amplitude": 300.0, "start": 0.3,
              "duration": 0.8},
             {"node": 4, "axis": "x", "shape": "constant", "amplitude": -200.0, "start": 1.1}]
    scripted, _ = run(chain(loads=loads), model, 2.0, rtol=1e-11)
    assert max_err(traj, scripted) < 1e-6
    assert np.max(np.abs(traj.phi)) > 0.05


# ----- never a silent NaN -----

@pytest.mark.parametrize("integrator, kw, force", [
    ("euler", {"step": 0.05}, 0.0), ("rk4", {"step": 0.05}, 0.0), ("dop853-jit", {}, 1e200),
    ("radau-jit", {}, 1e200),
    ("RK45", {}, 1e200), ("DOP853", {}, 1e200), ("Radau", {}, 1e200), ("BDF", {}, 1e200),
    ("LSODA", {}, 1e200)])
def test_every_integrator_raises_instead_of_returning_nan(integrator, kw, force):
    sim = Simulator(make_model("full", load_scene(PAPER)), make_integrator(integrator, **kw))
    sim.set_forces(np.full(16, force))
    with pytest.raises(IntegrationError) as info:
        sim.run(2.0, 100.0)
    message = str(info.value)
    assert "\n" not in message and "t = " in message
    assert " of rod " in message                      # names the quantity and the rod
    assert np.all(np.isfinite(sim.y))


@pytest.mark.timing
def test_simulate_exits_1_and_keeps_a_readable_log(tmp_path):
    from rod_sim.io.log_reader import LogReader
    from rod_sim.io.series import read_rod_states

    out = tmp_path / "diverge.mcap"
    proc = subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", "simulate", str(PAPER),
                           "--model", "full", "--integrator", "euler", "--step", "0.05",
                           "--t-end", "2", "--out", str(out)], capture_output=True, text=True)
    assert proc.returncode == 1
    err = [line for line in untimed_lines(proc.stderr) if line.startswith("rod-sim:")]
    assert len(err) == 1 and "non-finite" in err[0] and "phi_rate of rod 1" in err[0]
    assert "Traceback" not in proc.stderr
    t, phi, _ = read_rod_states(out)
    assert 0.1 < t[-1] < 0.2 and np.all(np.isfinite(phi))
    assert LogReader(out).metadata()["model"] == "full"


# ----- validity monitor -----

def test_bending_frequency_formula_against_the_linearization():
    """The per-rod formula (chord fixed) and the full model's linearization agree for the
    paper's chain (whose node masses barely couple to the bending), within 5 %."""
    scene = load_scene(PAPER)
    f_rod = validity.bending_frequencies(scene)[0]
    f_chain = validity.chain_bending_frequency(scene)
    assert abs(f_chain / f_rod - 1.0) < 0.05
    # and it scales like sqrt(EI)
    f4 = validity.chain_bending_frequency(scene.with_changes(bending_stiffness=np.full(8, 4e5)))
    assert abs(f4 / f_chain - 2.0) < 0.02


def test_monitor_quiet_on_the_paper_example_and_loud_on_a_soft_chain():
    scene = load_scene(PAPER)
    traj, _ = run(scene, "reduced", 2.0)
    assert validity.assess_trajectory(traj.model, traj.t, traj.y).findings() == []
    soft, _ = run(chain(EI=1e3), "reduced", 2.0)
    kinds = {f.kind for f in validity.assess_trajectory(soft.model, soft.t, soft.y).findings()}
    assert {"bending", "frequency"} <= kinds
    # the warning is right: the reduced model is off against the full model here
    full, _ = run(chain(EI=1e3), "full", 2.0)
    assert max_err(soft, full) > 10 * max_err(traj, run(scene, "full", 2.0)[0])


def test_force_jump_reported_only_when_it_bends_the_rods():
    model = make_model("reduced", chain(EI=1e3, loads=[]))
    mon = validity.ValidityMonitor(model)
    y = model.initial_state()
    f = np.zeros((8, 2))
    mon.update(0.0, y, f)
    mon.update(0.01, y, f)
    assert mon.findings() == []
    f[-1, 1] = 500.0
    mon.update(0.02, y, f)
    assert [x.kind for x in mon.findings()] == ["force_jump"]


def test_a_hinge_torque_jump_is_judged_like_a_force_jump():
    """A motor moment switched on bends the rods quasi-statically as a force does (T acts on
    the hinge deflection, whose generalized forces reach the end slopes): held (n, 3) inputs
    whose torque jumps are reported; the same torque held is not, and neither is a jump too
    small to bend the rods."""
    model = make_model("reduced", chain(EI=1e3, loads=[]))
    y = model.initial_state()
    held = np.zeros((8, 3))
    small = validity.ValidityMonitor(model)
    small.update(0.0, y, held)
    held[3, 2] = 1e-3
    small.update(0.01, y, held)
    assert small.findings() == []
    mon = validity.ValidityMonitor(model)
    held[3, 2] = 0.0
    mon.update(0.0, y, held)
    held[3, 2] = 2000.0                                   # [N m] at hinge 3
    mon.update(0.01, y, held)
    found = [x for x in mon.findings() if x.kind == "force_jump"]
    assert found and "hinge torques" in found[0].message and found[0].rod in (3, 4)
    a0, b0 = model.bending(0.0, y, np.zeros((8, 3)))
    a1, b1 = model.bending(0.0, y, held)
    assert found[0].value == pytest.approx(max(np.max(np.abs(a1 - a0)), np.max(np.abs(b1 - b0))))
    mon.update(0.02, y, held)                             # held: no new jump
    assert len([x for x in mon.findings() if x.kind == "force_jump"]) == 1


def test_energy_warning_reflects_the_latest_balance_not_an_early_tiny_scale():
    mon = validity.ValidityMonitor(make_model("reduced", chain(loads=[])))
    mon.update_energy(0.01, residual=3e-6, scale=5e-6)       # the first period: meaningless
    assert [f.kind for f in mon.findings()] == ["energy"]
    mon.update_energy(1.0, residual=3e-6, scale=10.0)        # later: 3e-7 of the scale
    assert mon.findings() == []
    mon.update_energy(2.0, residual=0.5, scale=10.0)         # a real 5 % imbalance
    assert [(f.kind, f.t) for f in mon.findings()] == [("energy", 2.0)]


# ----- advise -----

def advised_error(scene, rec, t_end) -> float:
    """The recommendation's error, checked independently against scipy Radau (full model)."""
    traj, _ = run(scene, rec["model"], t_end, rtol=rec["rtol"])
    ref, _ = run(scene, "full", t_end, rtol=1e-10, integrator="Radau")
    return max_err(traj, ref)


def test_advise_stiff_scene_gets_rigid_and_meets_the_tolerance():
    scene = chain(EI=1e7, name="stiff")
    res = advise.advise(scene, 1e-3, t_end=0.5, repeats=1)
    rec = res["recommendation"]
    assert rec["model"] == "rigid"
    assert advised_error(scene, rec, 0.5) <= 1e-3
    assert rec["speedup_vs_full"] > 10


def test_advise_paper_example_at_tight_tolerance_needs_the_full_model():
    scene = load_scene(PAPER)
    res = advise.advise(scene, 1e-5, t_end=1.0, repeats=1)
    rec = res["recommendation"]
    assert rec["model"] == "full"
    assert advised_error(scene, rec, 1.0) <= 1e-5
    loose = advise.advise(scene, 1e-3, t_end=1.0, repeats=1)["recommendation"]
    assert loose["model"] == "reduced"
    assert advised_error(scene, loose, 1.0) <= 1e-3


def test_advise_cli_json_and_bad_input(tmp_path):
    path = tmp_path / "stiff.yaml"
    path.write_text(scene_to_yaml(chain(EI=1e7, name="stiff")))
    proc = subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", "advise", str(path),
                           "--tolerance", "1e-3", "--t-end", "0.3", "--repeats", "1", "--json"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    import json
    assert json.loads(proc.stdout)["recommendation"]["model"] == "rigid"
    bad = subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", "advise", str(path),
                          "--tolerance", "-1"], capture_output=True, text=True)
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
