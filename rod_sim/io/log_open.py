"""Opening any log rod_sim reads, with one behaviour and one error type: :func:`open_log`.

``compare``, ``replay``, ``repair``, ``deployment-figure`` and the series readers
(:mod:`rod_sim.io.series`) all open their input here. What is accepted:

- an MCAP file (any name): read by :class:`~rod_sim.io.log_reader.LogReader` (integrity
  checked; a truncated or damaged file is read up to what is intact, with warnings);
- a rosbag2 bag directory with ``metadata.yaml`` (``rosbag2_bagfile_information``):

  - storage ``mcap``, uncompressed: the files of ``relative_file_paths``, in that order;
  - storage ``sqlite3``, or a compressed bag (``compression_mode`` file or message): copied
    with the ``rosbags`` library into one temporary MCAP file (:mod:`rod_sim.io.bag_copy`),
    removed on :meth:`OpenedLog.close`;
  - no ``storage_identifier``: ``mcap``; any other storage is refused, naming the tool that
    converts it;

- a directory without ``metadata.yaml``: every ``*.mcap`` file in it, in name order.

The messages of a log of several files are merged in log-time order (file order on ties).
Every problem that makes a log unusable is a :class:`~rod_sim.io.log_format.LogFormatError`
whose ``str()`` is one line naming the path: a missing path, an unreadable or non-MCAP file,
damaged record framing, a bag whose metadata is unreadable, lists no files or a missing file, an
unsupported storage, a sqlite3 or compressed bag without rosbags installed.
"""
from __future__ import annotations

import heapq
import os
import tempfile
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from rod_sim.io.log_format import METADATA_NAME, LogFormatError
from rod_sim.io.log_reader import LogReader
from rod_sim.io.topic_names import resolve_topics

BAG_METADATA = "metadata.yaml"
MCAP_STORAGE = "mcap"
SQLITE_STORAGE = "sqlite3"
STORAGES = (MCAP_STORAGE, SQLITE_STORAGE)


@dataclass(frozen=True)
class BagLayout:
    """What a log path holds: ``storage`` ('mcap' or 'sqlite3'), ``compressed`` (rosbag2
    file or message compression), ``files`` (the MCAP files to read; empty when the bag is
    copied first: sqlite3 or compressed) and ``copy`` (True when it is)."""

    storage: str
    compressed: bool
    files: tuple[Path, ...]

    @property
    def copy(self) -> bool:
        return self.storage != MCAP_STORAGE or self.compressed


def _bag_info(meta: Path) -> dict:
    """The ``rosbag2_bagfile_information`` mapping of a bag's metadata.yaml."""
    try:
        info = yaml.safe_load(meta.read_text(encoding="utf-8"))["rosbag2_bagfile_information"]
        if not isinstance(info, dict):
            raise TypeError("rosbag2_bagfile_information is not a mapping")
        return info
    except (OSError, yaml.YAMLError, KeyError, TypeError, UnicodeDecodeError) as exc:
        text = " ".join(str(exc).split())[:200]
        raise LogFormatError(f"{meta}: not a rosbag2 metadata file ({type(exc).__name__}: "
                             f"{text})") from None


MAX_LOG_FILES = 1000
"""Most files of one log (a bag directory): their messages are merged in time order, so all
are open at once (a file descriptor and a chunk each); more is refused before any is read."""


def _check_file_count(path: Path, count: int) -> None:
    if count > MAX_LOG_FILES:
        raise LogFormatError(f"{path}: more than {MAX_LOG_FILES} log files in one bag (they "
                             "are read together, all open at once); merge them first (e.g. "
                             "mcap merge) or pass fewer")


def bag_layout(path: str | os.PathLike) -> BagLayout:
    """How the log at ``path`` is read (see the module docstring). Raises LogFormatError."""
    path = Path(path)
    if not path.exists():
        raise LogFormatError(f"{path} does not exist (no such file or directory)")
    if not path.is_dir():
        return BagLayout(MCAP_STORAGE, False, (path,))
    meta = path / BAG_METADATA
    if not meta.is_file():
        files = []
        for p in path.glob("*.mcap"):           # stops counting past the bound
            if p.is_file():
                files.append(p)
                _check_file_count(path, len(files))
        if not files:
            raise LogFormatError(f"{path}: a directory without {BAG_METADATA} or .mcap files "
                                 "is not a rosbag2 bag")
        return BagLayout(MCAP_STORAGE, False, tuple(sorted(files)))
    info = _bag_info(meta)
    names = [str(name) for name in info.get("relative_file_paths") or ()]
    storage = str(info.get("storage_identifier") or MCAP_STORAGE)
    if storage not in STORAGES:
        raise LogFormatError(f"{path}: bag storage {storage!r} is not supported (only 'mcap' "
                             "and 'sqlite3' bags can be read; convert it with rosbags-convert "
                             "--src BAG --dst OUT --dst-storage mcap; pip install rosbags)")
    compressed = str(info.get("compression_mode") or "").strip().lower() not in ("", "none")
    if storage != MCAP_STORAGE or compressed:
        return BagLayout(storage, compressed, ())
    _check_file_count(path, len(names))
    files = tuple(path / name for name in names)
    if not files:
        raise LogFormatError(f"{meta} lists no files")
    missing = [str(f) for f in files if not f.is_file()]
    if missing:
        raise LogFormatError(f"{path}: bag file {missing[0]} listed in {BAG_METADATA} is "
                             "missing")
    return BagLayout(storage, compressed, files)


