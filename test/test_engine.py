"""One engine (issue 12): every tool integrates through the one driver with the scene's hinge
features compiled in.

- compare re-runs exactly the logged scene: each shipped config's full-model log passes
  against itself, and the deployment log fails against a scene with a tampered stop angle;
- the compiled event location agrees with scipy's solve_ivp event location (an independent
  root finder on another dense output) on the deployment scene's latch times;
- the contact law switches at located crossings, so tight tolerances do not underflow at a
  latch that sits on a stop (they did when a step straddled the contact's jump);
- the locked-hinge constraint holds through a compiled run in every model.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from rod_sim.core.integrators import make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.simulator import Simulator
from rod_sim.io.scene_yaml import load_scene
from rod_sim.tools import cli

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "config"
DEPLOYMENT = CONFIG / "deployment.yaml"
# (scene file, t_end [s], log rate [Hz]): short enough for the full model's two references
SHIPPED = [("deployment.yaml", 2.0, 100), ("paper_example.yaml", 0.5, 100),
           ("small_chain.yaml", 0.5, 100), ("bench/paper_stiff.yaml", 0.05, 1000),
           ("bench/chain_n32.yaml", 0.01, 1000), ("bench/chain_n128.yaml", 0.002, 5000)]
# scenes on a spacecraft base (SPEC section 8; simulate does not log their base yet): (scene file,
# t_end [s]) simulated in every model, long enough for every chain and the base to move
SPACECRAFT = [("two_wing_deployment.yaml", 0.2), ("spin_up_beam.yaml", 0.5),
              ("hub_arm_latch.yaml", 0.5), ("tether_pair.yaml", 0.005)]


def _compare(capsys, log, *extra):
    capsys.readouterr()
    code = cli.main(["compare", str(log), "--json", *map(str, extra)])
    out = capsys.readouterr()
    return code, json.loads(out.out)


def _full_log(tmp_path, scene_file, t_end, rate):
    log = tmp_path / (Path(scene_file).stem + ".mcap")
    assert cli.main(["simulate", str(CONFIG / scene_file), "--model", "full", "--t-end",
                     str(t_end), "--rate", str(rate), "--rtol", "1e-11", "--atol", "1e-11",
                     "--out", str(log)]) == 0
    return log


def test_every_shipped_config_is_listed():
    # shipped configs that are scenes (not params files or sweep specs): one chain from the
    # top-level rods, or chains on a base
    shipped = sorted(str(p.relative_to(CONFIG)) for p in CONFIG.rglob("*.yaml")
                     if {"rods", "chains"} & set(yaml.safe_load(p.read_text()) or {}))
    assert shipped == sorted([s for s, _, _ in SHIPPED] + [s for s, _ in SPACECRAFT])


@pytest.mark.parametrize("model", ["rigid", "reduced", "full"])
@pytest.mark.parametrize("scene_file,t_end", SPACECRAFT)
def test_every_spacecraft_scene_runs_in_every_model(scene_file, t_end, model):
    sc = load_scene(CONFIG / scene_file)
    m = make_model(model, sc)
    traj = Simulator(m, make_integrator("dop853-jit", rtol=1e-6, atol=1e-6)).run(t_end, 100.0)
    assert traj.t[-1] == pytest.approx(t_end) and np.all(np.isfinite(traj.y))
    first, last = m.base_state(traj.t[0], traj.y[0]), m.base_state(traj.t[-1], traj.y[-1])
    assert np.all(np.isfinite([last.x, last.y, last.psi, last.psi_rate]))
    nodes = m.node_positions(traj.t[-1], traj.y[-1])
    assert nodes.shape == (sc.n + len(sc.chains), 2) and np.all(np.isfinite(nodes))
    # something moves: the wings unfold and turn the bus, the beam spins up, the tethers turn
    assert np.max(np.abs(traj.y[-1, :sc.n] - traj.y[0, :sc.n])) > 1e-6
    if sc.base.mode != "fixed":
        assert abs(last.psi - first.psi) > 1e-9


def test_advise_counts_a_free_bases_angle(capsys):
    # rod-sim advise on the two-wing deployment: a candidate's error is the larger of its rod
    # angles' and its bus angle's distance from the full model's reference
    wings = CONFIG / "two_wing_deployment.yaml"
    assert cli.main(["advise", str(wings), "--tolerance", "1e-3", "--t-end", "0.2",
                     "--repeats", "1", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    trial = next(r for r in res["trials"] if r["model"] == "rigid" and r["rtol"] == 1e-4)
    sc = load_scene(wings)
    runs = {}
    for name, rtol in (("rigid", 1e-4), ("full", 1e-11)):
        m = make_model(name, sc)
        traj = Simulator(m, make_integrator(rtol=rtol)).run(0.2, 100.0)
        runs[name] = (traj.phi, traj.y[:, m.base_index + 2])
    phi_err = np.max(np.abs(runs["rigid"][0] - runs["full"][0]))
    psi_err = np.max(np.abs(runs["rigid"][1] - runs["full"][1]))
    assert psi_err > 1e-9                                   # the bus turns differently
    assert trial["max_phi_error"] == pytest.approx(max(phi_err, psi_err), rel=1e-6)
    assert res["recommendation"] is not None
    # here the rods' error is the larger; the angles advise compares end with the bus's psi
    from rod_sim.tools import advise
    angles = advise._run(sc, "rigid", 1e-4, 0.2).angles
    assert angles.shape == (21, sc.n + 1)
    assert np.array_equal(angles[:, :-1], runs["rigid"][0])
    assert np.array_equal(angles[:, -1], runs["rigid"][1])


def test_every_shipped_config_compares_with_its_own_full_log(tmp_path, capsys):
    for scene_file, t_end, rate in SHIPPED:
        log = _full_log(tmp_path, scene_file, t_end, rate)
        code, rep = _compare(capsys, log)
        assert code == 0 and rep["pass"], (scene_file, rep["max_abs_error"])
        assert rep["max_abs_error"]["phi"] < 1e-7, scene_file


def test_tampered_stop_angle_fails(tmp_path, capsys):
    log = _full_log(tmp_path, "deployment.yaml", 2.0, 100)
    data = yaml.safe_load(DEPLOYMENT.read_text())
    data["hinges"]["stop"]["angle"][4] = [-3.2, -1.0]      # hinge 4 now stops at -1 rad
    data["hinges"]["latch"][4] = -1.0          # (a latch at 0, beyond that stop, is refused)
    tampered = tmp_path / "tampered.yaml"
    tampered.write_text(yaml.safe_dump(data))
    code, rep = _compare(capsys, log, "--scene", tampered)
    assert code == 1 and not rep["pass"]
    assert rep["max_abs_error"]["phi"] > 0.1
    code, rep = _compare(capsys, log)                       # the logged scene still passes
    assert code == 0 and rep["pass"]


def _latch_times(model, integrator, t_end, rtol, stops=True):
    sc = load_scene(DEPLOYMENT)
    if not stops:      # the stops sit on the latch angles: the latch catches each hinge first
        sc = sc.with_changes(stop_lower=-np.inf, stop_upper=np.inf)
    sim = Simulator(make_model(model, sc), make_integrator(integrator, rtol=rtol, atol=rtol))
    sim.run(t_end, 10.0)
    return {e.hinge: e.t for e in sim.events if e.kind == "latch"}


def test_deployment_latch_times_agree_with_scipy_event_location():
    ours = _latch_times("reduced", "dop853-jit", 7.0, 1e-11)
    # scipy's methods refuse stops; without them the latches are the same events
    scipy = _latch_times("reduced", "DOP853", 7.0, 1e-11, stops=False)
    assert sorted(ours) == sorted(scipy) == [1, 2, 3, 4]
    for h in ours:
        assert abs(ours[h] - scipy[h]) < 1e-8, (h, ours[h], scipy[h])


def test_tight_tolerance_through_a_latch_on_a_stop():
    # hinge 4 reaches its latch and its stop (both at 0) at t ~ 1.003 s
    times = _latch_times("full", "dop853-jit", 1.2, 1e-13)
    assert list(times) == [4] and 1.0 < times[4] < 1.01
    loose = _latch_times("full", "dop853-jit", 1.2, 1e-9)
    assert abs(loose[4] - times[4]) < 1e-7


@pytest.mark.parametrize("model", ["rigid", "reduced", "full"])
def test_locked_root_hinge_holds_in_every_model(model):
    sc = load_scene(DEPLOYMENT)
    sim = Simulator(make_model(model, sc), make_integrator(rtol=1e-8))
    traj = sim.run(2.0, 50.0)
    # root hinge 0 locked at 0: theta_0 = phi_1 (rigid, reduced); the full model holds the
    # rod end, Delta_0 = phi_1 + alpha_1 (docs/hinges.md), and phi_1 alone moves
    held = traj.phi[:, 0] + (traj.y[:, sc.n] if model == "full" else 0.0)
    assert np.max(np.abs(held)) < 1e-12
    assert (np.max(np.abs(traj.phi[:, 0])) > 1e-4) == (model == "full")


def test_no_scene_specific_model_class():
    # hinge scenes and plain scenes run the same model classes (no wrapper, no dispatch)
    sc = load_scene(DEPLOYMENT)
    for name in ("rigid", "reduced", "full"):
        assert type(make_model(name, sc)) is type(make_model(name, load_scene(
            CONFIG / "small_chain.yaml")))


def test_stop_contacts_agree_across_integrators_and_scipy_is_refused(tmp_path, capsys):
    import sys
    sys.path.insert(0, str(ROOT / "test"))
    from test_hinge_features import _stop_scene

    sc = _stop_scene(5.0)
    runs = {}
    for name, kw in (("dop853-jit", {"rtol": 1e-10, "atol": 1e-10}), ("rk4", {"step": 1e-4})):
        sim = Simulator(make_model("rigid", sc), make_integrator(name, **kw))
        traj = sim.run(2.0, 1000.0)
        theta = traj.phi[:, 1] - traj.phi[:, 0]
        assert theta.max() < 0.2 + 0.05                         # the stop holds (p ~ 1e-2)
        runs[name] = [(e.t, e.kind) for e in sim.events]
    # a hinge that leaves the stop and hits it again soon after: every contact is seen
    assert len(runs["dop853-jit"]) == len(runs["rk4"]) >= 20
    for (ta, ka), (tb, kb) in zip(runs["dop853-jit"], runs["rk4"]):
        assert ka == kb and abs(ta - tb) < 1e-4
    with pytest.raises(ValueError, match="integrator: DOP853 cannot follow hinge stop"):
        Simulator(make_model("rigid", sc), make_integrator("DOP853")).advance(0.01)
    scene_file = tmp_path / "stops.yaml"
    from rod_sim.io.scene_yaml import scene_to_yaml
    scene_file.write_text(scene_to_yaml(sc))
    out = tmp_path / "x.mcap"
    assert cli.main(["simulate", str(scene_file), "--integrator", "RK45", "--t-end", "0.1",
                     "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "RK45 cannot follow hinge stop" in err[0] and not out.exists()
