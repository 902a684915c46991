"""Read what ``rod-sim compare`` needs from a log, as a stream: any log that
:func:`rod_sim.io.log_open.open_log` opens (an MCAP file; a rosbag2 bag directory of mcap or
sqlite3 storage, compressed or not, with or without ``metadata.yaml``), the messages of its
files merged in log-time order.

What is read (n rods; times in integer ns of simulated time), under any one namespace
(``/arm1/rod_states`` as well as ``/rod_states``):

- ``rod_states``: phi (n,) [rad], phi_rate (n,) [rad/s];
- ``bending``: alpha, beta (n,) [rad] (optional topic);
- ``node_poses``: node positions (n+1, 2) [m] (optional topic; a spacecraft scene: every
  chain's nodes and the base's origin, (n + chains + 1, 2));
- ``applied_base``: [Fx, Fy, M, T_w] on a free base (scripted + held), from its log time on
  (optional topic, node logs);
- ``base_odometry``: the base frame's origin and angle (x, y [m], psi [rad] in (-2 pi, 2 pi])
  (optional topic, moving bases);
- ``applied_forces``: forces (n, 2) [N] = scripted loads + held command, valid from the
  message time on (a zero-order hold of the command part);
- ``applied_torques``: hinge motor moments (n,) [N m] = the held ``hinge_torques`` command,
  valid from the message time on (optional topic: a log without it had no torques).

:meth:`LogStream.groups` yields them one log time at a time, so memory does not grow with the
log's length (each file's reader holds only the chunks whose time ranges overlap). The time of
a state message is its header stamp; a log whose stamps and log times disagree is refused
(:class:`~rod_sim.io.log_format.LogFormatError`): ``applied_forces`` has no header, so its log
time is the only clock it has, and that clock must be simulated time. Every problem that makes
a log unusable is a LogFormatError with a one-line message; problems that only limit what can
be said (a truncated file, duplicate messages) are collected in ``LogStream.notes``.
"""
from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from rod_sim.io.log_format import METADATA_NAME, LogFormatError
from rod_sim.io.log_open import OpenedLog, open_log
from rod_sim.io.log_reader import LogReader
from rod_sim.io.topic_names import base_name, namespace_of, resolve_topics

STATE_TOPIC = "/rod_states"
BENDING_TOPIC = "/bending"
POSES_TOPIC = "/node_poses"
APPLIED_TOPIC = "/applied_forces"
TORQUES_TOPIC = "/applied_torques"
BASE_TOPIC = "/base_odometry"
APPLIED_BASE_TOPIC = "/applied_base"
SCENE_TOPIC = "/scene"
"""Latched std_msgs/String with the scene as YAML (not part of :data:`TOPICS`: read once)."""
TOPICS = (STATE_TOPIC, BENDING_TOPIC, POSES_TOPIC, APPLIED_TOPIC, TORQUES_TOPIC, BASE_TOPIC,
          APPLIED_BASE_TOPIC)
HOLD_TOPICS = (APPLIED_TOPIC, TORQUES_TOPIC, APPLIED_BASE_TOPIC)
"""Topics without a header whose messages hold from their log time on (the last one at a
repeated time is used)."""


@dataclass
class Group:
    """The messages of one log time ``t_ns`` [ns], at most one per topic (duplicates resolved):
    ``state`` (phi (n,), phi_rate (n,)), ``bending`` (alpha (n,), beta (n,)), ``nodes``
    (n+1, 2) or more rows, ``applied`` (n, 2), ``torques`` (n,), ``base`` (x, y, psi) (3,);
    None where the topic has no message at this time."""

    t_ns: int
    state: tuple[np.ndarray, np.ndarray] | None = None
    bending: tuple[np.ndarray, np.ndarray] | None = None
    nodes: np.ndarray | None = None
    applied: np.ndarray | None = None
    torques: np.ndarray | None = None
    base: np.ndarray | None = None
    applied_base: np.ndarray | None = None


