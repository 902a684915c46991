"""rod-sim sweep: spec validation (exit 2, one line), grid and Monte-Carlo expansion, runs on a
local process pool and on a local Dask cluster against independent serial runs, result tables,
failed runs as rows, Ctrl-C."""
import contextlib
import math
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from procs import terminal_signals  # noqa: E402
import yaml

from rod_sim.core.integrators import make_integrator
from rod_sim.core.kinematics import node_positions
from rod_sim.core.models import make_model
from rod_sim.core.scene import Load
from rod_sim.core.simulator import Simulator
from rod_sim.core.validity import balance_run
from rod_sim.io.scene_yaml import load_scene
from rod_sim.sweep import worker as sweep_worker
from rod_sim.tools import cli
from rod_sim.sweep.spec import SweepSpecError, apply_path, expand, load_spec, parse_path
from rod_sim.sweep.table import read_metadata, read_table, write_table

ROOT = Path(__file__).resolve().parents[1]
SMALL = ROOT / "config" / "small_chain.yaml"
TIMED = {"wall_s", "rtf"}                 # the only columns that differ between equal runs

TINY = {                                  # 2 x 2 grid on small_chain, reduced model: 4 runs
    "name": "tiny",
    "scene": "small_chain.yaml",
    "models": ["reduced"],
    "rtol": 1e-9,
    "t_end": 0.2,
    "rate": 50,
    "parameters": {"hinges.stiffness": [30.0, 80.0],
                   "loads[0].amplitude": {"linspace": [10.0, 40.0, 2]}},
}


def write_spec(tmp_path, spec, name="spec.yaml"):
    shutil.copy(SMALL, tmp_path / "small_chain.yaml")
    path = tmp_path / name
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    return path


def sweep(*args):
    return cli.main(["sweep", *map(str, args)])


def same_rows(a, b):
    """Equal row lists, NaN == NaN, timing columns ignored."""
    assert len(a) == len(b)
    for ra, rb in zip(a, b):
        assert set(ra) == set(rb)
        for k in ra:
            if k in TIMED:
                continue
            va, vb = ra[k], rb[k]
            if isinstance(va, float) and math.isnan(va):
                assert isinstance(vb, float) and math.isnan(vb), (k, va, vb)
            else:
                assert va == vb, (ra["run"], k, va, vb)


# ----- spec validation -----

BAD = {
    "unknown top key": ({"colour": "red"}, "colour"),
    "t_end missing": ({"t_end": None}, "t_end"),
    "t_end negative": ({"t_end": -1.0}, "t_end"),
    "unknown model": ({"models": ["elastic"]}, "models"),
    "unknown integrator": ({"integrator": "leapfrog"}, "integrator"),
    "rtol zero": ({"rtol": 0.0}, "rtol"),
    "rate not a number": ({"rate": "fast"}, "rate"),
    "malformed path": ({"parameters": {"hinges..stiffness": [1.0]}}, "parameters.hinges..stiffness"),
    "unknown kind": ({"parameters": {"hinges.stiffness": {"range": [1, 2]}}},
                     "parameters.hinges.stiffness.range"),
    "linspace arity": ({"parameters": {"hinges.stiffness": {"linspace": [1, 2]}}},
                       "parameters.hinges.stiffness.linspace"),
    "empty values": ({"parameters": {"hinges.stiffness": []}}, "parameters.hinges.stiffness.values"),
    "normal std": ({"parameters": {"hinges.stiffness": {"normal": {"mean": 50, "std": 0}}},
                    "draws": 3}, "parameters.hinges.stiffness.normal.std"),
    "uniform key": ({"parameters": {"hinges.stiffness": {"uniform": {"low": 1, "hi": 2}}},
                     "draws": 3}, "parameters.hinges.stiffness.uniform.hi"),
    "draws missing": ({"parameters": {"hinges.stiffness": {"uniform": {"low": 1, "high": 2}}}},
                      "draws"),
    "draws unused": ({"draws": 5}, "draws"),
    "index out of range": ({"parameters": {"loads[3].amplitude": [1.0]}},
                           "parameters.loads[3].amplitude"),
    "bad value": ({"parameters": {"hinges.stiffness": [10.0, -5.0]}}, "parameters.hinges.stiffness"),
    "bad value by index": ({"parameters": {"rods.length[2]": [0.5, 0.0]}}, "parameters.rods.length[2]"),
    "unknown scene key": ({"parameters": {"hinges.stifness": [1.0]}}, "parameters.hinges.stifness"),
    "scene file missing": ({"scene": "nowhere.yaml"}, "scene"),
    "full model, massless rod": ({"models": ["full"], "parameters": {
        "rods.mass_per_length": [1.0, 0.0]}}, "models"),
    # issue 19 item 8: refused up front, before the grid is allocated (was exit 1 "out of memory")
    "1e9-point grid": ({"parameters": {"hinges.stiffness": {"linspace": [1, 2, 10 ** 9]}}},
                       "parameters.hinges.stiffness.linspace[2]"),
    "1e6-run grid": ({"parameters": {"hinges.stiffness": {"linspace": [1, 2, 1000]},
                                     "hinges.damping": {"geomspace": [0.1, 1, 1000]}}},
                     "parameters"),
    "1e9 draws": ({"parameters": {"hinges.stiffness": {"uniform": {"low": 1, "high": 2}}},
                   "draws": 10 ** 9}, "draws"),
    "lognormal overflow": ({"parameters": {"hinges.stiffness": {"lognormal": {
        "median": 50.0, "sigma": 1000.0}}}, "draws": 8}, "parameters.hinges.stiffness.lognormal"),
}


