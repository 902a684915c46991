"""rod-sim bench: fast correctness checks (no speed targets are asserted here).

- rows carry the keys of SPEC section 6;
- the reference check rejects an unconverged reference;
- a row's ``simulate_args`` reproduce its run through ``rod-sim simulate``, and its claimed
  error survives an independent re-run (scipy's DOP853, not the compiled integrator);
- the MuJoCo peer is the same physical model as our rigid chain (skipped without mujoco).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from rod_sim.core.integrators import make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.simulator import Simulator
from rod_sim.io.series import read_rod_states
from rod_sim.io.scene_yaml import load_scene
from rod_sim import bench
from rod_sim.tools import cli
from rod_sim.bench import mujoco_peer
from rod_sim.app.common import PAPER_EXAMPLE

SPEC_KEYS = {"scene", "n", "model", "integrator", "setting", "simulate_args", "wall_s", "sim_s",
             "rtf", "max_phi_error"}


@pytest.fixture(scope="module")
def paper():
    return load_scene(str(PAPER_EXAMPLE))


@pytest.fixture(scope="module")
def reduced_ref(paper):
    return bench.reference(paper, "reduced")


@pytest.fixture(scope="module")
def row(paper, reduced_ref):
    cfg = bench.BenchConfig(repeats=1, cap_s=30.0)
    return bench.measure_setting("paper_example", paper, "reduced", "dop853-jit",
                                 {"rtol": 1e-6}, reduced_ref, None, cfg)


def test_reference_check_passes_and_can_fail(paper, reduced_ref):
    assert reduced_ref.ok and reduced_ref.gap <= bench.REFERENCE_GAP
    loose = bench.reference(paper, "reduced", rtol=1e-5, check_rtol=1e-4)
    assert not loose.ok
    assert "not converged" in loose.message and loose.gap > bench.REFERENCE_GAP


def test_row_has_spec_keys_and_sane_values(row):
    data = bench.as_json([row])
    (out,) = data["rows"]
    assert SPEC_KEYS <= set(out)
    assert row.status == "ok"
    assert row.sim_s == bench.T_END and math.isclose(row.rtf, row.sim_s / row.wall_s)
    assert row.nfev > 0 and row.steps > 0
    # rtol 1e-6 on this scene: the error is well above rounding and well below 1 mrad
    assert 1e-8 < row.max_phi_error < 1e-4
    assert "targets" in data and "environment" in data


def test_unconverged_reference_gives_untimed_row(paper):
    bad = bench.Reference("reduced", None, 1.0, 0.0, False, "reference not converged: test")
    r = bench.measure_setting("paper_example", paper, "reduced", "dop853-jit", {"rtol": 1e-6},
                              bad, None, bench.BenchConfig(repeats=1))
    assert r.status.startswith("not timed") and math.isnan(r.wall_s)


def test_simulate_args_reproduce_the_row(row, paper, reduced_ref, tmp_path):
    out = tmp_path / "run.mcap"
    assert cli.main(["simulate", row.scene_file, *row.simulate_args, "--out", str(out)]) == 0
    t, phi, _ = read_rod_states(out)
    np.testing.assert_allclose(t, np.arange(201) / 100.0, atol=1e-9)
    # independent reference: scipy's DOP853 (not the compiled integrator) at rtol 1e-12
    indep = Simulator(make_model("reduced", paper),
                      make_integrator("DOP853", rtol=1e-12)).run(2.0, 100.0).phi
    assert np.max(np.abs(indep - reduced_ref.phi)) < 1e-8
    err = float(np.max(np.abs(phi - indep)))
    # the logged run integrates in 0.5 s chunks (the bench in one call): same error level
    assert 0.5 * row.max_phi_error <= err <= 2.0 * row.max_phi_error


def test_timeout_and_failure_are_listed(paper, reduced_ref):
    cfg = bench.BenchConfig(repeats=1, cap_s=1e-4)
    slow = bench.measure_setting("paper_example", paper, "reduced", "euler", {"step": 1e-5},
                                 reduced_ref, None, cfg)
    assert slow.status.startswith("timed out")
    full_ref = bench.Reference("full", np.zeros((201, 8)), 0.0, 0.0, True)
    unstable = bench.measure_setting("paper_example", paper, "full", "rk4", {"step": 4e-3},
                                     full_ref, None, bench.BenchConfig(repeats=1))
    assert unstable.status.startswith("failed") or unstable.status.startswith("diverged")


def test_report_files(row, tmp_path):
    data = bench.as_json([row])
    written = bench.write_report(tmp_path, data)
    names = {p.name for p in written}
    assert {"bench.json", "results.md", "wp_paper_example.png"} <= names
    text = (tmp_path / "results.md").read_text()
    assert "| reduced | dop853-jit | rtol=1e-06 |" in text


def test_bench_cli_rejects_a_file_as_out_dir(tmp_path, capsys):
    f = tmp_path / "x"
    f.write_text("")
    assert cli.main(["bench", "--quick", "--out", str(f)]) == 2
    assert "--out" in capsys.readouterr().err


def test_peer_reports_missing_mujoco(paper, monkeypatch):
    monkeypatch.setattr(mujoco_peer, "available", lambda: False)
    rows = bench.mujoco_rows("paper_example", paper, {}, None, bench.BenchConfig())
    assert len(rows) == 1 and "mujoco not installed" in rows[0].status


@pytest.mark.parametrize("scene_file", [str(PAPER_EXAMPLE),
                                        str(PAPER_EXAMPLE.parent / "small_chain.yaml")])
def test_mujoco_chain_is_our_rigid_model(scene_file):
    pytest.importorskip("mujoco")
    scene = load_scene(scene_file)
    t_end = 0.5
    ours = Simulator(make_model("rigid", scene),
                     make_integrator("dop853-jit", rtol=1e-12)).run(t_end, 100.0).phi
    peer = mujoco_peer.ChainPeer(scene, 1e-4, "RK4").run(t_end, 100.0)
    assert peer.phi.shape == ours.shape
    motion = float(np.max(np.abs(ours - ours[0])))
    assert motion > 0.01                                  # the check is not vacuous
    err = float(np.max(np.abs(peer.phi - ours)))
    assert err < 1e-6, f"MuJoCo vs rigid: {err:.3g} rad"
    # and the error is the time step's: 4x larger step, clearly larger error (2nd order)
    coarse = mujoco_peer.ChainPeer(scene, 4e-4, "RK4").run(t_end, 100.0)
    assert float(np.max(np.abs(coarse.phi - ours))) > 4 * err


def test_deployment_scene_row_has_the_hinge_angle_error():
    # issue 12: the deployment scene (hinge features) is benched over 0..10 s
    scene = bench.load_bench_scene("deployment")
    ref = bench.reference(scene, "reduced", t_end=bench.SCENE_T_END["deployment"])
    assert ref.ok
    cfg = bench.BenchConfig(repeats=1, cap_s=30.0)
    r = bench.measure_setting("deployment", scene, "reduced", "dop853-jit", {"rtol": 1e-7},
                              ref, None, cfg)
    assert r.status == "ok" and r.sim_s == 10.0
    assert r.simulate_args[-4:] == ["--t-end", "10.0", "--rate", "100.0"]
    # independent: hinge angles of a scipy DOP853 run (which refuses stops; here they sit on
    # the latch angles and never act) against the reference's
    free = scene.with_changes(stop_lower=-math.inf, stop_upper=math.inf)
    sim = Simulator(make_model("reduced", free), make_integrator("DOP853", rtol=1e-7))
    phi = sim.run(10.0, bench.RATE_HZ).phi
    theta = np.diff(phi, prepend=0.0, axis=1)
    assert sorted(e.hinge for e in sim.events if e.kind == "latch") == [1, 2, 3, 4]
    assert 1e-9 < r.max_hinge_error < 1e-6
    assert np.max(np.abs(theta - np.diff(ref.phi, prepend=0.0, axis=1))) < 1e-5
    t = bench.targets([r])
    assert t["deployment_reduced"]["setting"] == "rtol=1e-07"
    assert "deployment reduced >= 1000x" in t["met"]
    assert "deployment full >= 20x" not in t["met"]          # no full-model row: not run
    refused = bench.measure_setting("deployment", scene, "reduced", "RK45", {"rtol": 1e-7},
                                    ref, None, cfg)
    assert refused.status.startswith("refused: integrator: RK45 cannot follow hinge stop")


def test_hinge_rhs_cost_compares_with_the_plain_chain():
    out = bench.hinge_rhs_cost(models=("rigid",), rounds=2, span_s=0.05)
    c = out["rigid"]
    assert c["n"] == 5 and c["hinge_s"] > 0 and c["plain_s"] > 0 and c["rounds"] == 2
    assert math.isclose(c["ratio"], c["hinge_s"] / c["plain_s"])


def test_full_model_bound_is_a_lower_bound_on_dop853s_work(paper):
    """The stability bound of the report: no dop853-jit run of the full model can take fewer
    rhs evaluations than it says, and at loose tolerances (stability-bound) runs come close."""
    rows = []
    for rtol in (1e-4, 1e-6):
        sim = Simulator(make_model("full", paper), make_integrator("dop853-jit", rtol=rtol))
        sim.run(bench.T_END, bench.RATE_HZ)
        rows.append(bench.BenchRow("paper_example", 8, "full", "dop853-jit", f"rtol={rtol:g}",
                                   None, 0.03, bench.T_END, 66.0, 1e-7, cpu_s=0.03,
                                   rtf_cpu=bench.T_END / 0.03, nfev=sim.stats.nfev,
                                   steps=sim.stats.steps, rejected=sim.stats.rejected))
    b = bench.full_model_bound(rows)
    assert 2000.0 < b["max_abs_lambda"] < 4000.0
    assert b["dop853_min_rhs"] == b["dop853_min_steps"] * 12
    for r in rows:
        assert b["dop853_min_rhs"] <= r.nfev <= 1.6 * b["dop853_min_rhs"]
        assert r.steps >= b["dop853_min_steps"]
    assert b["dop853_rtf_bound"] >= b["dop853_best"]["rtf"]
    assert "radau_best" not in b
    text = "\n".join(bench._bound_lines(b))
    assert f"{b['dop853_min_rhs']} rhs at **any** tolerance" in text


def test_markdown_lists_every_target(row):
    data = bench.as_json([row], hinge_cost={"rigid": {"hinge_s": 2e-6, "plain_s": 1e-6,
                                                      "ratio": 2.0, "n": 5, "rounds": 7,
                                                      "span_s": 0.2}})
    assert data["targets"]["met"]["hinge rhs cost <= 1.5x plain"] is False
    text = bench.markdown([row], data)
    for label, _, check, _ in bench.TARGET_TABLE:
        assert f"| {label} |" in text
    # only the reduced model ran: the full model's targets are "not run", not "no"
    assert "full >= 120x (issue 12, best integrator) | -x | - | - | not run" in text
    assert "reduced >= 1000x | " in text and "| reduced/full >= 100x (paper example) | -x | " \
        "- | - | not run" in text
    assert "| rigid | 2 | 1 | 2.00 |" in text and "target <= 1.5x: **no**" in text
