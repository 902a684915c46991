"""Read what ``rod-sim compare`` needs from a log: one MCAP file or a rosbag2 bag directory.

A bag directory holds ``metadata.yaml`` (rosbag2's ``rosbag2_bagfile_information`` with
``storage_identifier: mcap`` and ``relative_file_paths``) and the ``.mcap`` files it lists; they
are read in that order (without ``metadata.yaml``: every ``*.mcap`` in name order) and their
messages merged in log-time order.

What is read (n rods; times in integer ns of simulated time):

- ``/rod_states``: phi (N, n) [rad], phi_rate (N, n) [rad/s];
- ``/bending``: alpha, beta (Nb, n) [rad] (optional topic);
- ``/node_poses``: node positions (Np, n+1, 2) [m] (optional topic);
- ``/applied_forces``: forces (K, n, 2) [N] = scripted loads + held command, valid from the
  message time on (a zero-order hold of the command part).

The time of a state message is its header stamp; a log whose stamps and log times disagree
is refused (:class:`~rod_sim.io.mcap_log.LogFormatError`): ``/applied_forces`` has no header,
so its log time is the only clock it has, and that clock must be simulated time. Every problem
that makes a log unusable is a LogFormatError with a one-line message; problems that only limit
what can be said (a truncated file, duplicate messages) are collected in ``LogData.notes``.
"""
from __future__ import annotations

import contextlib
import io
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from rod_sim.io.mcap_log import METADATA_NAME, LogFormatError, LogReader

STATE_TOPIC = "/rod_states"
BENDING_TOPIC = "/bending"
POSES_TOPIC = "/node_poses"
APPLIED_TOPIC = "/applied_forces"
TOPICS = (STATE_TOPIC, BENDING_TOPIC, POSES_TOPIC, APPLIED_TOPIC)

@dataclass
class Series:
    """Samples of one topic: ``t_ns`` (N,) int64 [ns] sorted, ``values`` (N, ...) float."""

    t_ns: np.ndarray
    values: np.ndarray

    def __len__(self) -> int:
        return int(self.t_ns.size)


@dataclass
class LogData:
    """Everything ``compare`` reads from a log (see the module docstring for units).

    ``metadata``: the ``rod_sim`` record (str -> str) or None; ``files``: the MCAP files read;
    ``truncated``: some file ended in an incomplete record (its readable part was used);
    ``notes``: one-line remarks about what was found and how it was handled.
    """

    path: Path
    files: list[Path]
    metadata: dict[str, str] | None
    n: int
    phi: Series
    phi_rate: Series
    alpha: Series | None
    beta: Series | None
    nodes: Series | None
    applied: Series
    truncated: bool = False
    notes: list[str] = field(default_factory=list)


def log_files(path: str | os.PathLike) -> list[Path]:
    """The MCAP files of ``path``: [path] for a file, the bag's files in order for a directory.

    Raises LogFormatError (one line) for a missing path, a bag without MCAP files or a bag
    whose metadata.yaml names another storage or a missing file."""
    path = Path(path)
    if not path.exists():
        raise LogFormatError(f"{path}: no such file or directory")
    if path.is_file():
        return [path]
    meta = path / "metadata.yaml"
    if not meta.is_file():
        files = sorted(path.glob("*.mcap"))
        if not files:
            raise LogFormatError(f"{path}: a directory without metadata.yaml or .mcap files "
                                 "is not a rosbag2 bag")
        return files
    try:
        info = yaml.safe_load(meta.read_text(encoding="utf-8"))["rosbag2_bagfile_information"]
        storage = str(info.get("storage_identifier", "mcap"))
        names = [str(p) for p in info["relative_file_paths"]]
    except (yaml.YAMLError, KeyError, TypeError, AttributeError, UnicodeDecodeError) as exc:
        raise LogFormatError(f"{meta}: not a rosbag2 metadata file "
                             f"({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''})"
                             ) from None
    if storage != "mcap":
        raise LogFormatError(f"{path}: bag storage is {storage!r}; only 'mcap' bags can be read")
    files = [path / name for name in names]
    missing = [str(f) for f in files if not f.is_file()]
    if missing:
        raise LogFormatError(f"{path}: bag file {missing[0]} listed in metadata.yaml is missing")
    if not files:
        raise LogFormatError(f"{path}: metadata.yaml lists no files")
    return files