@pytest.mark.filterwarnings("error")           # no numpy RuntimeWarning before the clean error
def test_overflowing_draws_are_refused_without_runtime_warnings(tmp_path):
    spec = {**TINY, "parameters": {"hinges.stiffness": {"lognormal": {
        "median": 1e11, "sigma": 800.0}}}, "draws": 16}
    with pytest.raises(SweepSpecError, match="not finite") as info:
        expand(load_spec(write_spec(tmp_path, spec)))
    assert info.value.key == "parameters.hinges.stiffness.lognormal"


def test_the_run_limit_is_inclusive(tmp_path):
    from rod_sim.sweep.spec import MAX_RUNS
    spec = {**TINY, "parameters": {"hinges.stiffness": {"linspace": [1, 2, MAX_RUNS]}}}
    assert len(load_spec(write_spec(tmp_path, spec)).parameters[0].values) == MAX_RUNS


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_spec_exits_2_with_one_line_naming_the_key(tmp_path, capsys, case):
    changes, key = BAD[case]
    spec = {**TINY, **changes}
    spec = {k: v for k, v in spec.items() if v is not None}
    out = tmp_path / "out.csv"
    assert sweep(write_spec(tmp_path, spec), "--out", out, "--workers", 0) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith(f"rod-sim sweep: error: {key}:"), err
    assert not out.exists()


def test_bad_value_names_the_run_and_value(tmp_path):
    spec = {**TINY, "parameters": {"hinges.stiffness": [10.0, -5.0]}}
    with pytest.raises(SweepSpecError, match=r"run 1 \(hinges.stiffness=-5.0\).*must be >= 0"):
        expand(load_spec(write_spec(tmp_path, spec)))


def test_duplicate_key_in_spec_is_named(tmp_path, capsys):
    path = tmp_path / "dup.yaml"
    path.write_text(f"scene: {SMALL}\nt_end: 1.0\nt_end: 2.0\n")
    assert sweep(path, "--out", tmp_path / "o.csv") == 2
    assert capsys.readouterr().err.startswith("rod-sim sweep: error: t_end: duplicate key")


def test_existing_output_and_bad_extension_are_refused(tmp_path, capsys):
    spec = write_spec(tmp_path, TINY)
    out = tmp_path / "out.csv"
    out.write_text("keep")
    assert sweep(spec, "--out", out, "--workers", 0) == 2
    assert out.read_text() == "keep"
    assert sweep(spec, "--out", tmp_path / "out.xlsx", "--workers", 0) == 2
    err = capsys.readouterr().err.splitlines()
    assert "exists" in err[0] and "--out" in err[1] and ".parquet" in err[1]


# ----- expansion -----

