"""Snapshot -> CDR bytes of the state topics (docs/interface.md section 3), straight from numpy.

One function per topic, each ``encode(snapshot, scene, frame_id) -> bytes`` (plus the applied
inputs, the clock and the string topics), giving exactly the bytes of
``rod_sim.io.cdr.encoder(type)(rod_sim.io.topics.<builder>(...))`` -- the message dicts of
:mod:`rod_sim.io.topics` define the content; this module only makes it cheap: each message's
layout (names, frame, sizes, the markers' constant fields) is built once per chain size and
frame by :mod:`rod_sim.io.cdr_layout`, and a sample fills its numbers with a few O(n) numpy
assignments (no Python loop over rods or points). test/test_encoders.py compares every topic
with the dict path and with mcap_ros2, byte for byte, and with rclpy's deserializer.

:data:`SNAPSHOT_ENCODERS` maps the relative topic names of
:data:`rod_sim.io.topics.SNAPSHOT_TOPICS` to their encoders: the one table the node, ``rod-sim
simulate`` and the log writer share.
"""
from __future__ import annotations

import functools
import math
import struct
from collections.abc import Mapping
from typing import Callable

import numpy as np

from rod_sim.core.scene import Scene
from rod_sim.core.snapshot import ENERGY_TERMS, Snapshot
from rod_sim.io import cdr, topics
from rod_sim.io.cdr_layout import Layout, LayoutWriter, stamp_bytes

SnapshotEncoder = Callable[[Snapshot, Scene, str], bytes]

_CACHE = 64
"""Layouts kept per topic (chain sizes x frame ids)."""


def _stamp(snapshot: Snapshot) -> np.ndarray:
    return _stamp_at(snapshot.t)


@functools.lru_cache(maxsize=4)
def _stamp_at(t: float) -> np.ndarray:
    """The stamp (2,) uint32 of ``t`` [s] (kept: the topics of one sample share it;
    read-only)."""
    t_ns = topics.time_ns(t)
    if t_ns >= 2 ** 31 * 1_000_000_000:
        raise ValueError(f"time {t!r} s does not fit a ROS stamp (int32 seconds)")
    out = stamp_bytes(t_ns)
    out.flags.writeable = False
    return out


def _stamps(snapshot: Snapshot, k: int) -> np.ndarray:
    """The snapshot's stamp k times (2k,) uint32: ``np.tile(_stamp(snapshot), k)``, cheaper."""
    out = np.empty((k, 2), dtype="<u4")
    out[:] = _stamp(snapshot)
    return out.ravel()


def _f64(values) -> np.ndarray:
    return np.asarray(values, dtype="<f8").ravel()


# ----- sensor_msgs/JointState -----

@functools.lru_cache(maxsize=_CACHE)
def _joint_state_layout(frame_id: str, names: tuple[str, ...], sizes: tuple[int, int, int]
                        ) -> Layout:
    w = LayoutWriter()
    w.header(frame_id)
    w.string_seq(names)
    for field, k in zip(("position", "velocity", "effort"), sizes):
        w.f64_seq(field, k)
    return w.layout()


_LAYOUT_BY_NAMES: dict[tuple, tuple[tuple[str, ...], Callable]] = {}
"""(frame_id, id(names), sizes) -> (names, its layout's filler): :func:`_joint_state_layout`
looked up without hashing the names (a tuple's hash is not kept: ~4 us per 1024 names at every
sample); ``names`` come from the lru caches of :func:`chain_names` and friends, and an entry
counts only for the very tuple it was made for (``is``), so a reused id cannot pick a wrong
layout."""


_JOINT_FIELDS = ("position", "velocity", "effort")


def _joint_state(snapshot: Snapshot, frame_id: str, names: tuple[str, ...], *arrays) -> bytes:
    arrays = [_f64(a) for a in arrays]
    sizes = tuple(a.size for a in arrays) + (0,) * (3 - len(arrays))
    key = (frame_id, id(names), sizes)
    hit = _LAYOUT_BY_NAMES.get(key)
    if hit is not None and hit[0] is names:
        fill = hit[1]
    else:
        fill = _joint_state_layout(frame_id, names, sizes).filler(
            ("stamp",) + tuple(field for field, k in zip(_JOINT_FIELDS, sizes) if k))
        if len(_LAYOUT_BY_NAMES) >= _CACHE:
            _LAYOUT_BY_NAMES.clear()
        _LAYOUT_BY_NAMES[key] = (names, fill)
    return fill(_stamp(snapshot), *[a for a in arrays if a.size])


