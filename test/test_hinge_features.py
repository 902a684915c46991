"""Hinge rest angles, stops, latches, locked hinges and rigid rods (docs/hinges.md).

References are independent of rod_sim.core.hinges wherever possible: the huge-kappa and
huge-EI limits run the plain compiled models; the latch time is found by bisection on a
fixed-step RK4 run of the plain model; the kinetic energy lost at a latch is computed with
the Lagrange-multiplier formula (not the null-space projection the code uses)."""
from __future__ import annotations

import copy
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from rod_sim.core import hinges
from rod_sim.core.integrators import make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.scene import Scene, SceneError
from rod_sim.core.simulator import Simulator
from rod_sim.io.hinge_events import read_hinge_events
from rod_sim.io.scene_yaml import load_scene, scene_from_yaml_text, scene_to_yaml
from rod_sim.tools import cli

from dense_kernels import constraint_matrix, dense_mass_matrix
from ros_domains import next_domain

REPO = Path(__file__).resolve().parents[1]
DEPLOYMENT = REPO / "config" / "deployment.yaml"

BASE = {
    "name": "hinge_test",
    "rods": {"count": 3, "length": 1.0, "mass_per_length": 2.0, "bending_stiffness": 1.0e4},
    "nodes": {"mass": 0.5},
    "hinges": {"stiffness": 10.0, "damping": 0.0},
    "initial": {"phi": [0.3, 0.3, 0.9], "phi_rate": 0.0},
    "loads": [{"node": 3, "axis": "y", "shape": "raised_cosine_pulse", "amplitude": 20.0,
               "start": 0.0, "duration": 0.4}],
}


def scene(**changes) -> Scene:
    data = copy.deepcopy(BASE)
    for path, value in changes.items():
        section, key = path.split("__")
        data[section][key] = value
    return Scene.from_dict(data)


def run(sc: Scene, model: str, t_end: float, rate: float = 50.0, rtol: float = 1e-10):
    sim = Simulator(make_model(model, sc), make_integrator("dop853-jit", rtol=rtol, atol=rtol))
    return sim.run(t_end, rate), sim


# ----- scene keys -----

def test_defaults_reproduce_plain_scene():
    sc = scene()
    assert not sc.has_hinge_features
    assert "rest_angle" not in sc.to_dict()["hinges"]
    assert type(make_model("reduced", sc)).__name__ == "ReducedModel"


@pytest.mark.parametrize("path, value, key", [
    ("hinges__rest_angle", "a", "hinges.rest_angle"),
    ("hinges__rest_angle", [0.0, 1.0], "hinges.rest_angle"),
    ("hinges__rest_angle", math.inf, "hinges.rest_angle"),
    ("hinges__locked", 1, "hinges.locked"),
    ("hinges__locked", [True, False], "hinges.locked"),
    ("rods__rigid", [True, "no", False], "rods.rigid"),
    ("hinges__latch", [0.1, None], "hinges.latch"),
    ("hinges__latch", [0.1, "x", None], "hinges.latch"),
    ("hinges__stop", [0.0, 1.0], "hinges.stop"),
    ("hinges__stop", {"angle": [-1.0, 1.0]}, "hinges.stop.stiffness"),
    ("hinges__stop", {"angle": [-1.0, 1.0], "stiffness": 0.0}, "hinges.stop.stiffness"),
    ("hinges__stop", {"angle": [-1.0, 1.0], "stiffness": 1.0, "damping": -1.0},
     "hinges.stop.damping"),
    ("hinges__stop", {"angle": [1.0, -1.0], "stiffness": 1.0}, "hinges.stop.angle"),
    ("hinges__stop", {"angle": [[0, 1], [0, 1]], "stiffness": 1.0}, "hinges.stop.angle"),
    ("hinges__stop", {"angle": [0.5, 1.0], "stiffness": 1.0}, "hinges.stop.angle"),  # phi0 outside
    ("hinges__stop", {"angle": [-1.0, 1.0], "stiffness": 1.0, "gap": 1.0}, "hinges.stop.gap"),
])
def test_bad_feature_keys_are_named(path, value, key):
    with pytest.raises(SceneError) as info:
        scene(**{path: value})
    assert info.value.key == key
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("latch", [[None, 1.5, None], [None, None, -0.6]])
def test_a_latch_beyond_its_hinges_stops_is_refused(latch):
    # issue 19 item 8: accepted without a word before (the hinge can never reach it)
    with pytest.raises(SceneError) as info:
        scene(hinges__latch=latch,
              hinges__stop={"angle": [None, [-0.5, 1.0], [-0.5, 0.7]], "stiffness": 1e4})
    assert info.value.key == "hinges.latch" and "outside its stops" in str(info.value)
    assert "\n" not in str(info.value)
    # on a stop (the deployment scene's latches) and without stops it is a valid latch
    scene(hinges__latch=[None, 1.0, -0.5],
          hinges__stop={"angle": [None, [-0.5, 1.0], [-0.5, 0.7]], "stiffness": 1e4})
    scene(hinges__latch=[None, 2.0, -0.6], hinges__stop={"angle": [None, None, [-0.7, 0.7]],
                                                         "stiffness": 1e4})


