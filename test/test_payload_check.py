"""replay's payload check walks a payload instead of decoding it: the same verdict as decoding
it with mcap_ros2 (the oracle here, called directly), on every topic of a plain and of a
spacecraft log, whole and damaged (cut at many places, padded, bit flips, random bytes). (Why:
a 1200-rod replay spent 97 % of its time in mcap_ros2's decoder, 19 ms a message, and fell
19 s behind in a 5 s log; the speed is measured in docs/replay.md, not here.)"""
from __future__ import annotations

import random
import struct
from pathlib import Path

import pytest
from mcap_ros2._cdr import CdrReader
from mcap_ros2._dynamic import TimeDefinition, _for_each_msgdef, _read_complex_type

from log_samples import logged_payloads
from rod_sim.io.payload_check import MAX_TRAILING, PayloadCheck

ROOT = Path(__file__).resolve().parents[1]
SCENES = {"plain": ROOT / "config" / "paper_example.yaml",
          "spacecraft": ROOT / "config" / "two_wing_deployment.yaml"}


def decodes(type_name: str, schema: str, data: bytes) -> bool:
    """The oracle: mcap_ros2 reads ``data`` as ``type_name`` and ends within MAX_TRAILING
    bytes of its end (and it has a CDR header)."""
    if len(data) < 4 or data[:2] not in (b"\x00\x00", b"\x00\x01"):
        return False
    msgdefs = {"builtin_interfaces/Time": TimeDefinition,
               "builtin_interfaces/Duration": TimeDefinition}

    def keep(name, short, msgdef):
        msgdefs[name] = msgdefs[short] = msgdef

    _for_each_msgdef(type_name, schema, keep)
    reader = CdrReader(data)
    try:
        _read_complex_type(msgdefs[type_name], msgdefs, reader, {})
    except Exception:  # noqa: BLE001 -- whatever the decoder raises
        return False
    return 0 <= len(data) - reader.decoded_bytes() <= MAX_TRAILING


@pytest.fixture(scope="module", params=sorted(SCENES))
def samples(request, tmp_path_factory):
    """(type name, schema, payload) of the first messages of every topic of a 0.2 s log."""
    out = tmp_path_factory.mktemp("payload") / "run.mcap"
    found = logged_payloads(SCENES[request.param], out, 0.2, keep=3)
    return [(schema.name, schema.data.decode(), d)
            for _, (schema, ds) in sorted(found.items()) for d in ds]


def damaged(data: bytes, rng: random.Random) -> list[bytes]:
    """Copies of ``data`` cut at many places, padded, with bits flipped (in the first 64
    bytes, where the lengths of headers and names are, and anywhere), a length field made
    huge, and random bytes of the same size."""
    cuts = {0, 3, 4, 5, 7, 8, 12, 16, len(data) // 3, len(data) // 2, len(data) - 8,
            len(data) - 4, len(data) - 1}
    out = [data[:k] for k in sorted(cuts) if 0 <= k < len(data)]
    out += [data + bytes(k) for k in (1, 3, 4, 8)]
    for _ in range(12):
        bad = bytearray(data)
        at = rng.randrange(4, min(len(data), 64)) if rng.random() < 0.6 else \
            rng.randrange(4, len(data))
        bad[at] ^= 1 << rng.randrange(8)
        out.append(bytes(bad))
    if len(data) >= 16:
        bad = bytearray(data)
        struct.pack_into("<I", bad, 12, 0xFFFFFFF0)       # e.g. a frame_id's or names' length
        out.append(bytes(bad))
    out.append(bytes(rng.randrange(256) for _ in data[:200]))
    out.append(b"\x00\x01\x00\x00" + bytes(rng.randrange(256) for _ in data[4:200]))
    return out


def test_the_walk_judges_every_payload_as_the_decoder_does(samples):
    rng = random.Random(5)
    checked = refused = 0
    types = set()
    for type_name, schema, data in samples:
        check = PayloadCheck(type_name, schema)
        assert check.complete
        types.add(type_name)
        for payload in [data] + damaged(data, rng):
            expected = decodes(type_name, schema, payload)
            assert (check.problem(payload) == "") == expected, (type_name, len(payload))
            checked += 1
            refused += not expected
    assert checked > 300 and refused > 100
    assert {"sensor_msgs/msg/JointState", "geometry_msgs/msg/PoseArray",
            "visualization_msgs/msg/MarkerArray", "std_msgs/msg/String"} <= types