@functools.lru_cache(maxsize=_CACHE)
def chain_names(scene: Scene | None, n: int, prefix: str, first: int) -> tuple[str, ...]:
    """Names of the n rods' (or hinges') entries in the flat order: ``prefix{first}`` ..
    for a scene without ``chains:``, ``{chain}/{prefix}{k}`` per chain with them (SPEC section
    8: ``left/hinge_0``, ``left/rod_1``)."""
    if scene is None or not getattr(scene, "has_chains", False):
        return topics._names(prefix, first, n)
    return tuple(f"{c.name}/{prefix}{k}" for c in scene.chains
                 for k in range(first, first + c.count))


BASE_JOINTS = ("base_x", "base_y", "base_psi")
"""``joint_states`` entries of a moving (free or prescribed) base, after the hinges: the
base frame's origin x, y [m] and angle psi [rad] in Oxy, their rates, effort 0 -- the joints
of the URDF's base (:mod:`rod_sim.io.urdf`)."""


@functools.lru_cache(maxsize=_CACHE)
def _joint_names(scene: Scene | None, n: int, base: bool) -> tuple[str, ...]:
    return chain_names(scene, n, "hinge_", 0) + (BASE_JOINTS if base else ())


def _moving_base(snapshot: Snapshot, scene: Scene | None) -> bool:
    return snapshot.base is not None and scene is not None and scene.moving_base


def joint_states(snapshot: Snapshot, scene: Scene | None = None, frame_id: str = "world"
                 ) -> bytes:
    """``joint_states`` (see :func:`rod_sim.io.topics.joint_states`); on a moving base the
    hinges are followed by :data:`BASE_JOINTS`."""
    if _moving_base(snapshot, scene):
        b = snapshot.base
        return _joint_state(snapshot, frame_id, _joint_names(scene, snapshot.n, True),
                            np.concatenate([snapshot.hinge_angle, b[0:3]]),
                            np.concatenate([snapshot.hinge_rate, b[3:6]]),
                            np.concatenate([snapshot.hinge_moment, np.zeros(3)]))
    return _joint_state(snapshot, frame_id, chain_names(scene, snapshot.n, "hinge_", 0),
                        snapshot.hinge_angle, snapshot.hinge_rate, snapshot.hinge_moment)


def rod_states(snapshot: Snapshot, scene: Scene | None = None, frame_id: str = "world") -> bytes:
    """``rod_states`` (see :func:`rod_sim.io.topics.rod_states`)."""
    return _joint_state(snapshot, frame_id, chain_names(scene, snapshot.n, "rod_", 1),
                        snapshot.phi, snapshot.phi_rate)


@functools.lru_cache(maxsize=_CACHE)
def _bending_names(scene: Scene | None, n: int) -> tuple[str, ...]:
    return (*chain_names(scene, n, "alpha_", 1), *chain_names(scene, n, "beta_", 1))


def bending(snapshot: Snapshot, scene: Scene | None = None, frame_id: str = "world") -> bytes:
    """``bending`` (see :func:`rod_sim.io.topics.bending`)."""
    return _joint_state(snapshot, frame_id, _bending_names(scene, snapshot.n),
                        np.concatenate([snapshot.alpha, snapshot.beta]))


@functools.lru_cache(maxsize=_CACHE)
def _node_rods(scene: Scene | None, n: int, k: int) -> np.ndarray:
    """For each of the k node rows of a snapshot (every chain's nodes 0..n_c), the rod whose
    direction the node takes: the rod ending there, a chain's node 0 its rod 1 (kept per
    scene, which is immutable and hashed by identity; read-only)."""
    if scene is None or k == n + 1 or len(getattr(scene, "chains", ())) <= 1:
        out = np.concatenate([[0], np.arange(n)])[:k]
        out.flags.writeable = False
        return out
    out = []
    for c in scene.chains:
        out.extend([c.start] + list(range(c.start, c.start + c.count)))
    out = np.asarray(out[:k])
    out.flags.writeable = False
    return out