def test_features_round_trip_through_yaml():
    sc = scene(hinges__rest_angle=[0.0, 0.2, -0.3], hinges__locked=[True, False, False],
               rods__rigid=[False, True, False], hinges__latch=[None, 0.4, -0.1],
               hinges__stop={"angle": [None, [-0.5, 1.0], [None, 0.7]], "stiffness": 1e4,
                             "damping": [1.0, 2.0, 3.0]})
    back = scene_from_yaml_text(scene_to_yaml(sc))
    for name in sc.__dataclass_fields__:
        a, b = getattr(sc, name), getattr(back, name)
        if isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b, err_msg=name)
    assert back.stop_lower[2] == -math.inf and back.stop_upper[0] == math.inf
    assert math.isnan(back.latch_angle[0]) and back.latch_angle[1] == 0.4


# ----- locked hinges and rigid rods: the constraint is the stiff limit -----

def _gap_to_locked(model, kappas, t_end, **scene_changes):
    locked, _ = run(scene(hinges__locked=[False, True, False], **scene_changes), model, t_end)
    theta = locked.phi[:, 1] - locked.phi[:, 0]
    if model != "full":
        assert np.ptp(theta) < 1e-12
    gaps = []
    for k in kappas:
        stiff, _ = run(scene(hinges__stiffness=[10.0, k, 10.0], **scene_changes), model, t_end)
        gaps.append(float(np.max(np.abs(stiff.phi - locked.phi))))
    return gaps


def test_locked_hinge_is_the_huge_kappa_limit_rigid():
    gaps = _gap_to_locked("rigid", [1e4, 1e5, 1e6], 0.5)
    assert gaps[0] < 2e-3
    assert gaps[1] < gaps[0] / 7 and gaps[2] < gaps[1] / 7    # ~ 1/kappa


@pytest.mark.slow
def test_locked_hinge_is_the_huge_kappa_limit_full():
    # full model: the lock holds Delta (rod ends); EI small so that kappa >> 4 EI / l
    gaps = _gap_to_locked("full", [1e5, 1e6, 1e7], 0.5, rods__bending_stiffness=1e3)
    assert gaps[0] < 2e-3
    assert gaps[1] < gaps[0] / 7 and gaps[2] < gaps[1] / 7


def test_locked_hinge_reduced_differs_from_huge_kappa_by_bending():
    # reduced: the lock holds the chords; kappa -> infinity still lets the rods bend, so the
    # gap at kappa = 1e6 falls with EI (docs/hinges.md)
    g4 = _gap_to_locked("reduced", [1e6], 0.5, rods__bending_stiffness=1e4)[0]
    g6 = _gap_to_locked("reduced", [1e6], 0.5, rods__bending_stiffness=1e6)[0]
    assert g6 < g4 / 20


def _rigid_rod_gaps(model, eis, t_end):
    rigid, _ = run(scene(rods__rigid=[False, True, False]), model, t_end)
    gaps = []
    for ei in eis:
        stiff, _ = run(scene(rods__bending_stiffness=[1e4, ei, 1e4]), model, t_end)
        gaps.append(float(np.max(np.abs(stiff.phi - rigid.phi))))
    return gaps


