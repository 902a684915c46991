"""Damaged logs: every reader path (LogReader, compare, replay, deployment-figure, repair)
checks chunk CRCs, the data-section CRC and the summary CRC (issue 11 item 11); nothing damaged
is ever used, and since issue 19 item 3 one flipped bit no longer makes the intact data
unreachable: a damaged chunk is skipped (warning with its offset and the gap in log time), a
damaged summary ignored, one flipped bit outside the chunks' data located by the data-section
CRC and corrected. Framing damage that hides the rest of the file is exit 2 naming the byte."""
from __future__ import annotations

import random
import re
import struct
import zlib
from pathlib import Path

import pytest

from rod_sim.io.log_format import LogFormatError
from rod_sim.io.log_reader import LogReader
from rod_sim.io.log_writer import LogWriter
from rod_sim.io.series import read_rod_states
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


def verdict_with_warning(capsys, warning: str, *args) -> tuple[int, str]:
    """Run a reader command on a damaged log: it works from the intact part and says what it
    skipped or corrected on stderr (one warning, no traceback)."""
    code = rod_sim(*args)
    out = capsys.readouterr()
    assert "Traceback" not in out.err
    assert warning in out.err, out.err
    return code, out.out + out.err


def test_flipped_bit_in_the_last_chunk_skips_it_and_says_so(tmp_path, capsys, good_log):
    """Issue 19 item 3 (was: exit 2 for the whole file): the damaged chunk is skipped, the
    chunks before it are read, a warning names its offset and the time it covered."""
    data = good_log.read_bytes()
    pos, length = chunks(data)[-1]
    bad = flipped(good_log, tmp_path / "bad.mcap", pos + 9 + length - 20)
    # (CRC mismatch) or, when the flip breaks the compressed stream, (undecodable)
    warning = f"the chunk at byte {pos} is damaged ("
    code, text = verdict_with_warning(capsys, warning, "compare", bad)
    assert code == 0 and "PASS" in text
    t_good, _, _ = read_rod_states(good_log)
    t_bad, _, _ = read_rod_states(bad)
    assert 0 < t_bad.size < t_good.size and (t_bad == t_good[:t_bad.size]).all()
    assert re.search(r"gap in log time from [0-9.]+ s to the end", capsys.readouterr().err
                     + text)
    open_source(bad).close()                 # replay opens it too (the player reads it)


def test_flipped_bit_in_a_chunk_header_is_located_and_corrected(tmp_path, capsys, good_log):
    """A chunk header (its time range) is outside the chunk's CRC: the data-section CRC
    locates the one flipped bit, and every message is read as written."""
    data = good_log.read_bytes()
    pos, _ = chunks(data)[-1]
    bad = flipped(good_log, tmp_path / "bad.mcap", pos + 9 + 3)
    with LogReader(bad) as reader:
        assert list(reader.raw_messages()) == list(LogReader(good_log).raw_messages())
        assert reader.damaged and not reader.complete
        assert f"one flipped bit at byte {pos + 12} (bit 4" in reader.warnings[0]


def test_flipped_bit_in_the_summary_ignores_it(tmp_path, capsys, good_log):
    data = good_log.read_bytes()
    footer = len(data) - 8 - 29
    start = struct.unpack_from("<Q", data, footer + 9)[0]
    bad = flipped(good_log, tmp_path / "bad.mcap", (start + footer) // 2)
    code, text = verdict_with_warning(capsys, f"the summary section (byte {start}) is damaged",
                                      "compare", bad)
    assert code == 0 and "PASS" in text and "TRUNCATED" not in text


def test_no_single_flip_gives_a_silently_wrong_message(tmp_path, good_log):
    """Seeded single-bit flips anywhere but the trailing magic: the reader either refuses
    the file (LogFormatError naming a byte, or 'not an MCAP' for the leading magic) or reads
    messages that are all exactly as written, and says so in a warning whenever it read fewer
    or could not verify the metadata; the metadata it returns is the original one unless a
    warning says it is not verified."""
    data = good_log.read_bytes()
    with LogReader(good_log) as reader:
        written = set(reader.raw_messages())
        meta = reader.metadata()
    rng = random.Random(5)
    outcomes = {"refused": 0, "warned": 0}
    for i in range(40):
        bad = bytearray(data)
        at = rng.randrange(len(data) - 8)
        bad[at] ^= 1 << rng.randrange(8)
        path = tmp_path / f"flip_{i}.mcap"
        path.write_bytes(bytes(bad))
        try:
            with LogReader(path) as reader:
                got = list(reader.raw_messages())
                got_meta = reader.metadata()
                warnings = reader.warnings
        except LogFormatError as exc:
            assert re.search(r"byte \d+|bad magic", str(exc)), exc
            outcomes["refused"] += 1
            continue
        assert set(got) <= written, at
        assert warnings, at                              # the flip was noticed
        assert got_meta == meta or any("not verified" in w for w in warnings), (at, warnings)
        outcomes["warned"] += 1
    assert outcomes["warned"] > 30, outcomes


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
    """The first chunk of a log without summary holds the channel definitions: without them
    the later chunks cannot be decoded, so the file is refused naming the damaged chunk."""
    data = good_log.read_bytes()
    first, length = chunks(data)[0]
    last, _ = chunks(data)[-1]
    cut = bytearray(data[:last + 20])
    cut[first + 9 + length - 20] ^= 0x01
    path = tmp_path / "cut_bad.mcap"
    path.write_bytes(bytes(cut))
    assert rod_sim("compare", path) == 2
    err = capsys.readouterr().err
    assert f"the chunk at byte {first} is damaged" in err          # the warning
    assert f"the damaged chunk at byte {first} held the definition of channel" in \
        err.splitlines()[-1]


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
    with LogReader(path) as reader:                      # that chunk is skipped, and said so
        assert f"the chunk at byte {pos} is damaged (" in reader.warnings[0]
        assert 40 <= len(list(reader.messages())) < 50