def test_grid_is_the_cartesian_product_with_models_fastest(tmp_path):
    spec = {**TINY, "models": ["reduced", "rigid"],
            "parameters": {"hinges.stiffness": [1.0, 2.0, 3.0],
                           "loads[0].amplitude": {"linspace": [0.0, 1.0, 3]},
                           "rods.bending_stiffness": {"geomspace": [1e3, 1e5, 3]}}}
    runs = expand(load_spec(write_spec(tmp_path, spec)))
    assert len(runs) == 3 * 3 * 3 * 2
    assert [r.index for r in runs] == list(range(54))
    assert [r.model for r in runs[:4]] == ["reduced", "rigid", "reduced", "rigid"]
    assert runs[0].params == {"hinges.stiffness": 1.0, "loads[0].amplitude": 0.0,
                              "rods.bending_stiffness": 1e3}
    assert runs[2].params["rods.bending_stiffness"] == pytest.approx(1e4)
    assert runs[6].params["loads[0].amplitude"] == 0.5
    assert runs[18].params["hinges.stiffness"] == 2.0
    combos = {tuple(r.params.values()) + (r.model,) for r in runs}
    assert len(combos) == 54
    scene = runs[-1].scene                # the values reach the scene data
    assert scene["hinges"]["stiffness"] == 3.0
    assert scene["loads"][0]["amplitude"] == 1.0
    assert scene["rods"]["bending_stiffness"] == pytest.approx(1e5)
    assert scene["loads"][0]["node"] == 3 and scene["rods"]["count"] == 3   # the rest untouched


def test_path_into_a_per_rod_scalar_spells_it_out():
    scene = {"rods": {"count": 3}, "hinges": {"stiffness": 50.0}, "loads": [{"amplitude": 1.0}]}
    apply_path(scene, parse_path("hinges.stiffness[1]"), 7.0)
    apply_path(scene, parse_path("initial.phi"), 0.25)
    apply_path(scene, parse_path("loads[0].amplitude"), -2.0)
    assert scene == {"rods": {"count": 3}, "hinges": {"stiffness": [50.0, 7.0, 50.0]},
                     "loads": [{"amplitude": -2.0}], "initial": {"phi": 0.25}}
    assert parse_path("a.b[2][0].c") == ("a", "b", 2, 0, "c")


def test_path_into_a_chain_spells_out_with_the_chains_count():
    scene = {"rods": {"count": 9}, "chains": [
        {"name": "a", "rods": {"count": 2, "length": 1.0}, "hinges": {"stiffness": 5.0}},
        {"name": "b", "rods": {"count": 3, "length": 2.0}}]}
    apply_path(scene, parse_path("chains[0].hinges.stiffness[1]"), 7.0)
    apply_path(scene, parse_path("chains[1].rods.length[2]"), 2.5)
    assert scene["chains"][0]["hinges"]["stiffness"] == [5.0, 7.0]
    assert scene["chains"][1]["rods"]["length"] == [2.0, 2.0, 2.5]
    path = "chains[1].nodes.mass[0]"                       # not set: one line naming it
    with pytest.raises(SweepSpecError, match=r"^parameters.chains\[1\].nodes.mass\[0\]: "):
        apply_path(scene, parse_path(path), 1.0, path)


def test_sweep_over_a_spacecraft_scene(tmp_path):
    # chain and base parameters of the two-wing deployment; the right wing's tip, computed here
    # from the logged state by hand (base pose + attach point + rod chords), is what the
    # row's max_tip_displacement reports (the right wing is the last chain)
    shutil.copy(ROOT / "config" / "two_wing_deployment.yaml", tmp_path / "wings.yaml")
    spec = {**TINY, "scene": "wings.yaml", "models": ["rigid"], "rtol": 1e-9, "t_end": 0.5,
            "rate": 20, "parameters": {"chains[1].hinges.stiffness[2]": [5.0, 50.0],
                                       "base.inertia": [900.0]}}
    out = tmp_path / "wings.csv"
    assert sweep(write_spec(tmp_path, spec), "--out", out, "--workers", 0) == 0
    rows = read_table(out)
    assert [r["status"] for r in rows] == ["ok", "ok"]
    assert rows[0]["max_tip_displacement"] != rows[1]["max_tip_displacement"]
    sc = load_scene(tmp_path / "wings.yaml")
    sc = sc.with_changes(hinge_stiffness=np.r_[sc.hinge_stiffness[:7], 50.0,
                                               sc.hinge_stiffness[8:]])
    model = make_model("rigid", sc)
    traj = Simulator(model, make_integrator(rtol=1e-9)).run(0.5, 20)
    i, n = model.base_index, sc.n
    x, y, psi = traj.y[:, i], traj.y[:, i + 1], traj.y[:, i + 2]
    ax, ay = -1.0, 0.0                               # the right wing's attach point
    phi = traj.y[:, 5:n]
    tip = np.stack([x + np.cos(psi) * ax - np.sin(psi) * ay + np.cos(phi) @ sc.length[5:],
                    y + np.sin(psi) * ax + np.cos(psi) * ay + np.sin(phi) @ sc.length[5:]], 1)
    left = traj.y[:, :5]
    ltip = np.stack([x + np.cos(psi) + np.cos(left) @ sc.length[:5],
                     y + np.sin(psi) + np.sin(left) @ sc.length[:5]], 1)
    expect = max(np.max(np.linalg.norm(tip - tip[0], axis=1)),
                 np.max(np.linalg.norm(ltip - ltip[0], axis=1)))
    assert abs(rows[1]["max_tip_displacement"] - expect) < 1e-9
    assert rows[1]["tip_phi_final"] == pytest.approx(phi[-1, -1], abs=1e-12)


