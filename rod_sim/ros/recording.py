"""The rod_sim node's log (docs/interface.md section 4, ``record_path``): creating it with the
run's metadata (:func:`node_log_opener`), writing to it (a received command as the bytes that
came: :meth:`NodeRecording.record_received`) until the first write error, rolling it after
``~/reset`` into the next free ``<stem>_<k><suffix>`` (existing files are skipped, never
overwritten) and closing it. A log that cannot be opened or written stops the recording with an
ERROR line and :attr:`NodeRecording.error` (which the node reports on diagnostics), never
silently."""
from __future__ import annotations

from pathlib import Path
from typing import Callable, Mapping

from rod_sim.io.hinge_events import HINGE_EVENTS_TOPIC
from rod_sim.io.log_writer import LogWriteError, LogWriter, offered_qos_yaml
from rod_sim.io.scene_yaml import scene_to_yaml
from rod_sim.ros.conversions import message_to_dict
from rod_sim.ros.errors import NodeConfigError, one_line
from rod_sim.ros.outputs import log_depths

MAX_LOG_ROLLS = 10_000
"""Names ``<stem>_<k>`` tried after a reset before giving up (existing files are skipped)."""
CDR_LE = b"\x00\x01"
"""The encapsulation of little-endian (plain) CDR, the first two bytes of a serialized message."""


def offered_qos(names: dict[str, str], latched) -> dict[str, str]:
    """``offered_qos_profiles`` of the resolved topics ``names[t]`` for the transient-local
    topics ``latched``: a mapping topic -> history depth (e.g. ``hinge_events``: 100, the state
    topics: 10, or 1 in lockstep), or an iterable of topics (depth 100 for ``hinge_events``,
    else 1). Other topics get the writer's default (reliable, volatile, depth 10)."""
    depths = (dict(latched) if isinstance(latched, dict) else
              {t: 100 if t == HINGE_EVENTS_TOPIC else 1 for t in latched})
    return {names[t]: offered_qos_yaml(depth=depth, durability="transient_local")
            for t, depth in depths.items()}


def create_log(path: Path, metadata: dict[str, str], qos: dict[str, str]) -> LogWriter:
    """A new log at ``path`` (its folder is created), its chunks compressed and written by a
    child process (:mod:`rod_sim.io.log_process`: off the node's thread). Raises
    NodeConfigError naming the cause (an existing file is refused)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        return LogWriter(path, metadata=metadata, qos=qos, writer_process=True)
    except FileExistsError:
        raise NodeConfigError(f"record_path: {path} exists; remove it or choose another "
                              "record_path") from None
    except (OSError, ValueError) as exc:
        raise NodeConfigError(f"record_path: {one_line(exc)}") from None


class NodeRecording:
    """The log being written (``writer``, None when not recording) and the reason it stopped
    (``error``). ``open_log(path)`` creates a log or raises NodeConfigError; ``logger`` is the
    node's rclpy logger."""

    def __init__(self, open_log: Callable[[Path], LogWriter], logger):
        self.writer: LogWriter | None = None
        self.error: str | None = None
        self._open_log = open_log
        self._logger = logger
        self._base: Path | None = None
        self._count = 0

    def start(self, base: Path | None) -> None:
        """Record to ``base`` (None: no recording). Raises NodeConfigError."""
        self._base = base
        if base is not None:
            self.writer = self._open_log(base)

    @property
    def path(self) -> Path | None:
        """The log being written (None when not recording)."""
        return self.writer.path if self.writer is not None else None

    def roll(self) -> str:
        """After a reset: close the log and continue in the next free ``<stem>_<k><suffix>``.
        Returns a note for the reset's answer ('' when not recording)."""
        if self.writer is None:
            return ""
        self.close()
        base = self._base
        for _ in range(MAX_LOG_ROLLS):
            self._count += 1
            path = base.with_name(f"{base.stem}_{self._count}{base.suffix}")
            if not path.exists():
                break
        try:
            self.writer = self._open_log(path)
        except NodeConfigError as exc:
            self._stopped(str(exc))
            return f"; recording stopped: {exc}"
        return f"; recording continues in {path}"

    def _stopped(self, reason: str) -> None:
        self.error = reason
        self._logger.error(f"recording stopped: {reason}")

    def record(self, topic: str, type_name: str, t_ns: int, data: dict) -> None:
        """Write ``data`` on ``topic`` at ``t_ns`` [ns]; a write error stops the recording."""
        if self.writer is None:
            return
        try:
            self.writer.write(topic, type_name, t_ns, data)
        except (LogWriteError, OSError) as exc:
            self._stopped(one_line(exc))
            self.close()

    def record_cdr(self, topic: str, type_name: str, t_ns: int, data: bytes) -> None:
        """Write the encoded message ``data`` (the bytes published) as :meth:`record` does."""
        if self.writer is None:
            return
        try:
            self.writer.write_cdr(topic, type_name, t_ns, data)
        except (LogWriteError, OSError) as exc:
            self._stopped(one_line(exc))
            self.close()

    def record_received(self, topic: str, type_name: str, t_ns: int, msg, data: bytes) -> None:
        """A received message (a command) at ``t_ns`` [ns]: its serialized bytes ``data`` as
        they came (as rosbag2 records) when they are little-endian CDR, else ``msg`` (the
        decoded message) re-encoded (the log is little-endian)."""
        if bytes(data[:2]) == CDR_LE:
            self.record_cdr(topic, type_name, t_ns, bytes(data))
        else:
            self.record(topic, type_name, t_ns, message_to_dict(msg))

    def close(self) -> None:
        """Close the log with its summary (idempotent)."""
        log, self.writer = self.writer, None
        if log is None:
            return
        try:
            log.close()
            self._logger.info(f"log closed: {log.path}")
        except OSError as exc:
            self._logger.error(f"cannot close the log {log.path}: {one_line(exc)}")


def node_log_metadata(scene_yaml: str, model: str, integrator: str, settings, mode: str,
                      node: str) -> dict[str, str]:
    """The ``rod_sim`` metadata record of a node's log (docs/interface.md section 4)."""
    from rod_sim.version import __version__

    return {"scene": scene_yaml, "model": model, "integrator": integrator,
            "version": __version__, "rtol": repr(settings.rtol),
            "rate_hz": repr(settings.rate_hz), "source": "rod_sim node", "mode": mode,
            "node": node}


def node_log_opener(scene, model: str, integrator: str, settings, mode: Callable[[], str],
                    node: str, names: Mapping[str, str]) -> Callable[[Path], LogWriter]:
    """``open_log(path)`` of a node's :class:`NodeRecording`: a new log (:func:`create_log`)
    with the run's metadata (:func:`node_log_metadata`; ``mode()`` is asked when the log
    opens: the real-time factor may have changed since the start) and the offered QoS of the
    scene's transient-local topics (:func:`~rod_sim.ros.outputs.log_depths`) under their
    resolved ``names`` (relative -> resolved). Raises NodeConfigError."""
    def open_log(path: Path) -> LogWriter:
        return create_log(path, node_log_metadata(scene_to_yaml(scene), model, integrator,
                                                  settings, mode(), node),
                          offered_qos(names, log_depths(settings.sync_mode, scene)))
    return open_log
