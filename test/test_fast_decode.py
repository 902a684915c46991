"""The log readers' numpy decoders of JointState, PoseArray and Float64MultiArray
(rod_sim.io.fast_decode) against mcap_ros2's own decoder (the oracle, called directly): the same
values on every message of a plain, a spacecraft and a multi-chain log, and on damaged payloads
either the same values or the same exception. (Why: reading a 1200-rod log took ~22 ms a time
step with mcap_ros2's decoder, longer than comparing it.)"""
from __future__ import annotations

import math
import random
import struct
from pathlib import Path

import pytest
from mcap_ros2.decoder import DecoderFactory

from log_samples import logged_payloads
from rod_sim.io.fast_decode import fast_decoder

ROOT = Path(__file__).resolve().parents[1]
SCENES = {"plain": ROOT / "config" / "paper_example.yaml",
          "spacecraft": ROOT / "config" / "two_wing_deployment.yaml",
          "chains": ROOT / "config" / "tether_pair.yaml"}
FAST_TYPES = ("sensor_msgs/msg/JointState", "geometry_msgs/msg/PoseArray",
              "std_msgs/msg/Float64MultiArray")


def plain(value):
    """A decoded message as nested lists, dicts and floats (attributes by name)."""
    if isinstance(value, (str, bytes, bool, int)):
        return value
    if isinstance(value, float):
        return ("nan",) if math.isnan(value) else value
    if hasattr(value, "__len__") and hasattr(value, "__getitem__"):     # lists, arrays, poses
        return [plain(v) for v in value]
    if hasattr(value, "__slots__") or hasattr(value, "__dict__"):
        names = getattr(value, "__slots__", None) or [k for k in vars(value)
                                                       if k not in ("positions", "orientations")]
        return {k: plain(getattr(value, k)) for k in names}
    return [plain(v) for v in value]


@pytest.fixture(scope="module", params=sorted(SCENES))
def channels(request, tmp_path_factory):
    """{topic: (schema, [payloads])} of the fast types of a 0.3 s log."""
    out = tmp_path_factory.mktemp("fast") / "run.mcap"
    found = logged_payloads(SCENES[request.param], out, 0.3)
    return {topic: entry for topic, entry in found.items() if entry[0].name in FAST_TYPES}


def oracle(schema):
    return DecoderFactory().decoder_for("cdr", schema)


def outcome(decode, data):
    try:
        return "ok", plain(decode(data))
    except Exception as exc:  # noqa: BLE001 -- whatever the decoder raises
        return "raises", type(exc).__name__


def test_every_message_decodes_to_the_same_values(channels):
    types = set()
    for topic, (schema, payloads) in channels.items():
        reference = oracle(schema)
        fast = fast_decoder(schema.name, schema.data.decode(), reference)
        assert fast is not reference, f"{topic}: no fast decoder for {schema.name}"
        types.add(schema.name)
        for data in payloads:
            assert plain(fast(data)) == plain(reference(data)), topic
    assert {"sensor_msgs/msg/JointState", "std_msgs/msg/Float64MultiArray"} <= types


def test_damaged_payloads_decode_or_fail_as_the_oracle(channels):
    rng = random.Random(9)
    raised = 0
    for topic, (schema, payloads) in channels.items():
        reference = oracle(schema)
        fast = fast_decoder(schema.name, schema.data.decode(), reference)
        for data in payloads[:4]:
            variants = [data[:k] for k in (4, 8, 11, 12, 20, len(data) // 2, len(data) - 1)]
            variants += [data + bytes(5)]
            for _ in range(10):
                bad = bytearray(data)
                bad[rng.randrange(4, min(len(data), 80))] ^= 1 << rng.randrange(8)
                variants.append(bytes(bad))
            bad = bytearray(data)
            struct.pack_into("<I", bad, 4, 0xFFFFFFF0)
            variants.append(bytes(bad))
            for payload in variants:
                expected = outcome(reference, payload)
                assert outcome(fast, payload) == expected, (topic, len(payload))
                raised += expected[0] == "raises"
    assert raised > 20


def test_a_nonstandard_definition_keeps_mcap_ros2s_decoder(channels):
    """A JointState whose schema is not the standard one (a field more, or integers where
    the floats are) is not taken over."""
    schema = next(s for s, _ in channels.values() if s.name == "sensor_msgs/msg/JointState")
    reference = object()
    for old, new in (("float64[] effort", "float64[] effort\nfloat64 extra"),
                     ("float64[] position", "int64[] position")):   # the same bytes, not floats
        text = schema.data.decode().replace(old, new, 1)
        assert text != schema.data.decode()
        assert fast_decoder(schema.name, text, reference) is reference
    assert fast_decoder(schema.name, schema.data.decode(), reference) is not reference
