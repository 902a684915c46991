"""MCAP logs: written by LogWriter, read back by the independent rosbags library and by LogReader."""
from __future__ import annotations

import io
import math
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.data_stream import ReadDataStream
from mcap.reader import make_reader
from mcap.records import Chunk
from mcap.stream_reader import breakup_chunk
from mcap.writer import Writer as PlainMcapWriter
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from rod_sim import __version__
from rod_sim.core.kinematics import node_positions, rod_points
from rod_sim.core.scene import Scene
from rod_sim.core.snapshot import Snapshot
from rod_sim.io import msgdefs, topics
from rod_sim.io.log_format import LogFormatError
from rod_sim.io.log_reader import LogReader
from rod_sim.io.log_writer import LogWriteError, LogWriter
from rod_sim.io.series import read_applied_forces, read_rod_states

JAZZY = get_typestore(Stores.ROS2_JAZZY)
REPO = Path(__file__).resolve().parents[1]
QOS_KEYS = {"history", "depth", "reliability", "durability", "deadline", "lifespan", "liveliness",
            "liveliness_lease_duration", "avoid_ros_namespace_conventions"}


def make_scene(n: int) -> Scene:
    return Scene.from_dict({
        "name": f"chain_{n}",
        "rods": {"count": n, "length": 2.0, "mass_per_length": 3.0, "bending_stiffness": 1e5},
        "nodes": {"mass": 3.0},
        "hinges": {"stiffness": 100.0, "damping": 0.01},
    })


def make_snapshots(scene: Scene, count: int, seed: int, dt: float = 0.01) -> list[Snapshot]:
    rng = np.random.default_rng(seed)
    n = scene.n
    out = []
    for i in range(count):
        phi = rng.uniform(-math.pi, math.pi, n)
        out.append(Snapshot(
            t=i * dt, phi=phi, phi_rate=rng.normal(size=n), alpha=0.01 * rng.normal(size=n),
            beta=0.01 * rng.normal(size=n), hinge_angle=np.diff(phi, prepend=0.0),
            hinge_rate=rng.normal(size=n), hinge_moment=100.0 * rng.normal(size=n),
            nodes=node_positions(np.asarray(scene.length), phi),
            forces=rng.normal(scale=100.0, size=(n, 2))))
    return out


METADATA = {"scene": "name: chain\nrods: {count: 3}\n", "model": "full",
            "integrator": "DOP853", "rtol": "1e-9"}


def write_log(path: Path, scene: Scene, snapshots: list[Snapshot]) -> list[tuple[str, str, int, dict]]:
    """Log every topic; returns the expected (topic, type, t_ns, msg dict) in write order."""
    expected = []
    with LogWriter(path, metadata=METADATA) as writer:
        for snap in snapshots:
            t_ns = topics.time_ns(snap.t)
            msgs = topics.snapshot_messages(snap, scene, "world", topics.SNAPSHOT_TOPICS)
            msgs["diagnostics"] = topics.diagnostics(
                snap.t, {"real_time_factor": "1.25", "max_abs_alpha": float(np.max(abs(snap.alpha)))},
                scene.name, frame_id="world")
            for name, msg in msgs.items():
                writer.write("/" + name, topics.TOPIC_TYPES[name], t_ns, msg)
                expected.append(("/" + name, topics.TOPIC_TYPES[name], t_ns, msg))
        writer.write("/events", "std_msgs/msg/String", topics.time_ns(snapshots[-1].t),
                     {"data": "done"})
        expected.append(("/events", "std_msgs/msg/String", topics.time_ns(snapshots[-1].t),
                         {"data": "done"}))
    return expected


# ----- an independent comparison: our dicts against rosbags' decoded objects -----

_DEFAULTS = {"bool": False, "string": "", "float32": 0.0, "float64": 0.0}


def assert_same(expected: dict, obj, typename: str, path: str = "") -> None:
    """Every field of ``obj`` (rosbags message) equals ``expected`` or, when absent, its default."""
    for name, desc in JAZZY.fielddefs[typename][1]:
        where = f"{typename}:{path}{name}"
        value = getattr(obj, name)
        assert_field(expected.get(name), value, desc, where)


