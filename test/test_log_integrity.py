"""Corrupt logs never pass: every reader path (LogReader, compare, replay, deployment-figure)
checks chunk CRCs, the data-section CRC and the summary CRC, and a corrupt log is exit 2 naming
the byte offset of the damaged record, never a physics verdict (issue 11 item 11)."""
from __future__ import annotations

import random
import re
import struct
import zlib
from pathlib import Path

import pytest

from rod_sim.io.mcap_log import LogFormatError, LogReader, LogWriter, read_rod_states
from rod_sim.io.playback import PlaybackError, open_source
from rod_sim.io.scene_yaml import load_scene, scene_to_yaml
from rod_sim.tools import cli

ROOT = Path(__file__).resolve().parents[1]
SMALL = ROOT / "config" / "small_chain.yaml"
CHUNK, DATA_END, FOOTER = 0x06, 0x0F, 0x02


def rod_sim(*args) -> int:
    return cli.main([str(a) for a in args])


@pytest.fixture(scope="module")
def good_log(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("integrity") / "good.mcap"
    assert rod_sim("simulate", SMALL, "--model", "reduced", "--t-end", "3", "--out", out) == 0
    return out


def records(data: bytes) -> list[tuple[int, int, int]]:
    """(offset, opcode, length) of the data section's records, parsed independently."""
    out, pos = [], 8
    while pos + 9 <= len(data):
        opcode, length = struct.unpack_from("<BQ", data, pos)
        out.append((pos, opcode, length))
        if opcode in (DATA_END, FOOTER):
            break
        pos += 9 + length
    return out


def chunks(data: bytes) -> list[tuple[int, int]]:
    return [(pos, length) for pos, op, length in records(data) if op == CHUNK]


def flipped(src: Path, dst: Path, at: int) -> Path:
    data = bytearray(src.read_bytes())
    data[at] ^= 0x10
    dst.write_bytes(bytes(data))
    return dst


def assert_exit2_at(capsys, offset: int, *args) -> str:
    code = rod_sim(*args)
    out = capsys.readouterr()
    assert code == 2, (out.out, out.err)
    assert "Traceback" not in out.err
    assert "PASS" not in out.out and "FAIL" not in out.out     # never a physics verdict
    lines = out.err.strip().splitlines()
    assert len(lines) == 1 and "corrupt" in lines[0], out.err
    assert re.search(rf"\bbyte {offset}\b", lines[0]), (offset, lines[0])
    return lines[0]


def test_our_logs_carry_every_crc(good_log):
    """The writer stores chunk CRCs, the data-section CRC and the summary CRC, and they are
    the CRC-32 of what they cover (computed here with zlib, not with our reader)."""
    data = good_log.read_bytes()
    recs = records(data)
    end = [r for r in recs if r[1] == DATA_END][0]
    stored = struct.unpack_from("<I", data, end[0] + 9)[0]
    assert stored != 0 and stored == zlib.crc32(data[:end[0]])
    footer = len(data) - 8 - 29
    start, _, crc = struct.unpack_from("<QQI", data, footer + 9)
    assert crc == zlib.crc32(data[start:footer + 25])
    assert len(chunks(data)) >= 1


@pytest.mark.parametrize("where", ["chunk_payload", "chunk_header_time"])
def test_flipped_byte_in_a_chunk_is_exit_2_naming_its_offset(tmp_path, capsys, good_log, where):
    data = good_log.read_bytes()
    pos, length = chunks(data)[-1]
    # chunk body: start(8) end(8) uncompressed_size(8) crc(4) compression(4+len) records(8+...)
    at = pos + 9 + length - 20 if where == "chunk_payload" else pos + 9 + 3
    bad = flipped(good_log, tmp_path / "bad.mcap", at)
    data_end = [r for r in records(data) if r[1] == DATA_END][0][0]
    expect = pos if where == "chunk_payload" else data_end       # the data-section CRC
    line = assert_exit2_at(capsys, expect, "compare", bad)
    assert bad.name in line
    assert_exit2_at(capsys, expect, "replay", bad)
    assert_exit2_at(capsys, expect, "deployment-figure", bad, tmp_path / "fig.png")
    assert not (tmp_path / "fig.png").exists()
    with pytest.raises(LogFormatError, match=f"byte {expect}"):
        read_rod_states(bad)
    with pytest.raises(PlaybackError, match=f"byte {expect}"):
        open_source(bad)


def test_flipped_byte_in_the_summary_is_exit_2(tmp_path, capsys, good_log):
    data = good_log.read_bytes()
    footer = len(data) - 8 - 29
    start = struct.unpack_from("<Q", data, footer + 9)[0]
    bad = flipped(good_log, tmp_path / "bad.mcap", (start + footer) // 2)
    assert_exit2_at(capsys, start, "compare", bad)


def test_every_single_flip_is_refused(tmp_path, good_log):
    """Seeded single-bit flips anywhere but the trailing magic: the reader refuses every one
    (LogFormatError naming a byte), or for a flip in the leading magic says 'not an MCAP'."""
    data = good_log.read_bytes()
    rng = random.Random(5)
    for i in range(40):
        bad = bytearray(data)
        at = rng.randrange(len(data) - 8)
        bad[at] ^= 1 << rng.randrange(8)
        path = tmp_path / f"flip_{i}.mcap"
        path.write_bytes(bytes(bad))
        with pytest.raises(LogFormatError, match=r"byte \d+|bad magic"):
            with LogReader(path) as reader:
                list(reader.messages())


def test_a_truncated_log_is_not_corrupt(tmp_path, good_log):
    """A cut log (a killed writer) is read up to its last complete chunk, CRCs checked."""
    data = good_log.read_bytes()
    pos, length = chunks(data)[-1]
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:pos + length // 2])
    with LogReader(cut) as reader:
        assert not reader.complete and reader.truncated
        assert list(reader.messages(["/rod_states"]))


def test_flip_in_a_truncated_log_is_still_found(tmp_path, capsys, good_log):
    data = good_log.read_bytes()
    first, length = chunks(data)[0]
    last, _ = chunks(data)[-1]
    cut = bytearray(data[:last + 20])
    cut[first + 9 + length - 20] ^= 0x01
    path = tmp_path / "cut_bad.mcap"
    path.write_bytes(bytes(cut))
    assert_exit2_at(capsys, first, "compare", path)


def test_legacy_log_without_data_crc_is_still_chunk_checked(tmp_path):
    """Logs written before the data-section CRC was enabled (or by writers without it) store
    0 there: the chunk CRCs are still checked."""
    scene = load_scene(SMALL)
    path = tmp_path / "legacy.mcap"
    meta = {"scene": scene_to_yaml(scene), "model": "full", "integrator": "x"}
    with LogWriter(path, metadata=meta, chunk_size=512) as log:
        for i in range(50):
            log.write("/applied_forces", "std_msgs/msg/Float64MultiArray", i * 10_000_000,
                      {"data": [float(i)] * 6})
    data = bytearray(path.read_bytes())
    end = [r for r in records(bytes(data)) if r[1] == DATA_END][0]
    struct.pack_into("<I", data, end[0] + 9, 0)          # "not computed", as before this change
    path.write_bytes(bytes(data))
    with LogReader(path) as reader:
        assert len(list(reader.messages())) == 50
    pos, length = chunks(bytes(data))[1]
    data[pos + 9 + length - 5] ^= 0x04
    path.write_bytes(bytes(data))
    with pytest.raises(LogFormatError, match=f"byte {pos}"):
        LogReader(path)