def _stamp_ns(msg: Any) -> int:
    stamp = msg.header.stamp
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


@dataclass
class LogStream:
    """A log opened for :meth:`groups` (see the module docstring for units).

    ``metadata``: the ``rod_sim`` record (str -> str) or None; ``files``: the MCAP files;
    ``topics``: our base topic -> the logged name; ``complete``: every file has its summary.
    After :meth:`groups` has run: ``n`` (rods), ``truncated`` (some file ended in an incomplete
    record; its readable part was used), ``notes`` (one-line remarks) and ``counts`` (messages
    read per topic). Opening checks every file's integrity (:class:`LogReader`).
    """

    path: Path
    files: list[Path]
    metadata: dict[str, str] | None
    topics: list[dict[str, str]]
    complete: bool
    n: int | None = None
    rod_names: list[str] | None = None
    """The ``rod_states`` names (``rod_k``, or ``<chain>/rod_k`` with ``chains:``)."""
    _bending_names: list[str] | None = field(default=None, repr=False)
    """The ``bending`` names those imply (alpha_k then beta_k), made once."""
    truncated: bool = False
    notes: list[str] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=lambda: {t: 0 for t in TOPICS})
    _log: OpenedLog | None = field(default=None, repr=False)

    @property
    def _readers(self) -> list[LogReader]:
        return self._log.readers if self._log is not None else []

    @property
    def end_ns(self) -> int | None:
        """[ns] the log time of the last message of every file, from their summaries; None
        when a file has no statistics (truncated, damaged, or written without them)."""
        ends = [r.message_end_ns for r in self._readers]
        return max(ends) if ends and None not in ends else None

    def close(self) -> None:
        if self._log is not None:
            self._log.close()

    def topic_scene(self):
        """The :class:`~rod_sim.core.scene.Scene` of the log's latched ``scene`` topic (YAML in
        a std_msgs/String, in the namespace of its ``rod_states``), None without one: what a
        log converted by rosbag2 tools, which drop MCAP metadata, still holds. Raises
        LogFormatError for an invalid scene."""
        for reader, names in zip(self._readers, self.topics):
            state = names.get(STATE_TOPIC.lstrip("/"))
            prefix = namespace_of(state).rstrip("/") if state else ""
            topic = f"{prefix}{SCENE_TOPIC}"
            if topic not in reader.topics():
                continue
            for _, _, msg in reader.messages([topic]):
                return metadata_scene({"scene": str(msg.data)}, f"{self.path} ({topic})")
        return None

    def scene(self):
        """(the log's :class:`~rod_sim.core.scene.Scene`, where it came from) or (None, ''):
        the ``rod_sim`` metadata record first, else the latched ``scene`` topic (a log
        converted by rosbag2 tools keeps the topic, not the metadata). The one way every tool
        (compare, deployment-figure) finds a log's scene. Raises LogFormatError for an
        invalid scene."""
        logged = metadata_scene(self.metadata, str(self.path))
        if logged is not None:
            return logged, "the log's metadata"
        logged = self.topic_scene()
        return (logged, "the log's /scene topic") if logged is not None else (None, "")

    def __enter__(self) -> "LogStream":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _messages(self) -> Iterator[tuple[int, str, Any]]:
        """(log time [ns], our base topic, message) in log-time order. The names found
        in each file map back to ours by their base name (each file's topics lie in one
        namespace, :func:`read_log`)."""
        logged = sorted({name for names in self.topics for name in names.values()})
        for topic, log_ns, msg in self._log.messages(logged):
            yield log_ns, "/" + base_name(topic), msg

    def groups(self) -> Iterator[Group]:
        """The log's messages grouped by log time, in time order (see :class:`Group`).
        Messages of one topic sharing a time: identical ones are merged; different state
        messages are refused, different applied forces: the last one in file order is used
        (the node re-records a period's start after a failed step). Raises LogFormatError."""
        pending: dict[str, list] = {}
        t_group = None
        self._dup = {t: 0 for t in TOPICS}
        messages = self._messages()
        try:
            while True:
                item = next(messages, None)       # (the parser's stderr print: log_reader)
                if item is None:
                    break
                log_ns, topic, msg = item
                if t_group is not None and log_ns != t_group:
                    yield self._group(t_group, pending)
                    pending = {}
                t_group = log_ns
                self.counts[topic] += 1
                pending.setdefault(topic, []).append(msg)
            if t_group is not None:
                yield self._group(t_group, pending)
        except (LogFormatError, MemoryError):
            raise
        except Exception as exc:  # noqa: BLE001 - a corrupt file can fail in any decoder
            text = " ".join(str(exc).split())[:200]
            raise LogFormatError(f"{self.path}: corrupt or unreadable ({type(exc).__name__}: "
                                 f"{text})") from None
        dup = self._dup
        for topic, count in dup.items():
            if count:
                self.notes.append(f"{count} {topic} message(s) repeat the time of an earlier one"
                                  + ("; the last one at each time is used"
                                     if topic in HOLD_TOPICS else
                                     " with identical content; merged"))
        self.truncated = any(r.truncated or not (r.complete or r.damaged) for r in self._readers)
        if self.truncated:
            self.notes.append("the log is truncated: only its readable part is compared")
        for reader in self._readers:
            self.notes.extend(w.split(": ", 1)[-1] for w in reader.warnings)

    def _group(self, t_ns: int, pending: dict[str, list]) -> Group:
        """Decode the messages of one log time (states first: they fix n) and resolve
        repeated ones (see :meth:`groups`)."""
        values: dict[str, Any] = {}
        for topic in TOPICS:
            for msg in pending.get(topic, ()):
                value = self._decode(topic, t_ns, msg)
                if topic in values:
                    same = all(np.array_equal(a, b) for a, b in
                               zip(np.atleast_1d(values[topic]), np.atleast_1d(value)))
                    if not same and topic not in HOLD_TOPICS:
                        raise LogFormatError(f"two different {topic} messages at t = "
                                             f"{t_ns / 1e9:.9g} s (a tampered or merged log?)")
                    self._dup[topic] += 1
                values[topic] = value
        applied = values.get(APPLIED_TOPIC)
        if applied is not None and applied.ndim == 1 and self.n is not None:
            applied = self.applied_array(t_ns, applied)
        torques = values.get(TORQUES_TOPIC)
        if torques is not None and self.n is not None:
            torques = self.torque_array(t_ns, torques)
        return Group(t_ns, state=values.get(STATE_TOPIC), bending=values.get(BENDING_TOPIC),
                     nodes=values.get(POSES_TOPIC), applied=applied, torques=torques,
                     base=values.get(BASE_TOPIC), applied_base=values.get(APPLIED_BASE_TOPIC))

    def _decode(self, topic: str, log_ns: int, msg: Any):
        """The arrays of one message, checked against the first state message's n."""
        t = f"{log_ns / 1e9:.9g}"
        if topic not in HOLD_TOPICS and _stamp_ns(msg) != log_ns:
            raise LogFormatError(
                f"{topic}: a message whose log time differs from the header stamp (log {t} s, "
                f"stamp {_stamp_ns(msg) / 1e9:.9g} s); the log times are not simulated time (a "
                "live recording?) or the log was altered, so the applied-force history (no "
                "header) cannot be placed in simulated time")
        if topic == STATE_TOPIC:
            names = list(msg.name)
            if self.n is None:
                n = len(names)
                if n == 0 or not valid_rod_names(names):
                    raise LogFormatError(f"{STATE_TOPIC} names {names[:4]}... are not "
                                         "rod_1..rod_n (or <chain>/rod_1.. per chain)")
                self.n, self.rod_names = n, names
            n = self.n
            pos = np.asarray(msg.position, dtype=float)
            vel = np.asarray(msg.velocity, dtype=float)
            if len(names) != n or names[-1] != self.rod_names[-1] or pos.size != n \
                    or vel.size != n:
                raise LogFormatError(f"{STATE_TOPIC} at t = {t} s has {len(names)} names, "
                                     f"{pos.size} positions, {vel.size} velocities (expected {n})")
            return pos, vel
        if topic == APPLIED_BASE_TOPIC:
            data = np.asarray(msg.data, dtype=float).reshape(-1)
            if data.size != 4 or not np.all(np.isfinite(data)):
                raise LogFormatError(f"{APPLIED_BASE_TOPIC} at t = {t} s is not 4 finite values "
                                     "[Fx, Fy, M, T_w]")
            return data
        if topic == TORQUES_TOPIC:
            data = np.asarray(msg.data, dtype=float)     # checked once n is known
            return data if self.n is None else self.torque_array(log_ns, data)
        if self.n is None:
            if topic == APPLIED_TOPIC:
                return np.asarray(msg.data, dtype=float)     # checked once n is known
            raise LogFormatError(f"{topic} at t = {t} s comes before the first {STATE_TOPIC}")
        n = self.n
        if topic == BENDING_TOPIC:
            if self._bending_names is None:
                self._bending_names = [_renamed(r, "alpha_") for r in self.rod_names] + \
                    [_renamed(r, "beta_") for r in self.rod_names]
            pos = np.asarray(msg.position, dtype=float)
            if list(msg.name) != self._bending_names or pos.size != 2 * n:
                raise LogFormatError(f"{BENDING_TOPIC} at t = {t} s does not hold "
                                     f"alpha_1..alpha_{n}, beta_1..beta_{n} (the rods' names)")
            return pos[:n], pos[n:]
        if topic == POSES_TOPIC:
            fast = getattr(msg, "positions", None)        # rod_sim.io.fast_decode's PoseArray
            xy = (np.array(fast[:, :2]) if fast is not None else
                  np.array([[p.position.x, p.position.y] for p in msg.poses], dtype=float))
            if xy.ndim != 2 or xy.shape[0] < n + 1:
                raise LogFormatError(f"{POSES_TOPIC} at t = {t} s has {xy.shape[0]} poses "
                                     f"(expected at least {n + 1}: nodes 0..{n})")
            return xy
        if topic == BASE_TOPIC:
            p = msg.pose.pose
            return np.array([p.position.x, p.position.y,
                             2.0 * np.arctan2(p.orientation.z, p.orientation.w)], dtype=float)
        return self.applied_array(log_ns, np.asarray(msg.data, dtype=float))

    def applied_array(self, log_ns: int, data: np.ndarray) -> np.ndarray:
        """``applied_forces`` data as (n, 2) [N]; LogFormatError for a wrong size or a
        non-finite value."""
        t = f"{log_ns / 1e9:.9g}"
        if data.size != 2 * self.n:
            raise LogFormatError(f"{APPLIED_TOPIC} at t = {t} s has {data.size} values "
                                 f"(expected 2n = {2 * self.n})")
        if not np.all(np.isfinite(data)):
            raise LogFormatError(f"{APPLIED_TOPIC} at t = {t} s has a non-finite value")
        return data.reshape(self.n, 2)

    def torque_array(self, log_ns: int, data: np.ndarray) -> np.ndarray:
        """``applied_torques`` data as (n,) [N m]; LogFormatError for a wrong size or a
        non-finite value."""
        t = f"{log_ns / 1e9:.9g}"
        data = np.asarray(data, dtype=float).reshape(-1)
        if data.size != self.n:
            raise LogFormatError(f"{TORQUES_TOPIC} at t = {t} s has {data.size} values "
                                 f"(expected n = {self.n})")
        if not np.all(np.isfinite(data)):
            raise LogFormatError(f"{TORQUES_TOPIC} at t = {t} s has a non-finite value")
        return data

    @property
    def has_torques(self) -> bool:
        """Whether any file of the log has an ``applied_torques`` topic."""
        return any(TORQUES_TOPIC.lstrip("/") in names for names in self.topics)


