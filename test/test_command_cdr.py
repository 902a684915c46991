"""Array commands decoded straight from their CDR bytes (rod_sim.ros.command_cdr) against
rclpy's own ``serialize_message``/``deserialize_message`` (the oracle; no ROS graph):

- random Float64MultiArray messages (0..3 dims, labels empty and non-ASCII, any sizes, strides
  and data_offset, 0..2000 values with NaN payloads, infinities, -0.0, subnormals) serialized
  by rclpy decode to rclpy's fields, the values bit for bit, and never fall back;
- the node's outcome (``CommandIntake.decode`` then ``accept``: the forces or torques bit for
  bit, or the rejection text) is the one rclpy's decoding gives, for valid and invalid
  commands on one chain and on a scene of named chains with a wheel;
- bytes the fast decoder does not read exactly (truncated, flipped, trailing, big-endian,
  options set, odd labels) fall back to rclpy: the same message or the same refusal.
"""
from __future__ import annotations

import array
import math
import struct

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from rod_sim.ros.command_cdr import decode_float64_array
from rod_sim.ros.command_layout import CommandLayout
from rod_sim.ros.commands import FORCES, TORQUES, CommandIntake

LABEL_CHARS = ["a", "Z", "0", "_", " ", "é", "ß", "中", "文", "😀", "\u2028", "~"]
WINGS = CommandLayout((("left", 5), ("right", 5)), "free", True)
LAYOUTS = [CommandLayout.single(3), CommandLayout.single(8), WINGS]


def random_label(rng) -> str:
    return "".join(rng.choice(LABEL_CHARS) for _ in range(int(rng.integers(0, 9))))


def random_values(rng, count: int) -> np.ndarray:
    """Float64 values with the awkward ones mixed in (NaN payloads, +-inf, -0.0,
    subnormals, extremes)."""
    values = rng.normal(scale=10.0 ** rng.integers(-3, 4), size=count)
    specials = np.array([math.nan, -math.nan, math.inf, -math.inf, -0.0, 0.0, 5e-324, -2.2e-308,
                         1.7976931348623157e308])
    pick = rng.random(count) < 0.1
    values[pick] = rng.choice(specials, size=int(pick.sum()))
    bits = values.view(np.uint64)
    payload = rng.random(count) < 0.02      # NaNs with payloads (quiet), either sign
    bits[payload] = (np.uint64(0x7FF8000000000000) | rng.integers(1, 2**51, size=int(payload.sum()),
                                                                  dtype=np.uint64)
                     | (rng.integers(0, 2, size=int(payload.sum()), dtype=np.uint64) << 63))
    return values


def message(values, dims=(), offset=0) -> Float64MultiArray:
    """An rclpy message; ``values`` passed as an array.array (their bits kept)."""
    msg = Float64MultiArray()
    msg.data = array.array("d", np.asarray(values, dtype=np.float64).tobytes())
    msg.layout.dim = [MultiArrayDimension(label=label, size=size, stride=stride)
                      for label, size, stride in dims]
    msg.layout.data_offset = offset
    return msg


def random_message(rng) -> Float64MultiArray:
    count = int(rng.choice([0, 1, 2, 3, 16, 2000, int(rng.integers(0, 2001))]))
    dims = [(random_label(rng), int(rng.integers(0, 2**32)), int(rng.integers(0, 2**32)))
            for _ in range(int(rng.integers(0, 4)))]
    offset = int(rng.choice([0, 1, int(rng.integers(0, 2**32))]))
    return message(random_values(rng, count), dims, offset)


def bits(values) -> list[int]:
    return np.frombuffer(memoryview(values).cast("B") if isinstance(values, array.array)
                         else np.ascontiguousarray(values).tobytes(), dtype="<u8").tolist()


def test_rclpy_serialized_messages_decode_to_rclpys_fields_bit_for_bit():
    rng = np.random.default_rng(20261126)
    for _ in range(400):
        data = serialize_message(random_message(rng))
        ref = deserialize_message(data, Float64MultiArray)
        got = decode_float64_array(data)
        assert got is not None, data[:64].hex()             # never falls back on rclpy's bytes
        assert [(d.label, d.size, d.stride) for d in got.layout.dim] == \
               [(d.label, d.size, d.stride) for d in ref.layout.dim]
        assert got.layout.data_offset == ref.layout.data_offset
        assert got.data.dtype == np.float64 and got.data.shape == (len(ref.data),)
        assert bits(got.data) == bits(ref.data)
        if len(ref.data):
            assert not got.data.flags.writeable


