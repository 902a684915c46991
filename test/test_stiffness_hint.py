"""A stiff scene says so: dop853-jit counts the steps its stability limited (Hairer's test),
``rod-sim simulate`` prints a hint towards radau-jit, and ``rod-sim advise`` tries radau-jit
where dop853-jit was stiff (a hanging cable of 1 cm rods ran 5.5 min with dop853-jit, 12 s
with radau-jit, and nothing said so).

The oracle is a rod on an overdamped hinge (rigid model: J phi'' + nu phi' + kappa phi = 0,
J = m l^3 / 3): its eigenvalues are known in closed form, and an explicit method's step on it is
bounded by its stability, h |lambda_fast| of order 6 (DOP853's real stability boundary), far
below what the tolerance asks of the slow mode.
"""
from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rod_sim.core.integrators import make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.simulator import Simulator
from rod_sim.io.scene_yaml import load_scene

M, L, KAPPA, NU, PHI0 = 3.0, 1.0, 1.0e5, 1.0e5, 0.1
J = M * L ** 3 / 3.0                                        # 1 kg m^2


def scene_text(kappa: float, nu: float) -> str:
    return (f"name: damped_hinge\n"
            f"rods: {{count: 1, length: {L}, mass_per_length: {M}, bending_stiffness: 1.0e3}}\n"
            f"nodes: {{mass: 0.0}}\n"
            f"hinges: {{stiffness: {kappa}, damping: {nu}}}\n"
            f"initial: {{phi: {PHI0}}}\n")


@pytest.fixture()
def stiff(tmp_path):
    path = tmp_path / "damped.yaml"
    path.write_text(scene_text(KAPPA, NU))
    return path


def rigid_run(path, t_end: float, integrator: str = "dop853-jit"):
    sim = Simulator(make_model("rigid", load_scene(path)), make_integrator(integrator))
    traj = sim.run(t_end, 100.0)
    return sim, traj


def test_dop853_counts_the_steps_its_stability_limited(stiff):
    lam_fast = (-NU - math.sqrt(NU ** 2 - 4 * J * KAPPA)) / (2 * J)       # ~ -1e5 1/s
    lam_slow = (-NU + math.sqrt(NU ** 2 - 4 * J * KAPPA)) / (2 * J)       # ~ -1 1/s
    sim, traj = rigid_run(stiff, 0.2)
    st = sim.stats
    mean_step = 0.2 / st.steps
    assert 3.0 < mean_step * abs(lam_fast) < 8.0          # at the stability boundary
    assert mean_step * abs(lam_slow) < 1e-3                # the slow mode would allow far more
    assert st.stiff_steps > 0.9 * st.steps
    exact = PHI0 * (lam_fast * np.exp(lam_slow * traj.t) - lam_slow * np.exp(lam_fast * traj.t)
                    ) / (lam_fast - lam_slow)             # phi(0) = PHI0, phi'(0) = 0
    assert np.max(np.abs(traj.phi[:, 0] - exact)) < 1e-8


def test_an_oscillating_hinge_is_not_called_stiff(tmp_path):
    # kappa / J = 1e4: omega = 100 rad/s, no damping; dop853-jit's steps follow the accuracy
    path = tmp_path / "spring.yaml"
    path.write_text(scene_text(1.0e4, 0.0))
    sim, traj = rigid_run(path, 40.0)
    assert sim.stats.steps >= 1000                      # enough steps for the hint to judge
    assert sim.stats.stiff_steps < 0.01 * sim.stats.steps
    exact = PHI0 * np.cos(math.sqrt(1.0e4 / J) * traj.t)
    assert np.max(np.abs(traj.phi[:, 0] - exact)) < 1e-5


def test_simulate_hints_at_radau_on_a_stiff_scene_only(stiff, tmp_path):
    def simulate(*extra):
        out = tmp_path / f"run{len(list(tmp_path.glob('*.mcap')))}.mcap"
        return subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", "simulate", str(stiff),
                               "--model", "rigid", "--t-end", "0.2", "--out", str(out), *extra],
                              capture_output=True, text=True, timeout=300)

    proc = simulate()
    assert proc.returncode == 0, proc.stderr
    hints = [ln for ln in proc.stderr.splitlines() if ln.startswith("rod-sim simulate: hint: ")]
    assert len(hints) == 1
    assert "stiff for dop853-jit" in hints[0] and "--integrator radau-jit" in hints[0]
    proc = simulate("--integrator", "radau-jit")
    assert proc.returncode == 0, proc.stderr
    assert "hint" not in proc.stderr


def test_advise_tries_radau_where_dop853_is_stiff_and_its_advice_holds(stiff):
    proc = subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", "advise", str(stiff),
                           "--tolerance", "5e-3", "--t-end", "0.2", "--repeats", "1", "--json"],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    res = json.loads(proc.stdout)
    assert res["reference"]["integrator"] == "radau-jit"      # the full model is stiffer still
    rigid = [r for r in res["trials"] if r["model"] == "rigid"]
    # each stiff dop853-jit candidate is followed by radau-jit at its tolerance
    assert [(r["integrator"], r["rtol"], bool(r.get("stiff"))) for r in rigid] == [
        ("dop853-jit", 1e-4, True), ("radau-jit", 1e-4, False),
        ("dop853-jit", 1e-6, True), ("radau-jit", 1e-6, False),
        ("dop853-jit", 1e-8, True), ("radau-jit", 1e-8, False)]
    rec = res["recommendation"]
    assert (rec["model"], rec["integrator"]) == ("rigid", "radau-jit")
    fastest_explicit = min(r["wall_s"] for r in rigid if r["integrator"] == "dop853-jit")
    assert rec["wall_s"] <= 0.5 * fastest_explicit
    assert rec["simulate_args"] == ["--model", "rigid", "--integrator", "radau-jit", "--rtol",
                                    f"{rec['rtol']:g}"]
    # the advice holds, checked against scipy's Radau on the full model
    full = make_model("full", load_scene(stiff))
    t = np.linspace(0.0, 0.2, 21)
    ref = solve_ivp(lambda tt, y: full.rhs(tt, y), (0.0, 0.2), full.initial_state(),
                    method="Radau", rtol=1e-10, atol=1e-12, t_eval=t)
    sim = Simulator(make_model("rigid", load_scene(stiff)),
                    make_integrator("radau-jit", rtol=rec["rtol"]))
    ours = sim.run(0.2, 100.0)
    assert np.max(np.abs(ours.phi[:, 0] - ref.y[0])) <= 5e-3
