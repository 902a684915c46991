"""Snapshot -> ROS 2 message dicts for the topics of docs/interface.md section 3 (no rclpy needed).

Messages are nested dicts and lists of plain Python numbers/strings, the form mcap_ros2's CDR
encoder takes (``header: {stamp: {sec, nanosec}, frame_id}``); the ROS node can fill rclpy
messages from the same dicts. Field names are checked against the schemas in
:mod:`rod_sim.io.msgdefs` by the log writer, since the encoder silently writes defaults for
misspelled fields.

Numbering (paper terms): hinges ``hinge_0..hinge_{n-1}``, rods ``rod_1..rod_n``, nodes 0..n.
Units: angles [rad], rates [rad/s], moments [N m], positions [m], forces [N], times [s].
"""
from __future__ import annotations

import functools
import math
from typing import Any, Callable, Iterable, Mapping

import numpy as np

from rod_sim.core.kinematics import rod_points, shape_table
from rod_sim.core.scene import Scene
from rod_sim.core.snapshot import Snapshot
from rod_sim.core.units import NS_PER_S

Msg = dict[str, Any]

TOPIC_TYPES: dict[str, str] = {
    "joint_states": "sensor_msgs/msg/JointState",
    "rod_states": "sensor_msgs/msg/JointState",
    "bending": "sensor_msgs/msg/JointState",
    "node_poses": "geometry_msgs/msg/PoseArray",
    "base_odometry": "nav_msgs/msg/Odometry",
    "markers": "visualization_msgs/msg/MarkerArray",
    "applied_forces": "std_msgs/msg/Float64MultiArray",
    "applied_torques": "std_msgs/msg/Float64MultiArray",
    "diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
    "clock": "rosgraph_msgs/msg/Clock",
    "robot_description": "std_msgs/msg/String",
    "scene": "std_msgs/msg/String",
}
"""Published topics (relative names; ``clock`` is ``/clock`` on a node) -> ROS type names."""

DEFAULT_TOPICS = ("joint_states", "rod_states", "bending", "node_poses", "applied_forces",
                  "markers")
"""Topics :func:`snapshot_messages` builds when ``topics`` is None."""

SNAPSHOT_TOPICS = DEFAULT_TOPICS + ("clock",)
"""Topics that a snapshot alone determines (``diagnostics`` needs :func:`diagnostics`)."""

BASE_TOPICS = ("base_odometry",)
"""Topics a snapshot determines on a moving (free or prescribed) base only."""


def divider(rate_hz: float, topic_rate_hz: float) -> int:
    """Samples (control periods) per message of a topic at ``topic_rate_hz`` when the states
    come at ``rate_hz``: k = max(1, round(rate_hz / topic_rate_hz)), counted from t = 0 (0:
    every sample): the node's ``markers_rate_hz`` and ``rod-sim simulate --markers-rate``
    (default and range: :mod:`rod_sim.app.limits`)."""
    return max(1, round(rate_hz / topic_rate_hz)) if topic_rate_hz > 0 else 1


FORCE_LAYOUT_LABELS = ("node", "xy")
"""``applied_forces``/``nodal_forces`` layout: a row-major (n, 2) array, dim[0] 'node'
(size n, stride 2n), dim[1] 'xy' (size 2, stride 2): data[2(k-1) + j] is X_k (j=0), Y_k (j=1)."""

TORQUE_LAYOUT_LABEL = "hinge"
"""``applied_torques``/``hinge_torques`` layout: one dim 'hinge' (size n, stride n):
data[h] is the motor moment T_h [N m] at hinge h (joint ``hinge_h``)."""

ROD_COLOR = {"r": 0.25, "g": 0.5, "b": 1.0, "a": 1.0}
NODE_COLOR = {"r": 1.0, "g": 0.5, "b": 0.0, "a": 1.0}
MARKER_DENSITY = 7850.0
"""[kg/m^3] density of the spheres drawn for the node masses (steel), sets their diameter."""

MARKER_LINE_STRIP = 4
MARKER_SPHERE_LIST = 7
MARKER_ADD = 0


# ----- time -----

def time_ns(t: float) -> int:
    """Simulated time ``t`` [s] as integer nanoseconds (rounded to the nearest ns).

    Raises ValueError for negative or non-finite times (ROS stamps are unsigned here).
    """
    t = float(t)
    if not math.isfinite(t) or t < 0.0:
        raise ValueError(f"time must be finite and >= 0 s (got {t!r})")
    return int(round(t * NS_PER_S))


def stamp(t: float) -> dict[str, int]:
    """``builtin_interfaces/Time`` dict ``{'sec', 'nanosec'}`` of ``t`` [s], exact to 1 ns."""
    return stamp_from_ns(time_ns(t))