def assert_field(exp, value, desc, where: str) -> None:
    kind, arg = desc
    if kind.name == "NAME":
        assert_same(exp or {}, value, arg, where + ".")
    elif kind.name == "BASE":
        base = arg[0]
        if exp is None:
            assert value == _DEFAULTS.get(base, 0), where
        elif base == "float32":
            assert np.float32(value) == np.float32(exp), where
        else:
            assert type(value) is type(exp) or (isinstance(value, (int, float)) and
                                                 isinstance(exp, (int, float))), where
            assert value == exp, where
    else:
        (item_kind, item_arg), _ = arg
        exp = [] if exp is None else exp
        assert len(value) == len(exp), where
        if item_kind.name == "NAME":
            for i, (e, v) in enumerate(zip(exp, value)):
                assert_same(e, v, item_arg, f"{where}[{i}].")
        elif item_arg[0] == "string":
            assert list(value) == list(exp), where
        else:
            np.testing.assert_array_equal(np.asarray(value), np.asarray(exp, dtype=float),
                                          err_msg=where)


def stamp_ns(msg, typename: str) -> int | None:
    if typename == "rosgraph_msgs/msg/Clock":
        return msg.clock.sec * 10**9 + msg.clock.nanosec
    if typename == "visualization_msgs/msg/MarkerArray":
        stamps = {m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in msg.markers}
        assert len(stamps) == 1
        return stamps.pop()
    if hasattr(msg, "header"):
        return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
    return None


@pytest.fixture(params=[3, 8], ids=["n3", "n8"])
def logged(request, tmp_path):
    scene = make_scene(request.param)
    snapshots = make_snapshots(scene, 6, seed=request.param)
    path = tmp_path / "run.mcap"
    expected = write_log(path, scene, snapshots)
    return path, scene, snapshots, expected


def test_rosbags_reads_every_field_back_exactly(logged):
    path, _, _, expected = logged
    got = []
    with AnyReader([path], default_typestore=JAZZY) as reader:
        assert {c.topic: c.msgtype for c in reader.connections} == {e[0]: e[1] for e in expected}
        for conn, timestamp, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            got.append((conn.topic, conn.msgtype, timestamp, msg, bytes(raw)))
    assert len(got) == len(expected)
    # same multiset and, per topic, same order
    for topic in {e[0] for e in expected}:
        exp_t = [e for e in expected if e[0] == topic]
        got_t = [g for g in got if g[0] == topic]
        assert len(exp_t) == len(got_t)
        for (_, typename, t_ns, exp_msg), (_, gtype, gtime, msg, raw) in zip(exp_t, got_t):
            assert gtype == typename and gtime == t_ns
            assert_same(exp_msg, msg, typename)
            stamp = stamp_ns(msg, typename)
            assert stamp is None or stamp == t_ns
            # exact CDR: rosbags re-serializes the decoded message to the very same bytes
            assert bytes(JAZZY.serialize_cdr(msg, typename)) == raw
    assert [g[2] for g in got] == sorted(g[2] for g in got)