def test_the_empty_array_with_or_without_its_padding():
    data = serialize_message(message([], offset=7))        # rclpy pads to the (empty) doubles
    assert len(data) == 20
    for cut in (data, data[:16]):
        assert deserialize_message(cut, Float64MultiArray).data.tolist() == []
        got = decode_float64_array(cut)
        assert got.data.size == 0 and got.layout.data_offset == 7


# ----- the node's outcome -----

def outcome(intake: CommandIntake, data: bytes):
    """What the node makes of ``data``: ('ok', bits of the command) or ('rejected', text)."""
    msg = intake.decode(data)
    command = None if msg is None else intake.accept(msg, 0)
    if command is None:
        return "rejected", intake.last_rejection
    return "ok", command.forces.shape, bits(command.forces)


def rclpy_outcome(intake: CommandIntake, data: bytes):
    """The same through rclpy's decoding (what the node did before the fast decoder)."""
    if len(data) > intake.max_bytes:
        return outcome(intake, data)                        # refused before any decoding
    try:
        msg = deserialize_message(data, Float64MultiArray)
    except Exception as exc:  # noqa: BLE001
        return "rejected", f"cannot be decoded ({type(exc).__name__}; not recorded)"
    command = intake.accept(msg, 0)
    if command is None:
        return "rejected", intake.last_rejection
    return "ok", command.forces.shape, bits(command.forces)


def same_outcome(layout: CommandLayout, kind: str, data: bytes):
    fast = outcome(CommandIntake(layout.n, 0.0, kind, layout), data)
    ref = rclpy_outcome(CommandIntake(layout.n, 0.0, kind, layout), data)
    assert fast == ref, (layout, kind, data[:48].hex())
    return fast


def commands(rng, layout: CommandLayout, kind: str):
    """Serialized commands for ``layout``: valid, wrong counts, non-finite values, per-chain
    dims right and wrong, values after a data_offset (with junk before it)."""
    width = 2 if kind == FORCES else 1
    size = layout.values(width)
    sizes = [size, size - 1, size + 1, 0]
    names = [name for name, _ in layout.chains] + (["wheel"] if width == 1 and layout.wheel
                                                   else [])
    counts = [width * c for _, c in layout.chains] + ([1] if width == 1 and layout.wheel else [])
    for count in sizes:
        yield message(rng.normal(size=count))
    for value in (math.nan, math.inf, -math.inf):
        values = rng.normal(size=size)
        values[int(rng.integers(0, size))] = value
        yield message(values)
    yield message(random_values(rng, size))                 # NaN payloads, -0.0, ...
    junk = np.array([math.nan, math.inf, 1.0])
    yield message(np.concatenate([junk, rng.normal(size=size)]), offset=3)
    yield message(np.concatenate([junk, rng.normal(size=size)]), offset=2)
    yield message(rng.normal(size=size), offset=size + 5)
    labelled = [(name or "", c, c) for name, c in zip(names, counts)]
    yield message(rng.normal(size=size), labelled)
    yield message(rng.normal(size=size), labelled[::-1])
    if len(labelled) > 1:
        wrong = [(label, c + (i == 1), s) for i, (label, c, s) in enumerate(labelled)]
        yield message(rng.normal(size=size), wrong)
        yield message(rng.normal(size=size + 1), wrong)
        bad = rng.normal(size=size)
        bad[-1] = math.nan
        yield message(bad, labelled)
    yield message(rng.normal(size=size), [("x", 3, 1), ("é中", 2, 2)])   # not per chain


@pytest.mark.parametrize("layout", LAYOUTS, ids=["one chain of 3", "one chain of 8", "wings"])
@pytest.mark.parametrize("kind", [FORCES, TORQUES])
def test_the_nodes_outcome_is_rclpys_for_valid_and_invalid_commands(layout, kind):
    rng = np.random.default_rng(7)
    seen = set()
    for msg in commands(rng, layout, kind):
        data = serialize_message(msg)
        assert decode_float64_array(data) is not None
        result = same_outcome(layout, kind, data)
        seen.add(result[0] if result[0] == "ok" else result[1].split(" ")[0])
        if result[0] == "rejected" and result[1].startswith("non-finite value"):
            ref = deserialize_message(data, Float64MultiArray)  # the value as rclpy gives it
            offset = ref.layout.data_offset
            j = next(k for k in range(offset, len(ref.data)) if not math.isfinite(ref.data[k]))
            assert result[1].startswith(f"non-finite value {ref.data[j]!r} at data[{j}]")
    assert {"ok", "expected", "non-finite"} <= seen
    if layout.named:
        assert {"layout", "chain"} <= seen


def test_a_valid_command_is_a_writable_copy_of_the_bytes():
    intake = CommandIntake(3, 0.0, FORCES)
    data = serialize_message(message(np.arange(6.0)))
    msg = intake.decode(data)
    assert isinstance(msg.data, np.ndarray)
    forces = intake.accept(msg, 0).forces
    assert forces.flags.writeable and not np.shares_memory(forces, msg.data)
    assert forces.tolist() == [[0, 1], [2, 3], [4, 5]]


