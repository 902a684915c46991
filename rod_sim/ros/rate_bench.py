"""Rate, real-time factor and jitter of the node as an outside subscriber sees them.

    python -m rod_sim.ros.rate_bench --rate 1000 --duration 10
    python -m rod_sim.ros.rate_bench --rods 128 --rate 100 --duration 10 --json
    python -m rod_sim.ros.rate_bench --lockstep 5000 --record --keep-log out/lockstep.mcap
    python -m rod_sim.ros.rate_bench --spacecraft --rate 100 --record

The node runs in its own process (``python -m rod_sim.ros.node``, real-time pace, the reduced
model by default); this process subscribes to ``rod_states`` and time-stamps every message on
arrival with a monotonic clock. After a warm-up (JIT load, discovery) the window of
``--duration`` wall seconds gives:

- ``rate_hz``: messages per wall second;
- ``rtf``: simulated time advanced (header stamps) per wall second of arrivals;
- inter-arrival times [ms]: median, p99 and max; ``missing``: control periods whose states never
  arrived (gaps in the header stamps: messages lost between the node and this subscriber, whose
  reader and the node's writer keep 10 each; the node simulates every period it does not drop,
  so its stamps have no gaps of their own);
- ``node_dropped_periods``: periods of backlog the node dropped in the window (it could not
  catch up with real time; its simulated time then falls behind), from its ``/diagnostics``;
- ``node_cpu_fraction``: CPU time of the node process and its log writer process
  (:mod:`rod_sim.io.log_process`) per wall second (Linux /proc): the node's whole cost, in
  cores; ``node_main_thread_cpu_fraction``: its main (Python) thread's, which runs the
  periods and must fit in one core.

With ``--lockstep K`` the node runs in lockstep (``sync_mode``) instead and this process is
its controller in another process: on each ``rod_states`` (taken as serialized bytes) it
publishes the next ``nodal_forces`` command (a fixed function of the step number, so that two
runs get the same inputs), K round trips (command -> period -> states) after the t = 0 state;
it reports round trips per wall second, the node process's CPU time per round trip (the
figure a loaded machine disturbs least), its main thread's, and this controller's own.
``--keep-log`` keeps the node's log (``--record``); ``--node-pythonpath`` runs the node from
another source tree (e.g. to compare the logs of two versions for the same inputs).

``--spacecraft`` runs two chains of ``--rods`` rods each (default 512) on a free base instead
(:func:`rod_sim.bench.spacecraft.two_chain_scene`: the base turning, the chains bent and
moving), the case of issue 28: 2 x 512 rods at 100 Hz with recording.

With ``--period-cost K`` no ROS graph is started: this process builds the node's simulation
from the same settings (:mod:`rod_sim.ros.simulation`) and runs K control periods through the
node's own parts (``PeriodRunner.run``, the output table's encoders, the recording with
``--record``), the held inputs changing every period (``lockstep_force``, as a lockstep
controller sends them) or, with ``--held-constant``, zero; it reports CPU time per period
[ms] (the minimum of three rounds of K/3): the integration alone (``Simulator.advance``, one
drive per period), the period (integration as the node's real-time mode does it: with inputs
held, several periods per drive, :mod:`rod_sim.core.ahead`; snapshot, energy ledger,
validity) and the period with its outputs (what the node does per period besides the executor
and DDS). It runs in this process, on the code this process imports: to measure
another tree, run it from inside that tree (``python -m`` puts the current directory first on
``sys.path``, before ``PYTHONPATH``). ``--rtol`` sets the node's ``rtol`` parameter (every mode). CPU time is what a loaded machine
disturbs least.

Before and after each run this process times :mod:`rod_sim.bench.yardstick` (a pure-Python
loop, small numpy calls, a compiled right-hand side of 1024 rods; ~1 s each) and reports both
with the figures (``yardstick`` {``before``, ``after``} in the JSON, two more lines
otherwise): this machine's speed swings 2-3x from hour to hour, and figures of different
hours compare only beside it. ``--no-yardstick`` skips it.

This process (the subscriber, or the lockstep controller) takes its messages with
``--bench-executor``: ``bare`` (default: :class:`BareTaker`, one rcl wait set and the
subscriptions' own take, no executor: the least a Python subscriber spends per message),
``lean`` (:class:`~rod_sim.ros.executor.LeanExecutor`, as ``rod-sim controller`` spins) or
``rclpy`` (rclpy's ``SingleThreadedExecutor``). Its own CPU is reported too
(``bench_cpu_fraction``, ``controller_cpu_ms_per_round_trip``): on 2 cores it competes with
the node it measures (docs/bench.md, "The bench's own subscriber and controller").

``ROS_AUTOMATIC_DISCOVERY_RANGE`` is LOCALHOST and ``ROS_DOMAIN_ID`` is ``--domain`` (default
226) for both processes: nothing leaves the machine.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from rod_sim.bench import yardstick

REPO = Path(__file__).resolve().parents[2]
DEFAULT_SCENE = REPO / "config" / "paper_example.yaml"


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m rod_sim.ros.rate_bench", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scene", default=str(DEFAULT_SCENE), help="scene YAML (default: the paper's example)")
    p.add_argument("--rods", type=int, default=None,
                   help="override the number of rods (same per-rod properties and loads)")
    p.add_argument("--spacecraft", action="store_true",
                   help="two chains of --rods rods each (default 512) on a free base")
    p.add_argument("--model", default="reduced", choices=("reduced", "full", "rigid"))
    p.add_argument("--rate", type=float, default=1000.0, help="node rate_hz [Hz]")
    p.add_argument("--rtol", type=float, default=None,
                   help="the node's rtol parameter (default: the node's default, 1e-8)")
    p.add_argument("--duration", type=float, default=10.0, help="measured wall window [s]")
    p.add_argument("--warmup", type=float, default=3.0, help="wall seconds ignored first")
    p.add_argument("--record", action="store_true", help="let the node record an MCAP log too")
    p.add_argument("--domain", type=int, default=226,
                   help="ROS_DOMAIN_ID of both processes (FastDDS allows 0..232)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--live-view", action="store_true",
                   help="give the node a live view (live_view_port) with a client connected "
                        "that subscribes to every channel for the whole run")
    p.add_argument("--lockstep", type=int, default=0, metavar="K",
                   help="lockstep: K command/state round trips with this process as controller")
    p.add_argument("--keep-log", type=Path, default=None,
                   help="copy the node's log here (with --record)")
    p.add_argument("--node-pythonpath", default=None,
                   help="PYTHONPATH of the node process (default: this process's)")
    p.add_argument("--period-cost", type=int, default=0, metavar="K",
                   help="no ROS: CPU per control period of the node's parts over K periods")
    p.add_argument("--held-constant", action="store_true",
                   help="with --period-cost: zero held inputs instead of a new command each "
                        "period")
    p.add_argument("--bench-executor", choices=BENCH_EXECUTORS, default=BENCH_EXECUTORS[0],
                   help="how this process (subscriber or lockstep controller) takes its "
                        "messages: a bare wait set (default), rod_sim's LeanExecutor or "
                        "rclpy's SingleThreadedExecutor")
    p.add_argument("--no-yardstick", dest="yardstick", action="store_false",
                   help="do not time the machine's yardstick (rod_sim.bench.yardstick) before "
                        "and after the run")
    return p


def scene_file(args, tmp: Path) -> Path:
    """The scene to run: ``--scene`` itself, or a copy with ``--rods`` rods, or with
    ``--spacecraft`` two chains of ``--rods`` (512) rods on a free base."""
    from rod_sim.io.scene_yaml import load_scene, scene_to_yaml
    from rod_sim.core.scene import Scene

    if args.spacecraft:
        from rod_sim.bench.spacecraft import two_chain_scene

        scene = two_chain_scene(args.rods or 512)
        path = tmp / f"{scene.name}.yaml"
        path.write_text(scene_to_yaml(scene))
        return path
    if args.rods is None:
        return Path(args.scene)

    data = load_scene(args.scene).to_dict()
    n_old = data["rods"]["count"]
    data["rods"]["count"] = args.rods
    for section in ("rods", "nodes", "hinges"):
        for key, value in data[section].items():
            if isinstance(value, list) and len(value) == n_old:
                data[section][key] = [value[0]] * args.rods
    data.pop("initial", None)
    for load in data.get("loads", []):
        load["node"] = args.rods if load["node"] == n_old else min(load["node"], args.rods)
    data["name"] = f"{data.get('name', 'scene')}_n{args.rods}"
    path = tmp / f"{data['name']}.yaml"
    path.write_text(scene_to_yaml(Scene.from_dict(data)))
    return path


def ros_arg(value) -> str:
    """A parameter value as written after ``-p name:=`` (YAML)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return value if value else "''"
    return repr(value)


