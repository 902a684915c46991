"""Fast CDR encoding of ROS 2 message dicts, compiled once per type from its ``ros2msg`` text.

:func:`encoder` returns ``encode(msg) -> bytes`` for a type of :data:`rod_sim.io.msgdefs.SCHEMAS`
(or :func:`compile_encoder` for any concatenated definition). The bytes are those of
``mcap_ros2``'s ``serialize_dynamic`` (what rosbag2 and every ROS 2 subscriber read): the
little-endian encapsulation header ``00 01 00 00``, then the fields in order, each primitive
aligned to its size counted from the end of the header, strings as uint32 length (with the NUL)
+ UTF-8 bytes + NUL, sequences as uint32 count + elements, no trailing padding.

Message values follow mcap_ros2's rules: nested dicts and lists; a missing field (or None) is
the field's default from the ``.msg`` text (else 0, 0.0, False, '', empty); numbers are
converted with ``float``/``int``/``bool`` and strings with ``str``. Beyond mcap_ros2, array
fields also take numpy arrays (1-D) and tuples. Stricter than mcap_ros2: a dict key the type
does not have raises :class:`rod_sim.io.msgdefs.MessageFieldError` (mcap_ros2 ignores it); a
struct value that is not a mapping raises TypeError; a fixed-size array of the wrong length or
a bounded one over its bound raises ValueError (mcap_ros2 pads or truncates). Every error
message names the field's path (``markers[0].points[1].x``).

How it is fast: the encoder is straight-line Python generated per type (nested structs inlined;
each run of consecutive fixed-size fields packed by one precompiled ``struct.Struct``, with one
variant per start offset mod 8 where the offset is not known at compile time; primitive arrays
packed in one call, float64 numpy arrays by ``tobytes``). Inputs that need conversion (None
values, floats in int fields, ...) or are wrong make the fast path give up; the message is then
encoded again by a field-by-field reference encoder that converts like mcap_ros2 and raises the
named errors. Both paths are tested against mcap_ros2 byte for byte (test/test_cdr.py).

Why not a library's encoder (issue 21): the libraries give the same bytes but cannot keep up.
``python -m rod_sim.io.cdr_bench`` (2 cores shared with three other jobs, load ~2.5, 2026-11-25),
per control period, the 6 default topics at n = 8: mcap_ros2's ``serialize_dynamic``
1300 us, rosbags' ``serialize_cdr`` 344 us on message objects built beforehand and 1920 us from
the dicts (building its objects first: what LogWriter would do), this module 126 us (10x, 2.7x
and 15x faster; markers alone 1026, 253, 1609 and 103 us; a second run at load 3.7:
1053, 280, 1404 and 92 us per period). At the node's 100 Hz that is 13 %,
3.4 % (19 %) or 1.3 % of each period. The ``.msg`` parser (:func:`parse_definition`) stays
with it: mcap_ros2 only vendors rosidl_adapter's parser as a private module, and rosbags (whose
``get_types_from_msg`` is public) is an optional test dependency; test/test_msgdefs.py checks
the parsed field tables against rosbags' Jazzy type store.
"""
from __future__ import annotations

import struct
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Callable

import numpy as np

from rod_sim.io.msgdefs import MessageFieldError

HEADER = b"\x00\x01\x00\x00"
"""CDR encapsulation header: CDR_LE, options 0."""

Encoder = Callable[[Any], bytes]

# primitive type -> (struct code, size [bytes]); byte = uint8, char = int8 as in mcap_ros2
PRIMITIVES: dict[str, tuple[str, int]] = {
    "bool": ("?", 1), "byte": ("B", 1), "char": ("b", 1), "int8": ("b", 1), "uint8": ("B", 1),
    "int16": ("h", 2), "uint16": ("H", 2), "int32": ("i", 4), "uint32": ("I", 4),
    "int64": ("q", 8), "uint64": ("Q", 8), "float32": ("f", 4), "float64": ("d", 8),
}
STRING_TYPES = ("string", "wstring")
_FLOATS = ("float32", "float64")