# ----- what the fast decoder leaves to rclpy -----

def big_endian(msg: Float64MultiArray) -> bytes:
    """``msg`` in big-endian CDR (rclpy writes little-endian only; its decoder reads both)."""
    out = bytearray(b"\x00\x00\x00\x00")

    def put(fmt, *values):
        size = struct.calcsize(fmt[-1])
        out.extend(b"\0" * ((-(len(out) - 4)) % size))
        out.extend(struct.pack(">" + fmt, *values))
    put("I", len(msg.layout.dim))
    for d in msg.layout.dim:
        label = d.label.encode() + b"\0"
        put("I", len(label))
        out.extend(label)
        put("II", d.size, d.stride)
    put("II", msg.layout.data_offset, len(msg.data))
    if len(msg.data):
        put(f"{len(msg.data)}d", *msg.data)
    return bytes(out)


def label_bytes(raw: bytes, data=(1.0, 2.0, 3.0)) -> bytes:
    """One dim whose label is the length-prefixed ``raw`` bytes as they are (no NUL added)."""
    out = bytearray(b"\x00\x01\x00\x00") + struct.pack("<II", 1, len(raw)) + raw
    out.extend(b"\0" * ((-(len(out) - 4)) % 4))
    out.extend(struct.pack("<IIII", 3, 3, 0, len(data)))
    out.extend(b"\0" * ((-(len(out) - 4)) % 8))
    out.extend(struct.pack(f"<{len(data)}d", *data))
    return bytes(out)


def test_big_endian_and_other_headers_are_decoded_by_rclpy():
    rng = np.random.default_rng(3)
    layout = CommandLayout.single(3)
    for msg in list(commands(rng, layout, FORCES))[:6]:
        data = big_endian(msg)
        ref = deserialize_message(data, Float64MultiArray)   # rclpy reads our BE bytes
        assert bits(ref.data) == bits(msg.data)
        assert decode_float64_array(data) is None
        same_outcome(layout, FORCES, data)
        le = serialize_message(msg)
        for header in (b"\x00\x01\x00\x01", b"\x00\x03\x00\x00", b"\x01\x01\x00\x00"):
            assert decode_float64_array(header + le[4:]) is None
            same_outcome(layout, FORCES, header + le[4:])


def test_labels_the_fast_decoder_refuses_are_read_by_rclpy():
    """No NUL, a NUL inside, length 0, bad UTF-8: rclpy's lenient reading decides, also whether
    the dims name the chains (the label 'left' without its NUL is still 'left' to rclpy)."""
    layout = CommandLayout((("left", 3),))
    cases = [b"left", b"left\0", b"left\0xy\0", b"", b"le\xfft\0", b"\xed\xa0\x80\0",
             b"left\0\0", b"\0"]
    for raw in cases:
        for values in ([1.0, 2.0, 3.0, 4.0, 5.0, 6.0], [1.0, 2.0, 3.0]):
            data = label_bytes(raw, values)
            if raw in (b"left\0", b"\0"):                     # well formed: decoded here
                assert decode_float64_array(data).layout.dim[0].label == raw[:-1].decode()
            else:
                assert decode_float64_array(data) is None, raw
            same_outcome(layout, FORCES, data)


def test_truncated_flipped_and_trailing_bytes_give_rclpys_outcome():
    rng = np.random.default_rng(11)
    fallbacks = 0
    for layout, kind in ((CommandLayout.single(3), FORCES), (WINGS, TORQUES)):
        for msg in commands(rng, layout, kind):
            data = serialize_message(msg)
            variants = [data[:cut] for cut in range(len(data))]
            tails = [data + tail for tail in (b"\0", b"\0" * 4, b"\0" * 8, b"\xff" * 3)]
            assert all(decode_float64_array(v) is None for v in tails)   # not exact
            variants += tails
            for _ in range(40):
                flipped = bytearray(data)
                flipped[int(rng.integers(0, len(data)))] ^= 1 << int(rng.integers(0, 8))
                variants.append(bytes(flipped))
            for variant in variants:
                fallbacks += decode_float64_array(variant) is None
                same_outcome(layout, kind, variant)
    assert fallbacks > 1000


def test_oversize_commands_are_still_refused_before_decoding():
    intake = CommandIntake(3, 0.0, FORCES)
    data = serialize_message(message(np.zeros(1000)))
    assert len(data) > intake.max_bytes
    assert intake.decode(data) is None
    assert intake.last_rejection.startswith(f"{len(data)} bytes, more than the")