def _stat_cpu(path: Path) -> tuple[int, float]:
    """(parent pid, CPU time [s] user + system) from a /proc ``stat`` file of a process or a
    thread."""
    fields = path.read_text().rsplit(")", 1)[1].split()
    return int(fields[1]), (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def process_cpu_s(pid: int) -> float | None:
    """CPU time [s] (user + system) used so far by process ``pid`` and its live children (the
    node's log writer, :mod:`rod_sim.io.log_process`); None where /proc is absent."""
    try:
        _, total = _stat_cpu(Path(f"/proc/{pid}/stat"))
    except OSError:
        return None
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit() and entry.name != str(pid):
            try:
                parent, cpu = _stat_cpu(entry / "stat")
            except (OSError, IndexError, ValueError):
                continue        # gone meanwhile
            if parent == pid:
                total += cpu
    return total


def main_thread_cpu_s(pid: int) -> float | None:
    """CPU time [s] (user + system) used so far by the main thread of process ``pid`` (the
    node's Python thread, which runs its periods); None where /proc is absent."""
    try:
        return _stat_cpu(Path(f"/proc/{pid}/task/{pid}/stat"))[1]
    except OSError:
        return None


def summarize(wall_ns: np.ndarray, stamp_ns: np.ndarray, rate_hz: float) -> dict:
    """Statistics of arrivals: wall arrival times and header stamps [ns], both (N,)."""
    dt_wall = np.diff(wall_ns) / 1e6
    period_ns = 1e9 / rate_hz
    gaps = np.round(np.diff(stamp_ns) / period_ns).astype(int)
    span_wall = (wall_ns[-1] - wall_ns[0]) / 1e9
    return {"messages": int(wall_ns.size),
            "rate_hz": (wall_ns.size - 1) / span_wall,
            "rtf": (stamp_ns[-1] - stamp_ns[0]) / 1e9 / span_wall,
            "interarrival_ms": {"median": float(np.median(dt_wall)),
                                "p99": float(np.percentile(dt_wall, 99)),
                                "max": float(dt_wall.max())},
            "missing_periods": int(np.sum(np.maximum(gaps - 1, 0))),
            "expected_period_ms": period_ns / 1e6}


STAMP = struct.Struct("<iI")
"""A std_msgs/Header's stamp (sec, nanosec) after the 4-byte CDR encapsulation header."""


def dropped_in_window(reports: list[tuple[float, int]], start: float) -> int | None:
    """Periods the node dropped (it could not catch up its backlog) during the window that
    starts at ``start`` [s, monotonic], from its ``/diagnostics`` reports (receipt time [s],
    ``dropped_periods`` total so far): the last total less the last one before ``start`` (0
    when none came before it). None without a report inside the window."""
    before = [total for t, total in reports if t < start]
    inside = [total for t, total in reports if t >= start]
    if not inside:
        return None
    return inside[-1] - (before[-1] if before else 0)


def free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class ViewerClient:
    """A Foxglove-protocol WebSocket client in a thread: connects to ``port`` (retrying while
    the node starts), subscribes to every channel and counts the frames it receives."""

    def __init__(self, port: int):
        import threading

        self.port, self.frames, self._stop = port, 0, threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        import asyncio

        asyncio.run(self._main())

    async def _main(self) -> None:
        import asyncio

        import websockets

        while not self._stop.is_set():
            try:
                async with websockets.connect(f"ws://127.0.0.1:{self.port}",
                                              subprotocols=["foxglove.sdk.v1"]) as ws:
                    while not self._stop.is_set():
                        try:
                            m = await asyncio.wait_for(ws.recv(), 0.2)
                        except asyncio.TimeoutError:
                            continue
                        if isinstance(m, str):
                            msg = json.loads(m)
                            if msg["op"] == "advertise":
                                await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                                    {"id": c["id"], "channelId": c["id"]}
                                    for c in msg["channels"]]}))
                        else:
                            self.frames += 1
                    return
            except OSError:
                await asyncio.sleep(0.2)

    def stop(self) -> int:
        self._stop.set()
        self._thread.join(5)
        return self.frames