def test_messages_mean_what_spec_section_4_says(logged):
    path, scene, snapshots, _ = logged
    n = scene.n
    by_topic: dict[str, list] = {}
    with AnyReader([path], default_typestore=JAZZY) as reader:
        for conn, _, raw in reader.messages():
            by_topic.setdefault(conn.topic, []).append(reader.deserialize(raw, conn.msgtype))
    for i, snap in enumerate(snapshots):
        js = by_topic["/joint_states"][i]
        assert list(js.name) == [f"hinge_{h}" for h in range(n)]
        np.testing.assert_array_equal(js.position, snap.hinge_angle)
        np.testing.assert_array_equal(js.velocity, snap.hinge_rate)
        np.testing.assert_array_equal(js.effort, snap.hinge_moment)
        rs = by_topic["/rod_states"][i]
        assert list(rs.name) == [f"rod_{k}" for k in range(1, n + 1)]
        np.testing.assert_array_equal(rs.position, snap.phi)
        np.testing.assert_array_equal(rs.velocity, snap.phi_rate)
        assert len(rs.effort) == 0
        bd = by_topic["/bending"][i]
        assert list(bd.name) == ([f"alpha_{k}" for k in range(1, n + 1)]
                                 + [f"beta_{k}" for k in range(1, n + 1)])
        np.testing.assert_array_equal(bd.position, np.concatenate([snap.alpha, snap.beta]))
        assert len(bd.velocity) == len(bd.effort) == 0
        poses = by_topic["/node_poses"][i].poses
        assert len(poses) == n + 1
        for k, pose in enumerate(poses):
            assert (pose.position.x, pose.position.y, pose.position.z) == (
                snap.nodes[k, 0], snap.nodes[k, 1], 0.0)
            q = pose.orientation
            assert q.x == q.y == 0.0 and math.isclose(q.z**2 + q.w**2, 1.0)
            yaw = 2.0 * math.atan2(q.z, q.w)
            assert math.isclose(math.remainder(yaw - snap.phi[max(k, 1) - 1], 2 * math.pi), 0.0,
                                abs_tol=1e-12)
        forces = by_topic["/applied_forces"][i]
        np.testing.assert_array_equal(forces.data, snap.forces.ravel())
        dims = forces.layout.dim
        assert [(d.label, d.size, d.stride) for d in dims] == [("node", n, 2 * n), ("xy", 2, 2)]
        markers = by_topic["/markers"][i].markers
        rods = [m for m in markers if m.ns == "rods"]
        spheres = [m for m in markers if m.ns == "nodes"]
        assert len(rods) == n and len(spheres) == 1
        pts = rod_points(np.asarray(scene.length), snap.phi, snap.alpha, snap.beta, 11)
        for k, m in enumerate(rods):
            assert m.type == 4 and m.action == 0 and m.id == k + 1 and not m.frame_locked
            assert (m.lifetime.sec, m.lifetime.nanosec) == (0, 0)
            xy = np.array([[p.x, p.y] for p in m.points])
            np.testing.assert_array_equal(xy, pts[k])
            np.testing.assert_allclose(xy[[0, -1]], snap.nodes[[k, k + 1]], atol=1e-12)
        s = spheres[0]
        assert s.type == 7 and s.scale.x > 0 and s.scale.x == s.scale.y == s.scale.z
        np.testing.assert_array_equal(np.array([[p.x, p.y] for p in s.points]), snap.nodes[1:])
        diag = by_topic["/diagnostics"][i].status[0]
        assert diag.name == "rod_sim" and diag.hardware_id == scene.name
        assert {kv.key: kv.value for kv in diag.values}["real_time_factor"] == "1.25"


def test_mcap_records_are_as_rosbag2_writes_them(logged):
    path, _, _, expected = logged
    with open(path, "rb") as f:
        reader = make_reader(f)
        header = reader.get_header()
        assert header.profile == "ros2"
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        assert summary.statistics.message_count == len(expected)
        assert summary.statistics.channel_count == len({e[0] for e in expected})
        assert summary.chunk_indexes, "chunked and indexed"
        for index in summary.chunk_indexes:
            assert index.compression in ("zstd", "lz4")
            assert index.message_index_length > 0 and index.message_index_offsets
        assert [m.name for m in summary.metadata_indexes] == ["rod_sim"]
        for schema in summary.schemas.values():
            assert schema.encoding == "ros2msg"
            assert schema.data.decode() == msgdefs.SCHEMAS[schema.name]
        for channel in summary.channels.values():
            assert channel.message_encoding == "cdr"
            profiles = yaml.safe_load(channel.metadata["offered_qos_profiles"])
            assert isinstance(profiles, list) and len(profiles) == 1
            assert set(profiles[0]) == QOS_KEYS
            assert profiles[0]["reliability"] == "reliable"
            assert set(profiles[0]["deadline"]) == {"sec", "nsec"}
            schema_name = summary.schemas[channel.schema_id].name
            assert channel.metadata["topic_type_hash"] == msgdefs.TYPE_HASHES[schema_name]
        sequences: dict[int, list[int]] = {}
        count = 0
        for _, channel, message in reader.iter_messages(log_time_order=False):
            assert message.log_time == message.publish_time
            sequences.setdefault(channel.id, []).append(message.sequence)
            count += 1
        assert count == len(expected)
        for seqs in sequences.values():
            assert seqs == list(range(1, len(seqs) + 1))
    with AnyReader([path], default_typestore=JAZZY) as reader:
        for conn in reader.connections:
            (qos,) = conn.ext.offered_qos_profiles
            assert qos.depth == 10 and qos.reliability.name == "RELIABLE"
            assert qos.durability.name == "VOLATILE"


