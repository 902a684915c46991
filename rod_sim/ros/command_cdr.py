"""Decoding of a ``std_msgs/msg/Float64MultiArray`` command (``nodal_forces``,
``hinge_torques``) straight from its serialized bytes with numpy, without building rclpy's
message object (:func:`decode_float64_array`).

What is decoded: plain little-endian CDR, the encapsulation header ``00 01 00 00`` (CDR_LE,
options 0), then

- ``layout.dim``: uint32 count, then per MultiArrayDimension ``label`` (string: uint32 length
  counting the NUL, the UTF-8 bytes, the NUL), ``size`` and ``stride`` (uint32);
- ``layout.data_offset`` (uint32);
- ``data``: uint32 count, then the float64 values aligned to 8,

each primitive aligned to its size counted from the end of the 4-byte header (the rules of
:mod:`rod_sim.io.cdr`, which are rclpy's). The bytes must end with the last value (an empty
``data`` may be followed by its alignment padding, as rclpy's ``serialize_message`` writes it).

What is not: anything else returns None and the caller decodes with rclpy's
``deserialize_message`` (whose outcome, message or error, then stands): another encapsulation
(big-endian, options set), a count or length running past the end, bytes left after the data,
a label of length 0, without its final NUL, with a NUL inside or not strict UTF-8 (rclpy reads
those leniently: cut at the first NUL, bad bytes replaced). So a command this module decodes
gives the values and labels rclpy's decoding gives, bit for bit (test/test_command_cdr.py).
"""
from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

from rod_sim.io.cdr import HEADER   # the one decoded here: CDR_LE, options 0
_U32 = struct.Struct("<I")
_U32X2 = struct.Struct("<II")
_F64 = np.dtype("<f8")
_MIN_DIM_BYTES = 16
"""The fewest bytes a MultiArrayDimension takes: label length 4, NUL 1, padding 3, 2 x 4."""


@dataclass(slots=True)
class Dimension:
    """A MultiArrayDimension: ``label``, ``size`` and ``stride`` (as rclpy's message)."""

    label: str
    size: int
    stride: int


@dataclass(slots=True)
class Layout:
    """A MultiArrayLayout: ``dim`` (list of :class:`Dimension`) and ``data_offset``."""

    dim: list
    data_offset: int


@dataclass(slots=True)
class Float64Array:
    """A decoded Float64MultiArray: ``layout`` and ``data``, a read-only float64 view (k,) of
    the serialized bytes (rclpy's message holds an ``array.array('d')``)."""

    layout: Layout
    data: np.ndarray


def _align(pos: int, size: int) -> int:
    """``pos`` (bytes from the start, header included) aligned to ``size`` counted from the
    end of the 4-byte header."""
    return pos + (-(pos - 4)) % size


def decode_float64_array(buf: bytes) -> Float64Array | None:
    """The Float64MultiArray serialized in ``buf`` (module docstring), or None when the bytes
    are not exactly what this decoder reads (the caller then decodes them with rclpy)."""
    end = len(buf)
    if end < 16 or buf[:4] != HEADER:
        return None
    try:
        (count,) = _U32.unpack_from(buf, 4)
        pos = 8
        if count * _MIN_DIM_BYTES > end - pos:
            return None
        dims = []
        for _ in range(count):
            (length,) = _U32.unpack_from(buf, pos)
            start = pos + 4
            pos = start + length
            # the label's only NUL is its last byte (also refuses length 0 and a short buffer)
            if length == 0 or pos > end or buf.find(b"\0", start, pos) != pos - 1:
                return None
            label = buf[start:pos - 1].decode("utf-8")
            pos = _align(pos, 4)
            size, stride = _U32X2.unpack_from(buf, pos)
            pos += 8
            dims.append(Dimension(label, size, stride))
        offset, values = _U32X2.unpack_from(buf, pos)   # pos is aligned to 4 here
        pos += 8
    except (struct.error, UnicodeDecodeError):
        return None
    start = _align(pos, 8)
    if values == 0:
        if end not in (pos, start):
            return None
        data = np.empty(0, dtype=_F64)
    else:
        if start + 8 * values != end:
            return None
        data = np.frombuffer(buf, dtype=_F64, count=values, offset=start)
    return Float64Array(Layout(dims, offset), data)