SPUN_BUS = """
name: spun_bus
base: {mode: free, mass: 50.0, inertia: 20.0}
chains:
  - name: wing
    attach: [0.5, 0.0]
    rods: {count: 3, length: 1.0, mass_per_length: 2.0, bending_stiffness: 500.0}
    nodes: {mass: 0.2}
    hinges: {stiffness: 30.0, damping: 0.5}
loads:
  - {node: base, axis: moment, shape: constant, amplitude: 10.0, start: 0.0}
"""


def test_a_spacecraft_sweep_books_the_base_angle_and_the_momentum_balance(tmp_path):
    """A free bus turned by a constant moment M = 10 N m with a flexible wing: its angular
    momentum about O grows by M t_end (the closed form of int M dt), its linear momentum stays
    0. The row's residuals are the balances (H(t_end) - H(0) - M t_end, |P(t_end) - P(0)|
    from the end state's momentum, computed here), and its base angle the end state's; a
    plain chain's table keeps its columns. The rigid and reduced models (whose momentum obeys
    the loads exactly; the full model's changes by a defect linear in the bending, which the
    ledger books: docs/spacecraft.md section 6)."""
    (tmp_path / "bus.yaml").write_text(SPUN_BUS)
    spec = {**TINY, "scene": "bus.yaml", "models": ["reduced", "rigid"], "rtol": 1e-10,
            "t_end": 0.5, "rate": 100, "parameters": {"base.inertia": [20.0]}}
    out = tmp_path / "bus.csv"
    assert sweep(write_spec(tmp_path, spec), "--out", out, "--workers", 0) == 0
    rows = read_table(out)
    assert [r["status"] for r in rows] == ["ok", "ok"]
    for row in rows:
        model = make_model(row["model"], load_scene(tmp_path / "bus.yaml"))
        traj = Simulator(model, make_integrator(rtol=1e-10)).run(0.5, 100)
        h0 = model.momentum(0.0, traj.y[0]).angular_origin
        end = model.momentum(0.5, traj.y[-1])
        assert row["angular_momentum_residual"] == pytest.approx(
            end.angular_origin - h0 - 10.0 * 0.5, abs=1e-9)
        assert row["momentum_residual"] == pytest.approx(np.hypot(*end.linear), abs=1e-9)
        assert row["base_psi_final"] == pytest.approx(
            model.base_state(0.5, traj.y[-1]).psi, abs=1e-12)
        assert row["base_psi_final"] > 0.01
    plain = tmp_path / "plain.csv"
    assert sweep(write_spec(tmp_path, TINY), "--out", plain, "--workers", 0) == 0
    assert "momentum_residual" not in read_table(plain)[0]


MC = {**TINY, "draws": 400, "seed": 11,
      "parameters": {"hinges.stiffness": {"uniform": {"low": 20.0, "high": 60.0}},
                     "hinges.damping": {"lognormal": {"median": 0.5, "sigma": 0.3}},
                     "loads[0].amplitude": {"normal": {"mean": 20.0, "std": 2.0}}}}


def test_monte_carlo_draws_are_reproducible_and_follow_the_distribution(tmp_path):
    path = write_spec(tmp_path, MC)
    runs = expand(load_spec(path), validate=False)
    assert len(runs) == 400
    again = expand(load_spec(path), validate=False)
    assert [r.params for r in runs] == [r.params for r in again]
    other = expand(load_spec(path, seed=12), validate=False)
    assert all(a.params != b.params for a, b in zip(runs, other))

    k = np.array([r.params["hinges.stiffness"] for r in runs])
    c = np.array([r.params["hinges.damping"] for r in runs])
    a = np.array([r.params["loads[0].amplitude"] for r in runs])
    assert k.min() >= 20.0 and k.max() < 60.0
    assert abs(k.mean() - 40.0) < 4 * (40.0 / math.sqrt(12)) / math.sqrt(400)
    assert abs(np.median(np.log(c)) - math.log(0.5)) < 0.06
    assert abs(np.std(np.log(c)) - 0.3) < 0.04
    assert abs(a.mean() - 20.0) < 4 * 2.0 / math.sqrt(400)
    assert abs(a.std() - 2.0) < 0.3
    assert runs[5].scene["hinges"]["stiffness"] == k[5]


