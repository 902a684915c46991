"""The compiled Radau IIA integrator (radau-jit): the step solves the collocation system, the
run converges with the tolerance on a stiff linear problem (exact solution by expm) and on
the three models (against scipy's Radau and compiled DOP853), it beats explicit integration
on a stiff scene, and it fails loudly."""
from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from rod_sim.core import dense_lu, jit, kernels, radau
from rod_sim.core.integrators import IntegrationError, make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.scene import Scene
from rod_sim.core.simulator import Simulator
from rod_sim.io.scene_yaml import load_scene
from ros_domains import next_domain

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "config" / "paper_example.yaml"
STIFF = ROOT / "config" / "bench" / "paper_stiff.yaml"

# ----- a stiff linear second-order test problem: q'' = -K q - D q', y = [q, q'] -----
_ROT = np.array([[np.cos(0.5), -np.sin(0.5)], [np.sin(0.5), np.cos(0.5)]])
K_LIN = _ROT @ np.diag([1.0, 1e6]) @ _ROT.T          # modes at 1 and 1000 rad/s
D_LIN = _ROT @ np.diag([0.1, 1e3]) @ _ROT.T          # damping ratios 0.05 and 0.5
A_LIN = np.block([[np.zeros((2, 2)), np.eye(2)], [-K_LIN, -D_LIN]])
Y0_LIN = np.array([1.0, -0.5, 0.0, 2.0])


def event_buffers(hinge=(), angle=(), kind=(), size=4, cap=64):
    """erk's events for the linear problem (the 'hinge angle' of hinge 0 is y[0])."""
    return kernels.Events(np.array(hinge, dtype=np.int64), np.array(angle, dtype=float),
                          np.array(kind, dtype=np.int64),
                          np.full(len(hinge), -1, dtype=np.int64),
                          np.zeros(kernels.N_MOTION), np.empty(cap),
                          np.empty(cap, dtype=np.int64), np.empty((cap, size)),
                          np.zeros(1, dtype=np.int64))


NO_EVENTS = event_buffers()


@jit.njit
def linear_rhs(t, y, chain, extra, loads, held, t_side, out):
    """Kernel calling convention (rod_sim.core.kernels); chain = (K, D)."""
    K, D = chain
    m = K.shape[0]
    for i in range(m):
        out[i] = y[m + i]
        acc = 0.0
        for j in range(m):
            acc -= K[i, j] * y[j] + D[i, j] * y[m + j]
        out[m + i] = acc


def linear_args():
    return (linear_rhs, (K_LIN, D_LIN), (np.zeros(1),), (np.zeros(1),), np.zeros((2, 2)))


def collocation_stages(A, y0, h):
    """Stage values y0 + Z_i of the 3-stage Radau IIA collocation method for y' = A y,
    from its Butcher matrix (independent of the transformed constants radau.py uses)."""
    s6 = np.sqrt(6.0)
    a = np.array([[(88 - 7 * s6) / 360, (296 - 169 * s6) / 1800, (-2 + 3 * s6) / 225],
                  [(296 + 169 * s6) / 1800, (88 + 7 * s6) / 360, (-2 - 3 * s6) / 225],
                  [(16 - s6) / 36, (16 + s6) / 36, 1 / 9]])
    n = y0.size
    big = np.eye(3 * n) - h * np.kron(a, A)
    Z = np.linalg.solve(big, h * np.kron(a, A) @ np.tile(y0, 3)).reshape(3, n)
    return y0 + Z


@pytest.mark.parametrize("dtype", [np.float64, np.complex128])
def test_shared_lu_solves_with_row_swaps(dtype):
    """dense_lu.lu_inplace / lu_solve, the LU of radau's real and complex iteration matrices, against numpy on matrices whose pivoting swaps
    rows after the first column (the solve must apply every swap before the triangular
    solves, since the factorisation swaps whole rows); a zero pivot returns False."""
    rng = np.random.default_rng(4)
    late_swaps = False
    for n in (1, 3, 6, 10):
        A = rng.standard_normal((n, n)).astype(dtype)
        b = rng.standard_normal(n).astype(dtype)
        if dtype is np.complex128:
            A += 1j * rng.standard_normal((n, n))
            b += 1j * rng.standard_normal(n)
        LU = A.copy()
        piv = np.zeros(n, dtype=np.int64)
        assert dense_lu.lu_inplace(LU, piv)
        late_swaps |= bool(np.any(piv[1:] != np.arange(1, n)))
        x = b.copy()
        dense_lu.lu_solve(LU, piv, x)
        np.testing.assert_allclose(x, np.linalg.solve(A, b), rtol=1e-10, atol=1e-12)
    assert late_swaps
    assert not dense_lu.lu_inplace(np.zeros((3, 3), dtype=dtype), np.zeros(3, dtype=np.int64))


