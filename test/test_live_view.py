"""The live view (foxglove-sdk WebSocket server) met as a viewer meets it: a WebSocket client
speaking the Foxglove protocol (subprotocol foxglove.sdk.v1, written here from the protocol:
JSON control messages, binary message data 0x01 = opcode, uint32 subscription id, uint64 log
time, payload; service call request 0x02 / response 0x03) subscribes, decodes the scene and
checks the rods against node_poses; the node goes on, and its log stays whole, when a viewer
is killed mid-run. ROS_DOMAIN_ID 217."""
from __future__ import annotations

import asyncio
import json
import os
import signal
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("foxglove")
websockets = pytest.importorskip("websockets")

from mcap.reader import make_reader  # noqa: E402
from rclpy.serialization import deserialize_message  # noqa: E402
from geometry_msgs.msg import PoseArray  # noqa: E402
from visualization_msgs.msg import MarkerArray  # noqa: E402

from procs import REPO  # noqa: E402

pytestmark = [pytest.mark.timeout(120)]
DOMAIN = 217
SUBPROTOCOL = "foxglove.sdk.v1"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


async def collect(port: int, want: set[str], timeout: float = 20.0, call=None):
    """Connect, subscribe to every channel, return {topic: [(log_time, payload), ...]} once
    each topic of ``want`` has a message at a time all of them share; ``call`` = (service,
    request dict): also call it and return its answer."""
    async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=[SUBPROTOCOL]) as ws:
        assert ws.subprotocol == SUBPROTOCOL
        channels, services, got, answer, called = {}, {}, {}, None, False
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            m = await asyncio.wait_for(ws.recv(), timeout)
            if isinstance(m, str):
                msg = json.loads(m)
                if msg["op"] == "advertise":
                    channels.update({c["id"]: c for c in msg["channels"]})
                    await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                        {"id": cid, "channelId": cid} for cid in channels]}))
                elif msg["op"] == "advertiseServices":
                    services.update({s["name"]: s["id"] for s in msg["services"]})
                continue
            if m[0] == 3:
                _, call_id, enc_len = struct.unpack_from("<III", m, 1)
                answer = json.loads(m[13 + enc_len:])
                if got and set.intersection(*(set(got.get(t, {})) for t in want)):
                    return channels, got, max(set.intersection(
                        *(set(got.get(t, {})) for t in want))), answer
                continue
            assert m[0] == 1, m[:1]
            sub, log_time = struct.unpack_from("<IQ", m, 1)
            got.setdefault(channels[sub]["topic"], {})[log_time] = m[13:]
            common = set.intersection(*(set(got.get(t, {})) for t in want))
            if common and call is not None and not called:     # after a frame: it may pause
                await ws.send(struct.pack("<BIII", 2, services[call[0]], 11, 4) + b"json"
                              + json.dumps(call[1]).encode())
                called = True
            if common and (call is None or answer is not None):
                return channels, got, max(common), answer
        raise AssertionError(f"no common frame of {want} in {timeout} s: {list(got)}")


def check_scene(markers: bytes, poses: bytes) -> int:
    """The rods of the markers (line strips, ns 'rods') run from node to node of node_poses
    (to 1e-9 m), the spheres sit on nodes 1..n; returns n."""
    scene = deserialize_message(markers, MarkerArray)
    nodes = np.array([[p.position.x, p.position.y, p.position.z]
                      for p in deserialize_message(poses, PoseArray).poses])
    strips = [m for m in scene.markers if m.ns == "rods"]
    spheres = [m for m in scene.markers if m.ns == "nodes"]
    assert len(spheres) == 1 and spheres[0].type == 7
    balls = np.array([[p.x, p.y, p.z] for p in spheres[0].points])
    np.testing.assert_allclose(balls, nodes[1:], rtol=0, atol=1e-9)
    n = len(nodes) - 1
    if len(strips) == 1 and strips[0].id == 0:          # long chains: one strip via the nodes
        pts = np.array([[p.x, p.y, p.z] for p in strips[0].points])
        np.testing.assert_allclose(pts, nodes, rtol=0, atol=1e-9)
        return n
    assert sorted(m.id for m in strips) == list(range(1, n + 1))
    for m in strips:
        pts = np.array([[p.x, p.y, p.z] for p in m.points])
        assert m.type == 4 and len(pts) >= 2
        np.testing.assert_allclose(pts[0], nodes[m.id - 1], rtol=0, atol=1e-9)
        np.testing.assert_allclose(pts[-1], nodes[m.id], rtol=0, atol=1e-9)
        chord = nodes[m.id] - nodes[m.id - 1]
        # bent, not straight, but close to its chord (small bending)
        rel = pts[:, :2] - nodes[m.id - 1][:2]          # z of chord x rel (2-D cross)
        off = (chord[0] * rel[:, 1] - chord[1] * rel[:, 0]) / np.linalg.norm(chord)
        assert np.max(np.abs(off)) < 0.1 * np.linalg.norm(chord)
    return n


