"""Time series of one topic of a log, as arrays: :func:`read_rod_states` (the rod angles and
rates), :func:`read_joint_states` (the hinge angles), :func:`read_base_odometry` and
:func:`read_applied_forces`. The log is any that :func:`rod_sim.io.log_open.open_log`
opens (an MCAP file, complete or truncated, or a rosbag2 bag); topics are found under any one
namespace. Errors: LogFormatError (one line).
"""
from __future__ import annotations

import os

import numpy as np

from rod_sim.io.log_format import LogFormatError
from rod_sim.io.log_open import open_log
from rod_sim.io.log_source import valid_rod_names
from rod_sim.io.topic_names import base_name


def read_base_odometry(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """``(t (N,) [s], base (N, 3))`` from ``base_odometry``: the base frame's origin x, y [m]
    and its angle psi [rad], unwrapped over the samples (the quaternion gives it modulo
    2 pi). LogFormatError when the log has no such message."""
    times, base = [], []
    topic = "/base_odometry"
    with open_log(path) as log:
        topic = log.resolve([topic]).get(base_name(topic), topic)
        for _, t_ns, msg in log.messages([topic]):
            p = msg.pose.pose
            times.append(t_ns)
            base.append((p.position.x, p.position.y,
                         2.0 * np.arctan2(p.orientation.z, p.orientation.w)))
    if not times:
        raise LogFormatError(f"{path} has no {topic} messages")
    base = np.asarray(base, dtype=float)
    base[:, 2] = np.unwrap(base[:, 2])
    return np.asarray(times, dtype=np.int64) / 1e9, base


def _joint_series(path, topic: str, prefix: str | None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
    times, position, velocity = [], [], []
    names = None
    with open_log(path) as log:
        topic = log.resolve([topic]).get(base_name(topic), topic)
        for _, t_ns, msg in log.messages([topic]):
            if names is None:
                names = list(msg.name)
                expected = [f"{prefix}{k}" for k in range(1, len(names) + 1)]
                if prefix is not None and names != expected and not (
                        prefix == "rod_" and valid_rod_names(names)):
                    raise LogFormatError(f"{path}: {topic} names {names} are not {prefix}1..")
            elif list(msg.name) != names:
                raise LogFormatError(f"{path}: {topic} changes its joint names at {t_ns} ns")
            times.append(t_ns)
            position.append(list(msg.position))
            velocity.append(list(msg.velocity))
    if not times:
        raise LogFormatError(f"{path} has no {topic} messages")
    return (np.asarray(times, dtype=np.int64) / 1e9, np.asarray(position, dtype=float),
            np.asarray(velocity, dtype=float), names)


def read_rod_states(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(t (N,) [s], phi (N, n) [rad], phi_rate (N, n) [rad/s])`` from the ``rod_states`` topic
    of a log (complete or truncated; under any one namespace). Raises LogFormatError if it has
    none."""
    return _joint_series(path, "/rod_states", "rod_")[:3]


def read_joint_states(path: str | os.PathLike
                      ) -> tuple[np.ndarray, list[str], np.ndarray, np.ndarray]:
    """``(t (N,) [s], names (m,), position (N, m), velocity (N, m))`` from ``joint_states``: the
    hinges' relative angles [rad] and rates [rad/s] (``hinge_0`` .. in the order of the
    scene's chains), then on a moving base its joints (docs/interface.md section 3). Raises
    LogFormatError if the log has none or the names change."""
    t, position, velocity, names = _joint_series(path, "/joint_states", None)
    return t, names, position, velocity


def read_applied_forces(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """``(t (N,) [s], forces (N, n, 2) [N])`` from ``/applied_forces`` (rows X_k, Y_k).
    Raises LogFormatError if the log has none or a message is not of even length."""
    times, forces = [], []
    with open_log(path) as log:
        topic = log.resolve(["applied_forces"]).get("applied_forces", "/applied_forces")
        for _, t_ns, msg in log.messages([topic]):
            data = np.asarray(msg.data, dtype=float)
            if data.size % 2:
                raise LogFormatError(f"{path}: /applied_forces at {t_ns} ns has odd length {data.size}")
            times.append(t_ns)
            forces.append(data.reshape(-1, 2))
    if not times:
        raise LogFormatError(f"{path} has no /applied_forces messages")
    if len({f.shape for f in forces}) != 1:
        raise LogFormatError(f"{path}: /applied_forces changes length")
    return np.asarray(times, dtype=np.int64) / 1e9, np.stack(forces)