@pytest.mark.slow
def test_one_step_is_the_collocation_solution_and_its_polynomial():
    rhs, chain, extra, loads, held = linear_args()
    y0 = Y0_LIN.copy()
    f0 = A_LIN @ y0
    work = radau.radau_workspace(4)
    y_new, f_new = np.empty(4), np.empty(4)
    stats = np.zeros(6, dtype=np.int64)
    status, t_new, h_next = radau.radau_step(rhs, radau.dense_jac, radau.dense_factor,
                                             radau.dense_solve, chain, extra, loads, held, 0.5,
                                             0.0, y0, f0,
                                             0.01, 1.0, 1e-2, 1e-2, work, y_new, f_new, stats)
    assert status == 0 and 0.0 < t_new <= 0.01 and h_next > 0
    h = t_new
    assert h * 1000.0 > 1.0                   # a step longer than the stiff mode's time scale
    stages = collocation_stages(A_LIN, y0, h)
    # Newton with a finite-difference Jacobian: the collocation solution to ~1e-9 relative
    size = np.max(np.abs(stages))
    np.testing.assert_allclose(y_new, stages[2], rtol=0, atol=1e-8 * size)
    np.testing.assert_allclose(f_new, A_LIN @ y_new, rtol=1e-12, atol=1e-9 * size)
    dense = np.empty(4)
    for x, stage in zip(radau.C, stages):
        radau.radau_dense(y0, work[8], x, dense)
        np.testing.assert_allclose(dense, stage, rtol=0, atol=1e-8 * size)
    radau.radau_dense(y0, work[8], 0.0, dense)
    np.testing.assert_array_equal(dense, y0)
    # the stiff transient is damped by the step as by the exact flow
    assert np.max(np.abs(y_new - expm(A_LIN * h) @ y0)) < 1e-2 * size


@pytest.mark.slow
def test_run_stops_at_an_event_located_on_the_collocation_polynomial():
    from scipy.optimize import brentq

    from rod_sim.core import erk, hinges

    rhs, chain, extra, loads, held = linear_args()
    q0 = lambda t: (expm(A_LIN * t) @ Y0_LIN)[0] - 0.2      # noqa: E731
    grid = np.linspace(0.0, 3.0, 3001)
    first = np.flatnonzero(np.diff(np.sign([q0(t) for t in grid])))[0]
    exact = brentq(q0, grid[first], grid[first + 1], xtol=1e-14)
    t_out = np.linspace(0.0, 3.0, 31)
    Y = np.full((t_out.size, 4), np.nan)
    ev = event_buffers([0], [0.2], [hinges.EV_LATCH])
    y, t, h, status, written = radau.radau_run(
        rhs, kernels.Problem(chain, extra, loads, held),
        kernels.Span(Y0_LIN, 0.0, t_out, np.zeros(0)),
        kernels.Control(1e-10, 1e-10, 0.0, np.inf, 100_000, 1 << 62),
        kernels.Output(Y, np.zeros(6, dtype=np.int64), ev))
    assert status == erk.STATUS_EVENT and ev.count[0] == 1 and ev.code[0] == 0     # falling
    assert abs(t - exact) < 1e-8, (t, exact)
    assert ev.t[0] == t and abs(y[0] - 0.2) < 1e-10
    np.testing.assert_allclose(y, expm(A_LIN * t) @ Y0_LIN, atol=1e-7)
    assert written == np.count_nonzero(t_out <= t) and np.isnan(Y[written:]).all()


def test_run_stops_when_the_event_buffer_is_full():
    from rod_sim.core import erk, hinges

    rhs, chain, extra, loads, held = linear_args()
    t_out = np.linspace(0.0, 3.0, 31)
    Y = np.empty((t_out.size, 4))
    ev = event_buffers([0], [0.2], [hinges.EV_LATCH], cap=0)
    y, t, h, status, written = radau.radau_run(
        rhs, kernels.Problem(chain, extra, loads, held),
        kernels.Span(Y0_LIN, 0.0, t_out, np.zeros(0)),
        kernels.Control(1e-8, 1e-8, 0.0, np.inf, 100_000, 1 << 62),
        kernels.Output(Y, np.zeros(6, dtype=np.int64), ev))
    assert status == erk.STATUS_EVENTS_FULL and t == 0.0 and written == 1
    np.testing.assert_array_equal(y, Y0_LIN)