def test_rigid_rod_is_the_huge_ei_limit_reduced():
    gaps = _rigid_rod_gaps("reduced", [1e5, 1e6, 1e7], 0.5)
    assert gaps[1] < gaps[0] / 7 and gaps[2] < gaps[1] / 7
    sim = Simulator(make_model("reduced", scene(rods__rigid=[False, True, False])))
    sim.run(0.3, 10)
    alpha, beta = sim.model.bending(sim.t, sim.y)
    assert alpha[1] == 0.0 and beta[1] == 0.0 and abs(alpha[2]) > 0.0


@pytest.mark.slow
def test_rigid_rod_is_the_huge_ei_limit_full():
    # O(1/EI) once asymptotic; measured gap ratios per decade: 3.7 (1e5 -> 1e6), 10.1, 10.9
    gaps = _rigid_rod_gaps("full", [1e6, 1e7, 1e8], 0.3)
    assert gaps[1] < gaps[0] / 7 and gaps[2] < gaps[1] / 7


# ----- rest angles, stops, energy -----

@pytest.mark.parametrize("model", ["rigid", "reduced", "full"])
def test_rest_angle_is_an_equilibrium(model):
    rest = np.array([0.3, -0.5, 0.7])
    sc = scene(hinges__rest_angle=list(rest), initial__phi=list(np.cumsum(rest))).with_changes(
        loads=())
    m = make_model(model, sc)
    y = m.initial_state()
    assert np.max(np.abs(m.rhs(0.0, y))) < 1e-10
    # displaced: a damped chain returns to the rest angles
    sc2 = sc.with_changes(phi0=np.cumsum(rest) + [0.1, -0.1, 0.2], hinge_damping=2.0)
    if model == "full":
        return
    traj, _ = run(sc2, model, 120.0, rate=1.0, rtol=1e-8)
    dev = np.max(np.abs(np.diff(traj.phi, prepend=0.0, axis=1) - rest), axis=1)
    assert dev[0] > 0.1 and dev[-1] < 2e-3 and dev[-1] < dev[60] / 3   # decays to rest


def _stop_scene(damping):
    return scene(hinges__stiffness=[10.0, 1.0, 10.0], hinges__damping=0.05,
                 hinges__rest_angle=[0.0, 0.0, 0.0],
                 hinges__stop={"angle": [None, [-0.2, 0.2], None], "stiffness": 1e4,
                               "damping": damping},
                 initial__phi=[0.0, 0.0, 0.0], initial__phi_rate=[0.0, 4.0, 4.0]).with_changes(
        loads=())


@pytest.mark.parametrize("damping", [0.0, 5.0])
def test_stop_keeps_hinge_within_limits_and_energy_balances(damping):
    sc = _stop_scene(damping)
    traj, sim = run(sc, "rigid", 2.0, rate=2000.0, rtol=1e-11)
    theta = traj.phi[:, 1] - traj.phi[:, 0]
    # penetration bounded by the impact: k p^2 / 2 <= initial kinetic energy
    e0 = sim.model.energies(0.0, traj.y[0]).total
    p_max = math.sqrt(2 * e0 / 1e4)
    assert theta.max() > 0.2 and theta.max() < 0.2 + p_max
    assert theta.min() > -0.2 - p_max
    kinds = [e.kind for e in sim.events]
    assert kinds.count("stop_contact_begin") >= 2
    assert abs(kinds.count("stop_contact_begin") - kinds.count("stop_contact_end")) <= 1
    for e in sim.events:
        assert abs(abs(e.data["angle"]) - 0.2) < 1e-9
    # energy balance: E(t) - E(0) = -int dissipated (contact conservative except its damping)
    m = sim.model
    E = np.array([m.energies(t, y).total for t, y in zip(traj.t, traj.y)])
    P = np.array([m.powers(t, y)[1] for t, y in zip(traj.t, traj.y)])
    dissipated = np.concatenate([[0.0], np.cumsum(0.5 * (P[1:] + P[:-1]) * np.diff(traj.t))])
    residual = np.max(np.abs(E - E[0] + dissipated))
    assert residual < 2e-3 * max(dissipated[-1], 0.05 * E[0])
    if damping > 0:
        contact_free = _stop_scene(0.0)
        t0, s0 = run(contact_free, "rigid", 2.0, rate=10.0)
        assert E[-1] < s0.model.energies(2.0, t0.y[-1]).total   # contact damping dissipates