@dataclass(frozen=True)
class Field:
    """One field of a message type. ``type``: a primitive name, 'string'/'wstring', or
    ``pkg/msg/Type``; ``array``: None (scalar), 'seq' (unbounded), 'bounded' (``[<=size]``) or
    'fixed' (``[size]``); ``default``: the value the ``.msg`` gives (None: zero/empty)."""

    name: str
    type: str
    array: str | None = None
    size: int | None = None
    default: Any = None

    @property
    def is_struct(self) -> bool:
        return self.type not in PRIMITIVES and self.type not in STRING_TYPES


# ----- parsing the concatenated definition -----

def _strip_comment(line: str) -> str:
    """The line before its first '#' (as rosidl_adapter, whose parser mcap_ros2 vendors, does
    it: even inside a quoted string default)."""
    return line.split("#", 1)[0]


def _resolve(base: str, package: str) -> str:
    base = base.split("<=")[0]  # string<=N: the bound is not encoded
    if base in PRIMITIVES or base in STRING_TYPES:
        return base
    parts = base.split("/")
    if len(parts) == 1:
        return "std_msgs/msg/Header" if base == "Header" else f"{package}/msg/{base}"
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    return base


def _scalar_default(ftype: str, text: str) -> Any:
    text = text.strip()
    if ftype in STRING_TYPES:
        if len(text) >= 2 and text[0] == text[-1] and text[0] in "\"'":
            return text[1:-1]
        return text
    if ftype in _FLOATS:
        return float(text)
    if ftype == "bool":
        low = text.lower()
        if low in ("true", "1"):
            return True
        if low in ("false", "0"):
            return False
        raise ValueError(f"bad bool default {text!r}")
    return int(text, 0)


def _parse_default(ftype: str, array: str | None, text: str) -> Any:
    text = text.strip()
    if not text:
        return None
    if array is None:
        return _scalar_default(ftype, text)
    inner = text.strip()
    if not (inner.startswith("[") and inner.endswith("]")):
        raise ValueError(f"bad array default {text!r}")
    items = [s for s in inner[1:-1].split(",") if s.strip()]
    return [_scalar_default(ftype, s) for s in items]


def _parse_fields(body: str, package: str, where: str) -> list[Field]:
    fields: list[Field] = []
    for raw in body.splitlines():
        code = _strip_comment(raw).strip()
        if not code:
            continue
        tokens = code.split(None, 1)
        if len(tokens) < 2:
            raise ValueError(f"{where}: cannot parse line {raw!r}")
        type_token, rest = tokens
        name, *more = rest.split(None, 1)
        tail = more[0] if more else ""
        if "=" in name or tail.lstrip().startswith("="):
            continue  # constant
        array, size = None, None
        base = type_token
        if "[" in type_token:
            base, _, bracket = type_token.partition("[")
            bound = bracket.rstrip("]").strip()
            if not bound:
                array = "seq"
            elif bound.startswith("<="):
                array, size = "bounded", int(bound[2:])
            else:
                array, size = "fixed", int(bound)
        ftype = _resolve(base, package)
        fields.append(Field(name, ftype, array, size, _parse_default(ftype, array, tail)))
    return fields


def parse_definition(type_name: str, text: str) -> dict[str, list[Field]]:
    """``{pkg/msg/Type: [Field, ...]}`` of the root ``type_name`` and every ``MSG:`` section of
    a concatenated definition (the MCAP ``ros2msg`` schema text). Constants are skipped."""
    root = _resolve(type_name, type_name.split("/")[0]) if "/" in type_name else type_name
    table: dict[str, list[Field]] = {}
    lines = [line for line in text.splitlines() if line.strip()]
    sections: list[list[str]] = [[]]
    for line in lines:
        if len(line.strip()) >= 3 and set(line.strip()) == {"="}:
            sections.append([])
        else:
            sections[-1].append(line)
    for i, section in enumerate(sections):
        name = root
        if i > 0 or (section and section[0].startswith("MSG:")):
            if not section or not section[0].startswith("MSG:"):
                raise ValueError(f"{type_name}: section {i} does not start with 'MSG: pkg/Type'")
            name = _resolve(section[0][4:].strip(), "")
            section = section[1:]
        package = name.split("/")[0]
        table[name] = _parse_fields("\n".join(section), package, name)
    for tname, fields in table.items():
        for f in fields:
            if f.is_struct and f.type not in table:
                raise ValueError(f"{type_name}: no definition of {f.type} (field {tname}.{f.name})")
    return table