def valid_rod_names(names: list[str]) -> bool:
    """Whether ``names`` are rod_1..rod_n, or per chain ``<chain>/rod_1..`` (chains one after
    the other, each once)."""
    seen, prefix, k = set(), None, 0
    for name in names:
        head, _, tail = name.rpartition("/")
        if head != prefix:
            if head in seen:
                return False
            seen.add(head)
            prefix, k = head, 0
        k += 1
        if tail != f"rod_{k}" or (head == "" and len(seen) > 1):
            return False
    return "" not in seen or len(seen) == 1


def _renamed(rod_name: str, prefix: str) -> str:
    """``left/rod_3`` -> ``left/alpha_3`` for ``prefix`` ``alpha_``."""
    head, sep, tail = rod_name.rpartition("/")
    return head + sep + prefix + tail[len("rod_"):]


def read_log(path: str | os.PathLike, namespace: str | None = None) -> LogStream:
    """Open a log file or bag directory for streaming (see the module docstring): every file's
    integrity is checked and its topics are found under any namespace (``/arm1/rod_states``
    as well as ``/rod_states``); a log holding them under two namespaces needs ``namespace``.
    Raises LogFormatError. Close the result (a context manager) when done."""
    log = open_log(path)
    stream = LogStream(path=Path(path), files=log.files, metadata=log.metadata(METADATA_NAME),
                       topics=[], complete=log.complete, _log=log)
    try:
        for f, reader in zip(log.files, log.readers):
            names = resolve_topics(reader.topics(), TOPICS, namespace, str(f))
            stream.topics.append(names)
            renamed = sorted(v for k, v in names.items() if v != "/" + k)
            if renamed:
                stream.notes.append(f"{f.name}: read {', '.join(renamed)}")
            if not reader.complete and not reader.damaged:
                stream.notes.append(f"{f.name} has no summary (writer stopped before closing "
                                    "it); read by scanning"
                                    + (", last record incomplete" if reader.truncated else ""))
    except BaseException:
        stream.close()
        raise
    return stream


