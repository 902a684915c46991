"""Is a recorded payload a whole message of its type? What ``rod-sim replay`` checks before it
republishes a message's bytes (issue 27, item 6): a bag without CRCs (rosbag2 sqlite3) can
hold corrupt payloads, and publishing them hands garbage to every subscriber.

A payload passes when it has a plain CDR encapsulation header (big or little endian), it reads
as the type of the log's own schema (the recorded message definition, read with mcap_ros2's
decoder) and that read ends within :data:`MAX_TRAILING` bytes of the payload's end (so a
payload cut short, padded, or whose sequence lengths no longer match its size is refused). A
corruption that still reads as a valid message of the same size (e.g. a flipped bit inside a
float) cannot be seen without a checksum: the MCAP logs rod_sim writes have chunk CRCs.

The payload is not decoded into Python objects (mcap_ros2's decoder builds one per field and
element: ~19 ms a message of a 1200-rod scene, so that replay could not keep up with real
time): :class:`PayloadCheck` walks it with a plan made once per type from the schema, reading
exactly what that decoder reads and failing where it fails -- a read past the end, a string
that is not UTF-8 -- and skipping primitive arrays and arrays of structures of one primitive
type (Pose, Point, ColorRGBA) in one step. A type the plan does not cover (``wstring``) is
decoded as before.
"""
from __future__ import annotations

import struct

CDR_HEADERS = (b"\x00\x00", b"\x00\x01")
"""Encapsulation kinds CDR_BE and CDR_LE (the two option bytes after them are free)."""
MAX_TRAILING = 3
"""Bytes a serializer may add after the last field (alignment of the size to 4)."""


_SIZES = {"bool": 1, "byte": 1, "char": 1, "int8": 1, "uint8": 1, "int16": 2, "uint16": 2,
          "int32": 4, "uint32": 4, "int64": 8, "uint64": 8, "float32": 4, "float64": 8}
"""Bytes of each primitive CDR type (aligned to its size, counted from after the header)."""
_U32 = (struct.Struct(">I"), struct.Struct("<I"))


class _Unplanned(Exception):
    """A type the walk does not cover: decode it instead."""


class _Bad(Exception):
    """The payload does not read as its type (what the decoder would raise)."""


_SCALAR, _STRING, _BYTES, _CHECKED1, _ALIGNED, _STRINGS, _NESTED_ARRAY, _FLAT = range(8)
"""The kinds of a plan's ops: (_SCALAR, size), (_STRING, 1), (_BYTES, count),
(_CHECKED1, count), (_ALIGNED, size, count), (_STRINGS, count), (_NESTED_ARRAY, ops, count),
(_FLAT, size, fields, count); a count None is a sequence's (a u32 first)."""


def _plan(name: str, msgdefs: dict, seen: tuple = ()) -> list:
    """The ops that read one message of type ``name`` (see :func:`_walk`), in the field order
    of its definition, as mcap_ros2's ``_read_complex_type`` reads them."""
    if name in seen:
        raise _Unplanned(f"recursive type {name}")
    msgdef = msgdefs[name]
    ops = []
    if not msgdef.fields:
        ops.append((_SCALAR, 1))            # an empty message holds one uint8
    for field in msgdef.fields:
        ftype = field.type
        count = (ftype.array_size if ftype.is_array and ftype.is_fixed_size_array()
                 and ftype.array_size is not None else None)     # None: a u32 length first
        if not ftype.is_primitive_type():
            nested = f"{ftype.pkg_name}/{ftype.type}"
            if nested not in msgdefs:
                raise _Unplanned(f"no definition of {nested}")
            inner = _plan(nested, msgdefs, seen + (name,))
            if not ftype.is_array:          # read in line: primitives are read as they come
                ops.extend(inner)
            elif all(op[0] == _SCALAR for op in inner) and len({op[1] for op in inner}) == 1:
                # a structure of one primitive type: k of them are k * len(inner) of those
                ops.append((_FLAT, inner[0][1], len(inner), count))
            else:
                ops.append((_NESTED_ARRAY, inner, count))
            continue
        kind = ftype.type
        if kind == "string":
            ops.append((_STRINGS, count) if ftype.is_array else (_STRING, 1))
        elif kind not in _SIZES:
            raise _Unplanned(f"primitive type {kind}")
        elif not ftype.is_array:
            ops.append((_SCALAR, _SIZES[kind]))
        elif kind in ("byte", "uint8"):      # read as one slice: no alignment, no bounds
            ops.append((_BYTES, count))
        elif _SIZES[kind] == 1:             # bool, char, int8: one read each
            ops.append((_CHECKED1, count))
        else:
            ops.append((_ALIGNED, _SIZES[kind], count))
    return ops


