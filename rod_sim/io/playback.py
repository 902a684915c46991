"""Reading a log for replay (no ROS here): sources, topic selection, QoS and timing.

:func:`open_source` opens any log that :func:`rod_sim.io.log_open.open_log` opens (an MCAP
file, ours or any ROS 2 one; a rosbag2 bag directory) as a :class:`PlaybackSource`: its
:class:`Track` s (topic, ROS type, the QoS to offer) and its raw CDR messages in log-time order,
merged across the files of a bag. :class:`Timeline` maps log time to wall time at a playback
rate. The ROS side is :mod:`rod_sim.ros.replay`.

Errors are :class:`PlaybackError`, the same class as every log reader's
(:class:`~rod_sim.io.log_format.LogFormatError`, a ValueError), with a one-line message naming
the file or topic, so ``rod-sim replay`` reports them with exit status 2.
"""
from __future__ import annotations

import os
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import yaml

from rod_sim.io.log_format import LogFormatError
from rod_sim.io.log_open import open_log
from rod_sim.io.log_reader import ChannelInfo

DEFAULT_DEPTH = 10
"""History depth offered when a channel records none (rclcpp's and rosbag2's default)."""

# rmw enum values, as rosbag2 before Jazzy wrote them into offered_qos_profiles
_RELIABILITY = {0: "system_default", 1: "reliable", 2: "best_effort", 3: "unknown",
                4: "best_available"}
_DURABILITY = {0: "system_default", 1: "transient_local", 2: "volatile", 3: "unknown",
               4: "best_available"}
_HISTORY = {0: "system_default", 1: "keep_last", 2: "keep_all", 3: "unknown"}


PlaybackError = LogFormatError
"""A log, bag or topic selection that cannot be replayed; ``str(err)`` is one line. The one
error class of opening and reading logs, under the name replay's callers know."""


@dataclass(frozen=True)
class QosSpec:
    """The QoS a replay publisher offers: ``reliability`` ('reliable' | 'best_effort'),
    ``durability`` ('volatile' | 'transient_local'), ``history`` ('keep_last' | 'keep_all')
    and ``depth`` (messages kept for keep_last)."""

    reliability: str = "reliable"
    durability: str = "volatile"
    history: str = "keep_last"
    depth: int = DEFAULT_DEPTH

    def describe(self) -> str:
        depth = f" depth {self.depth}" if self.history == "keep_last" else ""
        return f"{self.reliability}, {self.durability}, {self.history}{depth}"


def _policy(value, names: Mapping[int, str]) -> str:
    if isinstance(value, bool):
        raise ValueError(f"not a QoS policy: {value!r}")
    if isinstance(value, int):
        return names.get(value, "unknown")
    return str(value).strip().lower()


def adapt_offers(profiles: Sequence[Mapping]) -> QosSpec:
    """The QoS to offer for a topic recorded from publishers offering ``profiles`` (dicts as in
    ``offered_qos_profiles``), following rosbag2's player: reliable only if every recorded
    publisher was reliable, transient_local only if every one was; keep_last with the largest
    recorded depth (keep_all if every one was keep_all). No profiles: the default."""
    if not profiles:
        return QosSpec()
    reliability = [_policy(p.get("reliability", 1), _RELIABILITY) for p in profiles]
    durability = [_policy(p.get("durability", 2), _DURABILITY) for p in profiles]
    history = [_policy(p.get("history", 1), _HISTORY) for p in profiles]
    depths = [int(p.get("depth", 0) or 0) for p in profiles]
    keep_all = all(h == "keep_all" for h in history)
    depth = max(depths) if max(depths) > 0 else DEFAULT_DEPTH
    return QosSpec(
        reliability="reliable" if all(r == "reliable" for r in reliability) else "best_effort",
        durability=("transient_local" if all(d == "transient_local" for d in durability)
                    else "volatile"),
        history="keep_all" if keep_all else "keep_last", depth=depth)


def parse_offered_qos(text: str | None) -> QosSpec:
    """The QoS to offer from a channel's ``offered_qos_profiles`` YAML (rosbag2's format,
    Jazzy strings or the older enum numbers). Empty or missing: the default. Raises ValueError
    for text that is not such a list."""
    if text is None or not text.strip():
        return QosSpec()
    try:
        profiles = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ValueError(f"offered_qos_profiles is not YAML: {' '.join(str(exc).split())}"
                         ) from None
    if profiles is None:
        return QosSpec()
    if not isinstance(profiles, list) or not all(isinstance(p, Mapping) for p in profiles):
        raise ValueError("offered_qos_profiles is not a list of QoS mappings")
    return adapt_offers(profiles)


@dataclass(frozen=True)
class Track:
    """A topic of a source: ``topic`` (absolute), ``type_name`` (``pkg/msg/Name``),
    ``encoding`` ('cdr' for ROS 2), ``qos`` to offer, ``message_count`` (None if unknown) and
    ``note`` (why the QoS is a default, or ''), ``schema`` (the recorded definition)."""

    topic: str
    type_name: str
    encoding: str
    qos: QosSpec
    message_count: int | None = None
    note: str = ""
    schema: str = ""