# ----- the reference encoder: field by field, mcap_ros2's conversions, named errors -----

def _zero(ftype: str) -> Any:
    if ftype in STRING_TYPES:
        return ""
    if ftype in _FLOATS:
        return 0.0
    return False if ftype == "bool" else 0


def _coerce(value: Any, f: Field, default: Any, path: str) -> Any:
    if value is None:
        return _zero(f.type) if default is None else default
    try:
        if f.type in STRING_TYPES:
            return str(value)
        if f.type in _FLOATS:
            return float(value)
        if f.type == "bool":
            return bool(value)
        return int(value)
    except (TypeError, ValueError) as exc:
        raise type(exc)(f"{path}: cannot convert {value!r} to {f.type}: {exc}") from None


def _pad(b: bytearray, size: int) -> None:
    b.extend(b"\0" * (-len(b) % size))


def _write_primitive(b: bytearray, f: Field, value: Any, path: str) -> None:
    if f.type == "wstring":
        raise NotImplementedError(f"{path}: wstring is not supported")
    if f.type == "string":
        try:
            data = value.encode("utf-8")
        except UnicodeError as exc:
            raise ValueError(f"{path}: {exc}") from None
        _pad(b, 4)
        b += struct.pack("<I", len(data) + 1)
        b += data
        b.append(0)
        return
    code, size = PRIMITIVES[f.type]
    _pad(b, size)
    try:
        b += struct.pack("<" + code, value)
    except struct.error as exc:
        raise struct.error(f"{path}: {value!r} does not fit {f.type}: {exc}") from None
    except OverflowError as exc:
        raise ValueError(f"{path}: {value!r} does not fit {f.type}: {exc}") from None


def _array_items(value: Any, f: Field, path: str, struct_items: bool) -> list:
    """The elements of an array field as a list (checked length), or raw bytes for uint8/byte."""
    if value is None:
        value = []
        if f.array == "fixed":
            if f.default is not None and not struct_items:
                return list(f.default)
            value = [{} if struct_items else None] * f.size
    elif isinstance(value, np.ndarray) and not struct_items:
        if value.ndim != 1:
            raise ValueError(f"{path}: array field needs a 1-D array (got shape {value.shape})")
        value = value.tolist()
    elif isinstance(value, (bytes, bytearray)) and not struct_items:
        if f.type not in ("uint8", "byte"):
            raise ValueError(f"{path}: bytes given for {f.type}[] (only uint8[]/byte[] take bytes)")
        value = bytes(value)
    elif not struct_items and hasattr(value, "typecode") and hasattr(value, "tobytes"):
        if value.typecode == "B":
            if f.type not in ("uint8", "byte"):
                raise ValueError(f"{path}: a byte array given for {f.type}[]")
            value = value.tobytes()
        else:
            value = list(value)
    elif not isinstance(value, (list, tuple)):
        raise TypeError(f"{path}: {f.type}[] field needs a list"
                        f"{'' if struct_items else ', tuple or 1-D numpy array'} "
                        f"(got {type(value).__name__})")
    if f.array == "fixed" and len(value) != f.size:
        raise ValueError(f"{path}: fixed-size array needs {f.size} elements (got {len(value)})")
    if f.array == "bounded" and len(value) > f.size:
        raise ValueError(f"{path}: bounded array takes at most {f.size} elements (got {len(value)})")
    return value