def test_run_error_falls_with_the_tolerance_on_the_stiff_linear_problem():
    rhs, chain, extra, loads, held = linear_args()
    t_out = np.linspace(0.0, 3.0, 31)
    exact = np.array([expm(A_LIN * t) @ Y0_LIN for t in t_out])
    errors, nfev = [], []
    for rtol in (1e-4, 1e-6, 1e-8):
        Y = np.empty((t_out.size, 4))
        stats = np.zeros(6, dtype=np.int64)
        y, t, h, status, written = radau.radau_run(
        rhs, kernels.Problem(chain, extra, loads, held),
        kernels.Span(Y0_LIN, 0.0, t_out, np.array([1.5])),
        kernels.Control(rtol, rtol, 0.0, np.inf, 100_000, 1 << 62),
        kernels.Output(Y, stats, NO_EVENTS))
        assert status == 0 and t == 3.0 and written == t_out.size
        np.testing.assert_array_equal(y, Y[-1])
        errors.append(np.max(np.abs(Y - exact)))
        nfev.append(stats[0])
        assert stats[3] >= 1 and stats[4] >= 1 and stats[5] >= stats[1]
    assert errors[0] < 1e-3 and errors[-1] < 1e-7, errors
    for loose, tight in zip(errors[:-1], errors[1:]):
        assert tight < loose / 10.0, errors          # 100x tighter tolerance, >10x smaller error
    # the stiff mode (1000 rad/s) costs no stability-bound step: an explicit method would need
    # >1000 steps for 3 s; Radau's work follows the smooth 1 rad/s mode
    assert nfev[0] < 2000, nfev


def chain(EI=1e4):
    """The heterogeneous n = 4 chain of test_physics, with two overlapping pulses."""
    return Scene.from_dict({
        "rods": {"count": 4, "length": [1.0, 1.5, 1.2, 0.8],
                 "mass_per_length": [2.0, 1.0, 3.0, 1.5], "bending_stiffness": EI},
        "nodes": {"mass": [1.0, 0.5, 0.0, 2.0]},
        "hinges": {"stiffness": [50.0, 20.0, 30.0, 10.0], "damping": 2.0},
        "initial": {"phi": [0.3, -0.2, 0.5, 1.0], "phi_rate": 0.0},
        "loads": [{"node": 4, "axis": "y", "shape": "raised_cosine_pulse", "amplitude": 80.0,
                   "duration": 0.6},
                  {"node": 2, "axis": "x", "shape": "raised_cosine_pulse", "amplitude": -40.0,
                   "start": 0.2, "duration": 0.5}]})


@pytest.mark.parametrize("model_name", ["rigid", "reduced", pytest.param("full", marks=pytest.mark.slow)])
def test_models_converge_to_scipy_radau(model_name):
    model = make_model(model_name, chain())
    t_end = 0.8
    ref_sim = Simulator(model, make_integrator("Radau", rtol=1e-11, atol=1e-11))
    ref = ref_sim.run(t_end, 20.0).y
    errors = []
    for rtol in (1e-5, 1e-7, 1e-9):
        sim = Simulator(model, make_integrator("radau-jit", rtol=rtol))
        Y = sim.run(t_end, 20.0).y
        errors.append(np.max(np.abs(Y - ref)))
        assert sim.stats.steps > 0 and sim.stats.njev >= 1
    assert errors[0] < 1e-3 and errors[-1] < 1e-7, errors
    for loose, tight in zip(errors[:-1], errors[1:]):
        assert tight < loose / 5.0, errors


