"""Decoders for the heavy message types of a log that read arrays with numpy instead of building
a Python object per element: ``sensor_msgs/msg/JointState`` (``rod_states``, ``bending``,
``joint_states``: n names and 2-3 arrays of n floats), ``geometry_msgs/msg/PoseArray``
(``node_poses``: n + 1 poses) and ``std_msgs/msg/Float64MultiArray`` (the applied inputs).
mcap_ros2's decoder took ~22 ms a time step of a 1200-rod log (a float, a string, a Pose, a
Point, a Quaternion object each), so that reading the log took longer than comparing it.

Each decoder reads what mcap_ros2's decoder reads (the standard definitions only: a schema that
differs gets mcap_ros2's decoder), and hands any payload it cannot read to that decoder, so a
corrupt one fails the same way. The messages have the same attributes as mcap_ros2's
(``header.stamp.sec``, ``name``, ``position``, ``poses[k].position.x`` ...); the float arrays
are numpy arrays (float64) rather than lists, and a PoseArray also has ``positions`` (k, 3)
[m] and ``orientations`` (k, 4) (x, y, z, w). Tested against mcap_ros2 on every message of a
plain, a spacecraft and a multi-chain log (test/test_fast_decode.py).
"""
from __future__ import annotations

import struct
from types import SimpleNamespace
from typing import Callable

import numpy as np

from rod_sim.io.payload_check import _U32, _Bad, _read_u32, definitions

_F64 = (np.dtype(">f8"), np.dtype("<f8"))

_HEADER = ["uint32", "string"]
"""Header after its stamp's sec (int32 in ROS 2's builtin_interfaces/Time; uint32 where a
schema leaves Time out and mcap_ros2 uses its own definition): nanosec, frame_id."""
JOINT_STATE = _HEADER + ["string[]", "float64[]", "float64[]", "float64[]"]
"""The standard JointState's field types in read order (after the stamp's sec)."""
POSE_ARRAY = _HEADER + ["(" + ",".join(["float64"] * 7) + ")[]"]
"""The standard PoseArray's (each Pose: a Point and a Quaternion, 7 float64)."""
MULTI_ARRAY = ["(string,uint32,uint32)[]", "uint32", "float64[]"]
"""The standard Float64MultiArray's (layout: dims of label, size, stride; data_offset; data)."""


def field_types(name: str, msgdefs: dict, seen: tuple = ()) -> list[str]:
    """The primitive field types of ``name`` in the order its decoder reads them, nested
    structures in line, arrays as ``type[]`` / ``type[k]`` (of a structure:
    ``(types)[]``)."""
    if name in seen:
        raise ValueError(f"recursive type {name}")
    out = []
    for field in msgdefs[name].fields:
        ftype = field.type
        fixed = (ftype.array_size if ftype.is_array and ftype.is_fixed_size_array() else None)
        suffix = "" if not ftype.is_array else f"[{fixed}]" if fixed else "[]"
        if ftype.is_primitive_type():
            out.append(ftype.type + suffix)
            continue
        inner = field_types(f"{ftype.pkg_name}/{ftype.type}", msgdefs, seen + (name,))
        out.extend(inner if not suffix else ["(" + ",".join(inner) + ")" + suffix])
    return out


def _string(data: bytes, off: int, u32) -> tuple[str, int]:
    """(the string at ``off``, the offset after it), read as mcap_ros2 reads it."""
    length, off = _read_u32(data, off, u32)
    text = data[off:off + length - 1].decode("utf-8") if length > 1 else ""
    return text, off + length


_I32 = (struct.Struct(">i"), struct.Struct("<i"))


def _header(data: bytes, u32, sec_format):
    """(Header, offset after it): stamp sec (``sec_format``: int32 or uint32, as the schema
    defines it) and nanosec, frame_id."""
    if len(data) < 12:
        raise _Bad
    sec, nanosec = sec_format.unpack_from(data, 4)[0], u32.unpack_from(data, 8)[0]
    frame_id, off = _string(data, 12, u32)
    stamp = SimpleNamespace(sec=sec, nanosec=nanosec)
    return SimpleNamespace(stamp=stamp, frame_id=frame_id), off


def _floats(data: bytes, off: int, u32, dtype, per: int = 1) -> tuple[np.ndarray, int]:
    """A sequence of float64 (``per`` of them an element) at ``off``: (values, offset after)."""
    count, off = _read_u32(data, off, u32)
    count *= per
    if count:
        off += -(off - 4) % 8
        if off + 8 * count > len(data):
            raise _Bad
    values = np.frombuffer(data, dtype=dtype, count=count, offset=off if count else 0)
    return values.astype(np.float64), off + 8 * count        # native and writable: a copy


class _Names:
    """The last name block decoded (its bytes and the names): consecutive JointStates of a
    log carry the same n names."""

    def __init__(self):
        self.block, self.names = b"", []

    def read(self, data: bytes, off: int, u32) -> tuple[list[str], int]:
        start = off + (-(off - 4) % 4)
        count, off = _read_u32(data, off, u32)
        names = []
        for _ in range(count):
            name, off = _string(data, off, u32)
            names.append(name)
            if off > len(data):
                raise _Bad
        self.block, self.names = data[start:off], names
        return list(names), off

    def cached(self, data: bytes, off: int) -> tuple[list[str], int] | None:
        """The names at ``off`` when their block is the last one's, byte for byte."""
        aligned = off + (-(off - 4) % 4)
        block = self.block
        if block and data[aligned:aligned + len(block)] == block:
            return list(self.names), aligned + len(block)
        return None


