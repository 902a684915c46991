"""A live view of the chain for pip-only users: a Foxglove WebSocket server (``foxglove-sdk``).

Opt-in (the node's ``live_view_port``, ``rod-sim simulate/replay --live-view PORT``): the
Foxglove app or Lichtblick connects to ``ws://HOST:PORT`` (subprotocol ``foxglove.sdk.v1``;
the SDK's server runs on its own threads). Channels:

- ``/markers`` (visualization_msgs/msg/MarkerArray, CDR), ``/joint_states``
  (sensor_msgs/msg/JointState), ``/node_poses`` (geometry_msgs/msg/PoseArray): the very bytes
  the node publishes and records (:mod:`rod_sim.io.encoders`) -- the 3-D scene: each rod a
  line strip through its bent shape (the shape functions of eq. (1); for chains of more than
  256 rods one strip through the nodes), the node masses as spheres;
- ``/tf`` (foxglove.FrameTransforms, protobuf): ``FRAME -> node_k`` for nodes 0..n, encoded
  with numpy (:func:`frame_transforms`: the SDK's bytes, 0.34 ms at n = 1024 against 3.8 ms
  through its message objects);
- ``/rod_sim/series`` (JSON): ``t``, ``energy``, ``energy_residual``, ``rtf``,
  ``max_abs_alpha``, ``max_abs_beta`` for the plot panel.

Cost: nothing is built unless a client subscribes to a channel, and frames go out at most
:data:`MAX_FRAME_HZ` per wall second. ``log`` only queues: a slow client loses old frames (the
SDK's per-client backlog), one that connects or disconnects never blocks the caller.

Services (``pause``, ``step``, ``reset``; JSON request ``{"data": bool}`` for pause, answer
``{"success", "message"}``): the SDK calls them on its own thread; ``run_on_owner(fn)`` must
run ``fn`` where the simulation lives and return its result (the node hands it to its
executor).
"""
from __future__ import annotations

import functools
import json
import math
import time
from typing import Callable, Mapping

import numpy as np

from rod_sim.io.msgdefs import SCHEMAS
from rod_sim.io.topics import TOPIC_TYPES

SUBPROTOCOL = "foxglove.sdk.v1"
MAX_FRAME_HZ = 30.0
"""Frames per wall second at most (a viewer draws at display rate, not at 1 kHz)."""
CDR_TOPICS = ("markers", "joint_states", "node_poses")
SERIES_TOPIC = "/rod_sim/series"
SERIES = ("t", "energy", "energy_residual", "rtf", "max_abs_alpha", "max_abs_beta")
"""Fields of the series messages: [s], [J], [J], [1], [rad], [rad]."""


class LiveViewError(RuntimeError):
    """The live view cannot start (package missing, port taken): one line."""


def _sdk():
    try:
        import foxglove
        from foxglove import channels, messages
    except ImportError:
        raise LiveViewError("the live view needs the foxglove-sdk package (pip install "
                            "foxglove-sdk)") from None
    return foxglove, channels, messages