@pytest.mark.parametrize("model_name", ["rigid", "reduced", "full"])
def test_hinges_locked_between_rods_keep_the_accuracy(model_name):
    """A lock between rods holds C q = const (full model: phi_h + alpha_h - phi_p - beta_p):
    the exact Jacobian's rows give C a = 0, so Newton's increments are C x = C c' / g^2, not
    the C x = 0 the O(n) Newton system imposed; an error the stages carried along C was then
    never corrected, and no Newton or error test saw it. The full paper example with hinges 2
    and 6 locked, 5 s: 1.2e-4 rad at rtol 1e-8, 3.7e-2 rad at rtol 1e-10 (atol 1e-12), the
    spin-up beam 0.18 rad at rtol 1e-12 over 20 s; the dense Jacobian gave 1e-9 .. 1e-12."""
    base = load_scene(PAPER)
    locked = np.zeros(base.n, dtype=bool)
    locked[[2, 6]] = True
    model = make_model(model_name, dataclasses.replace(base, hinge_locked=locked))
    t_end = 2.0
    t = np.linspace(0.0, t_end, 21)
    ref = solve_ivp(lambda tt, y: model.rhs(tt, y), (0.0, t_end), model.initial_state(),
                    method="Radau", rtol=1e-12, atol=1e-14, t_eval=t)
    assert ref.status == 0
    for rtol, atol, bound in ((1e-8, 1e-8, 1e-6), (1e-10, 1e-12, 1e-8)):
        sim = Simulator(model, make_integrator("radau-jit", rtol=rtol, atol=atol))
        phi = sim.run(t_end, 10.0).phi
        assert np.max(np.abs(phi - ref.y[:base.n].T)) < bound, (rtol, atol)


def test_a_root_locked_to_a_free_base_keeps_the_accuracy():
    """The same for hinge 0 locked to a free base (C = phi_1 + alpha_1 - psi, psi a state):
    the two-wing deployment's full model, 3 s, lost 7.8e-6 rad at rtol 1e-8 and 1.6e-4 at
    rtol 1e-10 against compiled DOP853 at rtol 1e-12 (its stops keep scipy's methods out)."""
    model = make_model("full", load_scene(ROOT / "config" / "two_wing_deployment.yaml"))
    t_end = 3.0
    ref = Simulator(model, make_integrator("dop853-jit", rtol=1e-12, atol=1e-14)).run(t_end, 10.0)
    for rtol, bound in ((1e-8, 1e-6), (1e-10, 1e-8)):
        traj = Simulator(model, make_integrator("radau-jit", rtol=rtol)).run(t_end, 10.0)
        assert np.max(np.abs(traj.phi - ref.phi)) < bound, rtol


def test_stiff_scene_takes_far_fewer_rhs_than_explicit():
    """EI x 100 (bending modes up to 2.7e4 rad/s): DOP853 is stability-bound, Radau is not."""
    model = make_model("full", load_scene(STIFF))
    runs = {}
    for name in ("dop853-jit", "radau-jit"):
        sim = Simulator(model, make_integrator(name, rtol=1e-6))
        runs[name] = (sim.run(0.2, 100.0).y, sim.stats)
    (y_dop, s_dop), (y_rad, s_rad) = runs["dop853-jit"], runs["radau-jit"]
    assert np.max(np.abs(y_dop[:, :8] - y_rad[:, :8])) < 1e-5
    assert s_dop.nfev > 5 * s_rad.nfev, (s_dop, s_rad)
    assert s_dop.steps > 10 * s_rad.steps, (s_dop, s_rad)


@pytest.mark.parametrize("model_name", ["full", "reduced"])
def test_table1_times_agree_with_dop853(model_name):
    """The seed's example at Table 1's times: radau-jit at rtol 1e-9 against dop853-jit at 1e-11
    (what `rod-sim table1` uses): every state component within 1e-6."""
    model = make_model(model_name, load_scene(PAPER))
    ref = Simulator(model, make_integrator("dop853-jit", rtol=1e-11)).run(2.0, 2.0)
    got = Simulator(model, make_integrator("radau-jit", rtol=1e-9)).run(2.0, 2.0)
    np.testing.assert_array_equal(got.t, [0.0, 0.5, 1.0, 1.5, 2.0])
    assert np.max(np.abs(got.y - ref.y)) < 1e-6
    assert np.max(np.abs(ref.y[:, :8])) > 1.0                 # the chain did move


def test_non_finite_start_and_too_many_steps_raise_naming_the_cause():
    model = make_model("full", load_scene(PAPER))
    sim = Simulator(model, make_integrator("radau-jit"))
    sim.y = sim.y.copy()
    sim.y[1] = np.nan
    with pytest.raises(IntegrationError, match="phi of rod 2 is nan") as info:
        sim.run(0.1, 100.0)
    assert "step size" in str(info.value) and "\n" not in str(info.value)

    integ = dataclasses.replace(make_integrator("radau-jit"), max_steps=3)
    with pytest.raises(IntegrationError, match="too many steps"):
        Simulator(model, integ).run(0.5, 100.0)