def _rod_starts(scene: Scene, nodes: np.ndarray) -> np.ndarray:
    """Rows of the snapshot's nodes (n + nc, 2) where each rod starts (n,) (one chain: 0..n-1)."""
    return _scene_rod_starts(scene)


@functools.lru_cache(maxsize=_CACHE)
def _scene_rod_starts(scene: Scene) -> np.ndarray:
    out = np.arange(scene.n) + np.asarray(scene.chain_of_rod)
    out.flags.writeable = False
    return out


# ----- geometry_msgs/PoseArray -----

@functools.lru_cache(maxsize=_CACHE)
def _pose_array_layout(frame_id: str, k: int) -> Layout:
    w = LayoutWriter()
    w.header(frame_id)
    w.count(k)
    if k:
        w.slot("poses", 56 * k, 8)          # Pose = Point (x, y, z) + Quaternion (x, y, z, w)
    return w.layout()


def node_poses(snapshot: Snapshot, scene: Scene | None = None, frame_id: str = "world") -> bytes:
    """``node_poses`` (see :func:`rod_sim.io.topics.node_poses`): every chain's nodes 0..n_c in
    scene order, each oriented as the rod ending there (node 0: rod 1), and on a spacecraft
    scene (``snapshot.base``) then the base frame's origin, oriented by psi."""
    nodes = np.asarray(snapshot.nodes, dtype=float)
    phi = np.asarray(snapshot.phi, dtype=float)
    if len(nodes) == len(phi) + 1:
        half = 0.5 * np.concatenate([phi[:1], phi])[:len(nodes)]
    else:                                   # several chains: each one's nodes 0..n_c
        half = 0.5 * phi[_node_rods(scene, len(phi), len(nodes))]
    if snapshot.base is not None:
        nodes = np.concatenate([nodes, np.asarray(snapshot.base[None, 0:2], dtype=float)])
        half = np.append(half, 0.5 * float(snapshot.base[2]))
    poses = np.zeros((len(nodes), 7))
    poses[:, 0:2] = nodes[:, 0:2]
    poses[:, 5] = np.sin(half)
    poses[:, 6] = np.cos(half)
    if not len(nodes):
        return _pose_array_layout(frame_id, 0).fill(stamp=_stamp(snapshot))
    return _pose_array_layout(frame_id, len(nodes)).filler(("stamp", "poses"))(
        _stamp(snapshot), poses)


# ----- nav_msgs/Odometry -----

BASE_FRAME = "base"
"""``child_frame_id`` of ``base_odometry``: the base frame (the URDF's ``base`` link)."""


@functools.lru_cache(maxsize=_CACHE)
def _odometry_layout(frame_id: str) -> Layout:
    w = LayoutWriter()
    w.header(frame_id)
    w.string(BASE_FRAME)
    w.slot("pose", 56, 8)                   # Point + Quaternion
    w.slot("pose_covariance", 36 * 8, 8)
    w.slot("twist", 48, 8)                  # Vector3 linear + Vector3 angular
    w.slot("twist_covariance", 36 * 8, 8)
    return w.layout()


_ZERO_COVARIANCE = np.zeros(36)


def base_odometry(snapshot: Snapshot, scene: Scene | None = None, frame_id: str = "world"
                  ) -> bytes:
    """``base_odometry`` (nav_msgs/Odometry, see :func:`rod_sim.io.topics.base_odometry`): the
    pose of the base frame's origin in ``frame_id`` (z = 0, yaw psi) and its twist in the base
    frame (``child_frame_id`` ``base``): linear R(psi)^T (x', y') [m/s], angular z psi'
    [rad/s]; covariances zero (the simulated state is exact)."""
    if snapshot.base is None:
        raise ValueError("base_odometry needs a snapshot of a spacecraft scene (with a base)")
    x, y, psi, vx, vy, w = (float(v) for v in snapshot.base)
    c, s = math.cos(psi), math.sin(psi)
    pose = np.array([x, y, 0.0, 0.0, 0.0, math.sin(0.5 * psi), math.cos(0.5 * psi)])
    twist = np.array([c * vx + s * vy, -s * vx + c * vy, 0.0, 0.0, 0.0, w])
    return _odometry_layout(frame_id).fill(
        stamp=_stamp(snapshot), pose=pose, pose_covariance=_ZERO_COVARIANCE, twist=twist,
        twist_covariance=_ZERO_COVARIANCE)


# ----- visualization_msgs/MarkerArray -----

