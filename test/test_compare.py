"""rod-sim compare: the reported errors are the true ones, and tampered logs never pass silently.

Logs are short (small_chain, 0.3-0.6 s). "Node-like" logs mimic the ROS node's recording:
/applied_forces (scripted + held command) at the start of every control period, the states at
its end, held commands piecewise constant. The independent check reads logs with rosbags and
re-runs the full model with scipy's solve_ivp on model.rhs, rebuilding the held commands with
Scene.scripted_forces (Python) instead of the compiled load kernel the tool uses.
"""
from __future__ import annotations

import json
import random
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import Writer as McapWriter
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore
from scipy.integrate import solve_ivp

from rod_sim.core.integrators import make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.simulator import Simulator
from rod_sim.io import topics
from rod_sim.io.log_source import read_log
from rod_sim.io.log_writer import LogWriter
from rod_sim.io.scene_yaml import load_scene, scene_to_yaml
from rod_sim.tools import cli
from rod_sim.compare.stats import significant_digits
from rod_sim.compare.comparison import DEFAULT_TOLERANCE, compare_log
from ros_domains import next_domain

ROOT = Path(__file__).resolve().parents[1]
SMALL = ROOT / "config" / "small_chain.yaml"
PAPER = ROOT / "config" / "paper_example.yaml"
JAZZY = get_typestore(Stores.ROS2_JAZZY)
RATE = 100.0
PERIOD_NS = 10_000_000
STATE_TOPICS = ["rod_states", "bending", "node_poses"]