# ----- latches -----

def _latch_scene(latch):
    return scene(hinges__latch=[None, latch, None], hinges__damping=0.05)


def _bisect_crossing(sc, angle, step=1e-4):
    """Crossing time of theta_1 = angle with the plain model: fixed-step RK4 (step 1e-4 s)
    to bracket it, then bisection on the length of one RK4 step from the bracket's start."""
    model = make_model("reduced", sc)
    sim = Simulator(model, make_integrator("rk4", step=step))

    def theta(y):
        return y[1] - y[0]

    while True:
        y_prev, t_prev = sim.y.copy(), sim.t
        sim.advance(step)
        if (theta(sim.y) - angle) * (theta(y_prev) - angle) <= 0.0:
            break
    lo, hi = 0.0, step
    one = make_integrator("rk4", step=step)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        y = one.integrate(model, y_prev, t_prev, [t_prev + mid])[-1]
        if (theta(y) - angle) * (theta(y_prev) - angle) > 0.0:
            lo = mid
        else:
            hi = mid
    return t_prev + 0.5 * (lo + hi)


def test_latch_event_time_matches_bisection():
    traj, sim = run(_latch_scene(0.25), "reduced", 1.0, rate=100.0)
    latches = [e for e in sim.events if e.kind == "latch"]
    assert len(latches) == 1 and latches[0].hinge == 1
    t_ref = _bisect_crossing(scene(hinges__damping=0.05), 0.25)
    assert abs(latches[0].t - t_ref) < 1e-7
    theta = traj.phi[:, 1] - traj.phi[:, 0]
    after = traj.t > latches[0].t
    np.testing.assert_allclose(theta[after], 0.25, atol=1e-9)   # stays locked


@pytest.mark.parametrize("model", ["reduced", "rigid"])
def test_a_latch_fires_from_either_side(model):
    """The mirror image of a run (angles, rates and loads negated) is a run: a latch at -0.25
    reached from above fires at the same time as the latch at +0.25 reached from below, and
    each hinge stays at its latch angle."""
    data = copy.deepcopy(BASE)
    data["hinges"].update(latch=[None, 0.25, None], damping=0.05)
    up = Scene.from_dict(data)
    data["hinges"]["latch"] = [None, -0.25, None]
    data["initial"]["phi"] = [-0.3, -0.3, -0.9]
    data["loads"][0]["amplitude"] = -20.0
    down = Scene.from_dict(data)
    times = []
    for sc, angle in ((up, 0.25), (down, -0.25)):
        traj, sim = run(sc, model, 1.0, rate=100.0)
        latches = [e for e in sim.events if e.kind == "latch"]
        assert [e.hinge for e in latches] == [1], (angle, sim.events)
        theta = traj.phi[:, 1] - traj.phi[:, 0]
        assert np.all(np.sign(theta[traj.t < latches[0].t] - angle) != np.sign(angle))
        np.testing.assert_allclose(theta[traj.t > latches[0].t], angle, atol=1e-9)
        times.append(latches[0].t)
    assert abs(times[0] - times[1]) < 1e-9, times