def test_live_view_serves_the_same_bytes_and_a_consistent_scene():
    """No ROS: the view fed with encoded snapshots; a client decodes the scene."""
    sys.path.insert(0, str(Path(__file__).parent))
    from test_encoders import make_scene, make_snapshot

    from rod_sim.io import encoders
    from rod_sim.io.live_view import LiveView

    scene = make_scene(6)
    snap = make_snapshot(scene, seed=5)
    sent = {name: encoders.SNAPSHOT_ENCODERS[name](snap, scene, "world")
            for name in ("markers", "joint_states", "node_poses")}
    view = LiveView(0, services={"pause": lambda req: (True, f"paused {req['data']}")})
    try:
        assert not view.wanted(), "no client: no frame is built"
        import threading
        stop = threading.Event()

        def feed():
            k = 0
            while not stop.is_set():
                if view.wanted():
                    view.send(1_000_000 * k, sent, snap.nodes, snap.phi, {
                        "energy": 1.5, "energy_residual": 0.0, "rtf": 1.0,
                        "max_abs_alpha": 0.01, "max_abs_beta": 0.02})
                k += 1
                time.sleep(0.002)
        thread = threading.Thread(target=feed, daemon=True)
        thread.start()
        channels, got, t, answer = asyncio.run(collect(
            view.port, {"/markers", "/node_poses", "/joint_states", "/tf", "/rod_sim/series"},
            call=("pause", {"data": True})))
        stop.set()
        thread.join()
    finally:
        view.close()
    kinds = {c["topic"]: (c["encoding"], c["schemaName"]) for c in channels.values()}
    assert kinds["/markers"] == ("cdr", "visualization_msgs/msg/MarkerArray")
    assert kinds["/tf"] == ("protobuf", "foxglove.FrameTransforms")
    for name in sent:
        assert got[f"/{name}"][t] == sent[name], name      # the very bytes
    assert check_scene(got["/markers"][t], got["/node_poses"][t]) == 6
    series = json.loads(got["/rod_sim/series"][t])
    assert series["energy"] == 1.5 and series["t"] == t / 1e9
    assert answer == {"success": True, "message": "paused True"}


VIEWER = r"""
import asyncio, json, sys, websockets
async def main(port):
    async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"]) as ws:
        while True:
            m = await ws.recv()
            if isinstance(m, str) and json.loads(m)["op"] == "advertise":
                ids = [c["id"] for c in json.loads(m)["channels"]]
                await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                    {"id": i, "channelId": i} for i in ids]}))
            elif isinstance(m, bytes):
                print("frame", flush=True)
asyncio.run(main(int(sys.argv[1])))
"""