def _marker(w: LayoutWriter, frame_id: str, ns: str, marker_id: int, marker_type: int,
            width: float, color: dict, points_slot: str, k: int, pose_slot: str | None = None,
            scale: tuple[float, float, float] | None = None) -> None:
    """One marker (fields of :func:`rod_sim.io.topics._marker`) with ``k`` points filled by
    ``points_slot`` (x, y, z per point); its pose filled by ``pose_slot`` if given (else the
    identity), its scale ``scale`` if given (else ``width`` on every axis)."""
    w.header(frame_id)
    w.string(ns)
    w.prim("i", marker_id, marker_type, topics.MARKER_ADD)
    if pose_slot is None:
        w.prim("d", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)               # pose
    else:
        w.slot(pose_slot, 56, 8)
    w.prim("d", *(scale or (width, width, width)))                   # scale
    w.prim("f", color["r"], color["g"], color["b"], color["a"])
    w.prim("i", 0)                                                   # lifetime.sec
    w.prim("I", 0)                                                   # lifetime.nanosec
    w.prim("?", False)                                               # frame_locked
    w.count(k)
    if k:
        w.slot(points_slot, 24 * k, 8)
    w.count(0)                                                       # colors
    w.string("")                                                     # texture_resource
    w.stamp()                                                        # texture.header
    w.string("")
    w.string("")                                                     # texture.format
    w.count(0)                                                       # texture.data
    w.count(0)                                                       # uv_coordinates
    w.string("")                                                     # text
    w.string("")                                                     # mesh_resource
    w.string("")                                                     # mesh_file.filename
    w.count(0)                                                       # mesh_file.data
    w.prim("?", False)                                               # mesh_use_embedded_materials


@functools.lru_cache(maxsize=8)
def _markers_layout(scene: Scene, frame_id: str, points_per_rod: int) -> Layout:
    """The markers of :func:`rod_sim.io.topics.markers` for ``scene``. Each marker's header
    stamp is a ``stamp`` piece; its texture's header stamp is zero and so a ``zero`` piece."""
    n = scene.n
    w = LayoutWriter()
    w.count(n + 1 if n <= topics.MARKER_MAX_STRIPS else 2)
    if n > topics.MARKER_MAX_STRIPS:
        width, diameter = topics.marker_sizes(scene)
        _marker(w, frame_id, "rods", 0, topics.MARKER_LINE_STRIP, width, topics.ROD_COLOR,
                "chain", n + 1)
    else:
        width, diameter, _ = topics._marker_geometry(scene, points_per_rod)
        for k in range(n):
            _marker(w, frame_id, "rods", k + 1, topics.MARKER_LINE_STRIP, width,
                    topics.ROD_COLOR, "rods", points_per_rod)
    _marker(w, frame_id, "nodes", 0, topics.MARKER_SPHERE_LIST, diameter, topics.NODE_COLOR,
            "nodes", n)
    # the texture headers' stamps were reserved as stamp pieces too: every other piece
    pieces = w.slots.pop("stamp")
    w.slots["stamp"], w.slots["zero"] = pieces[0::2], pieces[1::2]
    return w.layout()


def _xyz(points: np.ndarray) -> np.ndarray:
    """(..., 2) [m] -> (..., 3) with z = 0."""
    out = np.zeros(points.shape[:-1] + (3,))
    out[..., :2] = points
    return out


CHAIN_COLORS = ({"r": 0.25, "g": 0.5, "b": 1.0, "a": 1.0}, {"r": 0.85, "g": 0.2, "b": 0.2, "a": 1.0},
                {"r": 0.2, "g": 0.7, "b": 0.3, "a": 1.0}, {"r": 0.6, "g": 0.3, "b": 0.8, "a": 1.0},
                {"r": 0.9, "g": 0.6, "b": 0.1, "a": 1.0}, {"r": 0.1, "g": 0.7, "b": 0.8, "a": 1.0})
"""Rod colours of a spacecraft scene's chains: chain c gets CHAIN_COLORS[c % 6] (the first is
the plain chain's :data:`rod_sim.io.topics.ROD_COLOR`)."""
BASE_COLOR = {"r": 0.6, "g": 0.6, "b": 0.6, "a": 0.8}
MARKER_CUBE = 1