def test_log_reader_round_trip(logged):
    path, _, snapshots, expected = logged
    with LogReader(path) as reader:
        assert reader.complete
        assert reader.metadata() == {**METADATA, "version": __version__}
        assert reader.topics() == {e[0]: e[1] for e in expected}
        got = list(reader.messages())
        rods = list(reader.messages(["rod_states"]))
    # written in time order, so log-time order (file order on ties) is the write order
    assert [(g[0], g[1]) for g in got] == [(e[0], e[2]) for e in expected]
    for (_, _, msg), (_, typename, _, exp) in zip(got, expected):
        if typename == "sensor_msgs/msg/JointState":
            assert list(msg.name) == exp["name"] and list(msg.position) == exp["position"]
    assert len(rods) == len(snapshots) and {g[0] for g in rods} == {"/rod_states"}
    t, phi, phi_rate = read_rod_states(path)
    np.testing.assert_array_equal(t, [s.t for s in snapshots])
    np.testing.assert_array_equal(phi, np.stack([s.phi for s in snapshots]))
    np.testing.assert_array_equal(phi_rate, np.stack([s.phi_rate for s in snapshots]))
    tf, forces = read_applied_forces(path)
    np.testing.assert_array_equal(tf, t)
    np.testing.assert_array_equal(forces, np.stack([s.forces for s in snapshots]))


def test_refuses_to_overwrite(tmp_path):
    path = tmp_path / "run.mcap"
    path.write_bytes(b"precious")
    with pytest.raises(FileExistsError, match="refusing to overwrite"):
        LogWriter(path, metadata=METADATA)
    assert path.read_bytes() == b"precious"
    scene = make_scene(3)
    with LogWriter(path, metadata=METADATA, overwrite=True) as writer:
        writer.write_snapshot(make_snapshots(scene, 1, seed=1)[0], scene)
    with LogReader(path) as reader:
        assert reader.complete and reader.metadata()["model"] == "full"


def test_writer_rejects_bad_input(tmp_path):
    with pytest.raises(ValueError, match="integrator"):
        LogWriter(tmp_path / "a.mcap", metadata={"scene": "", "model": "full"})
    with LogWriter(tmp_path / "b.mcap", metadata=METADATA) as writer:
        with pytest.raises(LogWriteError, match="secs"):
            writer.write("/clock", "rosgraph_msgs/msg/Clock", 0, {"clock": {"secs": 1}})
        with pytest.raises(LogWriteError, match="absolute"):
            writer.write("clock", "rosgraph_msgs/msg/Clock", 0, {"clock": {"sec": 1}})
        with pytest.raises(LogWriteError, match="no schema"):
            writer.write("/x", "std_msgs/msg/Int8", 0, {"data": 1})
        writer.write("/clock", "rosgraph_msgs/msg/Clock", 10, {"clock": {"sec": 0, "nanosec": 10}})
        with pytest.raises(LogWriteError, match="backwards"):
            writer.write("/clock", "rosgraph_msgs/msg/Clock", 9, {"clock": {"sec": 0, "nanosec": 9}})
        with pytest.raises(LogWriteError, match="already logged"):
            writer.write("/clock", "std_msgs/msg/String", 11, {"data": "x"})
        with pytest.raises(LogWriteError, match="t_ns"):
            writer.write("/events", "std_msgs/msg/String", -1, {"data": "x"})
    writer.close()  # idempotent