def lockstep_force(k: int, n: int) -> np.ndarray:
    """The command of round trip ``k`` (n, 2) [N]: small, smooth, the same in every run."""
    j = np.arange(n)
    out = np.zeros((n, 2))
    out[:, 0] = 0.01 * np.sin(0.01 * k + j)
    out[:, 1] = 0.01 * np.cos(0.013 * k - j)
    return out


BENCH_EXECUTORS = ("bare", "lean", "rclpy")


class BareTaker:
    """The subscriptions of the nodes added, served without an executor: per ``spin_once``
    one rcl wait set of them, then every ready subscription's messages taken and given to
    its callback (serialized bytes for ``raw=True``). No timer, service, guard condition or
    event is served. Subscriptions created after :meth:`add_node` are served too."""

    def __init__(self) -> None:
        self.nodes: list = []
        self._wait_set = None
        self._subs: tuple = ()

    def add_node(self, node) -> None:
        self.nodes.append(node)

    def spin_once(self, timeout_sec: float) -> None:
        subs = tuple(s for node in self.nodes for s in node.subscriptions)
        if subs != self._subs or self._wait_set is None:
            from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

            self._subs = subs
            self._wait_set = _rclpy.WaitSet(len(subs), 0, 0, 0, 0, 0,
                                            self.nodes[0].context.handle)
        wait_set = self._wait_set
        wait_set.clear_entities()
        for sub in subs:
            wait_set.add_subscription(sub.handle)
        wait_set.wait(round(timeout_sec * 1e9))
        ready = wait_set.get_ready_entities("subscription")
        for sub in subs:
            if sub.handle.pointer in ready:
                taken = sub.handle.take_message(sub.msg_type, sub.raw)
                if taken is not None:
                    sub.callback(taken[0])

    def shutdown(self) -> None:
        self.nodes.clear()