def base_box(scene: Scene) -> float:
    """[m] side of the square drawn for the base: a uniform square plate of the base's mass and
    inertia (a = sqrt(6 J_B / m_B)) when both are given, at least the span of the attach points
    about the centre of mass and 4 rod line widths."""
    b = scene.base
    attach = np.array([c.attach for c in scene.chains], dtype=float).reshape(-1, 2)
    span = 2.0 * float(np.max(np.abs(attach - np.asarray(b.centre_of_mass, float)),
                              initial=0.0))
    side = max(span, 4.0 * topics.marker_sizes(scene)[0])
    if math.isfinite(b.mass) and math.isfinite(b.inertia):
        side = max(side, math.sqrt(6.0 * b.inertia / b.mass))
    return side


@functools.lru_cache(maxsize=8)
def _spacecraft_markers_layout(scene: Scene, frame_id: str, points_per_rod: int) -> Layout:
    """The markers of a spacecraft scene: each chain's rods in its colour (one bent strip per
    rod, ns ``rods`` id k + 1 in the flat rod order; more than MARKER_MAX_STRIPS rods in all:
    one strip per chain through its nodes, ns ``rods`` id c), the node masses (ns ``nodes``)
    and the base as a box (ns ``base``, a CUBE at its centre of mass turned by psi)."""
    n, chains = scene.n, scene.chains
    per_rod = n <= topics.MARKER_MAX_STRIPS
    w = LayoutWriter()
    w.count((n if per_rod else len(chains)) + 2)
    if per_rod:
        width, diameter, _ = topics._marker_geometry(scene, points_per_rod)
        for k, c in enumerate(scene.chain_of_rod.tolist()):
            _marker(w, frame_id, "rods", k + 1, topics.MARKER_LINE_STRIP, width,
                    CHAIN_COLORS[c % len(CHAIN_COLORS)], "rods", points_per_rod)
    else:
        width, diameter = topics.marker_sizes(scene)
        for c, chain in enumerate(chains):
            _marker(w, frame_id, "rods", c, topics.MARKER_LINE_STRIP, width,
                    CHAIN_COLORS[c % len(CHAIN_COLORS)], "rods", chain.count + 1)
    _marker(w, frame_id, "nodes", 0, topics.MARKER_SPHERE_LIST, diameter, topics.NODE_COLOR,
            "nodes", n)
    side = base_box(scene)
    _marker(w, frame_id, "base", 0, MARKER_CUBE, side, BASE_COLOR, "none", 0,
            pose_slot="base_pose", scale=(side, side, 0.2 * side))
    pieces = w.slots.pop("stamp")
    w.slots["stamp"], w.slots["zero"] = pieces[0::2], pieces[1::2]
    return w.layout()


def _spacecraft_markers(snapshot: Snapshot, scene: Scene, frame_id: str,
                        points_per_rod: int) -> bytes:
    from rod_sim.core.kinematics import rod_points

    layout = _spacecraft_markers_layout(scene, frame_id, points_per_rod)
    nodes = np.asarray(snapshot.nodes, dtype=float)
    k = (scene.n if scene.n <= topics.MARKER_MAX_STRIPS else len(scene.chains)) + 2
    stamps = _stamps(snapshot, k)
    starts = _rod_starts(scene, nodes)
    if scene.n <= topics.MARKER_MAX_STRIPS:
        table = topics._marker_geometry(scene, points_per_rod)[2]
        rods = rod_points(np.asarray(scene.length, dtype=float),
                          np.asarray(snapshot.phi, dtype=float),
                          np.asarray(snapshot.alpha, dtype=float),
                          np.asarray(snapshot.beta, dtype=float), points_per_rod, table,
                          nodes[starts], z=True)
    else:
        rods = _xyz(nodes)
    x, y, psi = np.asarray(snapshot.base, dtype=float)[:3].tolist()
    cx, cy = scene.base.centre_of_mass
    c, s = math.cos(psi), math.sin(psi)
    pose = np.array([x + c * cx - s * cy, y + s * cx + c * cy, 0.0, 0.0, 0.0,
                     math.sin(0.5 * psi), math.cos(0.5 * psi)])
    values = {"stamp": stamps, "zero": np.zeros(stamps.size, dtype="<u4"), "rods": rods,
              "nodes": _xyz(nodes[starts + 1]), "base_pose": pose}
    return layout.fill(**{k: v for k, v in values.items() if k in layout.slots})