def open_mcap(path: str | os.PathLike) -> LogReader:
    """One MCAP file opened by :class:`~rod_sim.io.log_reader.LogReader` (its integrity
    checked). Raises LogFormatError (one line) for a missing, unreadable or non-MCAP file and
    for damaged record framing."""
    path = Path(path)
    try:
        return LogReader(path)
    except FileNotFoundError:
        raise LogFormatError(f"{path} does not exist (no such file or directory)") from None
    except OSError as exc:
        raise LogFormatError(f"{path}: cannot read it ({exc.strerror or exc})") from None


@dataclass
class OpenedLog:
    """A log opened by :func:`open_log` (a context manager; :meth:`close` when done).

    ``path``: what was opened; ``layout``: how (:class:`BagLayout`); ``files``: the MCAP files
    read (a sqlite3 or compressed bag: its temporary MCAP copy); ``readers``: one
    :class:`~rod_sim.io.log_reader.LogReader` per file, in that order."""

    path: Path
    layout: BagLayout
    files: list[Path] = field(default_factory=list)
    readers: list[LogReader] = field(default_factory=list)
    _copy: Any = field(default=None, repr=False)
    """The temporary directory of a copied bag (removed on :meth:`close`)."""

    @property
    def complete(self) -> bool:
        """Every file has its summary and indexes and no damage was found."""
        return all(r.complete for r in self.readers)

    def metadata(self, name: str = METADATA_NAME) -> dict[str, str] | None:
        """The metadata record ``name`` (str -> str) of the first file that has one, else
        None (a bag converted by rosbag2 tools has none)."""
        for reader in self.readers:
            try:
                return reader.metadata(name)
            except LogFormatError:
                continue
        return None

    def topics(self) -> dict[str, str]:
        """Absolute topic name -> ROS type name, over all files."""
        out: dict[str, str] = {}
        for reader in self.readers:
            for topic, type_name in reader.topics().items():
                out.setdefault(topic, type_name)
        return out

    def resolve(self, names: Iterable[str], namespace: str | None = None) -> dict[str, str]:
        """The logged topic of each base name in ``names`` (``rod_states`` ->
        ``/arm1/rod_states``), see :func:`~rod_sim.io.topic_names.resolve_topics`. Raises
        LogFormatError when two namespaces hold them."""
        return resolve_topics(self.topics(), names, namespace, str(self.path))

    def messages(self, topics: Iterable[str] | None = None, *, raw: bool = False
                 ) -> Iterator[tuple[str, int, Any]]:
        """``(topic, log_time [ns], message)`` of ``topics`` (absolute; default: all), in
        log-time order merged across the files (file order on ties): decoded messages (ROS
        field names as attributes), or the serialized CDR bytes when ``raw``. Raises
        LogFormatError for a file damaged beyond what opening it found."""
        wanted = None if topics is None else sorted({t if t.startswith("/") else "/" + t
                                                     for t in topics})

        def one(k: int, reader: LogReader):
            read = reader.raw_messages if raw else reader.messages
            for topic, t_ns, msg in read(wanted):
                yield int(t_ns), k, topic, msg
        streams = [one(k, reader) for k, reader in enumerate(self.readers)]
        for t_ns, _, topic, msg in heapq.merge(*streams, key=lambda m: (m[0], m[1])):
            yield topic, t_ns, msg

    def close(self) -> None:
        for reader in self.readers:
            reader.close()
        self.readers = []
        if self._copy is not None:
            self._copy.cleanup()
            self._copy = None

    def __enter__(self) -> "OpenedLog":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def open_log(path: str | os.PathLike) -> OpenedLog:
    """Open the log at ``path``: an MCAP file, a rosbag2 bag directory (mcap or sqlite3
    storage, compressed or not, with or without metadata.yaml) or a directory of MCAP files
    (see the module docstring). Every file's integrity is checked. Raises LogFormatError (one
    line); nothing stays open then."""
    from rod_sim.io.bag_copy import bag_to_mcap

    path = Path(path)
    layout = bag_layout(path)
    log = OpenedLog(path=path, layout=layout)
    try:
        if layout.copy:
            log._copy = tempfile.TemporaryDirectory(prefix="rod_sim_bag_")
            what = "compressed" if layout.compressed else layout.storage
            log.files = [bag_to_mcap(path, Path(log._copy.name) / f"{path.name}.mcap", what)]
        else:
            log.files = list(layout.files)
        for f in log.files:
            log.readers.append(open_mcap(f))
    except BaseException:
        log.close()
        raise
    return log