def test_step_size_is_carried_between_calls_and_reset():
    sim = Simulator(make_model("reduced", load_scene(PAPER)), make_integrator("radau-jit"))
    sim.advance(0.05)
    assert sim.carry.h > 0
    nfev = sim.stats.nfev
    sim.advance(0.05)
    carried = sim.stats.nfev - nfev
    sim.carry.h = 0.0                                    # the same period from a cold start
    nfev = sim.stats.nfev
    sim.advance(0.05)
    assert carried < sim.stats.nfev - nfev               # no new start-up
    sim.reset()
    assert sim.carry.h == 0.0 and sim.stats.nfev > 0     # counters live as long as the sim


def test_period_by_period_keeps_the_jacobian_and_the_accuracy():
    """Stepping 1 ms periods (the node's way) reuses the Jacobian across calls instead of
    building one per call, and stays on the one-call solution."""
    model = make_model("full", load_scene(STIFF))
    sim = Simulator(model, make_integrator("radau-jit", rtol=1e-8))
    for _ in range(100):
        sim.advance(0.001)
    assert sim.stats.njev < 20, sim.stats               # not one per call (100)
    ref = Simulator(model, make_integrator("dop853-jit", rtol=1e-11)).run(0.1, 10.0).y[-1]
    assert np.max(np.abs(sim.y[:8] - ref[:8])) < 1e-7
    work = sim.carry.work
    other = Simulator(make_model("full", load_scene(STIFF)), sim.integrator)
    other.advance(0.001)                  # the same settings, another simulator's own state
    assert other.carry.work is not None and other.carry.work is not work
    assert sim.carry.work is work and np.all(np.isfinite(other.y))
    sim.reset()
    assert sim.carry.work is None


@pytest.mark.skipif(not jit.HAVE_NUMBA, reason="numba not installed")
def test_radau_is_cached_under_the_core_stamp():
    if not jit.CORE_LOCATORS:
        pytest.skip("this numba has no cache locator API")
    assert (jit.CORE_DIR / "radau.py").exists()
    for dispatcher in (radau.radau_rigid, radau.radau_reduced, radau.radau_full):
        locator = dispatcher._cache._impl.locator
        assert isinstance(locator, jit.CORE_LOCATORS), type(locator)
        assert locator.get_source_stamp() == jit.sources_stamp()


def test_simulate_cli_runs_radau_jit(tmp_path):
    from rod_sim.io.log_reader import LogReader
    from rod_sim.io.series import read_rod_states

    out = tmp_path / "radau.mcap"
    proc = subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", "simulate", str(PAPER),
                           "--model", "full", "--integrator", "radau-jit", "--rtol", "1e-9",
                           "--t-end", "0.2", "--out", str(out)], capture_output=True, text=True,
                          cwd=ROOT, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert LogReader(out).metadata()["integrator"].startswith("radau-jit rtol=1e-09")
    t, phi, _ = read_rod_states(out)
    ref = Simulator(make_model("full", load_scene(PAPER)),
                    make_integrator("dop853-jit", rtol=1e-11)).run(0.2, 100.0)
    np.testing.assert_allclose(t, ref.t, atol=1e-9)
    assert np.max(np.abs(phi - ref.phi)) < 1e-7


