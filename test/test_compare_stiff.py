"""``rod-sim compare`` on a stiff scene re-runs the full model with radau-jit, chosen by the
stiffness probe that ``rod-sim advise`` uses (rod_sim.app.stiff_probe): a log of a rod on an
overdamped hinge took 74 s to compare with dop853-jit (every step at its stability limit) and
4.3 s with radau-jit, with the same numbers. A scene that is not stiff keeps dop853-jit.

The oracle of the reported error: the log's rigid rod has a closed-form solution (J phi'' +
nu phi' + kappa phi = 0, J = m l^3 / 3, phi(0) = PHI0, phi'(0) = 0), the full model is
integrated by scipy's Radau from its right-hand side, and compare's max |phi_log - phi_full|
must be their difference at the log's samples.
"""
from __future__ import annotations

import json
import math
import re
import threading
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

from rod_sim.core.models import make_model
from rod_sim.io.scene_yaml import load_scene
from rod_sim.tools import cli

ROOT = Path(__file__).resolve().parents[1]
M, L, KAPPA, NU, PHI0 = 3.0, 1.0, 1.0e5, 1.0e5, 0.1
J = M * L ** 3 / 3.0
T_END, RATE = 0.2, 100.0


def stiff_log(tmp_path, capsys) -> tuple[Path, Path]:
    scene = tmp_path / "damped.yaml"
    scene.write_text("name: damped_hinge\n"
                     f"rods: {{count: 1, length: {L}, mass_per_length: {M}, "
                     "bending_stiffness: 1.0e3}\n"
                     "nodes: {mass: 0.0}\n"
                     f"hinges: {{stiffness: {KAPPA}, damping: {NU}}}\n"
                     f"initial: {{phi: {PHI0}}}\n")
    log = tmp_path / "run.mcap"
    assert cli.main(["simulate", str(scene), "--model", "rigid", "--t-end", str(T_END),
                     "--rate", str(RATE), "--out", str(log)]) == 0
    capsys.readouterr()
    return scene, log


def test_a_stiff_log_is_compared_with_radau_and_its_error_is_the_oracles(tmp_path, capsys):
    scene, log = stiff_log(tmp_path, capsys)
    assert cli.main(["compare", str(log), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    ref = report["reference"]
    assert ref["integrator"] == "radau-jit rtol=1e-10 atol=1e-12"
    assert ref["check_integrator"] == "radau-jit rtol=1e-12 atol=1e-14"
    assert ref["twin_integrator"] == "radau-jit rtol=1e-10 atol=1e-12"
    assert ref["converged"] and ref["phi_change"] < 1e-10
    t = np.arange(int(round(T_END * RATE)) + 1) / RATE
    fast = (-NU - math.sqrt(NU ** 2 - 4 * J * KAPPA)) / (2 * J)
    slow = (-NU + math.sqrt(NU ** 2 - 4 * J * KAPPA)) / (2 * J)
    rigid = PHI0 * (fast * np.exp(slow * t) - slow * np.exp(fast * t)) / (fast - slow)
    full = make_model("full", load_scene(scene))
    sol = solve_ivp(lambda tt, y: full.rhs(tt, y), (0.0, T_END), full.initial_state(),
                    method="Radau", rtol=1e-12, atol=1e-14, t_eval=t)
    expected = float(np.max(np.abs(rigid - sol.y[0])))
    assert expected > 1e-3                       # the rigid log differs from the full model
    assert abs(report["max_abs_error"]["phi"] - expected) < 1e-7


def test_a_scene_that_is_not_stiff_keeps_dop853(tmp_path, capsys):
    log = tmp_path / "paper.mcap"
    assert cli.main(["simulate", str(ROOT / "config" / "paper_example.yaml"), "--t-end",
                     "0.3", "--out", str(log)]) == 0
    capsys.readouterr()
    assert cli.main(["compare", str(log), "--json"]) == 0
    ref = json.loads(capsys.readouterr().out)["reference"]
    assert ref["integrator"] == "dop853-jit rtol=1e-10 atol=1e-12"
    assert ref["check_integrator"] == "dop853-jit rtol=1e-12 atol=1e-14"


def test_a_twin_that_is_not_stiff_keeps_dop853_and_the_numbers_stay(tmp_path, capsys):
    """The spin-up beam's full model is stiff for dop853-jit from its initial state (42 % of the
    probe's steps), its chaos twin (every other rod turned by 1e-7 rad) is not (14 %): the
    reference and its check run radau-jit, the twin dop853-jit, and every number of the
    report is the all-dop853-jit comparison's."""
    from rod_sim.compare.comparison import compare_log
    from rod_sim.io.log_source import read_log

    scene = ROOT / "config" / "spin_up_beam.yaml"
    log = tmp_path / "beam.mcap"
    assert cli.main(["simulate", str(scene), "--t-end", "2", "--out", str(log)]) == 0
    capsys.readouterr()
    assert cli.main(["compare", str(log)]) in (0, 1)
    text = " ".join(capsys.readouterr().out.split())
    assert "reference: full model, radau-jit rtol=1e-10 atol=1e-12" in text
    assert "the twin run with dop853-jit rtol=1e-10 atol=1e-12)" in text
    reports = []
    for integrator in (None, "dop853-jit"):
        with read_log(log, None) as stream:
            reports.append(compare_log(stream, load_scene(scene), integrator=integrator))
    auto, explicit = reports
    assert auto.reference["integrator"].startswith("radau-jit")
    assert auto.reference["twin_integrator"].startswith("dop853-jit")
    assert explicit.reference["integrator"].startswith("dop853-jit")
    for name, q in explicit.quantities.items():
        assert abs(auto.quantities[name].max - q.max) <= 1e-9 * max(1.0, q.max), name
    assert abs(auto.chaos["gain"] - explicit.chaos["gain"]) <= 1e-6 * explicit.chaos["gain"]


def test_the_probe_has_its_progress_line(tmp_path, capsys, monkeypatch):
    """A line due at once while the probe runs names it, its time and its steps."""
    from rod_sim.app import progress
    from rod_sim.compare import command, comparison

    _, log = stiff_log(tmp_path, capsys)
    written = threading.Event()
    write_line = progress.write_line

    def noted(text, stream):
        write_line(text, stream)
        written.set()

    probing = comparison._Comparison._probing

    def waits_for_a_line(self, sim):
        probing(self, sim)
        assert written.wait(60)

    monkeypatch.setattr(command, "PROGRESS_FIRST_S", 0.0)
    monkeypatch.setattr(progress, "write_line", noted)
    monkeypatch.setattr(comparison._Comparison, "_probing", waits_for_a_line)
    assert cli.main(["compare", str(log)]) == 0
    err = capsys.readouterr().err.splitlines()
    probe = [ln for ln in err if ln.startswith("rod-sim compare: a probe")]
    assert probe, err
    assert re.match(r"rod-sim compare: a probe of the full model's stiffness \(dop853-jit, 1000 "
                    r"steps at most\) at t = [0-9.e+-]+ s of 0.2 s after \d+ s \(\d+ steps"
                    r"( of ~[0-9.e+-]+ s)?\)$", probe[0]), probe[0]