class ReferenceEncoder:
    """Field-by-field CDR encoder of one type (slow; the fast encoder's fallback and oracle)."""

    def __init__(self, type_name: str, table: Mapping[str, list[Field]], root: str):
        self.type_name = type_name
        self.table = table
        self.root = root

    def __call__(self, msg: Any) -> bytes:
        b = bytearray()
        self._struct(self.root, msg, b, "")
        return HEADER + b

    def _struct(self, tname: str, value: Any, b: bytearray, path: str) -> None:
        fields = self.table[tname]
        if not isinstance(value, Mapping):
            where = path[:-1] if path else "the message"
            raise TypeError(f"{self.type_name}: {where} must be a dict for {tname} "
                            f"(got {type(value).__name__})")
        names = {f.name for f in fields}
        for key in value:
            if key not in names:
                raise MessageFieldError(
                    f"{self.type_name}: no field {path + str(key)!r} in {tname} "
                    f"(fields: {', '.join(f.name for f in fields)})")
        if not fields:
            b.append(0)  # ROS 2 gives an empty message one uint8 member
            return
        for f in fields:
            item = value.get(f.name)
            fpath = path + f.name
            if f.is_struct:
                if f.array is None:
                    self._struct(f.type, item or {}, b, fpath + ".")
                    continue
                items = _array_items(item, f, fpath, True)
                if f.array != "fixed":
                    _pad(b, 4)
                    b += struct.pack("<I", len(items))
                for i, element in enumerate(items):
                    self._struct(f.type, element, b, f"{fpath}[{i}].")
            elif f.array is None:
                _write_primitive(b, f, _coerce(item, f, f.default, fpath), fpath)
            else:
                items = _array_items(item, f, fpath, False)
                if f.array != "fixed":
                    _pad(b, 4)
                    b += struct.pack("<I", len(items))
                if isinstance(items, bytes):
                    b += items
                    continue
                for i, element in enumerate(items):
                    epath = f"{fpath}[{i}]"
                    _write_primitive(b, f, _coerce(element, f, None, epath), epath)


# ----- the fast encoder: generated straight-line code -----

class _GiveUp(Exception):
    """The fast path cannot encode this message as is; the reference encoder takes over."""


_PAD = {k: tuple(b"\0" * (-r % k) for r in range(k)) for k in (2, 4, 8)}
_U32 = struct.Struct("<I").pack
_ARRAY_STRUCTS: dict[tuple[str, int], Any] = {}


def _array_struct(code: str, n: int):
    key = (code, n)
    s = _ARRAY_STRUCTS.get(key)
    if s is None:
        s = _ARRAY_STRUCTS[key] = struct.Struct(f"<{n}{code}").pack
    return s


def _fast_length(b: bytearray, n: int, kind: str | None, count: int | None) -> int:
    """Check an array's length ``n`` against its kind and append the uint32 count prefix of a
    sequence ('seq', 'bounded'); a fixed array has none. Returns ``n``."""
    if kind == "fixed":
        if n != count:
            raise _GiveUp
    else:
        if kind == "bounded" and n > count:
            raise _GiveUp
        b += _PAD[4][len(b) & 3]
        b += _U32(n)
    return n


def _fast_primitive_array(b: bytearray, a: Any, code: str, size: int, kind: str | None,
                          count: int | None) -> None:
    """Append a primitive array (``kind`` 'seq'/'bounded': with count; 'fixed': ``count``
    elements, no prefix). Raises _GiveUp for anything but lists, tuples, 1-D numpy arrays and
    bytes for uint8."""
    raw = None
    if a is None:
        if kind == "fixed":
            raise _GiveUp
        a = ()
    cls = a.__class__
    if cls is list or cls is tuple:
        if code == "?" and None in a:
            raise _GiveUp
    elif cls is np.ndarray:
        if a.ndim != 1:
            raise _GiveUp
        if code == "d" and a.dtype.kind == "f" and a.dtype.itemsize == 8:
            raw = a.astype("<f8", copy=False).tobytes()
        else:
            a = a.tolist()
    elif cls is bytes and code == "B":
        raw = a
    else:
        raise _GiveUp
    n = _fast_length(b, len(a), kind, count)
    if not n:
        return
    if size > 1:
        b += _PAD[size][len(b) & (size - 1)]
    b += raw if raw is not None else _array_struct(code, n)(*a)


STRING_CACHE_MIN = 16
"""String sequences of at least this many items (a long chain's joint names, the same every
period) are encoded once per alignment and reused while equal: encoding 1024 names took
~1.5 ms per message, the equality check (of the same string objects) ~10 us."""
_STRING_ARRAYS: dict[tuple, tuple[list, bytes]] = {}