def bench_executor(args):
    """What this process spins (``--bench-executor``)."""
    if args.bench_executor == "rclpy":
        from rclpy.executors import SingleThreadedExecutor

        return SingleThreadedExecutor()
    if args.bench_executor == "lean":
        from rod_sim.ros.executor import LeanExecutor

        return LeanExecutor()
    return BareTaker()


def _node_process(args, params: dict) -> subprocess.Popen:
    cmd = [sys.executable, *os.environ.get("ROD_SIM_BENCH_NODE", "-m rod_sim.ros.node").split(),
           "--ros-args"]
    for key, value in params.items():
        cmd += ["-p", f"{key}:={ros_arg(value)}"]
    env = dict(os.environ)
    if args.node_pythonpath:
        env["PYTHONPATH"] = args.node_pythonpath
    return subprocess.Popen(cmd, cwd=args.node_pythonpath or REPO, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, env=env)


def _stop(node_proc: subprocess.Popen) -> None:
    node_proc.terminate()
    try:
        node_proc.wait(timeout=30)
    except subprocess.TimeoutExpired:
        node_proc.kill()


def measure_lockstep(args) -> dict:
    """Round trips per second of a lockstep node with this process as its controller."""
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ["ROS_DOMAIN_ID"] = str(args.domain)
    import rclpy
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray

    from rod_sim.io.encoders import force_array
    from rod_sim.ros.qos import COMMAND_QOS, LOCKSTEP_STATE_QOS

    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        scene = scene_file(args, tmp)
        from rod_sim.io.scene_yaml import load_scene
        n = load_scene(scene).n
        period_ns = round(1e9 / args.rate)
        log = tmp / "lockstep.mcap"
        params = {"scene_file": str(scene), "model": args.model, "rate_hz": float(args.rate),
                  "sync_mode": True, "publish_clock": False,
                  "record_path": str(log) if args.record else ""}
        if args.rtol is not None:
            params["rtol"] = float(args.rtol)
        node_proc = _node_process(args, params)
        commands = [force_array(lockstep_force(k, n)) for k in range(args.lockstep)]
        rclpy.init()
        sent = [0]
        times: list[int] = []
        cpu0: list[float | None] = [None]
        main0: list[float | None] = [None]
        own0 = [0.0]
        try:
            node = rclpy.create_node("rate_bench_controller")
            pub = node.create_publisher(Float64MultiArray, "nodal_forces", COMMAND_QOS)

            def on_state(data: bytes) -> None:
                sec, nanosec = np.frombuffer(data, dtype="<u4", count=2, offset=4)
                k = sent[0]
                if int(sec) * 1_000_000_000 + int(nanosec) != k * period_ns or k >= len(commands):
                    return          # a repeated waiting state, or the last one
                if k == 0 and pub.get_subscription_count() == 0:
                    return          # the node's command subscription is not matched yet: the
                                    # waiting state comes again in 0.5 s
                times.append(time.perf_counter_ns())
                if k == 0:
                    cpu0[0] = process_cpu_s(node_proc.pid)
                    main0[0] = main_thread_cpu_s(node_proc.pid)
                    own0[0] = time.process_time()
                sent[0] = k + 1
                pub.publish(commands[k])

            node.create_subscription(JointState, "rod_states", on_state, LOCKSTEP_STATE_QOS,
                                     raw=True)
            executor = bench_executor(args)
            executor.add_node(node)
            deadline = time.monotonic() + 120.0
            while sent[0] < len(commands) and time.monotonic() < deadline:
                if node_proc.poll() is not None:
                    raise RuntimeError(f"node exited: {node_proc.stderr.read().strip()}")
                executor.spin_once(timeout_sec=0.1)
            done = sent[0]
            # the last command's period: wait for its state (stamp K periods)
            last = [False]
            node.create_subscription(JointState, "rod_states", lambda d: last.__setitem__(
                0, int.from_bytes(d[4:8], "little") * 1_000_000_000
                + int.from_bytes(d[8:12], "little") == done * period_ns), LOCKSTEP_STATE_QOS,
                raw=True)
            while not last[0] and time.monotonic() < deadline:
                executor.spin_once(timeout_sec=0.1)
            end = time.perf_counter_ns()
            own1 = time.process_time()
            cpu1 = process_cpu_s(node_proc.pid)
            main1 = main_thread_cpu_s(node_proc.pid)
            executor.shutdown()
            node.destroy_node()
        finally:
            rclpy.try_shutdown()
            _stop(node_proc)
        if args.keep_log is not None and args.record:
            args.keep_log.parent.mkdir(parents=True, exist_ok=True)
            args.keep_log.write_bytes(log.read_bytes())
    span = (end - times[0]) / 1e9 if times else float("nan")
    cpu = (cpu1 - cpu0[0]) if cpu0[0] is not None and cpu1 is not None else float("nan")
    main = (main1 - main0[0]) if main0[0] is not None and main1 is not None else float("nan")
    per_trip = (lambda seconds: 1e3 * seconds / done if done else float("nan"))
    return {"n": n, "model": args.model, "rate_hz_set": args.rate, "record": args.record,
            "round_trips": done, "round_trips_per_s": done / span if times else 0.0,
            "node_cpu_ms_per_round_trip": per_trip(cpu),
            "node_main_thread_ms_per_round_trip": per_trip(main),
            "controller_cpu_ms_per_round_trip": per_trip(own1 - own0[0]) if times
            else float("nan"),
            "controller_executor": args.bench_executor,
            "complete": bool(last[0] and done == len(commands))}