def test_a_parameters_draws_depend_only_on_seed_and_path(tmp_path):
    full = expand(load_spec(write_spec(tmp_path, MC)), validate=False)
    only = {**MC, "parameters": {"loads[0].amplitude": MC["parameters"]["loads[0].amplitude"]}}
    alone = expand(load_spec(write_spec(tmp_path, only, "only.yaml")), validate=False)
    assert [r.params["loads[0].amplitude"] for r in full] == \
        [r.params["loads[0].amplitude"] for r in alone]


def test_grid_times_draws(tmp_path):
    spec = {**MC, "draws": 3, "models": ["reduced", "rigid"],
            "parameters": {"hinges.stiffness": [10.0, 20.0],
                           "loads[0].amplitude": {"normal": {"mean": 20.0, "std": 2.0}}}}
    runs = expand(load_spec(write_spec(tmp_path, spec)))
    assert len(runs) == 2 * 3 * 2
    amps = [r.params["loads[0].amplitude"] for r in runs]
    assert amps[:6] == amps[6:]                     # the same draws at every grid point
    assert len(set(amps)) == 3


# ----- runs -----

def independent_row(index, stiffness, amplitude, model="reduced", t_end=0.2, rate=50):
    """The row of one TINY run, computed without the sweep code."""
    base = load_scene(SMALL)
    scene = base.with_changes(hinge_stiffness=stiffness, loads=(
        Load(node=3, axis="y", shape="constant", amplitude=amplitude, start=0.1),))
    m = make_model(model, scene)
    sim = Simulator(m, make_integrator("dop853-jit", rtol=1e-9))
    traj = sim.run(t_end, rate)
    phi = traj.phi
    tips = np.array([node_positions(scene.length, p)[-1] for p in phi])
    bend = [m.bending(t, y) for t, y in zip(traj.t, traj.y)]
    energy = [m.energies(t, y).total for t, y in zip(traj.t, traj.y)]
    *_, (_, balance, _) = balance_run(m, traj.t, traj.y, None, traj.modes, sim.events)
    return {"run": index, "hinges.stiffness": stiffness, "loads[0].amplitude": amplitude,
            "model": model, "status": "ok", "nfev": sim.stats.nfev,
            "max_abs_phi": np.abs(phi).max(), "tip_phi_final": phi[-1, -1],
            "max_tip_displacement": np.hypot(*(tips - tips[0]).T).max(),
            "max_abs_alpha": max(np.abs(a).max() for a, _ in bend),
            "max_abs_beta": max(np.abs(b).max() for _, b in bend),
            "energy_final": energy[-1],
            "energy_residual": balance.residual}


@pytest.fixture(scope="module")
def local_run(tmp_path_factory):
    """The TINY sweep on 2 local worker processes: (spec path, rows)."""
    tmp = tmp_path_factory.mktemp("local")
    path = write_spec(tmp, TINY)
    out = tmp / "local.csv"
    assert sweep(path, "--out", out, "--workers", 2) == 0
    return path, read_table(out)


def test_local_pool_rows_equal_independent_serial_runs(local_run):
    _, rows = local_run
    expected = [independent_row(i, k, a) for i, (k, a) in
                enumerate([(30.0, 10.0), (30.0, 40.0), (80.0, 10.0), (80.0, 40.0)])]
    assert [r["run"] for r in rows] == [0, 1, 2, 3]
    for row, exp in zip(rows, expected):
        assert row["wall_s"] > 0 and row["rtf"] == pytest.approx(0.2 / row["wall_s"])
        for k, v in exp.items():
            if isinstance(v, str) or k in ("run", "nfev"):
                assert row[k] == v, k
            else:
                assert row[k] == pytest.approx(float(v), rel=1e-11, abs=1e-13), k
    assert rows[1]["max_tip_displacement"] > rows[0]["max_tip_displacement"]  # 4x the push


def test_serial_and_parquet_give_the_same_table(local_run, tmp_path):
    path, rows = local_run
    out = tmp_path / "serial.parquet"
    assert sweep(path, "--out", out, "--workers", 0) == 0
    same_rows(read_table(out), rows)
    meta = read_metadata(out)
    assert meta["name"] == "tiny" and meta["seed"] == 0 and meta["t_end"] == 0.2