class LiveView:
    """A Foxglove WebSocket server on ``host``:``port`` (0: any free port, see :attr:`port`)
    showing the chain in frame ``frame_id``. ``services``: name -> ``fn(request dict) ->
    (success, message)``, run through ``run_on_owner``."""

    def __init__(self, port: int, *, host: str = "127.0.0.1", frame_id: str = "world",
                 name: str = "rod_sim", services: Mapping[str, Callable] | None = None,
                 run_on_owner: Callable | None = None, max_frame_hz: float = MAX_FRAME_HZ):
        foxglove, _, messages = _sdk()
        from foxglove.websocket import Capability

        self._messages = messages
        self.frame_id = frame_id
        self._context = foxglove.Context()
        self._cdr = {name: foxglove.Channel(
            f"/{name}", message_encoding="cdr", context=self._context,
            schema=foxglove.Schema(name=TOPIC_TYPES[name], encoding="ros2msg",
                                   data=SCHEMAS[TOPIC_TYPES[name]].encode()))
            for name in CDR_TOPICS}
        schema = messages.FrameTransforms.get_schema()
        self._tf = foxglove.Channel("/tf", message_encoding="protobuf", context=self._context,
                                    schema=foxglove.Schema(name=schema.name,
                                                           encoding=schema.encoding,
                                                           data=schema.data))
        self._series = foxglove.Channel(
            SERIES_TOPIC, message_encoding="json", context=self._context,
            schema=foxglove.Schema(name="rod_sim.Series", encoding="jsonschema", data=json.dumps(
                {"type": "object", "properties": {k: {"type": "number"} for k in SERIES}}
            ).encode()))
        run = run_on_owner or (lambda fn: fn())
        svc = [foxglove.Service(name=key, handler=self._handler(fn, run),
                                schema=foxglove.ServiceSchema(name=f"rod_sim.{key}"))
               for key, fn in (services or {}).items()]
        try:
            self._server = foxglove.start_server(
                name=name, host=host, port=port, context=self._context,
                capabilities=[Capability.Services] if svc else None,
                supported_encodings=["json"] if svc else None, services=svc or None)
        except Exception as exc:  # noqa: BLE001 -- the SDK raises RuntimeError subtypes
            raise LiveViewError(f"live view: cannot listen on {host}:{port}: {exc}") from None
        self._min_gap_ns = int(1e9 / max_frame_hz)
        self._last_ns = -self._min_gap_ns
        self._forwarded: dict[str, int] = {}
        self.frames = 0

    @property
    def port(self) -> int:
        return self._server.port

    @staticmethod
    def _handler(fn, run):
        def handle(request) -> bytes:
            data = json.loads(request.payload or b"{}") if request.payload else {}
            success, message = run(lambda: fn(data))
            return json.dumps({"success": bool(success), "message": str(message)}).encode()
        return handle

    def wanted(self) -> bool:
        """Whether a frame is due: a client subscribes, and the last frame is old enough."""
        if time.monotonic_ns() - self._last_ns < self._min_gap_ns:
            return False
        return any(ch.has_sinks() for ch in (*self._cdr.values(), self._tf, self._series))

    def send(self, t_ns: int, encoded: Mapping[str, bytes], nodes: np.ndarray, phi: np.ndarray,
             series: Mapping[str, float]) -> None:
        """One frame at simulated time ``t_ns``: the encoded messages of :data:`CDR_TOPICS`
        present in ``encoded``, the node frames (``nodes`` (n+1, 2) [m], ``phi`` (n,) [rad],
        node k oriented as rod max(k, 1)) and the ``series`` values."""
        self._last_ns = time.monotonic_ns()
        self.frames += 1
        for name, channel in self._cdr.items():
            if name in encoded and channel.has_sinks():
                channel.log(encoded[name], log_time=t_ns)
        if self._tf.has_sinks():
            self._tf.base.log(self._transforms(t_ns, nodes, phi), t_ns)
        if self._series.has_sinks():
            self._series.log({"t": t_ns / 1e9, **{k: (float(v) if math.isfinite(v) else None)
                                                  for k, v in series.items()}}, log_time=t_ns)

    def forward(self, topic: str, t_ns: int, data: bytes) -> None:
        """A recorded message (replay): ``data`` of a topic ending in one of
        :data:`CDR_TOPICS` goes to its channel, at most :data:`MAX_FRAME_HZ` per topic per
        wall second; other topics are ignored."""
        name = topic.rsplit("/", 1)[-1]
        channel = self._cdr.get(name)
        if channel is None or not channel.has_sinks():
            return
        now = time.monotonic_ns()
        if now - self._forwarded.get(name, -self._min_gap_ns) >= self._min_gap_ns:
            self._forwarded[name] = now
            channel.log(data, log_time=t_ns)

    def _transforms(self, t_ns: int, nodes: np.ndarray, phi: np.ndarray) -> bytes:
        return frame_transforms(t_ns, self.frame_id, nodes, phi)

    def close(self) -> None:
        self._server.stop()


# ----- foxglove.FrameTransforms (protobuf) straight from numpy -----

def _varint(value: int) -> bytes:
    out = bytearray()
    while True:
        byte, value = value & 0x7F, value >> 7
        out.append(byte | 0x80 if value else byte)
        if not value:
            return bytes(out)


@functools.lru_cache(maxsize=16)
def _tf_layout(parent: str, count: int, head_len: int):
    """The bytes of ``count`` transforms ``parent -> node_k`` with zeroed slots: a
    ``head_len``-byte timestamp field per transform and, per transform, x, y (translation) and
    z, w (rotation) doubles; returns (template, head index (count, head_len), double index
    (count, 4, 8)). Built once per chain size and frame (a loop over nodes, not per frame)."""
    out, heads, doubles = bytearray(), [], []
    p = parent.encode()
    for k in range(count):
        child = f"node_{k}".encode()
        names = b"\x12" + _varint(len(p)) + p + b"\x1a" + _varint(len(child)) + child
        out += b"\x0a" + _varint(head_len + len(names) + 40)
        heads.append(range(len(out), len(out) + head_len))
        out += bytes(head_len) + names
        slots = []
        for tag in (b"\x22\x12\x09", b"\x11", b"\x2a\x12\x19", b"\x21"):
            out += tag
            slots.append(range(len(out), len(out) + 8))
            out += bytes(8)
        doubles.append(slots)
    return (np.frombuffer(bytes(out), dtype=np.uint8).copy(),
            np.array(heads, dtype=np.intp).reshape(count, head_len),
            np.array(doubles, dtype=np.intp).reshape(count, 4, 8))


def frame_transforms(t_ns: int, parent: str, nodes: np.ndarray, phi: np.ndarray) -> bytes:
    """``foxglove.FrameTransforms`` (protobuf) of ``parent -> node_k`` for nodes 0..n at
    ``t_ns``: translation (x_k, y_k, 0) [m], rotation about z by the angle of the rod ending at
    node k (node 0: rod 1). The SDK's encoding of the same message (it omits fields equal to
    0, which decoders read as 0: so do its z and rotation x, y here), built with numpy."""
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    ts = (b"\x08" + _varint(sec) if sec else b"") + (b"\x10" + _varint(nsec) if nsec else b"")
    head = b"\x0a" + _varint(len(ts)) + ts
    nodes = np.asarray(nodes, dtype=float)
    half = 0.5 * np.concatenate([phi[:1], phi])[:len(nodes)]
    template, head_at, double_at = _tf_layout(parent, len(nodes), len(head))
    out = template.copy()
    out[head_at] = np.frombuffer(head, dtype=np.uint8)
    values = np.stack([nodes[:, 0], nodes[:, 1], np.sin(half), np.cos(half)], axis=1)
    out[double_at] = values.astype("<f8").view(np.uint8).reshape(len(nodes), 4, 8)
    return out.tobytes()