def test_an_exception_inside_the_writer_still_leaves_a_complete_log(tmp_path):
    path = tmp_path / "run.mcap"
    scene = make_scene(3)
    with pytest.raises(RuntimeError):
        with LogWriter(path, metadata=METADATA) as writer:
            writer.write_snapshot(make_snapshots(scene, 1, seed=2)[0], scene)
            raise RuntimeError("simulation failed")
    with LogReader(path) as reader:
        assert reader.complete and len(list(reader.messages())) == len(topics.DEFAULT_TOPICS)


def _messages_in_complete_chunks(full: bytes, cut: int) -> int:
    with io.BytesIO(full) as f:
        summary = make_reader(f).get_summary()
        count = 0
        for index in summary.chunk_indexes:
            if index.chunk_start_offset + index.chunk_length <= cut:
                f.seek(index.chunk_start_offset + 9)
                chunk = Chunk.read(ReadDataStream(f))
                count += sum(1 for r in breakup_chunk(chunk) if type(r).__name__ == "Message")
    return count


def test_truncated_log_yields_every_complete_chunk(tmp_path):
    scene = make_scene(3)
    snapshots = make_snapshots(scene, 200, seed=3)
    path = tmp_path / "full.mcap"
    expected = []
    with LogWriter(path, metadata=METADATA, chunk_size=4096) as writer:
        for snap in snapshots:
            writer.write_snapshot(snap, scene, topics=["rod_states", "clock"])
            expected += [("/rod_states", topics.time_ns(snap.t)), ("/clock", topics.time_ns(snap.t))]
    full = path.read_bytes()
    for fraction in (0.6, 0.25, 0.9):
        cut = int(len(full) * fraction)
        part = tmp_path / f"cut_{fraction}.mcap"
        part.write_bytes(full[:cut])
        with LogReader(part) as reader:
            assert not reader.complete
            assert reader.metadata() == {**METADATA, "version": __version__}
            got = [(topic, t) for topic, t, _ in reader.messages()]
            # cut inside the data section, or only the summary lost
            assert reader.truncated or len(got) == len(expected)
            assert reader.topics() == {"/rod_states": "sensor_msgs/msg/JointState",
                                       "/clock": "rosgraph_msgs/msg/Clock"}
        assert got == expected[:len(got)], "a prefix of what was written"
        assert len(got) == _messages_in_complete_chunks(full, cut) > 0
        t, phi, _ = read_rod_states(part)
        np.testing.assert_array_equal(phi, np.stack([s.phi for s in snapshots[:len(t)]]))


def test_killed_writer_leaves_its_complete_chunks_on_disk(tmp_path):
    path = tmp_path / "killed.mcap"
    script = textwrap.dedent(f"""
        import os, sys
        sys.path.insert(0, {str(REPO)!r})
        from rod_sim.io.log_writer import LogWriter
        w = LogWriter({str(path)!r}, metadata={{"scene": "s", "model": "m", "integrator": "i"}},
                      chunk_size=2048)
        for i in range(2000):
            w.write("/events", "std_msgs/msg/String", i, {{"data": "event %d" % i}})
        os._exit(0)  # no close(): like a SIGKILL
    """)
    subprocess.run([sys.executable, "-c", script], check=True, timeout=120)
    with LogReader(path) as reader:
        assert not reader.complete
        got = list(reader.messages())
    assert 0 < len(got) < 2000
    assert [(t, m.data) for _, t, m in got] == [(i, f"event {i}") for i in range(len(got))]


def test_non_mcap_files_raise_log_format_error(tmp_path):
    for name, content in [("text.mcap", b"hello, this is not a log\n" * 10), ("empty.mcap", b"")]:
        path = tmp_path / name
        path.write_bytes(content)
        with pytest.raises(LogFormatError, match="not an MCAP file"):
            LogReader(path)
    with pytest.raises(LogFormatError, match="no /rod_states"):
        read_rod_states(_plain_mcap(tmp_path / "plain.mcap"))


def _plain_mcap(path: Path) -> Path:
    with open(path, "wb") as f:
        writer = PlainMcapWriter(f)
        writer.start(profile="ros2", library="test")
        writer.finish()
    return path


def test_mcap_without_rod_sim_metadata_raises_on_request(tmp_path):
    path = _plain_mcap(tmp_path / "plain.mcap")
    with LogReader(path) as reader:
        assert reader.topics() == {} and list(reader.messages()) == []
        with pytest.raises(LogFormatError, match="no 'rod_sim' metadata"):
            reader.metadata()