def _track(info: ChannelInfo) -> Track:
    note = ""
    try:
        qos = parse_offered_qos(info.metadata.get("offered_qos_profiles"))
    except ValueError as exc:
        qos, note = QosSpec(), f"{exc}; offering the default QoS"
    return Track(topic=info.topic, type_name=info.type_name, encoding=info.encoding, qos=qos,
                 message_count=info.message_count, note=note, schema=info.schema)


class PlaybackSource:
    """An MCAP file or a rosbag2 bag directory opened for replay (a context manager).

    ``tracks``: absolute topic -> :class:`Track`. ``complete``: every file has its summary
    (False for a log whose writer was killed: it is read up to its last complete chunk).
    """

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        self._log = open_log(self.path)
        self.files = self._log.files
        try:
            self.tracks = self._collect_tracks()
        except BaseException:
            self.close()
            raise
        self.complete = self._log.complete

    def _collect_tracks(self) -> dict[str, Track]:
        tracks: dict[str, Track] = {}
        for reader in self._log.readers:
            for topic, info in reader.channels().items():
                track = _track(info)
                known = tracks.get(topic)
                if known is None:
                    tracks[topic] = track
                elif known.type_name != track.type_name:
                    raise PlaybackError(f"{self.path}: {topic} is {known.type_name} in one "
                                        f"file and {track.type_name} in another")
                elif known.message_count is not None and track.message_count is not None:
                    tracks[topic] = Track(**{**known.__dict__, "message_count":
                                             known.message_count + track.message_count})
        return tracks

    def messages(self, topics: Iterable[str] | None = None
                 ) -> Iterator[tuple[str, int, bytes]]:
        """``(topic, log_time [ns], CDR bytes)`` of ``topics`` (absolute; default all) in
        log-time order, merged across the files of a bag. Raises PlaybackError for a corrupt
        file."""
        return self._log.messages(topics, raw=True)

    def close(self) -> None:
        self._log.close()

    def __enter__(self) -> "PlaybackSource":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def open_source(path: str | os.PathLike) -> PlaybackSource:
    """Open a log for replay: any that :func:`rod_sim.io.log_open.open_log` opens
    (PlaybackError if not)."""
    return PlaybackSource(path)


def absolute(topic: str) -> str:
    return topic if topic.startswith("/") else "/" + topic


def find_topic(tracks: Mapping[str, Track], name: str) -> str:
    """The source's topic for a name given by the user: the absolute name itself; for a
    relative name without a match at the root (``rod_states``), the one topic with that base
    name under any namespace (``/arm1/rod_states``). Raises PlaybackError when there is none
    or several."""
    full = absolute(name)
    if full in tracks or name.startswith("/"):
        if full not in tracks:
            raise PlaybackError(f"topic {full} is not in the log (it has: "
                                f"{', '.join(sorted(tracks)) or 'no topics'})")
        return full
    matches = sorted(t for t in tracks if t.endswith(full))
    if len(matches) == 1:
        return matches[0]
    if matches:
        raise PlaybackError(f"topic {name} is ambiguous: the log has {', '.join(matches)}; "
                            "give the absolute name")
    raise PlaybackError(f"topic {name} is not in the log (it has: "
                        f"{', '.join(sorted(tracks)) or 'no topics'})")


def select_topics(tracks: Mapping[str, Track], topics: Iterable[str] | None = None,
                  exclude: Iterable[str] | None = None) -> list[str]:
    """The absolute topics to replay, sorted: ``topics`` (default all) minus ``exclude``; a
    relative name also matches the topic of that name under a namespace (see
    :func:`find_topic`). Raises PlaybackError for a name the source does not have, or when
    nothing is left."""
    chosen = sorted(tracks) if not topics else [find_topic(tracks, t) for t in topics]
    removed = [find_topic(tracks, t) for t in (exclude or ())]
    selected = sorted(set(chosen) - set(removed))
    if not selected:
        raise PlaybackError("no topic left to replay")
    return selected


class Timeline:
    """Log time [ns] <-> wall time [ns, monotonic] at ``rate`` log seconds per wall second,
    anchored by :meth:`anchor` (at the start, after a pause and at each loop)."""

    def __init__(self, rate: float):
        if not rate > 0:
            raise ValueError(f"rate must be > 0 (got {rate})")
        self.rate = float(rate)
        self.log_ns = 0
        self.wall_ns = 0

    def anchor(self, log_ns: int, wall_ns: int) -> None:
        """From now on log time ``log_ns`` corresponds to wall time ``wall_ns``."""
        self.log_ns, self.wall_ns = int(log_ns), int(wall_ns)

    def wall_at(self, log_ns: int) -> int:
        """Wall time at which log time ``log_ns`` is due."""
        return self.wall_ns + round((log_ns - self.log_ns) / self.rate)

    def log_at(self, wall_ns: int) -> int:
        """Log time that wall time ``wall_ns`` corresponds to."""
        return self.log_ns + round((wall_ns - self.wall_ns) * self.rate)