def test_table_round_trip(tmp_path):
    rows = [{"run": 0, "rods.count": 3, "x": 0.1 + 0.2, "model": "full",
             "status": "failed: IntegrationError: stopped, at t = 0.1 s", "nfev": 12,
             "energy_final": math.nan},
            {"run": 1, "rods.count": 4, "x": -1e-300, "model": "rigid", "status": "ok",
             "nfev": 0, "energy_final": 1.0 / 3.0}]
    columns = list(rows[0])
    for ext in ("csv", "parquet"):
        out = tmp_path / f"t.{ext}"
        write_table(rows, out, columns, {"seed": 4})
        back = read_table(out)
        same_rows(back, rows)
        assert list(back[0]) == columns
        assert type(back[0]["rods.count"]) is int and type(back[0]["x"]) is float


def test_failed_run_is_a_row(tmp_path, capsys):
    # Explicit Euler with 10 ms steps is unstable for the full model's bending modes (their
    # periods are well under 10 ms) and overflows; the reduced model survives the same steps.
    spec = {**TINY, "models": ["full", "reduced"], "integrator": "euler", "step": 0.01,
            "rate": 5, "parameters": {"hinges.stiffness": [30.0]}}
    out = tmp_path / "failed.csv"
    assert sweep(write_spec(tmp_path, spec), "--out", out, "--workers", 0) == 0
    rows = read_table(out)
    assert [r["model"] for r in rows] == ["full", "reduced"]
    assert rows[0]["status"].startswith("failed: IntegrationError: integration stopped at t =")
    assert "non-finite" in rows[0]["status"]
    assert math.isnan(rows[0]["max_abs_phi"]) and rows[0]["nfev"] > 0
    assert rows[1]["status"] == "ok" and math.isfinite(rows[1]["max_abs_phi"])
    assert "1 failed" in capsys.readouterr().out


def test_plot_is_written(tmp_path):
    spec = {**TINY, "t_end": 0.05, "draws": 3,
            "parameters": {"hinges.stiffness": [30.0, 80.0],
                           "loads[0].amplitude": {"uniform": {"low": 5.0, "high": 9.0}}}}
    png = tmp_path / "s.png"
    assert sweep(write_spec(tmp_path, spec), "--out", tmp_path / "s.csv", "--plot", png,
                 "--workers", 0) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000