def measure(args) -> dict:
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ["ROS_DOMAIN_ID"] = str(args.domain)
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from sensor_msgs.msg import JointState

    from rod_sim.io.scene_yaml import load_scene
    from rod_sim.ros.qos import keep_last

    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        scene = scene_file(args, tmp)
        scene_name, n = scene.stem, load_scene(scene).n
        params = {"scene_file": str(scene), "model": args.model, "rate_hz": float(args.rate),
                  "real_time_factor": 1.0, "sync_mode": False, "publish_clock": True,
                  "record_path": str(tmp / "bench.mcap") if args.record else ""}
        if args.rtol is not None:
            params["rtol"] = float(args.rtol)
        viewer = None
        if args.live_view:
            params["live_view_port"] = free_port()
            viewer = ViewerClient(params["live_view_port"])
        node_proc = _node_process(args, params)
        rclpy.init()
        wall, stamps = [], []
        try:
            node = rclpy.create_node("rate_bench_subscriber")

            def on_state(data: bytes):
                # serialized: the stamp is all this needs (decoding 1024 names per message
                # took a third of a core at 1 kHz, beside the node it measures)
                wall.append(time.perf_counter_ns())
                sec, nanosec = STAMP.unpack_from(data, 4)
                stamps.append(sec * 1_000_000_000 + nanosec)

            node.create_subscription(JointState, "rod_states", on_state, keep_last(10),
                                     raw=True)
            reports: list[tuple[float, int]] = []     # the node's dropped periods, as reported

            def on_diagnostics(msg):
                for status in msg.status:
                    for kv in status.values:
                        if kv.key == "dropped_periods" and kv.value.isdigit():
                            reports.append((time.monotonic(), int(kv.value)))

            node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics,
                                     keep_last(10))
            executor = bench_executor(args)
            executor.add_node(node)
            deadline = time.monotonic() + 60.0
            while not wall and time.monotonic() < deadline:
                if node_proc.poll() is not None:
                    raise RuntimeError(f"node exited: {node_proc.stderr.read().strip()}")
                executor.spin_once(timeout_sec=0.1)
            if not wall:
                raise RuntimeError("no rod_states within 60 s")
            start = time.monotonic()
            first_kept = cpu0 = main0 = None
            while time.monotonic() < start + args.warmup + args.duration:
                executor.spin_once(timeout_sec=0.05)
                if first_kept is None and time.monotonic() >= start + args.warmup:
                    main0 = main_thread_cpu_s(node_proc.pid)
                    first_kept, cpu0 = len(wall), process_cpu_s(node_proc.pid)
                    own0 = time.process_time()
            main1, cpu1 = main_thread_cpu_s(node_proc.pid), process_cpu_s(node_proc.pid)
            own1 = time.process_time()
            if viewer is not None:
                viewer_frames = viewer.stop()
            executor.shutdown()
            node.destroy_node()
        finally:
            rclpy.try_shutdown()
            node_proc.terminate()
            try:
                node_proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                node_proc.kill()
        result = summarize(np.array(wall[first_kept:], dtype=np.int64),
                           np.array(stamps[first_kept:], dtype=np.int64), args.rate)
    if cpu0 is not None and cpu1 is not None:
        result["node_cpu_fraction"] = (cpu1 - cpu0) / args.duration
    if main0 is not None and main1 is not None:
        result["node_main_thread_cpu_fraction"] = (main1 - main0) / args.duration
    if first_kept is not None:
        result["bench_cpu_fraction"] = (own1 - own0) / args.duration
    result["bench_executor"] = args.bench_executor
    result["node_dropped_periods"] = dropped_in_window(reports, start + args.warmup)
    if args.live_view:
        result["viewer_frames"] = viewer_frames
    result.update({"scene": Path(args.scene).name if not args.spacecraft else scene_name,
                   "n": n,
                   "model": args.model, "rate_hz_set": args.rate, "record": args.record,
                   "window_s": args.duration})
    return result