@pytest.mark.parametrize("model", ["rigid", "full"])
def test_latch_kinetic_energy_loss_is_the_impulsive_projection(model):
    sc = scene(hinges__latch=[None, 0.25, None]) if model == "rigid" else \
        scene(hinges__latch=[None, 0.25, None], rods__bending_stiffness=1e3)
    m = make_model(model, sc)
    rng = np.random.default_rng(3)
    y = m.initial_state()
    y[m.state_size // 2:] = rng.normal(size=m.state_size // 2)
    mode = np.array([False, True, False])
    y1 = m.project_velocity(y, mode)
    d = m.state_size // 2
    v0, v1 = y[d:], y1[d:]
    M = dense_mass_matrix(m, y)
    C = constraint_matrix(sc, m.dof_per_rod, hinges.locked_hinges(sc, mode))
    lam = np.linalg.solve(C @ np.linalg.solve(M, C.T), C @ v0)
    expected_loss = 0.5 * float(lam @ (C @ v0))          # (C v)^T (C M^-1 C^T)^-1 (C v) / 2
    loss = 0.5 * float(v0 @ M @ v0 - v1 @ M @ v1)
    assert abs(loss - expected_loss) < 1e-10 * max(1.0, expected_loss)
    assert expected_loss > 1e-3
    np.testing.assert_allclose(C @ v1, 0.0, atol=1e-12)
    np.testing.assert_allclose(M @ (v1 - v0), -C.T @ lam, atol=1e-10)   # impulse along C^T
    assert abs(m.kinetic_energy(0.0, y) - m.kinetic_energy(0.0, y1) - loss) < 1e-10


def test_latch_in_a_run_loses_the_reported_energy():
    _, sim = run(_latch_scene(0.25), "rigid", 1.0, rate=100.0)
    (ev,) = [e for e in sim.events if e.kind == "latch"]
    assert ev.data["kinetic_energy_loss"] > 0.0
    # before the latch the chain is the plain one: its state at t_ev gives the same loss
    plain = Simulator(make_model("rigid", scene(hinges__damping=0.05)),
                      make_integrator("dop853-jit", rtol=1e-11, atol=1e-11))
    plain.run(ev.t, 1000.0)
    m = sim.model
    y1 = m.project_velocity(plain.y, np.array([False, True, False]))
    loss = m.kinetic_energy(0.0, plain.y) - m.kinetic_energy(0.0, y1)
    assert abs(loss - ev.data["kinetic_energy_loss"]) < 1e-6 * loss


# ----- the deployment scene -----

@pytest.mark.parametrize("model", ["rigid", "reduced"])
def test_deployment_unfolds_and_latches_every_hinge(model):
    sc = load_scene(DEPLOYMENT)
    traj, sim = run(sc, model, 20.0, rate=10.0, rtol=1e-8)
    latched = sorted(e.hinge for e in sim.events if e.kind == "latch")
    assert latched == [1, 2, 3, 4]
    assert max(e.t for e in sim.events) < 20.0
    np.testing.assert_allclose(traj.phi[-1], 0.0, atol=1e-6)     # straight: fully deployed


def test_deployment_events_in_the_log(tmp_path):
    out = tmp_path / "deployment.mcap"
    assert cli.main(["simulate", str(DEPLOYMENT), "--model", "reduced", "--t-end", "10",
                     "--out", str(out)]) == 0
    events = read_hinge_events(out)
    assert sorted(e["hinge"] for e in events if e["event"] == "latch") == [1, 2, 3, 4]
    assert all(0.0 < e["t"] < 10.0 and e["kinetic_energy_loss"] > 0 for e in events)
    from rosbags.highlevel import AnyReader       # independent reader: type and stamps
    from rosbags.typesys import Stores, get_typestore
    with AnyReader([out], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        conns = [c for c in reader.connections if c.topic == "/hinge_events"]
        assert conns and conns[0].msgtype == "std_msgs/msg/String"
        stamps = [t for _, t, _ in reader.messages(connections=conns)]
    assert stamps == [round(e["t"] * 1e9) for e in events]


@pytest.mark.parametrize("name, step, tol", [("rk4", 1e-3, 1e-7), ("euler", 1e-4, 2e-3)])
def test_fixed_step_integrator_locates_the_latch(name, step, tol):
    # fixed-step methods locate events on each step's cubic Hermite interpolant
    traj, sim = None, Simulator(make_model("reduced", _latch_scene(0.25)),
                                make_integrator(name, step=step))
    traj = sim.run(1.0, 100.0)
    (latch,) = [e for e in sim.events if e.kind == "latch"]
    assert latch.hinge == 1
    assert abs(latch.t - _bisect_crossing(scene(hinges__damping=0.05), 0.25)) < tol
    theta = traj.phi[:, 1] - traj.phi[:, 0]
    np.testing.assert_allclose(theta[traj.t > latch.t], theta[-1], atol=1e-12)   # stays locked


@pytest.mark.ros
@pytest.mark.timeout(120)
def test_node_records_hinge_events(tmp_path, monkeypatch):
    rclpy = pytest.importorskip("rclpy")
    from rclpy.parameter import Parameter
    from rod_sim.ros.node import RodSimNode
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    domain = next_domain()
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain)
    log = tmp_path / "node.mcap"
    try:
        node = RodSimNode(context=ctx, parameter_overrides=[
            Parameter("scene_file", value=str(DEPLOYMENT)), Parameter("model", value="reduced"),
            Parameter("record_path", value=str(log)), Parameter("rate_hz", value=50.0)])
        for _ in range(400):                       # 8 s of simulated time, no commands
            assert node._step_period(np.zeros((5, 2)))
        node._recording.writer.close()
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)
    events = read_hinge_events(log)
    assert sorted(e["hinge"] for e in events if e["event"] == "latch") == [1, 2, 3, 4]