@pytest.mark.parametrize("t, sec, nanosec", [
    (0.0, 0, 0), (0.1, 0, 100_000_000), (0.3, 0, 300_000_000), (1.000000001, 1, 1),
    (3.3, 3, 300_000_000), (12.999999999, 12, 999_999_999), (86400.01, 86400, 10_000_000),
])
def test_stamp_is_exact(t, sec, nanosec):
    assert topics.stamp(t) == {"sec": sec, "nanosec": nanosec}
    assert topics.time_ns(t) == sec * 10**9 + nanosec


@pytest.mark.parametrize("t", [-1e-9, -1.0, float("nan"), float("inf")])
def test_stamp_rejects_negative_and_non_finite_times(t):
    with pytest.raises(ValueError, match="time"):
        topics.stamp(t)


def test_snapshot_messages_topic_selection():
    scene = make_scene(3)
    snap = make_snapshots(scene, 1, seed=4)[0]
    assert set(topics.snapshot_messages(snap, scene)) == set(topics.DEFAULT_TOPICS)
    assert set(topics.snapshot_messages(snap, scene, topics=["clock"])) == {"clock"}
    with pytest.raises(ValueError, match="diagnostics"):
        topics.snapshot_messages(snap, scene, topics=["diagnostics"])
    with pytest.raises(ValueError, match="rods"):
        topics.snapshot_messages(snap, make_scene(4))
    massless = Scene.from_dict({"rods": {"count": 2, "length": 1.0, "mass_per_length": 1.0,
                                         "bending_stiffness": 1.0},
                                "nodes": {"mass": 0.0}, "hinges": {"stiffness": 1.0,
                                                                   "damping": 0.0}})
    width, diameter = topics.marker_sizes(massless)
    assert 0 < width < diameter < 1.0


def full_disk(monkeypatch, budget: int) -> list[int]:
    """Writes of an in-process log fail with ENOSPC once ``budget`` bytes are written; returns
    the one-element list counting the bytes that did reach the file."""
    import errno
    import os

    from rod_sim.io import log_writer

    written = [0]
    real = log_writer._FlushingFile.write

    def write(self, data):
        if written[0] + len(data) > budget:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        written[0] += len(data)
        return real(self, data)

    monkeypatch.setattr(log_writer._FlushingFile, "write", write)
    return written


def test_a_failed_write_leaves_the_complete_chunks_and_nothing_after(tmp_path, monkeypatch):
    """A full disk in the middle of a log: close() writes nothing more (no data-end record with
    a CRC over bytes that never reached the file), the file ends at its last complete chunk and
    the readers give every sample of those chunks (rosbags too, after `rod-sim repair`)."""
    from rod_sim.io.repair import repair_log

    budget = 20_000
    written = full_disk(monkeypatch, budget)
    scene = make_scene(3)
    path = tmp_path / "full.mcap"
    writer = LogWriter(path, metadata=METADATA, chunk_size=2048)
    logged = 0
    with pytest.raises(OSError):
        for snap in make_snapshots(scene, 2000, seed=5):
            writer.write_snapshot(snap, scene, topics=["rod_states"])
            logged += 1
    size = path.stat().st_size
    assert size == written[0] <= budget
    writer.close()
    writer.close()                                   # idempotent
    assert writer.closed and path.stat().st_size == size
    monkeypatch.undo()
    t, phi, _ = read_rod_states(path)
    # the failing call's message may sit in the last complete chunk (the chunk was written,
    # its message index was not)
    assert 0 < t.size <= logged + 1 and phi.shape == (t.size, 3)
    np.testing.assert_allclose(np.diff(t), 0.01, atol=1e-9)    # a prefix, no gaps
    # no footer (as after a kill): `rod-sim repair` makes it a log that rosbags reads whole
    fixed = tmp_path / "fixed.mcap"
    repair_log(path, fixed)
    with AnyReader([fixed], default_typestore=JAZZY) as reader:
        assert sum(1 for _ in reader.messages()) == t.size