def commands(n: int, periods: int, seed: int = 7, hold: int = 3) -> list[np.ndarray]:
    """Seeded piecewise-constant commands (n, 2) [N], each held for ``hold`` periods."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(periods):
        if i % hold == 0:
            cmd = rng.uniform(-15.0, 15.0, size=(n, 2))
        out.append(cmd)
    return out


def node_like_log(path, scene, model="full", periods=40, *, seed=7, tamper=None,
                  metadata_scene=None, rtol=1e-10, applied_at_end=False):
    """Write a log as the node records one: state at 0, then per period applied forces at its
    start, advance, states at its end. ``tamper(topic, t_ns, msg) -> msg | None`` may change
    or drop (None) a message dict. ``applied_at_end`` writes the applied forces at the period's
    end instead (the wrong semantics, a negative control). Returns the commands."""
    sim = Simulator(make_model(model, scene), make_integrator("dop853-jit", rtol=rtol,
                                                              atol=rtol))
    meta = {"scene": scene_to_yaml(metadata_scene or scene), "model": model,
            "integrator": sim.integrator.describe(), "rate_hz": repr(RATE),
            "source": "test node-like"}
    cmds = commands(scene.n, periods, seed)

    def put(log, topic, t_ns, msg):
        if tamper is not None:
            msg = tamper(topic, t_ns, msg)
        if msg is not None:
            log.write(topic, topics.TOPIC_TYPES[topic.lstrip("/")], t_ns, msg)

    def states(log):
        snap = sim.snapshot()
        for name, msg in topics.snapshot_messages(snap, scene, topics=STATE_TOPICS).items():
            put(log, "/" + name, sim.t_ns, msg)

    with LogWriter(path, metadata=meta, chunk_size=8192) as log:
        states(log)
        for cmd in cmds:
            sim.set_forces(cmd)
            t0 = sim.t_ns
            applied = topics.force_array(sim.model.forces(t0 / 1e9, sim.held))
            if not applied_at_end:
                put(log, "/applied_forces", t0, applied)
            sim.advance(PERIOD_NS / 1e9)
            if applied_at_end:
                put(log, "/applied_forces", sim.t_ns, applied)
            states(log)
    return cmds


def rod_sim(*args) -> int:
    return cli.main([str(a) for a in args])


def run_json(capsys, *args):
    code = rod_sim("compare", *args, "--json")
    out = capsys.readouterr()
    return code, json.loads(out.out), out.err


def assert_clean_error(capsys, *args, match: str):
    code = rod_sim("compare", *args)
    out = capsys.readouterr()
    assert code == 2, out
    assert "Traceback" not in out.err
    lines = out.err.strip().splitlines()
    assert len(lines) == 1 and match in lines[0], out.err
    return lines[0]


def rewrite(src: Path, dst: Path, transform=lambda items: items, keep_metadata=True):
    """Copy an MCAP file record by record (raw payloads) through ``transform`` of the list of
    (schema, channel, message) in file order."""
    with open(src, "rb") as f:
        reader = make_reader(f)
        items = list(reader.iter_messages(log_time_order=False))
        metas = list(reader.iter_metadata())
    items = transform(items)
    with open(dst, "wb") as f:
        w = McapWriter(f, chunk_size=8192)
        w.start(profile="ros2", library="test")
        if keep_metadata:
            for m in metas:
                w.add_metadata(m.name, dict(m.metadata))
        sids, cids = {}, {}
        for schema, channel, msg in items:
            if schema.id not in sids:
                sids[schema.id] = w.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in cids:
                cids[channel.id] = w.register_channel(channel.topic, channel.message_encoding,
                                                      sids[schema.id], dict(channel.metadata))
            w.add_message(channel_id=cids[channel.id], log_time=msg.log_time,
                          publish_time=msg.publish_time, sequence=msg.sequence, data=msg.data)
        w.finish()


@pytest.fixture(scope="module")
def small():
    return load_scene(SMALL)


@pytest.fixture(scope="module")
def full_log(tmp_path_factory, small):
    path = tmp_path_factory.mktemp("full") / "node_full.mcap"
    node_like_log(path, small, "full")
    return path


@pytest.fixture(scope="module")
def reduced_log(tmp_path_factory, small):
    path = tmp_path_factory.mktemp("reduced") / "node_reduced.mcap"
    node_like_log(path, small, "reduced", periods=50)
    return path


# ----- the force history semantics -----

def test_full_simulate_log_matches_its_own_rerun(tmp_path, small, capsys):
    log = tmp_path / "sim_full.mcap"
    assert rod_sim("simulate", SMALL, "--model", "full", "--t-end", "0.5", "--rtol", "1e-11",
                   "--out", log) == 0
    capsys.readouterr()
    code, rep, _ = run_json(capsys, log)
    assert code == 0 and rep["pass"]
    assert rep["samples_compared"] == 51
    assert rep["forces"]["max_abs_held"] == 0.0          # simulate holds no command
    assert rep["max_abs_error"]["phi"] < 1e-8
    assert rep["max_abs_error"]["phi_rate"] < 1e-7
    assert rep["max_abs_error"]["node_position"] < 1e-8
    assert rep["max_abs_error"]["alpha"] < 1e-8 and rep["max_abs_error"]["beta"] < 1e-8
    assert rep["significant_digits"]["phi"] > 7


def test_node_like_log_matches_its_own_rerun(full_log, small):
    report = compare_log(read_log(full_log), small)
    assert report.forces["segments"] == 14                 # 40 periods, command held 3 each
    assert report.forces["max_abs_held"] > 1.0
    assert report.quantities["phi"].max < 1e-8
    assert report.quantities["phi_rate"].max < 1e-7
    assert report.quantities["alpha"].max < 1e-8
    assert report.passed


def replace_commands(scene, new_cmds):
    """Tamper: every /applied_forces message carries scripted(t) + new_cmds[period]."""
    model = make_model("full", scene)

    def tamper(topic, t_ns, msg):
        if topic != "/applied_forces":
            return msg
        return topics.force_array(model.forces(t_ns / 1e9, new_cmds[t_ns // PERIOD_NS]))
    return tamper


def test_wrong_force_timing_is_seen(tmp_path, small):
    """Negative control for the zero-order-hold reading: a log whose applied forces say each
    command started one period late (as if they were valid up to, not from, their time) is far
    from its re-run, so the 1e-8 agreement above is not automatic."""
    path = tmp_path / "late.mcap"
    cmds = commands(small.n, 40)
    late = [np.zeros((small.n, 2))] + cmds[:-1]
    node_like_log(path, small, "full", tamper=replace_commands(small, late))
    report = compare_log(read_log(path), small, tolerance=1e-6)
    assert report.quantities["phi"].max > 1e-4
    assert not report.passed


def test_piecewise_commands_matter(tmp_path, small):
    """A log whose applied forces are not the commands that ran fails by a wide margin."""
    path = tmp_path / "other_cmds.mcap"
    node_like_log(path, small, "full", tamper=replace_commands(small, commands(small.n, 40, 99)))
    report = compare_log(read_log(path), small, tolerance=1e-6)
    assert report.quantities["phi"].max > 1e-3
    assert not report.passed


# ----- the reported error equals an independent computation -----

def independent_phi_error(path: Path, scene):
    """Max |phi_log - phi_full| over samples and rods, its (rod, t), computed with rosbags and
    solve_ivp (DOP853, rtol 1e-12) on model.rhs, held = applied - Scene.scripted_forces."""
    states, applied = {}, []
    with AnyReader([path], default_typestore=JAZZY) as reader:
        for conn, t_ns, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == "/rod_states":
                states[t_ns] = np.array(msg.position)
            elif conn.topic == "/applied_forces":
                applied.append((t_ns, np.array(msg.data).reshape(-1, 2)))
    model = make_model("full", scene)
    n = scene.n
    t_states = sorted(states)
    y = model.initial_state()
    worst = (0.0, None, None)
    edges = [t for t, _ in applied] + [t_states[-1]]
    for i, (t0, f) in enumerate(applied):
        t1 = edges[i + 1]
        if t1 <= t0:
            continue
        held = f - scene.scripted_forces(t0 / 1e9)
        cuts = [t0 / 1e9] + [b for b in scene.load_breakpoints() if t0 / 1e9 < b < t1 / 1e9] \
            + [t1 / 1e9]
        for a, b in zip(cuts[:-1], cuts[1:]):
            sol = solve_ivp(lambda t, yy: model.rhs(t, yy, held), (a, b), y, method="DOP853",
                            rtol=1e-12, atol=1e-14, dense_output=True)
            assert sol.status == 0
            for ts in t_states:
                if a * 1e9 < ts <= b * 1e9 + 0.5:
                    err = np.abs(states[ts] - sol.sol(ts / 1e9)[:n])
                    k = int(np.argmax(err))
                    if err[k] > worst[0]:
                        worst = (float(err[k]), k + 1, ts / 1e9)
            y = sol.y[:, -1]
    return worst


@pytest.mark.slow
def test_reported_phi_error_equals_independent_computation(reduced_log, small, capsys):
    code, rep, _ = run_json(capsys, reduced_log)
    err, rod, t = independent_phi_error(reduced_log, small)
    assert err > 1e-5                     # a reduced-model run: a real, non-trivial error
    assert rep["max_abs_error"]["phi"] == pytest.approx(err, rel=1e-6, abs=1e-10)
    assert rep["where"]["phi"] == {"rod": rod, "t": pytest.approx(t, abs=1e-9)}
    assert code == (0 if err <= DEFAULT_TOLERANCE else 1)


def test_node_position_error_is_the_distance_of_logged_to_full_nodes(reduced_log, small):
    """Node errors follow from the phi errors through eq. (3): |d node_k| <= sum_j l_j |dphi_j|."""
    report = compare_log(read_log(reduced_log), small, keep_samples=True)
    dphi = report.quantities["phi"].err
    bound = np.cumsum(np.asarray(small.length) * dphi, axis=1)
    dnode = report.quantities["node_position"].err[:, 1:]
    assert np.all(dnode <= bound + 1e-12)
    assert np.max(dnode) > 0.2 * np.max(bound)


# ----- tampering -----

def perturb(rod: int, t_ns: int, delta: float):
    def tamper(topic, t, msg):
        if topic == "/rod_states" and t == t_ns:
            msg["position"][rod - 1] += delta
        return msg
    return tamper


@pytest.mark.parametrize("delta, verdict", [(2e-4, 1), (-3e-3, 1), (5e-5, 0)])
def test_perturbed_sample(tmp_path, small, capsys, delta, verdict):
    path = tmp_path / "perturbed.mcap"
    t_ns = 23 * PERIOD_NS
    node_like_log(path, small, "full", tamper=perturb(2, t_ns, delta))
    code, rep, _ = run_json(capsys, path, "--tolerance", "1e-4")
    assert code == verdict and rep["pass"] is (verdict == 0)
    assert rep["max_abs_error"]["phi"] == pytest.approx(abs(delta), rel=1e-4)
    assert rep["where"]["phi"] == {"rod": 2, "t": pytest.approx(0.23)}
    assert rep["tolerance_first_exceeded_at"] == (pytest.approx(0.23) if verdict else None)


def test_non_finite_sample_fails(tmp_path, small, capsys):
    path = tmp_path / "nan.mcap"
    node_like_log(path, small, "full", tamper=perturb(1, 5 * PERIOD_NS, float("nan")))
    code, rep, _ = run_json(capsys, path)
    assert code == 1 and not rep["pass"]
    assert rep["max_abs_error"]["phi"] is None
    assert "non-finite" in rep["reasons"][0]


def test_messages_out_of_order_in_the_file_are_read_in_time_order(tmp_path, full_log, small):
    path = tmp_path / "shuffled.mcap"
    rewrite(full_log, path, lambda items: random.Random(3).sample(items, len(items)))
    a = compare_log(read_log(full_log), small)
    b = compare_log(read_log(path), small)
    assert b.samples == a.samples
    assert b.quantities["phi"].max == a.quantities["phi"].max


def swap_times(topic: str, a: int, b: int):
    """A ``rewrite`` edit: swap the log and publish times of the a-th and b-th message on
    ``topic``."""
    def swap(items):
        idx = [i for i, it in enumerate(items) if it[1].topic == topic]
        i, j = idx[a], idx[b]
        ti, tj = items[i][2].log_time, items[j][2].log_time
        items[i][2].log_time = items[i][2].publish_time = tj
        items[j][2].log_time = items[j][2].publish_time = ti
        return items
    return swap


def test_state_log_times_swapped_are_refused(tmp_path, full_log, capsys):
    path = tmp_path / "swapped.mcap"
    rewrite(full_log, path, swap_times("/rod_states", 10, 20))
    assert_clean_error(capsys, path, match="differs from the header stamp")


def test_applied_forces_times_swapped_fail(tmp_path, full_log, capsys):
    """/applied_forces has no stamp: swapped times cannot be detected as such, but the re-run
    then departs from the log and the verdict is a fail, not a pass."""
    path = tmp_path / "swapped_forces.mcap"
    rewrite(full_log, path, swap_times("/applied_forces", 3, 30))
    code, rep, _ = run_json(capsys, path, "--tolerance", "1e-5")
    assert code == 1 and rep["max_abs_error"]["phi"] > 1e-4


def drop(topic: str, t_ns: int):
    return lambda top, t, msg: None if (top == topic and t == t_ns) else msg


def test_dropped_applied_forces_refused(tmp_path, small, capsys):
    path = tmp_path / "no_force.mcap"
    node_like_log(path, small, "full", tamper=drop("/applied_forces", 12 * PERIOD_NS))
    assert_clean_error(capsys, path, match="/applied_forces has a gap")
    path0 = tmp_path / "no_force0.mcap"
    node_like_log(path0, small, "full", tamper=drop("/applied_forces", 0))
    assert_clean_error(capsys, path0, match="/applied_forces starts at t = 0.01 s, not 0")
    last = tmp_path / "no_last_force.mcap"
    node_like_log(last, small, "full", periods=10,
                  tamper=lambda top, t, m: None if top == "/applied_forces" and t >= 8 * PERIOD_NS
                  else m)
    assert_clean_error(capsys, last, match="messages are missing")


def test_dropped_state_is_reported_and_not_a_pass(tmp_path, small, capsys):
    path = tmp_path / "no_state.mcap"
    node_like_log(path, small, "full", tamper=drop("/rod_states", 17 * PERIOD_NS))
    code, rep, _ = run_json(capsys, path)
    assert code == 1 and not rep["pass"] and rep["within_tolerance"]
    assert rep["gaps"]["rod_states"] == [[pytest.approx(0.16), pytest.approx(0.18)]]
    assert any("gap" in r for r in rep["reasons"])
    assert rep["samples_compared"] == 40


def test_scene_with_other_n_is_refused(tmp_path, small, capsys):
    path = tmp_path / "other_n.mcap"
    other = load_scene(PAPER)
    node_like_log(path, small, "full", periods=5, metadata_scene=other)
    assert_clean_error(capsys, path, match="the log has 3 rods but the scene 'paper_example' has 8")


def test_scene_with_other_parameters_fails(tmp_path, small, capsys):
    path = tmp_path / "other_kappa.mcap"
    stiffer = small.with_changes(hinge_stiffness=np.asarray(small.hinge_stiffness) * 1.5)
    node_like_log(path, small, "full", periods=30, metadata_scene=stiffer)
    code, rep, _ = run_json(capsys, path)
    assert code == 1 and rep["max_abs_error"]["phi"] > DEFAULT_TOLERANCE
    # --scene overrides the metadata, and the report says that they differ
    code, rep, _ = run_json(capsys, path, "--scene", SMALL)
    assert code == 0 and rep["max_abs_error"]["phi"] < 1e-8
    assert "differs from the scene in the log's metadata" in rep["notes"][0]


def test_truncated_log_compares_the_readable_part_flagged(tmp_path, small, capsys):
    src = tmp_path / "long.mcap"
    node_like_log(src, small, "full", periods=60)
    data = src.read_bytes()
    part = tmp_path / "cut.mcap"
    part.write_bytes(data[:int(len(data) * 0.6)])
    code, rep, _ = run_json(capsys, part)
    assert code == 0 and rep["truncated"]
    assert 0.05 < rep["t_end"] < 0.6
    assert rep["max_abs_error"]["phi"] < 1e-8
    assert any("truncated" in note for note in rep["notes"])
    rod_sim("compare", part)
    assert "TRUNCATED" in capsys.readouterr().out
    tiny = tmp_path / "tiny.mcap"
    tiny.write_bytes(data[:300])
    assert_clean_error(capsys, tiny, match="")


def test_not_mcap_and_missing_files(tmp_path, capsys):
    junk = tmp_path / "junk.mcap"
    junk.write_text("this is not a log\n")
    assert_clean_error(capsys, junk, match="not an MCAP file")
    assert_clean_error(capsys, tmp_path / "absent.mcap", match="no such file")
    empty = tmp_path / "emptydir"
    empty.mkdir()
    assert_clean_error(capsys, empty, match="not a rosbag2 bag")


def test_log_without_metadata_needs_scene(tmp_path, full_log, small, capsys):
    bare = tmp_path / "bare.mcap"
    rewrite(full_log, bare, keep_metadata=False)
    assert_clean_error(capsys, bare, match="pass --scene")
    code, rep, _ = run_json(capsys, bare, "--scene", SMALL)
    assert code == 0 and rep["scene_source"] == f"--scene {SMALL}"
    assert rep["max_abs_error"]["phi"] < 1e-8


def test_rosbag2_directory_with_two_files(tmp_path, full_log, small, capsys):
    """A bag directory (metadata.yaml + two MCAP files, no rod_sim metadata) gives the same
    numbers as the single file."""
    bag = tmp_path / "bag"
    bag.mkdir()
    with open(full_log, "rb") as f:
        n_msgs = sum(1 for _ in make_reader(f).iter_messages())
    half = n_msgs // 2
    rewrite(full_log, bag / "bag_0.mcap", lambda items: items[:half], keep_metadata=False)
    rewrite(full_log, bag / "bag_1.mcap", lambda items: items[half:], keep_metadata=False)
    (bag / "metadata.yaml").write_text(
        "rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: mcap\n"
        "  relative_file_paths:\n    - bag_0.mcap\n    - bag_1.mcap\n")
    code, rep, _ = run_json(capsys, bag, "--scene", SMALL)
    ref = compare_log(read_log(full_log), small)
    assert code == 0 and len(rep["files"]) == 2
    assert rep["samples_compared"] == ref.samples
    assert rep["max_abs_error"]["phi"] == ref.quantities["phi"].max
    (bag / "metadata.yaml").write_text(
        "rosbag2_bagfile_information:\n  storage_identifier: zarr\n"
        "  relative_file_paths: [bag_0.zarr]\n")
    assert_clean_error(capsys, bag, "--scene", SMALL, match="only 'mcap' and 'sqlite3' bags")
    (bag / "metadata.yaml").write_text(
        "rosbag2_bagfile_information:\n  storage_identifier: sqlite3\n"
        "  relative_file_paths: [bag_0.db3]\n")
    assert_clean_error(capsys, bag, "--scene", SMALL, match="cannot read the sqlite3 bag")


# ----- output -----

def test_text_table_json_and_plot(tmp_path, reduced_log, capsys):
    png = tmp_path / "cmp.png"
    code = rod_sim("compare", reduced_log, "--plot", png)
    out = capsys.readouterr().out
    assert code in (0, 1)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    lines = out.splitlines()
    head = next(i for i, line in enumerate(lines) if line.lstrip().startswith("rod "))
    assert lines[head + 1].split()[0] == "[rad]"                   # units on their own row
    assert [line.split()[0] for line in lines[head + 2:head + 6]] == ["1", "2", "3", "max"]
    verdict = [line for line in lines if line.startswith(("PASS", "FAIL"))]
    assert len(verdict) == 1 and verdict[0].startswith("PASS" if code == 0 else "FAIL")
    assert max(len(line) for line in lines) <= 100, max(lines, key=len)   # issue 13 item 13
    assert_clean_error(capsys, reduced_log, "--plot", png, match="refusing to overwrite")
    code, rep, _ = run_json(capsys, reduced_log)
    for key in ("max_abs_error", "tolerance", "pass", "per_rod", "where", "significant_digits",
                "reference", "samples_compared"):
        assert key in rep
    assert set(rep["max_abs_error"]) >= {"phi", "phi_rate", "node_position", "alpha", "beta"}
    assert rep["reference"]["converged"] and rep["reference"]["phi_change"] < 1e-8
    assert [r["rod"] for r in rep["per_rod"]] == [1, 2, 3]
    assert max(r["phi"] for r in rep["per_rod"]) == rep["max_abs_error"]["phi"]
    assert rep["tolerance"] == DEFAULT_TOLERANCE


def test_significant_digits():
    ref = np.array([1.0, 2.0, -4.0])
    assert significant_digits(np.array([1e-3, 0.0, 0.0]), ref) == pytest.approx(3.0)
    assert significant_digits(np.array([0.0, 0.0, 4e-5]), ref) == pytest.approx(5.0)
    # near-zero reference: the floor (1 % of max |ref| = 0.04) is the denominator
    assert significant_digits(np.array([4e-6]), np.array([0.0])) == 0.0   # nothing right
    assert significant_digits(np.array([0.0]), np.array([0.0])) == 16.0
    assert significant_digits(np.array([3.0]), np.array([1.0])) == pytest.approx(-np.log10(3))
    assert significant_digits(np.array([4e-6, 0.0]), np.array([1e-9, 4.0])) == pytest.approx(4.0)
    assert significant_digits(np.zeros(3), ref) == 16.0
    assert significant_digits(np.array([np.inf]), ref[:1]) == 0.0


@pytest.mark.slow
def test_paper_example_reduced_against_independent_rerun(tmp_path, capsys):
    """The seed's example (n = 8, 1 s): the reduced model's reported error is the independent one."""
    log = tmp_path / "paper_reduced.mcap"
    assert rod_sim("simulate", PAPER, "--model", "reduced", "--t-end", "1", "--out", log) == 0
    capsys.readouterr()
    code, rep, _ = run_json(capsys, log)
    err, rod, t = independent_phi_error(log, load_scene(PAPER))
    assert rep["max_abs_error"]["phi"] == pytest.approx(err, rel=1e-6, abs=1e-10)
    assert rep["where"]["phi"]["rod"] == rod
    assert code == (0 if err <= DEFAULT_TOLERANCE else 1)


@pytest.mark.ros
def test_real_node_log_matches_the_full_model(tmp_path, capsys):
    """A log recorded by the ROS node (lockstep with the PD controller, full model, commands
    changing every period) compares to rounding-level agreement: the held-command reading of
    /applied_forces is the node's."""
    import os
    import subprocess
    import sys

    out = tmp_path / "node_full.mcap"
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               ROS_DOMAIN_ID=str(next_domain()))
    done = subprocess.run([sys.executable, "-m", "rod_sim.ros.demo", "--out", str(out),
                           "--duration", "0.3", "--model", "full", "--sync"], cwd=ROOT,
                          env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    code, rep, _ = run_json(capsys, out)
    assert rep["source"] == "rod_sim node" and rep["model"] == "full"
    assert rep["forces"]["segments"] >= 25 and rep["forces"]["max_abs_held"] > 1.0
    assert rep["max_abs_error"]["phi"] < 1e-8 and code == 0


def test_bag_written_by_rosbags_rosbag2_writer(tmp_path, full_log, small, capsys):
    """A rosbag2 bag (version 9, MCAP storage) written by the independent rosbags library from
    the log's raw messages compares like the log itself."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    bag = tmp_path / "rosbag2_bag"
    with AnyReader([full_log], default_typestore=JAZZY) as reader, \
            Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conns = {}
        for conn, t_ns, raw in reader.messages():
            if conn.topic not in conns:
                conns[conn.topic] = writer.add_connection(conn.topic, conn.msgtype,
                                                          typestore=JAZZY)
            writer.write(conns[conn.topic], t_ns, raw)
    assert (bag / "metadata.yaml").is_file()
    code, rep, _ = run_json(capsys, bag, "--scene", SMALL)
    ref = compare_log(read_log(full_log), small)
    assert code == 0 and rep["samples_compared"] == ref.samples
    assert rep["max_abs_error"]["phi"] == ref.quantities["phi"].max
    assert_clean_error(capsys, bag, match="pass --scene")


def test_corrupted_and_cut_files_never_crash(tmp_path, full_log, capsys):
    """Seeded byte flips and cuts anywhere in a log: exit 0, 1 or 2, never an exception, at
    most one line on stderr besides the warnings that name damaged sections (issue 19 item
    3); an exit 2 names the file."""
    data = full_log.read_bytes()
    rng = random.Random(11)
    seen = set()
    for i in range(30):
        bad = bytearray(data)
        if i % 3 == 0:
            bad = bad[:rng.randrange(8, len(bad))]
        else:
            for _ in range(rng.choice([1, 4, 16])):
                bad[rng.randrange(len(bad))] ^= 1 << rng.randrange(8)
        path = tmp_path / f"bad_{i}.mcap"
        path.write_bytes(bytes(bad))
        code = rod_sim("compare", path)
        out = capsys.readouterr()
        seen.add(code)
        assert code in (0, 1, 2) and "Traceback" not in out.err
        lines = [ln for ln in out.err.strip().splitlines()
                 if not ln.startswith("rod-sim: warning:")]
        assert len(lines) <= (1 if code == 2 else 0), out.err
        if code == 2:
            assert "error:" in out.err
    assert 2 in seen


def test_one_sample_is_not_a_comparison(tmp_path, small, capsys):
    path = tmp_path / "one.mcap"
    node_like_log(path, small, "full", periods=3,
                  tamper=lambda top, t, m: None if top == "/rod_states" and t > 0 else m)
    assert_clean_error(capsys, path, match="only 1 /rod_states sample")


def test_help_and_verdict_use_the_documented_default_tolerance(tmp_path, small, capsys):
    """docs/interface.md states the default tolerance (the oracle); --help says it and a
    comparison without --tolerance applies it."""
    import re
    from rod_sim.tools.cli import build_parser
    doc = " ".join((ROOT / "docs" / "interface.md").read_text().split())
    documented = float(re.search(r"exceeds the tolerance \(default ([0-9.e-]+) rad\)", doc)[1])
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    help_text = " ".join(sub.choices["compare"].format_help().split())
    assert f"default {documented:g}" in help_text, help_text
    path = tmp_path / "d.mcap"
    node_like_log(path, small, "full", periods=3)
    cli.main(["compare", str(path), "--json"])
    assert json.loads(capsys.readouterr().out)["tolerance"] == documented


def test_validity_warnings_name_slopes_beyond_small_bending_and_fast_loads():
    from types import SimpleNamespace

    from rod_sim.core.validity import SMALL_BENDING_RAD
    from rod_sim.compare.command import validity_messages

    paper = load_scene(PAPER)
    small = SimpleNamespace(quantities={"alpha": SimpleNamespace(ref_max=0.01),
                                        "beta": SimpleNamespace(ref_max=0.0)})
    assert validity_messages(paper, "reduced", small) == []
    large = SimpleNamespace(quantities={"alpha": SimpleNamespace(ref_max=0.0),
                                        "beta": SimpleNamespace(ref_max=0.3)})
    (msg,) = validity_messages(paper, "reduced", large)
    assert "0.3 rad" in msg and str(SMALL_BENDING_RAD) in msg
    soft = paper.with_changes(bending_stiffness=np.full(8, 10.0))   # first mode ~0.8 Hz
    assert any("bending mode" in m for m in validity_messages(soft, "reduced", small))
    assert validity_messages(soft, "full", small) == []


def test_the_plot_series_of_a_long_chain_stays_within_its_budget(tmp_path):
    """The plot's decimated series kept phi of every rod at up to 8000 samples: ~150 MB for a
    1200-rod log, ~1.3 GB for 10 000 rods, even without --plot. Now it keeps the angles only
    for a plot, and within 64 MiB (fewer samples for a longer chain)."""
    import tracemalloc

    from rod_sim.compare.comparison import plot_points
    from rod_sim.compare.stats import Decimated

    n = 5000
    series = Decimated(plot_points(n))
    phi = np.zeros(n)
    tracemalloc.start()
    for k in range(20_000):
        series.add(k * 1e-3, 1e-6, phi, phi, 1.0)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert peak <= 66 * 2**20 and series.rows.shape[1] == 3 + 2 * n
    assert 250 <= series.rows.shape[0] <= 2 * 4000


def test_without_a_plot_compare_keeps_no_angles_for_it(tmp_path):
    scene = Path(__file__).resolve().parents[1] / "config" / "bench" / "chain_n32.yaml"
    out = tmp_path / "run.mcap"
    assert rod_sim("simulate", scene, "--t-end", "0.1", "--out", out) == 0
    widths = []
    for plot in (True, False):
        with read_log(out) as log:
            report = compare_log(log, load_scene(scene), plot=plot)
        widths.append(report.series.rows.shape)
    assert widths == [(11, 3 + 2 * 32), (11, 3)]