def measure_period_cost(args) -> dict:
    """CPU [ms] per control period of the node's parts, without ROS (``--period-cost``)."""
    import logging

    from rod_sim.ros import simulation
    from rod_sim.ros.outputs import (IDLE_CLOCK_PERIOD_S, OUTPUTS, Outputs, SimClock,
                                     rate_dividers)
    from rod_sim.ros.parameters import PARAMETERS, NodeSettings
    from rod_sim.ros.recording import NodeRecording, node_log_opener
    from rod_sim.ros.stepper import Stepper

    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        values = {spec.name: spec.default for spec in PARAMETERS}
        values.update(scene_file=str(scene_file(args, tmp)), model=args.model,
                      rate_hz=float(args.rate),
                      record_path=str(tmp / "cost.mcap") if args.record else "")
        if args.rtol is not None:
            values["rtol"] = float(args.rtol)
        settings = NodeSettings(**values)
        built = simulation.build(settings, "/rod_sim", ())
        period = simulation.start(built, settings)
        sim, model, n = built.sim, built.model, built.scene.n
        names = {o.name: "/" + o.name for o in OUTPUTS}
        recording = NodeRecording(node_log_opener(
            built.scene, model.name, sim.integrator.describe(), settings, lambda: "lockstep",
            "/rod_sim", names), logging.getLogger("rate_bench"))
        recording.start(Path(settings.record_path) if settings.record_path else None)
        outputs = Outputs(built.scene, names, {}, recording, built.period_ns, "world",
                          rate_dividers(settings))
        # the node's period with its outputs (no publishers: recorded only; no /clock)
        stepper = Stepper(period, outputs, SimClock(None, IDLE_CLOCK_PERIOD_S))
        k_all = max(3, args.period_cost)
        commands = [np.zeros((n, 2)) if args.held_constant else lockstep_force(k, n)
                    for k in range(k_all + 10)]

        def with_outputs(k: int) -> None:
            stepper.run(commands[k])

        def bare(k: int) -> None:
            period.run(commands[k])

        def integration(k: int) -> None:
            sim.advance(built.period_ns / 1e9)

        for k in range(10):
            with_outputs(k)
        per_round = k_all // 3
        best = {}
        for _ in range(3):
            for name, step in (("integration", integration), ("period", bare),
                               ("period_with_outputs", with_outputs)):
                start = time.process_time()
                for k in range(per_round):
                    step(10 + k)
                cost = (time.process_time() - start) / per_round * 1e3
                best[name] = min(best.get(name, math.inf), cost)
        recording.close()
    return {"n": n, "model": args.model, "rate_hz_set": args.rate, "record": args.record,
            "held": "constant" if args.held_constant else "changing every period",
            "periods": per_round, **{f"{k}_ms": v for k, v in best.items()}}


