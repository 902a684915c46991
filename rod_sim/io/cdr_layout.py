"""CDR messages whose byte layout is fixed once their sizes are known: a template + slots.

A state message of a chain of n rods has the same length and the same field offsets every
period (names, frame, sizes do not change); only some numbers do. So it is laid out once, by
:class:`LayoutWriter` (slow, plain Python, run once per chain size and frame), into a
:class:`Layout`: the message's bytes with every changing number zeroed, and per *slot* (a named
group of changing numbers, e.g. ``stamp`` or ``position``) the byte positions it fills. Each
sample then costs one copy of the template and one numpy assignment per slot (O(n), no Python
loop over rods): :meth:`Layout.fill`.

The bytes follow the rules of :mod:`rod_sim.io.cdr` (and mcap_ros2's ``serialize_dynamic``):
encapsulation header ``00 01 00 00`` (CDR little endian), every primitive aligned to its size
counted from the end of that header, padding zero, strings as uint32 length (NUL included) +
UTF-8 + NUL, sequences as uint32 count + elements (no alignment padding before the elements of
an empty sequence), no trailing padding. test/test_encoders.py checks the bytes against
:mod:`rod_sim.io.cdr` and mcap_ros2.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Callable

import numpy as np

from rod_sim.io.cdr import HEADER


class LayoutWriter:
    """Writes one message's constant parts and reserves its slots (offsets exclude the
    4-byte encapsulation header, as CDR alignment does)."""

    def __init__(self) -> None:
        self.b = bytearray()
        self.slots: dict[str, list[tuple[int, int]]] = {}

    def pad(self, size: int) -> None:
        self.b += bytes(-len(self.b) % size)

    def prim(self, code: str, *values) -> None:
        """Primitives of one struct code ('i', 'I', 'd', 'f', '?', 'B'), the first aligned to
        its size (the rest follow unpadded: same size)."""
        self.pad(struct.calcsize(code))
        self.b += struct.pack(f"<{len(values)}{code}", *values)

    def string(self, text: str) -> None:
        data = text.encode("utf-8")
        self.prim("I", len(data) + 1)
        self.b += data + b"\0"

    def count(self, k: int) -> None:
        """The uint32 element count of a sequence."""
        self.prim("I", k)

    def slot(self, name: str, size: int, align: int) -> None:
        """Reserve ``size`` bytes (aligned to ``align``) filled by slot ``name`` at each sample;
        a slot reserved several times is filled piece after piece."""
        self.pad(align)
        self.slots.setdefault(name, []).append((len(self.b), size))
        self.b += bytes(size)

    def stamp(self) -> None:
        """A ``builtin_interfaces/Time`` (int32 sec, uint32 nanosec) filled by slot ``stamp``."""
        self.slot("stamp", 8, 4)

    def header(self, frame_id: str) -> None:
        """A ``std_msgs/Header``: the stamp slot, then the constant frame id."""
        self.stamp()
        self.string(frame_id)

    def f64_seq(self, name: str, k: int) -> None:
        """A float64 sequence of ``k`` elements filled by slot ``name`` (nothing to fill if 0)."""
        self.count(k)
        if k:
            self.slot(name, 8 * k, 8)

    def f64_seq_const(self, values) -> None:
        """A float64 sequence of constant values."""
        values = np.asarray(values, dtype="<f8").ravel()
        self.count(values.size)
        if values.size:
            self.pad(8)
            self.b += values.tobytes()

    def string_seq(self, names) -> None:
        """A sequence of strings, each as :meth:`string` writes it, joined in one pass (a
        1e6-rod chain has 1e6 joint names)."""
        self.count(len(names))      # aligned to 4: so is each string's start (padded below)
        if not len(names):
            return
        u32, pads = struct.Struct("<I").pack, (b"", b"\0\0\0", b"\0\0", b"\0")
        data = [name.encode("utf-8") for name in names]
        joined = b"".join([u32(len(d) + 1) + d + b"\0" + pads[(len(d) + 1) % 4] for d in data])
        self.b += joined[:len(joined) - len(pads[(len(data[-1]) + 1) % 4])]  # no trailing pad

    def layout(self) -> "Layout":
        slots = {}
        for name, pieces in self.slots.items():
            if len(pieces) == 1:
                start, size = pieces[0]
                slots[name] = slice(len(HEADER) + start, len(HEADER) + start + size)
            else:
                slots[name] = np.concatenate([np.arange(len(HEADER) + start,
                                                        len(HEADER) + start + size)
                                              for start, size in pieces])
        return Layout(np.frombuffer(HEADER + bytes(self.b), dtype=np.uint8).copy(), slots)


@dataclass(frozen=True, eq=False)
class Layout:
    """A message's bytes with zeroed slots (``template``, uint8) and, per slot, the byte
    positions it fills (a slice, or an index array for a slot of several pieces)."""

    template: np.ndarray
    slots: dict

    def __post_init__(self) -> None:
        # the template as bytes: :meth:`fill` copies it into a bytearray per message (a slice
        # slot is then one memoryview assignment), :meth:`filler` joins its constant runs
        object.__setattr__(self, "_bytes", self.template.tobytes())
        object.__setattr__(self, "_fillers", {})

    def filler(self, names: tuple[str, ...]) -> Callable[..., bytes]:
        """:meth:`fill` with the slots' values given by position, in the order ``names`` (every
        slot once), made once per order: ``filler(("stamp", "data"))(stamp, data)`` is
        ``fill(stamp=stamp, data=data)``, the same bytes, without its per-call lookups and with
        one copy of each byte instead of three (a ``joint_states`` of 8 hinges 6.2 -> 3.6 us, of
        1024 hinges 8.9 -> 4.6 us). Each value is a numpy array (its C-order bytes fill the
        slot; ValueError when their count differs) or anything :meth:`fill` takes."""
        found = self._fillers.get(names)
        if found is not None:
            return found
        if sorted(names) != sorted(self.slots):
            raise ValueError(f"filler: slots {sorted(self.slots)}, got {list(names)}")
        where = [self.slots[name] for name in names]
        if not all(type(w) is slice for w in where):    # pieces: the general path
            def fill(*values: np.ndarray) -> bytes:
                return self.fill(**dict(zip(names, values)))
        else:
            # the message is the template's constant runs joined with the slots' bytes: one
            # copy of each (no bytearray of the whole to copy again into bytes)
            order = sorted(range(len(names)), key=lambda i: where[i].start)
            template = self._bytes
            bounds = [0] + [b for i in order for b in (where[i].start, where[i].stop)] + \
                [len(template)]
            consts = [template[a:b] for a, b in zip(bounds[0::2], bounds[1::2])]
            spans = tuple((i, where[i].stop - where[i].start, names[i], consts[j + 1])
                          for j, i in enumerate(order))
            first = consts[0]

            def fill(*values: np.ndarray) -> bytes:
                parts = [first]
                for i, size, name, after in spans:
                    value = values[i]
                    if type(value) is not np.ndarray or not value.flags.c_contiguous:
                        value = memoryview(np.ascontiguousarray(value)).cast("B")
                    if value.nbytes != size:
                        raise ValueError(f"slot {name!r}: {value.nbytes} bytes for {size}")
                    parts.append(value)
                    parts.append(after)
                return b"".join(parts)
        self._fillers[names] = fill
        return fill

    def fill(self, **values: np.ndarray) -> bytes:
        """The message with each slot's bytes: ``values[name]`` is an array whose raw
        little-endian bytes fill the slot's positions in order (its byte count must match:
        ValueError otherwise)."""
        out = bytearray(self._bytes)
        view = None
        for name, where in self.slots.items():
            data = memoryview(np.ascontiguousarray(values[name])).cast("B")
            if type(where) is slice:
                if data.nbytes != where.stop - where.start:   # a bytearray would resize
                    raise ValueError(f"slot {name!r}: {data.nbytes} bytes for "
                                     f"{where.stop - where.start}")
                out[where] = data
            else:                                           # pieces: an index array
                if view is None:
                    view = np.frombuffer(out, dtype=np.uint8)
                view[where] = np.frombuffer(data, dtype=np.uint8)
        del view                    # the bytearray's buffer export, before bytes() copies it
        return bytes(out)


def stamp_bytes(t_ns: int) -> np.ndarray:
    """The 8 bytes of a ``builtin_interfaces/Time`` at ``t_ns`` >= 0 [ns] (int32 sec, uint32
    nanosec; sec < 2**31 as a uint32 has the same bytes)."""
    sec, nanosec = divmod(int(t_ns), 1_000_000_000)
    return np.array([sec, nanosec], dtype="<u4")