def test_a_failed_advance_leaves_latches_and_events_as_they_were(monkeypatch):
    from rod_sim.core.integrators import IntegrationError, Stretch

    sim = Simulator(make_model("rigid", scene(hinges__latch=[None, 0.5, None])))
    sim.advance(0.01)
    before = (sim.t_ns, sim.y.copy(), sim.mode.copy(), list(sim.events))
    calls = []

    def latch_then_fail(self, carry, model, plan, y0, t0, t_out, held, breaks):
        calls.append(t0)
        if len(calls) == 1:        # a latch of hinge 1 at once, then a failure
            latch = int(np.flatnonzero(plan.events.hinge == 1)[0])
            return Stretch(np.empty((t_out.size, y0.size)), 0, y0, t0, latch,
                           (np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros((0, y0.size))))
        raise IntegrationError("step size underflow", t0)

    monkeypatch.setattr(type(sim.integrator), "advance", latch_then_fail)   # settings are frozen
    with pytest.raises(IntegrationError):
        sim.advance(0.01)
    assert len(calls) == 2
    assert sim.t_ns == before[0] and np.array_equal(sim.y, before[1])
    assert np.array_equal(sim.mode, before[2]) and not sim.mode.any()
    assert sim.events == before[3]


def test_energy_balance_accounts_for_latch_impacts_and_stops():
    """Issue 19, item 6: the shipped deployment scene (three latch impacts, stop contacts on
    the latched hinges) balances to quadrature/integration error once the kinetic energy lost
    in the impacts (hand-checked against the momentum balance above) is counted: without it
    the residual is ~0.7 of the energy scale."""
    from rod_sim.core.validity import EnergyBalance, assess_trajectory, balance_terms, latch_losses

    m = make_model("rigid", load_scene(DEPLOYMENT))
    sim = Simulator(m, make_integrator("dop853-jit", rtol=1e-10))
    traj = sim.run(3.0, 1000.0)
    latches = [e for e in sim.events if e.kind == "latch"]
    assert len(latches) >= 2
    lost = latch_losses(sim.events)
    assert lost > 1.0
    mon = assess_trajectory(m, traj.t, traj.y, modes=traj.modes, events=sim.events)
    assert not [f for f in mon.findings() if f.kind == "energy"], mon.summary()
    bal = EnergyBalance()
    prev = None
    for i, t in enumerate(traj.t):
        e, p = balance_terms(m, t, traj.y[i], None, traj.modes[i])
        if prev is None:
            bal.start(e)
        else:
            bal.add_period(t - prev[0], prev[1], p, e,
                           latch_losses(sim.events, prev[0], t))
        prev = (t, p)
    assert abs(bal.residual) < 1e-3 * bal.scale, (bal.residual, bal.scale)
    # the same run without the impact losses: the old, wrong balance
    assert abs(bal.residual - bal.impacts) > 0.5 * bal.scale