def markers(snapshot: Snapshot, scene: Scene, frame_id: str = "world",
            points_per_rod: int = 11) -> bytes:
    """``markers`` (see :func:`rod_sim.io.topics.markers`; a spacecraft scene:
    :func:`_spacecraft_markers_layout`)."""
    from rod_sim.core.kinematics import rod_points

    if snapshot.n != scene.n:
        raise ValueError(f"snapshot has {snapshot.n} rods but the scene {scene.name!r} has "
                         f"{scene.n}")
    if snapshot.base is not None:
        return _spacecraft_markers(snapshot, scene, frame_id, points_per_rod)
    layout = _markers_layout(scene, frame_id, points_per_rod)
    nodes = np.asarray(snapshot.nodes, dtype=float)
    stamps = _stamps(snapshot, scene.n + 1 if scene.n <= topics.MARKER_MAX_STRIPS else 2)
    values = {"stamp": stamps, "zero": np.zeros(stamps.size, dtype="<u4")}
    several = len(nodes) != scene.n + 1          # several chains: each one's nodes 0..n_c
    if scene.n > topics.MARKER_MAX_STRIPS:
        values["chain"] = _xyz(nodes[:scene.n + 1])
    elif scene.n:
        table = topics._marker_geometry(scene, points_per_rod)[2]
        starts = nodes[_rod_starts(scene, nodes)] if several else None
        values["rods"] = rod_points(np.asarray(scene.length, dtype=float),
                                    np.asarray(snapshot.phi, dtype=float),
                                    np.asarray(snapshot.alpha, dtype=float),
                                    np.asarray(snapshot.beta, dtype=float),
                                    points_per_rod, table, starts, z=True)
    if scene.n:
        values["nodes"] = _xyz(nodes[_rod_starts(scene, nodes) + 1] if several else nodes[1:])
    return layout.fill(**{k: v for k, v in values.items() if k in layout.slots})


# ----- std_msgs/Float64MultiArray: applied forces and torques -----

@functools.lru_cache(maxsize=_CACHE)
def _multi_array_layout(dims: tuple[tuple[str, int, int], ...], k: int) -> Layout:
    w = LayoutWriter()
    w.count(len(dims))
    for label, size, stride in dims:
        w.string(label)
        w.prim("I", size, stride)
    w.prim("I", 0)                      # data_offset
    w.f64_seq("data", k)
    return w.layout()


def force_array(forces: np.ndarray) -> bytes:
    """``applied_forces`` of (n, 2) forces [N] (see :func:`rod_sim.io.topics.force_array`)."""
    f = _f64(np.asarray(forces, dtype=float).reshape(-1, 2))
    n = f.size // 2
    layout = _multi_array_layout(((topics.FORCE_LAYOUT_LABELS[0], n, 2 * n),
                                  (topics.FORCE_LAYOUT_LABELS[1], 2, 2)), f.size)
    return layout.filler(("data",))(f) if f.size else layout.fill()


def labelled_array(values, label: str) -> bytes:
    """std_msgs/Float64MultiArray of (k,) values with one layout dim ``label``."""
    v = _f64(values)
    layout = _multi_array_layout(((label, v.size, v.size),), v.size)
    return layout.filler(("data",))(v) if v.size else layout.fill()


def torque_array(torques) -> bytes:
    """``applied_torques`` of (n,) torques [N m] (see :func:`rod_sim.io.topics.torque_array`)."""
    return labelled_array(torques, topics.TORQUE_LAYOUT_LABEL)


def applied_forces(snapshot: Snapshot, scene: Scene | None = None, frame_id: str = "world"
                   ) -> bytes:
    return force_array(snapshot.forces)


# ----- diagnostic_msgs/DiagnosticArray -----

_U32 = struct.Struct("<I").pack
_STAMP = struct.Struct("<iI").pack
_ALIGN4 = (b"", b"\0\0\0", b"\0\0", b"\0")
"""Padding to the next multiple of 4 after ``len(b) & 3`` bytes."""


def _cdr_string(b: bytearray, text: str) -> None:
    """Append a CDR string to ``b``: aligned uint32 length (with the NUL), UTF-8 bytes, NUL."""
    data = text.encode()
    b += _ALIGN4[len(b) & 3]
    b += _U32(len(data) + 1)
    b += data
    b.append(0)