def _count(value: int | None) -> str:
    return "?" if value is None else str(value)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    before = yardstick.measure() if args.yardstick else None

    def report(result: dict, line: str) -> None:
        """The result as JSON (with the yardstick) or as its line (then the yardstick's)."""
        stick = None
        if before is not None:
            stick = result["yardstick"] = {"before": before, "after": yardstick.measure()}
        print(json.dumps(result, indent=1) if args.json else line + (
            "" if stick is None else "".join(f"\n{when} the run: {yardstick.describe(v)}"
                                             for when, v in stick.items())))

    if args.period_cost:
        result = measure_period_cost(args)
        report(result,
               f"n = {result['n']} {result['model']}, {args.rate:g} Hz, held {result['held']}"
               f"{', recording' if args.record else ''}: CPU per period: integration "
               f"{result['integration_ms']:.3f} ms, period {result['period_ms']:.3f} ms, with "
               f"outputs {result['period_with_outputs_ms']:.3f} ms (min of 3 x "
               f"{result['periods']})")
        return 0
    if args.lockstep:
        result = measure_lockstep(args)
        report(result,
               f"n = {result['n']} {result['model']}, lockstep at rate_hz {args.rate:g}"
               f"{' + recording' if args.record else ''}: {result['round_trips']} round trips, "
               f"{result['round_trips_per_s']:.0f} per second, node CPU "
               f"{result['node_cpu_ms_per_round_trip']:.3f} ms per round trip (main thread "
               f"{result['node_main_thread_ms_per_round_trip']:.3f} ms; this controller, "
               f"{result['controller_executor']} executor: "
               f"{result['controller_cpu_ms_per_round_trip']:.3f} ms)"
               + ("" if result["complete"] else " (INCOMPLETE)"))
        return 0 if result["complete"] else 1
    result = measure(args)
    ia = result["interarrival_ms"]
    report(result,
           f"n = {result['n']} {result['model']}, rate_hz {args.rate:g}"
           f"{' + recording' if args.record else ''}: {result['rate_hz']:.1f} msg/s, "
           f"RTF {result['rtf']:.3f}, inter-arrival median {ia['median']:.3f} ms, "
           f"p99 {ia['p99']:.3f} ms, max {ia['max']:.2f} ms, "
           f"{result['missing_periods']} missing periods of {result['messages']} at the "
           f"subscriber, {_count(result['node_dropped_periods'])} dropped by the node, "
           f"node CPU {100 * result.get('node_cpu_fraction', float('nan')):.0f}% of a core "
           f"(main thread "
           f"{100 * result.get('node_main_thread_cpu_fraction', float('nan')):.0f}%; this "
           f"subscriber, {result['bench_executor']} executor: "
           f"{100 * result.get('bench_cpu_fraction', float('nan')):.0f}%)"
           + (f", live view: {result['viewer_frames']} frames received"
              if args.live_view else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