@pytest.mark.ros
@pytest.mark.timeout(120)
def test_node_runs_radau_jit(monkeypatch):
    """The node's ``integrator`` parameter selects radau-jit; its states are those of an
    offline reference run (radau-jit at rtol 1e-12) to the integrator's tolerance. (Not bit
    for bit the offline run advanced period by period: outside lockstep the node integrates
    across periods while its inputs are held, rod_sim.core.ahead; seen 1.3e-8 apart.)"""
    rclpy = pytest.importorskip("rclpy")
    from rclpy.parameter import Parameter

    from rod_sim.ros.node import RodSimNode

    domain = next_domain()
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain)
    params = {"scene_file": str(PAPER), "model": "full", "integrator": "radau-jit",
              "real_time_factor": 0.0, "rate_hz": 100.0}
    node = RodSimNode(context=context,
                      parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
    try:
        assert node.settings.integrator == "radau-jit"
        assert node.sim.integrator.name == "radau-jit"
        from rclpy.executors import SingleThreadedExecutor

        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        deadline = os.times().elapsed + 60.0
        while node.sim.t_ns < 50_000_000 and os.times().elapsed < deadline:
            executor.spin_once(timeout_sec=0.01)
        t_ns, y = node.sim.t_ns, node.sim.y.copy()
        assert t_ns >= 50_000_000
        assert node.settings.rtol <= 1e-8
        offline = Simulator(make_model("full", load_scene(PAPER)),
                            make_integrator("radau-jit", rtol=1e-12))
        offline.advance(t_ns / 1e9)
        assert offline.t_ns == t_ns
        np.testing.assert_allclose(y, offline.y, rtol=0.0, atol=1e-6)
        executor.shutdown()
    finally:
        node.destroy_node()
        context.try_shutdown()


def test_bench_times_radau_jit_for_every_model_and_filters_by_integrator():
    from rod_sim import bench

    for model_name in bench.MODELS:
        for quick in (True, False):
            assert any(i == "radau-jit" for i, _ in bench.settings_grid(model_name, quick))
    cfg = bench.BenchConfig(quick=True, repeats=1, cap_s=10.0, models=("rigid",),
                            integrators=("radau-jit",), mujoco=False)
    rows, refs = bench.bench_scene("paper_example", cfg)
    assert list(refs) == ["rigid"] and refs["rigid"]["ok"]
    assert [r.setting for r in rows] == [f"rtol={r:g}" for r in bench.RADAU_RTOLS_QUICK]
    assert all(r.integrator == "radau-jit" and r.status == "ok" and r.njev >= 1 for r in rows)
    errors = [r.max_phi_error for r in rows]
    assert errors == sorted(errors, reverse=True) and errors[-1] < 1e-6, errors


@pytest.mark.slow
def test_cost_split_accounts_for_every_rhs_and_the_run_time():
    from rod_sim.tools import radau_cost

    r = radau_cost.measure(load_scene(PAPER), "reduced", rtol=1e-6, t_end=0.5)
    split = list(r["split"].values())
    assert split[0]["count"] == r["nfev"]                 # no rhs spent on Jacobians
    assert split[1]["count"] == r["njev"] >= 1 and split[3]["count"] == r["newton_iterations"]
    assert all(v["unit_us"] > 0 for v in split)
    # the parts, timed separately, explain the run's CPU time to within a factor 3
    total = sum(v["total_ms"] for v in split)
    assert r["cpu_ms"] / 3 < total < 3 * r["cpu_ms"], (total, r["cpu_ms"])
    assert "Newton iterations" in radau_cost.format_report(r)


def _events_and_angles(sc, model, integrator, t_end, rate, rtol):
    sim = Simulator(make_model(model, sc), make_integrator(integrator, rtol=rtol, atol=rtol))
    traj = sim.run(t_end, rate)
    theta = np.diff(traj.phi, axis=1, prepend=0.0)
    return [(e.t, e.kind, e.hinge) for e in sim.events], theta, sim.stats


def _assert_same_events(a, b, dt):
    assert [(k, h) for _, k, h in a] == [(k, h) for _, k, h in b]
    for (ta, _, _), (tb, _, _) in zip(a, b):
        assert abs(ta - tb) < dt, (ta, tb)


def test_radau_locates_the_deployment_latches_like_dop853():
    sc = load_scene(ROOT / "config" / "deployment.yaml")
    ev_d, th_d, _ = _events_and_angles(sc, "reduced", "dop853-jit", 7.0, 10.0, 1e-10)
    ev_r, th_r, stats = _events_and_angles(sc, "reduced", "radau-jit", 7.0, 10.0, 1e-10)
    assert sorted(h for _, k, h in ev_r if k == "latch") == [1, 2, 3, 4]
    _assert_same_events(ev_d, ev_r, 1e-8)          # measured: 1.6e-10 s
    np.testing.assert_allclose(th_r, th_d, rtol=0, atol=1e-8)      # measured: 4e-10 rad
    assert stats.njev >= 4          # the Jacobian is rebuilt after every latch


def test_radau_follows_stop_contacts_like_dop853():
    import sys
    sys.path.insert(0, str(ROOT / "test"))
    from test_hinge_features import _stop_scene

    sc = _stop_scene(5.0)
    ev_d, th_d, st_d = _events_and_angles(sc, "rigid", "dop853-jit", 2.0, 1000.0, 1e-8)
    ev_r, th_r, st_r = _events_and_angles(sc, "rigid", "radau-jit", 2.0, 1000.0, 1e-8)
    assert len(ev_r) >= 20 and {k for _, k, _ in ev_r} == {"stop_contact_begin",
                                                          "stop_contact_end"}
    _assert_same_events(ev_d, ev_r, 1e-6)          # measured: 1.4e-7 s
    np.testing.assert_allclose(th_r, th_d, rtol=0, atol=1e-6)      # measured: 1.5e-8 rad
    assert th_r[:, 1].max() < 0.2 + 0.05                           # the stop holds