def _fast_string_array(b: bytearray, a: Any, kind: str | None, count: int | None) -> None:
    if a is None:
        if kind == "fixed":
            raise _GiveUp
        a = ()
    elif a.__class__ is not list and a.__class__ is not tuple:
        raise _GiveUp
    _fast_length(b, len(a), kind, count)
    cached = len(a) >= STRING_CACHE_MIN and a.__class__ is list
    if cached:
        key = (len(b) & 3, len(a), a[0], a[-1])
        hit = _STRING_ARRAYS.get(key)
        if hit is not None and hit[0] == a:
            b += hit[1]
            return
        start = len(b)
    pad4 = _PAD[4]
    for s in a:
        data = s.encode()
        b += pad4[len(b) & 3]
        b += _U32(len(data) + 1)
        b += data
        b.append(0)
    if cached:
        if len(_STRING_ARRAYS) >= 64:
            _STRING_ARRAYS.clear()
        _STRING_ARRAYS[key] = (list(a), bytes(b[start:]))


class _Codegen:
    """Emits the body of ``encode(m)`` for one type; see :func:`compile_encoder`."""

    def __init__(self, table: Mapping[str, list[Field]], reference: "ReferenceEncoder"):
        self.table = table
        self.reference = reference
        self.lines: list[str] = []
        self.ns: dict[str, Any] = {"_GiveUp": _GiveUp, "_PAD2": _PAD[2], "_PAD4": _PAD[4],
                                   "_PAD8": _PAD[8], "_U32": _U32, "_E": {},
                                   "_EMPTY": tuple(p + b"\x01\x00\x00\x00\x00" for p in _PAD[4]),
                                   "_parr": _fast_primitive_array, "_sarr": _fast_string_array}
        self.count = 0
        self.run: list[tuple[str, str]] = []  # pending (expression, struct code)
        self.residue: int | None = 0  # offset (after the header) mod 8, None when unknown

    def name(self, prefix: str) -> str:
        self.count += 1
        return f"{prefix}{self.count}"

    def const(self, prefix: str, value: Any) -> str:
        key = self.name(prefix)
        self.ns[key] = value
        return key

    def emit(self, indent: int, line: str) -> None:
        self.lines.append("    " * indent + line)

    @staticmethod
    def _layout(codes: list[str], start: int) -> tuple[str, int]:
        fmt, pos = "<", start
        for code in codes:
            size = struct.calcsize("<" + code)
            pad = -pos % size
            fmt += "x" * pad + code
            pos += pad + size
        return fmt, pos

    def flush(self, indent: int) -> None:
        if not self.run:
            return
        exprs = ", ".join(e for e, _ in self.run)
        codes = [c for _, c in self.run]
        self.run = []
        if self.residue is not None:
            fmt, end = self._layout(codes, self.residue)
            packer = self.const("_S", struct.Struct(fmt).pack)
            self.emit(indent, f"b += {packer}({exprs})")
            self.residue = end % 8
            return
        variants, formats, ends = [], set(), set()
        for r in range(8):
            fmt, end = self._layout(codes, r)
            variants.append(struct.Struct(fmt).pack)
            formats.add(fmt)
            ends.add(end % 8)
        if len(formats) == 1:  # no padding whatever the offset (all 1-byte fields)
            packer = self.const("_S", variants[0])
            self.emit(indent, f"b += {packer}({exprs})")
            self.residue = None
            return
        packers = self.const("_V", tuple(variants))
        self.emit(indent, f"b += {packers}[len(b) & 7]({exprs})")
        self.residue = ends.pop() if len(ends) == 1 else None

    def align(self, indent: int, size: int) -> None:
        if self.residue is None:
            self.emit(indent, f"b += _PAD{size}[len(b) & {size - 1}]")
        else:
            pad = -self.residue % size
            if pad:
                zeros = bytes(pad)
                self.emit(indent, f"b += {zeros!r}")
            self.residue = (self.residue + pad) % 8

    def check_keys(self, indent: int, tname: str, var: str) -> None:
        keys = self.const("_K", frozenset(f.name for f in self.table[tname]))
        self.emit(indent, f"if not {keys}.issuperset({var}): raise _GiveUp")

    def variable(self, tname: str) -> bool:
        """Whether ``tname`` has a string or an array anywhere inside (its size varies)."""
        return any(f.array is not None or f.type in STRING_TYPES
                   or (f.is_struct and self.variable(f.type)) for f in self.table[tname])

    def default_bytes(self, tname: str, residue: int) -> bytes:
        """The encoding of an all-default ``tname`` starting at offset ``residue`` mod 8."""
        b = bytearray(residue)
        self.reference._struct(tname, {}, b, "")
        return bytes(b[residue:])

    def packed_elements(self, tname: str, arr: str, elem: str, indent: int) -> bool:
        """For a struct of primitive scalars only (Point, ColorRGBA, ...) whose first field
        has the largest alignment A and whose size is a multiple of A, every element has the
        same layout once the first is aligned to A: emit one list comprehension of one Struct
        (returns True). Otherwise emit nothing and return False."""
        fields = self.table[tname]
        if not fields or any(f.array is not None or f.type not in PRIMITIVES for f in fields):
            return False
        codes = [PRIMITIVES[f.type][0] for f in fields]
        sizes = [PRIMITIVES[f.type][1] for f in fields]
        first = sizes[0]
        fmt, end = self._layout(codes, 0)
        if max(sizes) != first or end % first:
            return False
        packer = self.const("_S", struct.Struct(fmt).pack)
        keys = self.const("_K", frozenset(f.name for f in fields))
        values = ", ".join(
            f"{elem}.get({f.name!r}, {(_zero(f.type) if f.default is None else f.default)!r})"
            for f in fields)
        if any(f.type == "bool" and f.default for f in fields):
            return False  # None must become True there: leave it to the loop
        indexed = ", ".join(f"{elem}[{f.name!r}]" for f in fields)
        data = self.name("p")
        # Usually every element has every field: index them, and then an element has no
        # unknown field iff it has exactly len(fields) keys. Else (KeyError) check the keys
        # and take defaults.
        self.emit(indent, f"if {arr}:")
        self.emit(indent + 1, "try:")
        self.emit(indent + 2, f"{data} = b''.join([{packer}({indexed}) for {elem} in {arr}])")
        self.emit(indent + 2, f"if max(map(len, {arr})) != {len(fields)}: raise _GiveUp")
        self.emit(indent + 1, "except KeyError:")
        self.emit(indent + 2, f"if not all(map({keys}.issuperset, {arr})): raise _GiveUp")
        self.emit(indent + 2, f"{data} = b''.join([{packer}({values}) for {elem} in {arr}])")
        if first > 1:
            self.emit(indent + 1, f"b += _PAD{first}[len(b) & {first - 1}]")
        self.emit(indent + 1, f"b += {data}")
        return True

    def struct(self, tname: str, var: str, indent: int) -> None:
        """Code appending the struct ``tname`` held by the (checked) dict in ``var``."""
        fields = self.table[tname]
        if not fields:
            self.run.append(("0", "B"))
        for f in fields:
            get = f"{var}.get({f.name!r})"
            if f.is_struct and f.array is None and self.variable(f.type):
                # strings or arrays inside: not part of a run; an absent or empty value is
                # one precomputed byte string (per offset mod 8), e.g. Marker.texture
                self.flush(indent)
                sub = self.name("d")
                self.emit(indent, f"{sub} = {get}")
                self.emit(indent, f"if {sub}:")
                before = self.residue
                self.check_keys(indent + 1, f.type, sub)
                self.struct(f.type, sub, indent + 1)
                self.flush(indent + 1)
                self.emit(indent, "else:")
                defaults = tuple(self.default_bytes(f.type, r) for r in range(8))
                if before is None:
                    self.emit(indent + 1, f"b += {self.const('_D', defaults)}[len(b) & 7]")
                else:
                    self.emit(indent + 1, f"b += {defaults[before]!r}")
                self.residue = None
            elif f.is_struct and f.array is None:
                sub = self.name("d")
                self.emit(indent, f"{sub} = {get} or _E")
                self.check_keys(indent, f.type, sub)
                self.struct(f.type, sub, indent)
            elif f.is_struct:
                self.flush(indent)
                arr, elem = self.name("a"), self.name("e")
                self.emit(indent, f"{arr} = {get}")
                self.emit(indent, f"if {arr} is None: {arr} = ()")
                self.emit(indent, f"elif {arr}.__class__ is not list and "
                                  f"{arr}.__class__ is not tuple: raise _GiveUp")
                if f.array == "fixed":
                    self.emit(indent, f"if len({arr}) != {f.size}: raise _GiveUp")
                else:
                    if f.array == "bounded":
                        self.emit(indent, f"if len({arr}) > {f.size}: raise _GiveUp")
                    self.align(indent, 4)
                    self.emit(indent, f"b += _U32(len({arr}))")
                if not self.packed_elements(f.type, arr, elem, indent):
                    self.emit(indent, f"for {elem} in {arr}:")
                    self.residue = None
                    self.check_keys(indent + 1, f.type, elem)
                    self.struct(f.type, elem, indent + 1)
                    self.flush(indent + 1)
                self.residue = None
            elif f.type == "wstring":
                self.emit(indent, "raise _GiveUp  # wstring: the reference encoder raises")
            elif f.array is not None:
                self.flush(indent)
                if f.type == "string":
                    self.emit(indent, f"_sarr(b, {get}, {f.array!r}, {f.size!r})")
                else:
                    code, size = PRIMITIVES[f.type]
                    if f.array == "fixed" and f.default is not None:
                        # a missing fixed array takes the .msg default: leave it to the reference
                        self.emit(indent, f"if {get} is None: raise _GiveUp")
                    self.emit(indent, f"_parr(b, {get}, {code!r}, {size}, {f.array!r}, {f.size!r})")
                self.residue = None
            elif f.type == "string":
                self.flush(indent)
                data = self.name("s")
                default = "" if f.default is None else f.default
                self.emit(indent, f"{data} = {var}.get({f.name!r}, {default!r})")
                before = self.residue
                self.emit(indent, f"if {data} == '':")
                empty = b"\x01\x00\x00\x00\x00"
                if before is None:
                    self.emit(indent + 1, f"b += _EMPTY[len(b) & 3]")
                else:
                    self.emit(indent + 1, f"b += {bytes(-before % 4) + empty!r}")
                self.emit(indent, "else:")
                self.emit(indent + 1, f"{data} = {data}.encode()")
                self.align(indent + 1, 4)
                self.emit(indent + 1, f"b += _U32(len({data}) + 1)")
                self.emit(indent + 1, f"b += {data}")
                self.emit(indent + 1, "b.append(0)")
                self.residue = None
            else:
                code, _ = PRIMITIVES[f.type]
                default = _zero(f.type) if f.default is None else f.default
                if f.type == "bool" and default:
                    tmp = self.name("t")
                    expr = f"(True if ({tmp} := {get}) is None else {tmp})"
                else:
                    expr = f"{var}.get({f.name!r}, {default!r})"
                self.run.append((expr, code))


