"""The cheap per-sample path (issue 26 item 5) gives the values of the plain calls, bit for bit:
one right-hand side per sample for the slopes and the energy balance's power rate
(``ChainModel.rhs_bending``), the snapshot and the balance sample fed with them, the hinge
angles without ``np.diff``, no stop contact without finite stops; the validity monitor's
force-jump check on a free-base scene; start-up without importing ``scipy.integrate``."""
from __future__ import annotations

import dataclasses
import subprocess
import sys

import numpy as np
import pytest

from procs import REPO
from rod_sim.core import hinges
from rod_sim.core.integrators import make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.simulator import Simulator
from rod_sim.core.validity import ValidityMonitor, balance_sample, force_jump_slopes
from rod_sim.io.scene_yaml import load_scene

SCENES = ("paper_example.yaml", "deployment.yaml", "two_wing_deployment.yaml")
MODELS = ("reduced", "rigid", "full")


def _held(n: int, k: int) -> np.ndarray:
    j = np.arange(n)
    return np.stack([0.3 * np.sin(k + j), 0.2 * np.cos(k - j), 0.01 * np.sin(2 * k + j)], 1)


def _states(scene_name: str, model_name: str, count: int = 3):
    """(model, sim) after each of ``count`` periods of 10 ms with changing held inputs."""
    scene = load_scene(REPO / "config" / scene_name)
    model = make_model(model_name, scene)
    sim = Simulator(model, make_integrator("dop853-jit"))
    for k in range(count):
        held = _held(scene.n, k)
        sim.set_forces(held[:, :2])
        sim.set_hinge_torques(held[:, 2])
        sim.advance(0.01)
        yield model, sim


def _same(a, b) -> bool:
    """Bitwise equality of arrays, floats and (nested) tuples/dataclasses of them."""
    if dataclasses.is_dataclass(a):
        return _same(dataclasses.astuple(a), dataclasses.astuple(b))
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (tuple, list)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if a is None or b is None:
        return a is b
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("scene_name", SCENES)
@pytest.mark.parametrize("model_name", MODELS)
def test_one_rhs_per_sample_gives_the_plain_values(scene_name, model_name):
    for model, sim in _states(scene_name, model_name):
        t, y, held, mode = sim.t, sim.y, sim.held, sim.mode
        f, bending = model.rhs_bending(t, y, held, mode)
        assert _same(f, model.rhs(t, y, held, mode))
        assert _same(bending, model.bending(t, y, held, mode))
        assert _same(model.snapshot(t, y, held, mode, bending), model.snapshot(t, y, held, mode))
        plain = balance_sample(model, t, y, held, mode)
        assert _same(balance_sample(model, t, y, held, mode, bending, f), plain)
        assert _same(balance_sample(model, t, y, held, mode, bending), plain)


def test_hinge_angles_are_np_diff_with_a_leading_zero():
    rng = np.random.default_rng(3)
    for phi in (rng.normal(size=7), rng.normal(size=(4, 5)), np.array([-0.0, 1.0, np.nan]),
                np.zeros(0), np.array([2.5]), np.arange(4)):
        want = np.diff(phi, prepend=0.0, axis=-1)
        got = hinges.hinge_angles(phi)
        assert got.dtype == want.dtype and got.tobytes() == want.tobytes()


def test_no_finite_stop_no_contact_and_with_stops_the_law():
    scene = load_scene(REPO / "config" / "paper_example.yaml")
    model = make_model("reduced", scene)
    assert not model.has_stops
    y = model.initial_state()
    y[:scene.n] = np.linspace(-3.0, 3.0, scene.n)
    assert np.array_equal(model.contact_state(y), np.zeros(scene.n, dtype=np.int8))
    stopped = make_model("reduced", load_scene(REPO / "config" / "deployment.yaml"))
    assert stopped.has_stops
    y = stopped.initial_state()
    theta = stopped.hinge_angles(y)
    s = stopped.scene
    want = np.where(theta > s.stop_upper, 1, np.where(theta < s.stop_lower, -1, 0))
    assert np.array_equal(stopped.contact_state(y), want)


def test_rhs_refuses_a_state_of_the_wrong_size():
    model = make_model("reduced", load_scene(REPO / "config" / "two_wing_deployment.yaml"))
    y = model.initial_state()
    with pytest.raises(ValueError, match="components"):
        model.rhs(0.0, y[:2 * model.n])