def stamp_from_ns(t_ns: int) -> dict[str, int]:
    """``{'sec', 'nanosec'}`` of an integer time in ns (>= 0)."""
    if t_ns < 0:
        raise ValueError(f"time must be >= 0 ns (got {t_ns})")
    sec, nanosec = divmod(int(t_ns), NS_PER_S)
    return {"sec": sec, "nanosec": nanosec}


def header(t: float, frame_id: str) -> Msg:
    """``std_msgs/Header`` dict stamped at ``t`` [s]."""
    return {"stamp": stamp(t), "frame_id": frame_id}


def _floats(a: Iterable[float]) -> list[float]:
    return np.asarray(a, dtype=float).ravel().tolist()


@functools.lru_cache(maxsize=32)
def _names(prefix: str, first: int, count: int) -> tuple[str, ...]:
    """``prefix{first}`` .. ``prefix{first + count - 1}``, built once per chain size."""
    return tuple(f"{prefix}{k}" for k in range(first, first + count))


def _joint_state(t: float, frame_id: str, names: list[str], position, velocity=(),
                 effort=()) -> Msg:
    return {"header": header(t, frame_id), "name": names, "position": _floats(position),
            "velocity": _floats(velocity), "effort": _floats(effort)}


# ----- one builder per topic -----

def joint_states(snapshot: Snapshot, frame_id: str = "world") -> Msg:
    """``sensor_msgs/JointState``: hinges ``hinge_0..hinge_{n-1}``; position = relative rigid
    hinge angle [rad], velocity = its rate [rad/s], effort = elastic + viscous moment [N m]."""
    names = list(_names("hinge_", 0, snapshot.n))
    return _joint_state(snapshot.t, frame_id, names, snapshot.hinge_angle, snapshot.hinge_rate,
                        snapshot.hinge_moment)


def rod_states(snapshot: Snapshot, frame_id: str = "world") -> Msg:
    """``sensor_msgs/JointState``: ``rod_1..rod_n``; position = phi_k [rad], velocity =
    phi_dot_k [rad/s], effort empty."""
    names = list(_names("rod_", 1, snapshot.n))
    return _joint_state(snapshot.t, frame_id, names, snapshot.phi, snapshot.phi_rate)


def bending(snapshot: Snapshot, frame_id: str = "world") -> Msg:
    """``sensor_msgs/JointState``: ``alpha_1..alpha_n, beta_1..beta_n``; position = end slopes
    [rad] in that order; velocity and effort empty."""
    n = snapshot.n
    names = [*_names("alpha_", 1, n), *_names("beta_", 1, n)]
    return _joint_state(snapshot.t, frame_id, names,
                        np.concatenate([snapshot.alpha, snapshot.beta]))


def yaw_quaternion(angle: float) -> Msg:
    """``geometry_msgs/Quaternion`` of a rotation by ``angle`` [rad] about z."""
    return {"x": 0.0, "y": 0.0, "z": math.sin(0.5 * angle), "w": math.cos(0.5 * angle)}


def node_poses(snapshot: Snapshot, frame_id: str = "world") -> Msg:
    """``geometry_msgs/PoseArray`` of nodes 0..n: position (x_k, y_k, 0) [m]; orientation = the
    chord direction phi_k of rod k, the rod ending at node k (node 0: rod 1)."""
    nodes = np.asarray(snapshot.nodes, dtype=float)
    phi = np.asarray(snapshot.phi, dtype=float)
    half = 0.5 * np.concatenate([phi[:1], phi])[:len(nodes)]      # node k: rod max(k, 1)
    poses = [{"position": {"x": x, "y": y, "z": 0.0},
              "orientation": {"x": 0.0, "y": 0.0, "z": qz, "w": qw}}
             for x, y, qz, qw in zip(nodes[:, 0].tolist(), nodes[:, 1].tolist(),
                                     np.sin(half).tolist(), np.cos(half).tolist())]
    return {"header": header(snapshot.t, frame_id), "poses": poses}


def base_odometry(snapshot: Snapshot, frame_id: str = "world", child_frame_id: str = "base"
                  ) -> Msg:
    """``nav_msgs/Odometry`` of the base frame's origin (``snapshot.base``): pose in
    ``frame_id`` (x, y, 0) [m], yaw psi; twist in the base frame ``child_frame_id``, as
    nav_msgs defines it: linear R(psi)^T (x', y') [m/s], angular z psi' [rad/s]; covariances
    zero."""
    x, y, psi, vx, vy, w = (float(v) for v in snapshot.base)
    c, s = math.cos(psi), math.sin(psi)
    zero = [0.0] * 36
    return {"header": header(snapshot.t, frame_id), "child_frame_id": child_frame_id,
            "pose": {"pose": {"position": {"x": x, "y": y, "z": 0.0},
                              "orientation": yaw_quaternion(psi)}, "covariance": zero},
            "twist": {"twist": {"linear": {"x": c * vx + s * vy, "y": -s * vx + c * vy,
                                           "z": 0.0},
                                "angular": {"x": 0.0, "y": 0.0, "z": w}},
                      "covariance": list(zero)}}