def _read_u32(data: bytes, off: int, u32) -> tuple[int, int]:
    """(the uint32 at ``off`` aligned to 4 (``u32``: its byte order), the offset after it);
    _Bad where it does not fit (a sequence's or string's length, mostly)."""
    off += -(off - 4) % 4
    if off + 4 > len(data):
        raise _Bad
    return u32.unpack_from(data, off)[0], off + 4


def _walk(ops: list, data: bytes, off: int, u32) -> int:
    """The offset after one message read by ``ops`` from ``data`` at ``off`` (``u32``: the
    payload's byte order); raises _Bad where mcap_ros2's reader raises: a read that does not
    fit (its ``struct.unpack_from``) or a string that is not UTF-8. Like that reader it aligns
    an element of size s to s counted from byte 4, reads uint8/byte arrays and a string's
    bytes as slices (no bounds: the end check catches them) and aligns an array only when it
    has an element."""
    n = len(data)
    for op in ops:
        kind = op[0]
        if kind == _SCALAR:
            size = op[1]
            off += -(off - 4) % size + size
            if off > n:
                raise _Bad
        else:
            count = op[-1]
            if count is None:                           # a sequence: its u32 length first
                count, off = _read_u32(data, off, u32)
            if kind == _STRING or kind == _STRINGS:
                for _ in range(count):
                    length, off = _read_u32(data, off, u32)
                    if length > 1:
                        try:
                            data[off:off + length - 1].decode("utf-8")
                        except UnicodeDecodeError:
                            raise _Bad from None
                    off += length
            elif kind == _BYTES:
                off += count
            elif kind == _CHECKED1:
                off += count
                if off > n:
                    raise _Bad
            elif kind == _ALIGNED or kind == _FLAT:
                size = op[1]
                total = count * size * (op[2] if kind == _FLAT else 1)
                if total:
                    off += -(off - 4) % size + total
                    if off > n:
                        raise _Bad
            else:                                       # _NESTED_ARRAY
                inner = op[1]
                for _ in range(count):
                    off = _walk(inner, data, off, u32)
    return off


def definitions(type_name: str, schema: str) -> dict | None:
    """The message definitions of ``type_name`` and every type it uses, parsed by mcap_ros2
    from ``schema`` (a log's ros2msg text, dependencies concatenated), by full and short name
    (``std_msgs/msg/Header`` and ``std_msgs/Header``), as its decoder looks them up; None
    without mcap_ros2 or for a schema it cannot parse."""
    try:
        from mcap_ros2._dynamic import TimeDefinition, _for_each_msgdef

        msgdefs = {"builtin_interfaces/Time": TimeDefinition,
                   "builtin_interfaces/Duration": TimeDefinition}

        def keep(name, short, msgdef):
            msgdefs[name] = msgdefs[short] = msgdef

        _for_each_msgdef(type_name, schema, keep)
    except Exception:  # noqa: BLE001 -- no mcap_ros2, or a schema it cannot parse
        return None
    return msgdefs


class PayloadCheck:
    """The check of payloads of ROS 2 type ``type_name`` (``pkg/msg/Name``) whose definition
    is ``schema`` (a log's ros2msg schema text, dependencies concatenated). Without a schema
    that parses, only the encapsulation header is checked (``complete`` is False then)."""

    def __init__(self, type_name: str, schema: str):
        self.type_name = type_name
        self._msgdefs = definitions(type_name, schema) or {}
        self.complete = type_name in self._msgdefs
        self._ops = None
        """The walk's plan of the type (None: decode each payload instead)."""
        if self.complete:
            try:
                self._ops = _plan(type_name, self._msgdefs)
            except _Unplanned:
                pass

    def problem(self, data: bytes) -> str:
        """'' when ``data`` is a whole message of the type, else a short reason (one line)."""
        if len(data) < 4 or bytes(data[:2]) not in CDR_HEADERS:
            return "not a CDR payload (its encapsulation header)"
        if not self.complete:
            return ""
        data = bytes(data)
        if self._ops is not None:
            try:
                end = _walk(self._ops, data, 4, _U32[data[1] & 1])
            except _Bad:
                return f"does not read as {self.type_name}"
            return self._end_problem(len(data), end)
        return self._decoded_problem(data)

    def _end_problem(self, size: int, end: int) -> str:
        if not 0 <= size - end <= MAX_TRAILING:
            return f"{size} bytes, but the {self.type_name} it holds ends at byte {end}"
        return ""

    def _decoded_problem(self, data: bytes) -> str:
        """:meth:`problem` by decoding ``data`` with mcap_ros2 (a type the walk does not
        cover)."""
        from mcap_ros2._cdr import CdrReader
        from mcap_ros2._dynamic import _read_complex_type

        reader = CdrReader(bytes(data))
        try:
            _read_complex_type(self._msgdefs[self.type_name], self._msgdefs, reader, {})
        except Exception as exc:  # noqa: BLE001 -- struct.error, UnicodeDecodeError, ...
            return f"does not read as {self.type_name} ({type(exc).__name__})"
        return self._end_problem(len(data), reader.decoded_bytes())