@pytest.mark.slow
def test_local_dask_cluster_gives_the_same_rows(local_run, tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    path, rows = local_run
    out = tmp_path / "dask.csv"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        assert sweep(path, "--out", out, "--scheduler", cluster.scheduler_address) == 0
    same_rows(read_table(out), rows)


# ----- Ctrl-C -----

def test_interrupt_writes_the_finished_rows(tmp_path, monkeypatch, capsys):
    real = sweep_worker.run_one

    def run_one(task):                   # Ctrl-C arrives during the third run
        if task["index"] == 2:
            raise KeyboardInterrupt
        return real(task)

    monkeypatch.setattr(sweep_worker, "run_one", run_one)
    out = tmp_path / "partial.csv"
    assert sweep(write_spec(tmp_path, TINY), "--out", out, "--workers", 0) == 130
    assert [r["run"] for r in read_table(out)] == [0, 1]
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("rod-sim sweep: interrupted: 2 of 4 runs")


@pytest.mark.slow
@pytest.mark.timing
def test_sigint_stops_the_process_pool(tmp_path):
    spec = {**TINY, "scene": str(ROOT / "config" / "paper_example.yaml"), "models": ["full"],
            "rtol": 1e-10, "t_end": 2.0, "parameters": {"hinges.stiffness": {
                "linspace": [50.0, 150.0, 400]}}}
    out = tmp_path / "partial.csv"
    proc = subprocess.Popen([sys.executable, "-m", "rod_sim.tools.cli", "sweep",
                             str(write_spec(tmp_path, spec)), "--out", str(out),
                             "--workers", "2"], cwd=tmp_path,
                            stderr=subprocess.PIPE, text=True, preexec_fn=terminal_signals)
    first = proc.stderr.readline()
    assert "400 runs" in first
    time.sleep(6.0)
    proc.send_signal(signal.SIGINT)
    started = time.monotonic()
    _, err = proc.communicate(timeout=60)
    assert time.monotonic() - started < 30
    assert proc.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err
    rows = read_table(out)
    assert len(rows) < 400
    assert [r["run"] for r in rows] == sorted(r["run"] for r in rows)


def test_a_killed_worker_loses_no_run_of_the_other_workers():
    # issue 19 item 8: a worker killed (SIGKILL) in the middle of a run broke the pool and
    # failed the runs of the other worker too; now the lost runs are retried
    import sweep_crash
    from rod_sim.sweep.command import run_local

    with sweep_crash.flag_dir() as flags:
        tasks = [{"index": i, "flags": str(flags), "params": {}, "model": "rigid"}
                 for i in range(6)]
        rows = run_local(tasks, 2, function=sweep_crash.die_once_at_index_2)
        assert sorted(rows) == list(range(6))
        assert all(rows[i]["status"] == "ok" for i in range(6)), rows
        assert sweep_crash.died(flags) == [2]          # it really died once
        assert sweep_crash.runs(flags, 2) == 2          # and ran again


def test_a_run_that_kills_its_worker_every_time_is_one_failed_row():
    import sweep_crash
    from rod_sim.sweep.command import run_local

    with sweep_crash.flag_dir() as flags:
        tasks = [{"index": i, "flags": str(flags), "params": {}, "model": "rigid", "t_end": 1.0}
                 for i in range(4)]
        rows = run_local(tasks, 2, function=sweep_crash.always_die_at_index_1)
        assert [rows[i]["status"] == "ok" for i in range(4)] == [True, False, True, True]
        assert "its process died while running it, also when run alone" in rows[1]["status"]


@pytest.mark.parametrize("name, runs", [("sweep_example", 32), ("sweep_monte_carlo", 64)])
def test_shipped_specs_are_valid(name, runs):
    assert len(expand(load_spec(ROOT / "config" / f"{name}.yaml"))) == runs


def test_inline_scene_and_text_values():
    base = load_scene(SMALL).to_dict()
    spec = {**TINY, "scene": base, "models": "rigid",
            "parameters": {"loads[0].shape": ["constant", "step"], "loads[0].duration": [0.05]}}
    from rod_sim.sweep.spec import parse_spec

    runs = expand(parse_spec(spec))
    assert [r.params for r in runs] == [{"loads[0].shape": "constant", "loads[0].duration": 0.05},
                                        {"loads[0].shape": "step", "loads[0].duration": 0.05}]
    assert runs[1].scene["loads"][0]["shape"] == "step" and runs[1].model == "rigid"
    assert base["loads"][0]["shape"] == "constant"         # the caller's data is not changed


def test_plot_legend_names_the_other_parameters_levels_and_axes_carry_units(tmp_path,
                                                                          monkeypatch):
    import matplotlib.pyplot as plt
    from rod_sim.sweep.plot import plot_sweep
    rows = [{"model": "reduced", "status": "ok", "hinges.stiffness": k, "loads[0].amplitude": a,
             "max_tip_displacement": k * a, "max_abs_phi": 1.0, "max_abs_alpha": 0.1,
             "max_abs_beta": 0.2, "nfev": 10} for k in (30.0, 80.0) for a in (5.0, 9.0)]
    figures = []
    monkeypatch.setattr(plt, "close", figures.append)       # keep the figure to inspect it
    plot_sweep(rows, ["hinges.stiffness", "loads[0].amplitude"], set(), tmp_path / "p.png")
    fig, = figures
    legends = [t.get_text() for ax in fig.axes if ax.get_legend()
               for t in ax.get_legend().get_texts()]
    assert {"loads[0].amplitude = 5", "loads[0].amplitude = 9", "hinges.stiffness = 30",
            "hinges.stiffness = 80", "reduced"} <= set(legends)
    xlabels = {ax.get_xlabel() for ax in fig.axes}
    assert {"hinges.stiffness [N m/rad]", "loads[0].amplitude [N]"} <= xlabels


def test_default_workers_leave_a_core_and_the_design_is_worded(monkeypatch):
    from types import SimpleNamespace as NS
    from rod_sim.sweep import command as sweep
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    assert sweep.local_workers(None, 100) == 1
    monkeypatch.setattr(os, "cpu_count", lambda: 8)
    assert sweep.local_workers(None, 100) == 7 and sweep.local_workers(3, 100) == 3
    grid, rnd = NS(values=(1, 2), random=False), NS(values=(), random=True)
    assert sweep._design(NS(parameters=[grid, grid], draws=0, models=("reduced",))) == \
        "2 x 2 grid, 1 model"
    assert sweep._design(NS(parameters=[grid, rnd], draws=64, models=("full", "rigid"))) == \
        "2 grid, 64 Monte-Carlo draws per grid point, 2 models"
    assert sweep._design(NS(parameters=[rnd], draws=1, models=("full",))) == \
        "1 Monte-Carlo draw, 1 model"


def _descendants(pid: int) -> set[int]:
    """Every living descendant of process ``pid`` (from /proc; zombies count as dead)."""
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            with contextlib.suppress(OSError, IndexError, ValueError):
                stat = (entry / "stat").read_text()
                fields = stat[stat.rindex(")") + 2:].split()
                if fields[0] != "Z":
                    children.setdefault(int(fields[1]), []).append(int(entry.name))
    found, todo = set(), [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            if child not in found:
                found.add(child)
                todo.append(child)
    return found


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rindex(")") + 2:].split()[0] != "Z"


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="parent-death signal: Linux")
def test_sigkill_of_the_sweep_takes_its_workers_forkserver_and_tracker_with_it(tmp_path):
    """Issue 27, item 8: SIGKILL of `rod-sim sweep`'s main process left its forkserver,
    resource tracker and workers running (> 81 s). The workers get a parent-death signal and
    the helpers see their pipes close: all are gone within 5 s."""
    spec = {**TINY, "scene": str(ROOT / "config" / "paper_example.yaml"), "models": ["full"],
            "rtol": 1e-10, "t_end": 2.0, "parameters": {"hinges.stiffness": {
                "linspace": [50.0, 150.0, 400]}}}
    proc = subprocess.Popen([sys.executable, "-m", "rod_sim.tools.cli", "sweep",
                             str(write_spec(tmp_path, spec)), "--out", str(tmp_path / "k.csv"),
                             "--workers", "2"], cwd=tmp_path, stderr=subprocess.PIPE,
                            text=True, preexec_fn=terminal_signals)
    helpers: set[int] = set()
    try:
        assert "400 runs" in proc.stderr.readline()
        deadline = time.monotonic() + 60
        while len(_descendants(proc.pid)) < 3:          # forkserver, tracker, workers
            assert proc.poll() is None and time.monotonic() < deadline
            time.sleep(0.2)
        time.sleep(3.0)                                  # runs under way
        helpers = _descendants(proc.pid)
        proc.kill()
        proc.wait()
        deadline = time.monotonic() + 5.0
        while any(_alive(p) for p in helpers) and time.monotonic() < deadline:
            time.sleep(0.1)
        left = sorted(p for p in helpers if _alive(p))
        cmdlines = [Path(f"/proc/{p}/cmdline").read_bytes().replace(b"\0", b" ")[:120]
                    for p in left if _alive(p)]
        assert not left, f"still running 5 s after SIGKILL of the sweep: {cmdlines}"
    finally:
        if proc.poll() is None:
            proc.kill()
        for p in helpers | _descendants(proc.pid):
            with contextlib.suppress(OSError):
                os.kill(p, signal.SIGKILL)