def _with_fallback(read, fallback: Callable[[bytes], object]) -> Callable[[bytes], object]:
    """A decoder: ``read(data, little)`` (``little``: 1 for a little-endian payload, else 0)
    on the payload's bytes, or ``fallback`` on them where ``read`` cannot read them."""

    def decode(data):
        data = bytes(data)
        try:
            if len(data) < 4:
                raise _Bad
            return read(data, data[1] & 1)
        except (_Bad, UnicodeDecodeError, struct.error):
            return fallback(data)
    return decode


def joint_state_decoder(fallback: Callable[[bytes], object], signed: bool
                        ) -> Callable[[bytes], object]:
    """A decoder of standard JointState payloads (``signed``: the stamp's sec is int32);
    ``fallback`` (mcap_ros2's) for any payload this one cannot read."""
    names = _Names()

    def read(data: bytes, little: int):
        u32, f64 = _U32[little], _F64[little]
        header, off = _header(data, u32, _I32[little] if signed else u32)
        hit = names.cached(data, off)
        name, off = hit if hit is not None else names.read(data, off, u32)
        position, off = _floats(data, off, u32, f64)
        velocity, off = _floats(data, off, u32, f64)
        effort, off = _floats(data, off, u32, f64)
        return SimpleNamespace(header=header, name=name, position=position,
                               velocity=velocity, effort=effort)
    return _with_fallback(read, fallback)


class _Poses:
    """``poses`` of a fast PoseArray: Pose-like objects made when asked for."""

    def __init__(self, values: np.ndarray):
        self._values = values

    def __len__(self) -> int:
        return len(self._values)

    def __getitem__(self, k):
        if isinstance(k, slice):
            return [self[i] for i in range(*k.indices(len(self)))]
        v = self._values[k]
        return SimpleNamespace(
            position=SimpleNamespace(x=float(v[0]), y=float(v[1]), z=float(v[2])),
            orientation=SimpleNamespace(x=float(v[3]), y=float(v[4]), z=float(v[5]),
                                        w=float(v[6])))

    def __iter__(self):
        return (self[k] for k in range(len(self)))

    def __repr__(self) -> str:                  # the values, as a list's repr would show them
        return repr(list(self))

    def __eq__(self, other) -> bool:
        return list(self) == list(other) if hasattr(other, "__len__") else NotImplemented


def pose_array_decoder(fallback: Callable[[bytes], object], signed: bool
                       ) -> Callable[[bytes], object]:
    """A decoder of standard PoseArray payloads (``signed``: the stamp's sec is int32);
    ``fallback`` for any it cannot read."""

    def read(data: bytes, little: int):
        u32 = _U32[little]
        header, off = _header(data, u32, _I32[little] if signed else u32)
        values = _floats(data, off, u32, _F64[little], per=7)[0].reshape(-1, 7)
        return SimpleNamespace(header=header, poses=_Poses(values), positions=values[:, 0:3],
                               orientations=values[:, 3:7])
    return _with_fallback(read, fallback)


def multi_array_decoder(fallback: Callable[[bytes], object], signed: bool
                        ) -> Callable[[bytes], object]:
    """A decoder of standard Float64MultiArray payloads (``applied_forces``,
    ``applied_torques``, ``applied_base``; no header: ``signed`` unused); ``fallback`` for
    any it cannot read."""

    def read(data: bytes, little: int):
        u32 = _U32[little]
        count, off = _read_u32(data, 4, u32)
        dims = []
        for _ in range(count):
            label, off = _string(data, off, u32)
            size, off = _read_u32(data, off, u32)
            stride, off = _read_u32(data, off, u32)
            dims.append(SimpleNamespace(label=label, size=size, stride=stride))
        data_offset, off = _read_u32(data, off, u32)
        values = _floats(data, off, u32, _F64[little])[0]
        return SimpleNamespace(layout=SimpleNamespace(dim=dims, data_offset=data_offset),
                               data=values)
    return _with_fallback(read, fallback)


_FAST = {"sensor_msgs/msg/JointState": (JOINT_STATE, True, joint_state_decoder),
         "geometry_msgs/msg/PoseArray": (POSE_ARRAY, True, pose_array_decoder),
         "std_msgs/msg/Float64MultiArray": (MULTI_ARRAY, False, multi_array_decoder)}
"""Type -> (its field types after the stamp's sec, whether it starts with a Header, the
decoder's factory)."""


def fast_decoder(type_name: str, schema: str, fallback):
    """The fast decoder of ``type_name`` when its definition in ``schema`` (a log's ros2msg
    text) is the standard one (:func:`field_types`), else ``fallback`` (mcap_ros2's decoder)
    itself."""
    fast = _FAST.get(type_name)
    if fast is None:
        return fallback
    msgdefs = definitions(type_name, schema)
    try:
        types = field_types(type_name, msgdefs) if msgdefs and type_name in msgdefs else None
    except Exception:  # noqa: BLE001 -- a definition it cannot follow
        types = None
    expected, header, factory = fast
    if types is None:
        return fallback
    if not header:
        return factory(fallback, False) if types == expected else fallback
    if types[:1] not in (["int32"], ["uint32"]) or types[1:] != expected:
        return fallback
    return factory(fallback, types[0] == "int32")