def _stamp_ns(msg: Any) -> int:
    stamp = msg.header.stamp
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _read_file(path: Path, raw: dict[str, list], notes: list[str],
               namespace: str | None) -> tuple[dict | None, bool]:
    """Append (log_time, stamp or None, msg) of :data:`TOPICS` (found under any namespace, or
    under ``namespace``) to ``raw``; return (rod_sim metadata or None, truncated)."""
    with LogReader(path) as reader:
        try:
            metadata = reader.metadata(METADATA_NAME)
        except LogFormatError:
            metadata = None
        logged = reader.resolve(TOPICS, namespace)
        ours = {name: "/" + base for base, name in logged.items()}
        renamed = sorted(name for name, topic in ours.items() if name != topic)
        if renamed:
            notes.append(f"{path.name}: read {', '.join(renamed)}")
        for name, log_ns, msg in reader.messages(list(ours)):
            topic = ours[name]
            stamp = None if topic == APPLIED_TOPIC else _stamp_ns(msg)
            raw[topic].append((int(log_ns), stamp, msg))
        truncated = reader.truncated or not reader.complete
        if not reader.complete:
            notes.append(f"{path.name} has no summary (writer stopped before closing it); "
                         "read by scanning" + (", last record incomplete" if reader.truncated
                                               else ""))
    return metadata, truncated


def _dedupe(topic: str, items: list, key, notes: list[str], *, last_wins: bool = False) -> list:
    """Sort by time (stable) and resolve messages sharing one time: identical ones are merged;
    different ones are refused, or for ``last_wins`` the last in file order is kept."""
    items = sorted(items, key=lambda it: it[0])
    out: list = []
    dropped = 0
    for item in items:
        if out and out[-1][0] == item[0]:
            same = np.array_equal(key(out[-1][1]), key(item[1]))
            if not same and not last_wins:
                raise LogFormatError(f"two different {topic} messages at t = {item[0] / 1e9:.9g} s "
                                     "(a tampered or merged log?)")
            out[-1] = item
            dropped += 1
        else:
            out.append(item)
    if dropped:
        notes.append(f"{dropped} {topic} message(s) repeat the time of an earlier one"
                     + ("; the last one at each time is used" if last_wins else
                        " with identical content; merged"))
    return out


def _joint(msg: Any) -> tuple[list[str], np.ndarray, np.ndarray]:
    return (list(msg.name), np.asarray(msg.position, dtype=float),
            np.asarray(msg.velocity, dtype=float))