POOL_SIGNAL = """
import os, signal, sys
from concurrent.futures import process

made = process.ProcessPoolExecutor.__init__

def init(self, *args, **kwargs):          # Ctrl-C the moment the pool's queues exist
    made(self, *args, **kwargs)
    os.kill(os.getpid(), signal.SIGINT)

process.ProcessPoolExecutor.__init__ = init
sys.argv = ["rod-sim", *sys.argv[1:]]
from rod_sim.tools.launch import main
sys.exit(main())
"""


def test_ctrl_c_as_the_worker_pool_is_made_leaks_nothing(tmp_path):
    """A Ctrl-C that arrived inside the pool's constructor left its semaphores to
    multiprocessing's resource tracker, which printed "There appear to be 5 leaked semaphore
    objects" after the command's line (a signal-moments run at 0.28 s): now the pool is made
    whole, then stopped, and the finished rows (none) are written."""
    spec = {"name": "sig", "scene": str(ROOT / "config" / "paper_example.yaml"),
            "models": ["reduced"], "t_end": 0.1, "rate": 50,
            "parameters": {"hinges.stiffness": {"linspace": [50.0, 150.0, 3]}}}
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(spec))
    done = subprocess.run([sys.executable, "-c", POOL_SIGNAL, "sweep", "s.yaml", "--out",
                           "s.csv", "--workers", "1"], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(ROOT)},
                          preexec_fn=terminal_signals)
    assert done.returncode == 130, done.stderr
    lines = done.stderr.strip().splitlines()
    assert lines[-1] == ("rod-sim sweep: interrupted: 0 of 3 runs: 0 ok, 0 failed; finished "
                         "rows written to s.csv"), done.stderr
    assert "leaked" not in done.stderr and "Traceback" not in done.stderr, done.stderr
    assert len(read_table(tmp_path / "s.csv")) == 0