MAX_METADATA_SCENE_NODES = 10**6
"""Largest scene in a log's metadata, in YAML nodes after expanding aliases (a resolved scene
of n rods has about 10 n): a "billion laughs" scene is refused before anything walks it."""


def metadata_scene(metadata: dict[str, str] | None, where: str):
    """The :class:`~rod_sim.core.scene.Scene` of a log's ``rod_sim`` metadata record (None
    without one). Raises LogFormatError (one line, values quoted at most 80 characters) for a
    scene that is not valid or expands past :data:`MAX_METADATA_SCENE_NODES`."""
    from rod_sim.core.scene import SceneError
    from rod_sim.io.quote import quote, yaml_node_count
    from rod_sim.io.scene_yaml import scene_from_yaml_text

    if metadata is None or "scene" not in metadata:
        return None
    text = metadata["scene"]
    try:
        nodes = yaml_node_count(text, MAX_METADATA_SCENE_NODES + 1)
    except yaml.YAMLError:
        nodes = 0                      # scene_from_yaml_text reports the YAML error with its line
    if nodes > MAX_METADATA_SCENE_NODES:
        raise LogFormatError(f"{where}: the scene in the log's metadata expands to more than "
                             f"{MAX_METADATA_SCENE_NODES} YAML nodes (a YAML bomb?); refused")
    try:
        return scene_from_yaml_text(text, "the log's metadata")
    except (SceneError, ValueError, TypeError) as exc:
        raise LogFormatError(f"{where}: the scene in the log's metadata is invalid: "
                             f"{quote(str(exc), 200, plain=True)}") from None