def read_log(path: str | os.PathLike, namespace: str | None = None) -> LogData:
    """Read a log file or bag directory (see the module docstring). The topics are found under
    any namespace (``/arm1/rod_states`` as well as ``/rod_states``); a log holding them under
    two namespaces needs ``namespace``. Raises LogFormatError."""
    path = Path(path)
    files = log_files(path)
    raw: dict[str, list] = {t: [] for t in TOPICS}
    notes: list[str] = []
    metadata = None
    truncated = False
    for f in files:
        try:
            # mcap_ros2's vendored .msg parser prints to stderr before raising on a corrupt
            # schema; the error is re-raised below as one line, so the print is dropped
            with contextlib.redirect_stderr(io.StringIO()):
                meta, cut = _read_file(f, raw, notes, namespace)
        except LogFormatError:
            raise
        except Exception as exc:  # noqa: BLE001 - a corrupt file can fail in any decoder
            text = str(exc).splitlines()[0] if str(exc) else ""
            raise LogFormatError(f"{f}: corrupt or unreadable ({type(exc).__name__}: {text})"
                                 ) from None
        truncated |= cut
        if metadata is None and meta is not None:
            metadata = meta

    # ----- time base: header stamps of the state topics must be the log times -----
    for topic in (STATE_TOPIC, BENDING_TOPIC, POSES_TOPIC):
        bad = [(log_ns, stamp) for log_ns, stamp, _ in raw[topic] if log_ns != stamp]
        if bad:
            log_ns, stamp = bad[0]
            raise LogFormatError(
                f"{topic}: {len(bad)} message(s) whose log time differs from the header stamp "
                f"(first: log {log_ns / 1e9:.9g} s, stamp {stamp / 1e9:.9g} s); the log times "
                "are not simulated time (a live recording?) or the log was altered, so the "
                "applied-force history (no header) cannot be placed in simulated time")

    if not raw[STATE_TOPIC]:
        raise LogFormatError(f"{path}: no {STATE_TOPIC} messages" + (" in the readable part "
                                                                      "of a truncated log"
                                                                      if truncated else ""))
    if not raw[APPLIED_TOPIC]:
        raise LogFormatError(f"{path}: no {APPLIED_TOPIC} messages, so the applied-force "
                             "history cannot be rebuilt")

    # ----- rod states -----
    states = _dedupe(STATE_TOPIC, [(t, _joint(m)) for t, _, m in raw[STATE_TOPIC]],
                     lambda j: np.concatenate([j[1], j[2]]), notes)
    names = states[0][1][0]
    n = len(names)
    if n == 0 or names != [f"rod_{k}" for k in range(1, n + 1)]:
        raise LogFormatError(f"{STATE_TOPIC} names {names[:4]}... are not rod_1..rod_n")
    for t, (nm, pos, vel) in states:
        if nm != names or pos.size != n or vel.size != n:
            raise LogFormatError(f"{STATE_TOPIC} at t = {t / 1e9:.9g} s has {len(nm)} names, "
                                 f"{pos.size} positions, {vel.size} velocities (expected {n})")
    t_states = np.array([t for t, _ in states], dtype=np.int64)
    phi = Series(t_states, np.array([j[1] for _, j in states]))
    phi_rate = Series(t_states, np.array([j[2] for _, j in states]))

    # ----- bending -----
    alpha = beta = None
    if raw[BENDING_TOPIC]:
        bend = _dedupe(BENDING_TOPIC, [(t, _joint(m)) for t, _, m in raw[BENDING_TOPIC]],
                       lambda j: j[1], notes)
        want = [f"alpha_{k}" for k in range(1, n + 1)] + [f"beta_{k}" for k in range(1, n + 1)]
        for t, (nm, pos, _) in bend:
            if nm != want or pos.size != 2 * n:
                raise LogFormatError(f"{BENDING_TOPIC} at t = {t / 1e9:.9g} s does not hold "
                                     f"alpha_1..alpha_{n}, beta_1..beta_{n}")
        tb = np.array([t for t, _ in bend], dtype=np.int64)
        values = np.array([j[1] for _, j in bend])
        alpha, beta = Series(tb, values[:, :n]), Series(tb, values[:, n:])
    else:
        notes.append(f"no {BENDING_TOPIC} messages: alpha, beta not compared")

    # ----- node poses -----
    nodes = None
    if raw[POSES_TOPIC]:
        def xy(msg):
            return np.array([[p.position.x, p.position.y] for p in msg.poses], dtype=float)

        poses = _dedupe(POSES_TOPIC, [(t, xy(m)) for t, _, m in raw[POSES_TOPIC]],
                        lambda a: a, notes)
        for t, a in poses:
            if a.shape != (n + 1, 2):
                raise LogFormatError(f"{POSES_TOPIC} at t = {t / 1e9:.9g} s has {a.shape[0]} "
                                     f"poses (expected {n + 1}: nodes 0..{n})")
        nodes = Series(np.array([t for t, _ in poses], dtype=np.int64),
                       np.array([a for _, a in poses]))
    else:
        notes.append(f"no {POSES_TOPIC} messages: node positions not compared")

    # ----- applied forces -----
    forces = []
    for t, _, m in raw[APPLIED_TOPIC]:
        data = np.asarray(m.data, dtype=float)
        if data.size != 2 * n:
            raise LogFormatError(f"{APPLIED_TOPIC} at t = {t / 1e9:.9g} s has {data.size} "
                                 f"values (expected 2n = {2 * n})")
        if not np.all(np.isfinite(data)):
            raise LogFormatError(f"{APPLIED_TOPIC} at t = {t / 1e9:.9g} s has a non-finite value")
        forces.append((t, data.reshape(n, 2)))
    forces = _dedupe(APPLIED_TOPIC, forces, lambda a: a, notes, last_wins=True)
    applied = Series(np.array([t for t, _ in forces], dtype=np.int64),
                     np.array([a for _, a in forces]))
    if truncated:
        notes.append("the log is truncated: only its readable part is compared")
    return LogData(path=path, files=files, metadata=metadata, n=n, phi=phi, phi_rate=phi_rate,
                   alpha=alpha, beta=beta, nodes=nodes, applied=applied, truncated=truncated,
                   notes=notes)