@pytest.mark.ros
def test_node_live_view_scene_services_and_a_killed_viewer(tmp_path):
    port = free_port()
    log = tmp_path / "run.mcap"
    env = dict(os.environ, ROS_DOMAIN_ID=str(DOMAIN), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    node = subprocess.Popen(
        [sys.executable, "-m", "rod_sim.ros.node", "--ros-args",
         "-p", f"scene_file:={REPO / 'config' / 'paper_example.yaml'}",
         "-p", f"live_view_port:={port}", "-p", f"record_path:={log}",
         "-r", f"__ns:=/t{os.getpid()}_live"],
        cwd=REPO, env=env, stderr=subprocess.PIPE, text=True)
    try:
        started = time.monotonic()
        for line in node.stderr:
            if "live view on" in line:
                break
            assert time.monotonic() - started < 60, "no live view line"
        else:
            raise AssertionError(f"node exited: {node.wait()}")
        # a viewer that subscribes to everything, killed while frames flow
        viewer = subprocess.Popen([sys.executable, "-c", VIEWER, str(port)], env=env,
                                  stdout=subprocess.PIPE, text=True)
        assert viewer.stdout.readline().startswith("frame")
        viewer.send_signal(signal.SIGKILL)
        viewer.wait(10)
        _, got, t1, _ = asyncio.run(collect(port, {"/markers", "/node_poses"}))
        assert check_scene(got["/markers"][t1], got["/node_poses"][t1]) == 8
        time.sleep(0.5)
        _, got, t2, answer = asyncio.run(collect(port, {"/node_poses"},
                                                 call=("pause", {"data": True})))
        assert t2 > t1, "the node stopped after the viewer was killed"
        assert answer["success"] and answer["message"].startswith("paused at t = "), answer
    finally:
        node.send_signal(signal.SIGINT)
        assert node.wait(30) == 0
    with open(log, "rb") as f:              # whole: summary and every period's state
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics.message_count > 0
        stamps = [m.log_time for _, c, m in reader.iter_messages()
                  if c.topic.endswith("/rod_states")]
    assert stamps == [k * 10_000_000 for k in range(len(stamps))]
    assert stamps[-1] >= t2


def test_simulate_live_view_shows_the_run_and_logs_the_same_bytes(tmp_path):
    port = free_port()
    scene = REPO / "config" / "paper_example.yaml"
    args = [sys.executable, "-m", "rod_sim.tools.cli", "simulate", str(scene), "--t-end", "1.5"]
    plain = subprocess.run([*args, "--out", str(tmp_path / "plain.mcap")], cwd=REPO,
                           capture_output=True, text=True, timeout=120)
    assert plain.returncode == 0, plain.stderr
    shown = subprocess.Popen([*args, "--out", str(tmp_path / "shown.mcap"), "--live-view",
                              str(port), "--real-time-factor", "1"], cwd=REPO,
                             stderr=subprocess.PIPE, text=True)
    try:
        for line in shown.stderr:
            if "live view on" in line:
                break
        _, got, t, _ = asyncio.run(collect(port, {"/markers", "/node_poses", "/tf"}))
        assert check_scene(got["/markers"][t], got["/node_poses"][t]) == 8
    finally:
        assert shown.wait(60) == 0
    assert (tmp_path / "shown.mcap").read_bytes() == (tmp_path / "plain.mcap").read_bytes()


def test_frame_transforms_are_the_sdks_encoding():
    """/tf from numpy: the SDK's own protobuf bytes for nonzero values; with zeros (node 0 at
    the origin, which the SDK omits) the same message for a protobuf decoder."""
    from foxglove import messages as m
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    from rod_sim.io.live_view import frame_transforms

    def sdk(t_ns, nodes, phi):
        half = 0.5 * np.concatenate([phi[:1], phi])
        return m.FrameTransforms(transforms=[m.FrameTransform(
            timestamp=m.Timestamp(sec=t_ns // 10**9, nsec=t_ns % 10**9),
            parent_frame_id="base", child_frame_id=f"node_{k}",
            translation=m.Vector3(x=float(x), y=float(y), z=0.0),
            rotation=m.Quaternion(x=0.0, y=0.0, z=float(np.sin(h)), w=float(np.cos(h))))
            for k, ((x, y), h) in enumerate(zip(nodes, half))]).encode()

    rng = np.random.default_rng(7)
    for n, t_ns in ((1, 0), (5, 7), (300, 3_000_000_007)):
        nodes, phi = rng.normal(size=(n + 1, 2)), rng.normal(size=n)
        assert frame_transforms(t_ns, "base", nodes, phi) == sdk(t_ns, nodes, phi)
    nodes[0] = 0.0
    files = descriptor_pb2.FileDescriptorSet.FromString(m.FrameTransforms.get_schema().data)
    pool = descriptor_pool.DescriptorPool()
    for f in files.file:
        pool.Add(f)
    cls = message_factory.GetMessageClass(pool.FindMessageTypeByName("foxglove.FrameTransforms"))
    ours = cls.FromString(frame_transforms(5, "base", nodes, phi))
    assert ours == cls.FromString(sdk(5, nodes, phi)) and len(ours.transforms) == 301