def _marker(when: dict[str, int], frame_id: str, ns: str, marker_id: int, marker_type: int,
            width: float, color: Msg, points: list[list[float]]) -> Msg:
    """One marker stamped ``when`` ({'sec', 'nanosec'}); ``points``: [x, y] pairs [m] of
    Python floats (``ndarray.tolist()``: converting row by row from numpy is much slower)."""
    return {
        "header": {"stamp": dict(when), "frame_id": frame_id},
        "ns": ns,
        "id": marker_id,
        "type": marker_type,
        "action": MARKER_ADD,
        "pose": {"position": {"x": 0.0, "y": 0.0, "z": 0.0},
                 "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}},
        "scale": {"x": width, "y": width, "z": width},
        "color": dict(color),
        "lifetime": {"sec": 0, "nanosec": 0},
        "frame_locked": False,
        "points": [{"x": x, "y": y, "z": 0.0} for x, y in points],
    }


def marker_sizes(scene: Scene) -> tuple[float, float]:
    """(rod line width, node sphere diameter) [m] for ``markers``.

    Line width: 2 % of the mean rod length. Spheres: the diameter of a steel sphere
    (:data:`MARKER_DENSITY`) of the mean positive node mass, kept between 1.5 line widths and
    a quarter of the shortest rod; 2 line widths when every node mass is zero.
    """
    length = np.asarray(scene.length, dtype=float)
    width = 0.02 * float(np.mean(length))
    masses = np.asarray(scene.node_mass, dtype=float)
    masses = masses[masses > 0.0]
    if masses.size == 0:
        return width, 2.0 * width
    diameter = (6.0 * float(np.mean(masses)) / (math.pi * MARKER_DENSITY)) ** (1.0 / 3.0)
    return width, min(max(diameter, 1.5 * width), 0.25 * float(np.min(length)))


@functools.lru_cache(maxsize=8)
def _marker_geometry(scene: Scene, points_per_rod: int):
    """What :func:`markers` needs of a scene alone (a Scene is immutable and hashed by
    identity): the marker sizes and the rod shape table."""
    return (*marker_sizes(scene),
            shape_table(np.asarray(scene.length, dtype=float), points_per_rod))


MARKER_MAX_STRIPS = 256
"""Above this many rods the rods are drawn as one LINE_STRIP through the nodes instead of one
bent strip per rod: building and encoding a marker costs ~20 us in Python, so 1024 per-rod
strips took 20-34 ms, more than a 10 ms control period (measured at n = 1024)."""


def markers(snapshot: Snapshot, scene: Scene, frame_id: str = "world",
            points_per_rod: int = 11) -> Msg:
    """``visualization_msgs/MarkerArray``: one LINE_STRIP per rod (ns ``rods``, id k = 1..n)
    through ``points_per_rod`` points of the bent rod (paper eq. (4)) -- for chains of more
    than :data:`MARKER_MAX_STRIPS` rods one LINE_STRIP through nodes 0..n (ns ``rods``, id 0)
    instead --, and one SPHERE_LIST (ns ``nodes``, id 0) at nodes 1..n for the node masses
    (size from :func:`marker_sizes`). All ADD, lifetime 0 (forever), not frame-locked, z = 0."""
    when = stamp(snapshot.t)
    all_nodes = np.asarray(snapshot.nodes, dtype=float)
    if scene.n > MARKER_MAX_STRIPS:
        width, diameter = marker_sizes(scene)
        items = [_marker(when, frame_id, "rods", 0, MARKER_LINE_STRIP, width, ROD_COLOR,
                         all_nodes.tolist())]
    else:
        width, diameter, table = _marker_geometry(scene, points_per_rod)
        pts = rod_points(np.asarray(scene.length, dtype=float),
                         np.asarray(snapshot.phi, dtype=float),
                         np.asarray(snapshot.alpha, dtype=float),
                         np.asarray(snapshot.beta, dtype=float), points_per_rod, table)
        items = [_marker(when, frame_id, "rods", k + 1, MARKER_LINE_STRIP, width, ROD_COLOR,
                         rod) for k, rod in enumerate(pts.tolist())]
    items.append(_marker(when, frame_id, "nodes", 0, MARKER_SPHERE_LIST, diameter,
                         NODE_COLOR, all_nodes[1:].tolist()))
    return {"markers": items}


def force_array(forces: np.ndarray) -> Msg:
    """``std_msgs/Float64MultiArray`` of nodal forces (n, 2) [N]: data = [X_1, Y_1, ..., X_n,
    Y_n] with the layout of :data:`FORCE_LAYOUT_LABELS`."""
    f = np.asarray(forces, dtype=float).reshape(-1, 2)
    n = f.shape[0]
    return {"layout": {"dim": [{"label": FORCE_LAYOUT_LABELS[0], "size": n, "stride": 2 * n},
                               {"label": FORCE_LAYOUT_LABELS[1], "size": 2, "stride": 2}],
                       "data_offset": 0},
            "data": _floats(f)}


def torque_array(torques) -> Msg:
    """``std_msgs/Float64MultiArray`` of hinge torques (n,) [N m]: data = [T_0, ..., T_{n-1}]
    in joint order hinge_0..hinge_{n-1}, layout dim 'hinge' (:data:`TORQUE_LAYOUT_LABEL`)."""
    t = np.asarray(torques, dtype=float).reshape(-1)
    return {"layout": {"dim": [{"label": TORQUE_LAYOUT_LABEL, "size": t.size,
                                "stride": t.size}], "data_offset": 0},
            "data": _floats(t)}


def applied_forces(snapshot: Snapshot) -> Msg:
    """``std_msgs/Float64MultiArray`` of the applied forces of ``snapshot`` (see :func:`force_array`)."""
    return force_array(snapshot.forces)


def clock(t: float) -> Msg:
    """``rosgraph_msgs/Clock`` at simulated time ``t`` [s]."""
    return {"clock": stamp(t)}


DIAGNOSTIC_OK, DIAGNOSTIC_WARN, DIAGNOSTIC_ERROR, DIAGNOSTIC_STALE = 0, 1, 2, 3
DIAGNOSTICS_STATUS_NAME = "rod_sim: simulation"
"""The status name of the node's ``/diagnostics`` (and of ``simulate``'s per-sample ones)."""


def diagnostics(t: float, values: Mapping[str, Any], hardware_id: str, *,
                level: int = DIAGNOSTIC_OK, message: str = "", frame_id: str = "",
                name: str = "rod_sim") -> Msg:
    """``diagnostic_msgs/DiagnosticArray`` with one status called ``name``.

    ``values``: key -> value (non-strings are converted with ``str``); ``hardware_id``: the
    scene name; ``level``: 0 OK, 1 WARN, 2 ERROR, 3 STALE.
    """
    if level not in (DIAGNOSTIC_OK, DIAGNOSTIC_WARN, DIAGNOSTIC_ERROR, DIAGNOSTIC_STALE):
        raise ValueError(f"diagnostic level must be 0..3 (got {level!r})")
    status = {"level": int(level), "name": str(name), "message": str(message),
              "hardware_id": str(hardware_id),
              "values": [{"key": str(k), "value": v if isinstance(v, str) else str(v)}
                         for k, v in values.items()]}
    return {"header": header(t, frame_id), "status": [status]}


_BUILDERS: dict[str, Callable[[Snapshot, Scene, str], Msg]] = {
    "joint_states": lambda s, scene, f: joint_states(s, f),
    "rod_states": lambda s, scene, f: rod_states(s, f),
    "bending": lambda s, scene, f: bending(s, f),
    "node_poses": lambda s, scene, f: node_poses(s, f),
    "base_odometry": lambda s, scene, f: base_odometry(s, f),
    "markers": lambda s, scene, f: markers(s, scene, f),
    "applied_forces": lambda s, scene, f: applied_forces(s),
    "clock": lambda s, scene, f: clock(s.t),
}


def snapshot_messages(snapshot: Snapshot, scene: Scene, frame_id: str = "world",
                      topics: Iterable[str] | None = None) -> dict[str, Msg]:
    """Message dicts of ``snapshot`` keyed by relative topic name (types in :data:`TOPIC_TYPES`).

    ``topics`` defaults to :data:`DEFAULT_TOPICS`; any of :data:`SNAPSHOT_TOPICS` may be asked
    for. Raises ValueError for other names or a snapshot that does not match the scene.
    """
    if snapshot.n != scene.n:
        raise ValueError(f"snapshot has {snapshot.n} rods but the scene {scene.name!r} has {scene.n}")
    wanted = DEFAULT_TOPICS if topics is None else tuple(topics)
    unknown = [t for t in wanted if t not in _BUILDERS]
    if unknown:
        raise ValueError(f"cannot build topic(s) {', '.join(unknown)} from a snapshot "
                         f"(choose from {', '.join(SNAPSHOT_TOPICS + BASE_TOPICS)})")
    return {name: _BUILDERS[name](snapshot, scene, frame_id) for name in wanted}