def compile_encoder(type_name: str, text: str, *, source: bool = False) -> Encoder:
    """The fast encoder ``encode(msg) -> bytes`` of ``type_name`` (``pkg/msg/Type``) from its
    concatenated ``ros2msg`` definition ``text``. ``source=True`` returns the generated Python
    source instead (for reading). Raises ValueError for a definition it cannot parse."""
    table = parse_definition(type_name, text)
    root = next(iter(table))
    reference = ReferenceEncoder(type_name, table, root)
    gen = _Codegen(table, reference)
    gen.emit(1, "try:")
    gen.emit(2, "b = bytearray()")
    gen.check_keys(2, root, "m")
    gen.struct(root, "m", 2)
    gen.flush(2)
    gen.emit(2, "return _HEADER + b")
    gen.emit(1, "except Exception:")
    gen.emit(2, "return _reference(m)")
    code = "def encode(m):\n" + "\n".join(gen.lines) + "\n"
    if source:
        return code  # type: ignore[return-value]
    ns = dict(gen.ns, _HEADER=HEADER, _reference=reference)
    exec(compile(code, f"<cdr encoder {type_name}>", "exec"), ns)
    encode = ns["encode"]
    encode.__doc__ = f"CDR bytes of a {type_name} dict (generated by rod_sim.io.cdr)."
    encode.reference = reference
    return encode


@lru_cache(maxsize=None)
def encoder(type_name: str) -> Encoder:
    """The (cached) fast encoder of a type of :data:`rod_sim.io.msgdefs.SCHEMAS`; KeyError
    for another type."""
    from rod_sim.io.msgdefs import SCHEMAS
    if type_name not in SCHEMAS:
        raise KeyError(f"no schema for {type_name!r} (known: {', '.join(SCHEMAS)})")
    return compile_encoder(type_name, SCHEMAS[type_name])


def reference_encoder(type_name: str) -> Encoder:
    """The field-by-field reference encoder of a type of ``SCHEMAS`` (same bytes, slower)."""
    return encoder(type_name).reference