def test_force_jump_on_a_free_base_scene_uses_the_whole_state():
    """The monitor judged a jump of the held inputs with [phi, phi_rate] as the state, which a
    free base's pose and twist are missing from (IndexError). The jump is the difference of
    two quasi-static slope solves of a loads-free reduced model at the whole state."""
    scene = load_scene(REPO / "config" / "two_wing_deployment.yaml")
    model = make_model("reduced", scene)
    assert model.nb
    monitor = ValidityMonitor(model)
    y = model.initial_state()
    before, after = _held(scene.n, 0), _held(scene.n, 1) * 50.0
    monitor.update(0.0, y, before)
    monitor.update(0.01, y, after)            # raised IndexError before the fix
    free = make_model("reduced", scene.with_changes(loads=()))
    a0, b0 = free.bending(0.0, y, before)
    a1, b1 = free.bending(0.0, y, after)
    want = np.abs(np.concatenate([a1 - a0, b1 - b0]))
    got = force_jump_slopes(scene, model.phi(y), model.phi_rate(y), before, after, y)
    np.testing.assert_array_equal(got, want)
    assert want.max() > 0.0


def test_start_up_does_not_import_scipy_integrate():
    code = (
        "import sys\n"
        "import numpy as np\n"
        "import rod_sim.core.models, rod_sim.core.integrators\n"
        "from rod_sim.core import erk\n"
        "assert 'scipy.integrate' not in sys.modules, 'scipy.integrate imported'\n"
        "from scipy.integrate import solve_ivp\n"
        "from scipy.integrate._ivp import dop853_coefficients as d\n"
        "assert np.array_equal(erk.A_DOP, d.A) and np.array_equal(erk.E5_DOP, d.E5)\n"
        "r = solve_ivp(lambda t, y: -y, (0, 1), [1.0], method='DOP853', rtol=1e-10, atol=1e-12)\n"
        "assert abs(r.y[0, -1] - np.exp(-1.0)) < 1e-8\n"
        "print('ok')\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr


def test_force_jump_around_states_without_held_inputs():
    """The monitor keeps the zeros of a state without held inputs and does not compare two
    such states again (no jump between them); a jump from or to them is still judged, at the
    state where it happens."""
    scene = load_scene(REPO / "config" / "paper_example.yaml")
    model = make_model("reduced", scene)
    y = model.initial_state()
    big = _held(scene.n, 1) * 1e4

    def jumps(*helds):
        monitor = ValidityMonitor(model)
        for k, held in enumerate(helds):
            monitor.update(0.01 * k, y, held)
        return [f.t for f in monitor.findings() if f.kind == "force_jump"]

    assert jumps(None, None, None) == []
    assert jumps(None, None, big) == [0.02]
    assert jumps(big, None, None) == [0.01]
    assert jumps(big, big, None) == [0.02]
    assert jumps(None, np.zeros((scene.n, 3)), None) == []


@pytest.mark.parametrize("scene_name", SCENES + ("spin_up_beam.yaml",))
@pytest.mark.parametrize("model_name", MODELS)
def test_a_state_with_other_held_inputs_gives_a_fresh_states_values(scene_name, model_name):
    """State.with_held (the node's period start: the last end with the new commands) shares
    only what the held inputs do not change: every value bit for bit that of a fresh State."""
    for model, sim in _states(scene_name, model_name, count=2):
        t, y, mode, n = sim.t, sim.y, sim.mode, model.n
        old, new = _held(n, 7), _held(n, 8) * 3.0
        before = model.state(t, y, old, mode, data=sim.data)
        before.snapshot()
        balance_sample(model, t, y, old, mode, state=before)
        _ = before.momentum, before.base_energies, before.energies     # every cache filled
        shared = before.with_held(new)
        fresh = model.state(t, y, new, mode)
        assert _same(shared.snapshot(), fresh.snapshot())
        assert _same(balance_sample(model, t, y, new, mode, state=shared),
                     balance_sample(model, t, y, new, mode, state=fresh))
        for name in ("energies", "powers", "momentum", "base_energies", "loads", "f"):
            assert _same(getattr(shared, name), getattr(fresh, name)), name
        assert not _same(fresh.powers, before.powers)       # the inputs do matter


@pytest.mark.parametrize("model_name", MODELS)
def test_a_span_start_sample_skips_only_the_energy(model_name):
    """balance_sample(energy=False) (the node's period start: EnergyBalance.add reads the
    energy at a span's end only) gives every other field of the full sample, bit for bit."""
    for model, sim in _states("deployment.yaml", model_name, count=2):
        t, y, held, mode = sim.t, sim.y, sim.held, sim.mode
        full = balance_sample(model, t, y, held, mode)
        start = balance_sample(model, t, y, held, mode, energy=False)
        assert np.isnan(start.energy) and np.isfinite(full.energy)
        assert _same(dataclasses.replace(start, energy=full.energy), full)


def _power_by_hand(scene, loads: np.ndarray, y: np.ndarray) -> float:
    """The net power [W] of one chain on a fixed base at the origin without slope rates,
    from its definition: nodal forces on the end nodes' velocities (sums of l_j phi_j' (-sin
    phi_j, cos phi_j) up to rod k), hinge motors on the hinge rates phi_h' - phi_{h-1}'
    (phi_{-1}' = 0), minus the dampers nu_h Delta phi_h'^2. ``loads`` (n + 2, 3)."""
    n = scene.n
    phi, dphi = y[:n], y[n:2 * n]
    l = scene.length
    vx = np.cumsum(-l * np.sin(phi) * dphi)
    vy = np.cumsum(l * np.cos(phi) * dphi)
    rate = dphi - np.concatenate([[0.0], dphi[:-1]])
    return float(np.sum(loads[:n, 0] * vx + loads[:n, 1] * vy) + np.sum(loads[:n, 2] * rate)
                 - np.sum(scene.hinge_damping * rate**2))


def _pair_matches_the_moved_states(model, t: float, y, held):
    """The one-call pair (State.moved_net_powers) at (t, y, held), checked against two moved
    States' net powers to rounding (numba's sines and cosines are not numpy's, bit for bit);
    returns it and the two moved states y +- h f."""
    from rod_sim.core.validity import RATE_STEP, _net_power

    s = model.state(t, y, held)
    hf = RATE_STEP * s.f
    pair = s.moved_net_powers(t + RATE_STEP, t - RATE_STEP, hf)
    moved = (s.moved(t + RATE_STEP, y + hf).value(_net_power),
             s.moved(t - RATE_STEP, y - hf).value(_net_power))
    assert pair == pytest.approx(moved, rel=1e-13, abs=1e-13)
    return pair, (y + hf, y - hf)


@pytest.mark.parametrize("model_name", ("reduced", "rigid"))
@pytest.mark.parametrize("scripted", (True, False))
def test_the_balance_rate_pair_is_the_moved_states_values(model_name, scripted):
    """A balance sample's central difference evaluates its two moved states in one call
    (State.moved_net_powers) for one chain on a fixed base without stops: the values of two
    moved States and the net power's definition at y +- h f, to rounding (numba's sines and
    cosines are not numpy's, bit for bit)."""
    from rod_sim.core.validity import RATE_STEP

    scene = load_scene(REPO / "config" / "paper_example.yaml")
    if not scripted:
        scene = scene.with_changes(loads=())
    model = make_model(model_name, scene)
    assert model.paired_balance and bool(model.scripted_loads) == scripted
    rng = np.random.default_rng(7)
    for k in range(4):
        y = model.initial_state() + rng.normal(scale=0.3, size=model.state_size)
        held = _held(scene.n, k)
        t = 0.0005 * k          # the paper's tip pulse acts from t = 0
        pair, moved_y = _pair_matches_the_moved_states(model, t, y, held)
        for got, tm, ym in zip(pair, (t + RATE_STEP, t - RATE_STEP), moved_y):
            want = _power_by_hand(scene, model.loads_at(tm, held), ym)
            assert got == pytest.approx(want, rel=1e-12, abs=1e-12)
        if scripted:
            assert model.loads_at(t + RATE_STEP, held)[scene.n - 1, 0] != held[scene.n - 1, 0]


@pytest.mark.parametrize("base", ("free", "fixed"))
@pytest.mark.parametrize("model_name", ("reduced", "rigid"))
def test_the_balance_rate_pair_on_chains_of_a_base(base, model_name):
    """Two chains on a free base with a reaction wheel, and on a fixed base: the one-call
    pair is the moved States' net powers to rounding and the net power's definition from the
    independent Lagrangian (test/lagrangian_base.py: the generalized forces of the held
    loads, base and wheel rows included, minus the hinge dampers', on q')."""
    from sc_common import Layout, chain_dict, free_base, oracle_from_dict, scene_dict

    from rod_sim.core.scene import Scene

    rng = np.random.default_rng(23)
    d = scene_dict([chain_dict("a", 3, rng), chain_dict("b", 2, rng)],
                   free_base() if base == "free" else None, None)
    model = make_model(model_name, Scene.from_dict(d))
    assert model.paired_balance
    lag = oracle_from_dict(d)
    lay = Layout(model_name, lag.N, base == "free", base == "free")
    for k in range(4):
        y = model.initial_state() + rng.normal(scale=0.5, size=model.state_size)
        held = rng.normal(scale=3.0, size=(lag.N + 2, 3))
        t = 0.001 * k
        pair, moved_y = _pair_matches_the_moved_states(model, t, y, held)
        for got, ym in zip(pair, moved_y):
            q, qd = lay.to_oracle(ym)
            want = float((lag.load_force(q, held) - lag.dissipation_force(q, qd)) @ qd)
            assert got == pytest.approx(want, rel=1e-11, abs=1e-11)


@pytest.mark.parametrize("model_name", ("reduced", "rigid"))
def test_the_balance_rate_pair_on_a_prescribed_base(model_name):
    """Two chains on a base prescribed in x, y and psi, gravity on the bent rods, a scripted
    load and held inputs: the one-call pair (two right-hand sides, then one compiled call) is
    the moved States' net powers to rounding, and the spin-up beam's too."""
    from sc_common import chain_dict, scene_dict

    from rod_sim.core.scene import Scene

    rng = np.random.default_rng(31)
    base = {"mode": "prescribed", "initial": {"x": 0.3, "y": -0.2, "psi": 0.4},
            "motion": {"psi": {"shape": "spin_up", "rate": 2.0, "duration": 1.5},
                       "x": {"shape": "harmonic", "amplitude": 0.2, "frequency": 1.3},
                       "y": {"shape": "cycloidal", "amplitude": 0.5, "duration": 2.0}}}
    load = {"chain": "a", "node": 2, "axis": "y", "shape": "raised_cosine_pulse",
            "amplitude": 5.0, "start": 0.0, "duration": 1.0}
    d = scene_dict([chain_dict("a", 3, rng), chain_dict("b", 2, rng)], base, (0.3, -9.81),
                   loads=[load])
    for scene in (Scene.from_dict(d), load_scene(REPO / "config" / "spin_up_beam.yaml")):
        model = make_model(model_name, scene)
        assert model.paired_balance and model.prescribed_base
        for k in range(4):
            y = model.initial_state() + rng.normal(scale=0.3, size=model.state_size)
            held = rng.normal(scale=3.0, size=(scene.n + 2, 3))
            _pair_matches_the_moved_states(model, 0.37 * k, y, held)


@pytest.mark.parametrize("scene_name", ("deployment.yaml", "two_wing_deployment.yaml",
                                        "hub_arm_latch.yaml"))
@pytest.mark.parametrize("model_name", ("reduced", "rigid"))
def test_the_balance_rate_pair_with_stops_and_latches(scene_name, model_name):
    """Stops (a fixed base, two wings on a free base, an arm on a prescribed base), with and
    without latched hinges: the one-call pair is the moved States' net powers to rounding,
    the contacts' dissipation included (states spread so that hinges are beyond their
    stops)."""
    from rod_sim.core.validity import RATE_STEP, _net_power

    scene = load_scene(REPO / "config" / scene_name)
    model = make_model(model_name, scene)
    assert model.paired_balance and model.has_stops
    rng = np.random.default_rng(41)
    beyond = 0
    for k in range(6):
        y = model.initial_state() + rng.normal(scale=0.6, size=model.state_size)
        held = rng.normal(scale=3.0, size=(scene.n + 2, 3))
        mode = None if k % 2 == 0 else rng.random(scene.n) < 0.4
        t = 0.3 * k
        s = model.state(t, y, held, mode)
        hf = RATE_STEP * s.f
        pair = s.moved_net_powers(t + RATE_STEP, t - RATE_STEP, hf)
        up, down = s.moved(t + RATE_STEP, y + hf), s.moved(t - RATE_STEP, y - hf)
        moved = (up.value(_net_power), down.value(_net_power))
        assert pair == pytest.approx(moved, rel=1e-13, abs=1e-13)
        beyond += up.penetrating and up.damper_power != up.chain_powers[1]
    assert beyond >= 2


@pytest.mark.parametrize("scene_name", ("deployment.yaml", "spin_up_beam.yaml",
                                        "paper_example.yaml"))
def test_the_full_model_moves_its_states_one_by_one(scene_name):
    """Slope rates in the state (the full model): no one-call pair (None)."""
    model_name = "full"
    model = make_model(model_name, load_scene(REPO / "config" / scene_name))
    assert not model.paired_balance
    y = model.initial_state()
    s = model.state(0.0, y)
    assert s.moved_net_powers(1e-7, -1e-7, 1e-7 * s.f) is None


def test_hinge_rates_are_right_minus_left_with_the_first_rods_on_the_base():
    """chain_power.deflection_rates against eq. (2) written out: Delta phi_h' = (phi_h' +
    alpha_h') - (phi_{h-1}' + beta_{h-1}'), each chain's first rod against the base's rate."""
    from rod_sim.core.chain_power import deflection_rates

    rng = np.random.default_rng(11)
    n = 9
    dphi, dalpha, dbeta = rng.normal(size=(3, n))
    for first, rate in ((np.zeros(0, dtype=np.int64), 0.0),
                        (np.array([0, 4], dtype=np.int64), 0.7)):
        out = np.empty(n)
        deflection_rates(dphi, dalpha, dbeta, first, rate, out)
        left = np.array([0.0] + [dphi[h - 1] + dbeta[h - 1] for h in range(1, n)])
        left[first] = rate
        assert np.allclose(out, dphi + dalpha - left, rtol=0, atol=1e-15)
        assert out[4] != pytest.approx(dphi[4] + dalpha[4] - dphi[3] - dbeta[3]) or not len(first)
