"""Is a recorded payload a whole message of its type? What ``rod-sim replay`` checks before it
republishes a message's bytes (issue 27, item 6): a bag without CRCs (rosbag2 sqlite3) can
hold corrupt payloads, and publishing them hands garbage to every subscriber.

A payload passes when it has a plain CDR encapsulation header (big or little endian), it reads
as the type of the log's own schema (the recorded message definition, read with mcap_ros2's
decoder) and that read ends within :data:`MAX_TRAILING` bytes of the payload's end (so a
payload cut short, padded, or whose sequence lengths no longer match its size is refused). A
corruption that still reads as a valid message of the same size (e.g. a flipped bit inside a
float) cannot be seen without a checksum: the MCAP logs rod_sim writes have chunk CRCs.
"""
from __future__ import annotations

CDR_HEADERS = (b"\x00\x00", b"\x00\x01")
"""Encapsulation kinds CDR_BE and CDR_LE (the two option bytes after them are free)."""
MAX_TRAILING = 3
"""Bytes a serializer may add after the last field (alignment of the size to 4)."""


class PayloadCheck:
    """The check of payloads of ROS 2 type ``type_name`` (``pkg/msg/Name``) whose definition
    is ``schema`` (a log's ros2msg schema text, dependencies concatenated). Without a schema
    that parses, only the encapsulation header is checked (``complete`` is False then)."""

    def __init__(self, type_name: str, schema: str):
        self.type_name = type_name
        self._msgdefs = {}
        self.complete = False
        try:
            from mcap_ros2._dynamic import TimeDefinition, _for_each_msgdef

            msgdefs = {"builtin_interfaces/Time": TimeDefinition,
                       "builtin_interfaces/Duration": TimeDefinition}

            def keep(name, short, msgdef):
                msgdefs[name] = msgdefs[short] = msgdef

            _for_each_msgdef(type_name, schema, keep)
            self.complete = type_name in msgdefs
            self._msgdefs = msgdefs
        except Exception:  # noqa: BLE001 -- no mcap_ros2, or a schema it cannot parse
            pass

    def problem(self, data: bytes) -> str:
        """'' when ``data`` is a whole message of the type, else a short reason (one line)."""
        if len(data) < 4 or bytes(data[:2]) not in CDR_HEADERS:
            return "not a CDR payload (its encapsulation header)"
        if not self.complete:
            return ""
        from mcap_ros2._cdr import CdrReader
        from mcap_ros2._dynamic import _read_complex_type

        reader = CdrReader(bytes(data))
        try:
            _read_complex_type(self._msgdefs[self.type_name], self._msgdefs, reader, {})
        except Exception as exc:  # noqa: BLE001 -- struct.error, UnicodeDecodeError, ...
            return f"does not read as {self.type_name} ({type(exc).__name__})"
        end = reader.decoded_bytes()
        if not 0 <= len(data) - end <= MAX_TRAILING:
            return f"{len(data)} bytes, but the {self.type_name} it holds ends at byte {end}"
        return ""