def diagnostics(t: float, values: Mapping[str, object], hardware_id: str, *,
                level: int = topics.DIAGNOSTIC_OK, message: str = "", frame_id: str = "",
                name: str = "rod_sim") -> bytes:
    """``/diagnostics`` (diagnostic_msgs/DiagnosticArray of one status): the bytes of
    ``cdr.encoder(type)(topics.diagnostics(t, values, hardware_id, ...))``, written without
    the message dicts (arguments as :func:`rod_sim.io.topics.diagnostics`)."""
    if level not in (topics.DIAGNOSTIC_OK, topics.DIAGNOSTIC_WARN, topics.DIAGNOSTIC_ERROR,
                     topics.DIAGNOSTIC_STALE):
        raise ValueError(f"diagnostic level must be 0..3 (got {level!r})")
    b = bytearray(_STAMP(*divmod(topics.time_ns(t), 1_000_000_000)))
    _cdr_string(b, frame_id)
    b += _ALIGN4[len(b) & 3]
    b += _U32(1)                                       # one status
    b.append(int(level))
    for text in (name, message, hardware_id):
        _cdr_string(b, str(text))
    b += _ALIGN4[len(b) & 3]
    b += _U32(len(values))
    for key, value in values.items():
        _cdr_string(b, str(key))
        _cdr_string(b, value if isinstance(value, str) else str(value))
    return cdr.HEADER + bytes(b)


# ----- rosgraph_msgs/Clock, std_msgs/String -----

def clock_ns(t_ns: int) -> bytes:
    """``rosgraph_msgs/Clock`` at ``t_ns`` [ns]."""
    return cdr.HEADER + stamp_bytes(t_ns).tobytes()


def clock(snapshot: Snapshot, scene: Scene | None = None, frame_id: str = "world") -> bytes:
    return cdr.HEADER + _stamp(snapshot).tobytes()


def string(text: str) -> bytes:
    """``std_msgs/String`` (``robot_description``, ``scene``)."""
    return cdr.encoder("std_msgs/msg/String")({"data": text})


SNAPSHOT_ENCODERS: dict[str, SnapshotEncoder] = {
    "joint_states": joint_states,
    "rod_states": rod_states,
    "bending": bending,
    "node_poses": node_poses,
    "base_odometry": base_odometry,
    "markers": markers,
    "applied_forces": applied_forces,
    "clock": clock,
}
"""Relative topic name -> ``encode(snapshot, scene, frame_id) -> bytes`` (types in
:data:`rod_sim.io.topics.TOPIC_TYPES`)."""


def snapshot_bytes(snapshot: Snapshot, scene: Scene, frame_id: str = "world",
                   names=None) -> dict[str, bytes]:
    """CDR bytes of ``snapshot`` keyed by relative topic name, as
    :func:`rod_sim.io.topics.snapshot_messages` (same ``names`` default and errors) encoded."""
    if snapshot.n != scene.n:
        raise ValueError(f"snapshot has {snapshot.n} rods but the scene {scene.name!r} has "
                         f"{scene.n}")
    wanted = topics.DEFAULT_TOPICS if names is None else tuple(names)
    unknown = [t for t in wanted if t not in SNAPSHOT_ENCODERS]
    if unknown:
        raise ValueError(f"cannot build topic(s) {', '.join(unknown)} from a snapshot "
                         f"(choose from {', '.join(topics.SNAPSHOT_TOPICS + topics.BASE_TOPICS)})")
    return {name: SNAPSHOT_ENCODERS[name](snapshot, scene, frame_id) for name in wanted}


def zero_snapshot(scene: Scene) -> Snapshot:
    """A snapshot of ``scene`` at t = 0 with every value zero, without a model: the shapes
    (and so the byte sizes of the state topics' messages) of every sample of the scene."""
    n, zeros = scene.n, np.zeros(scene.n)
    extra = {}
    if scene.is_spacecraft:
        extra = dict(base=np.zeros(6), wheel_rate=0.0, momentum=np.zeros(6),
                     energy_terms=dict.fromkeys(ENERGY_TERMS, 0.0))
    return Snapshot(0.0, zeros, zeros, zeros, zeros, zeros, zeros, zeros,
                    np.zeros((n + len(scene.chains), 2)), np.zeros((n, 2)), **extra)
