"""Where one flipped bit is, from a CRC-32 mismatch.

zlib's CRC-32 is linear over GF(2): for two inputs of equal length, crc(A) ^ crc(A') depends
only on A ^ A'. A single flipped bit at byte i (bit b) of an N-byte input changes the CRC by
``shift^(N-1-i)(D_b)``, where ``D_b`` is the change a flip of bit b makes in a one-byte input
and ``shift`` advances the CRC register over one zero byte. The polynomial's period (2^32 - 1
bits) makes that value distinct for every position of inputs under 512 MiB, so the syndrome
``stored ^ computed`` names the bit. :func:`locate_single_bit` walks the register back from the
end through the candidate byte ranges (jumping over the others), which costs O(candidate bytes
+ 32 x log N per range).
"""
from __future__ import annotations

import zlib
from collections.abc import Iterable

_MASK = 0xFFFFFFFF
_TABLE = [zlib.crc32(b"\0", j) ^ zlib.crc32(b"\0", 0) for j in range(256)]
"""shift(j) for j < 256: the reflected CRC-32 table (its top bytes are all distinct)."""
_BY_TOP = {t >> 24: j for j, t in enumerate(_TABLE)}
_FLIP = {zlib.crc32(bytes([1 << b])) ^ zlib.crc32(b"\0"): b for b in range(8)}
"""D_b -> b: the CRC change of flipping bit b of a one-byte input."""


def _unshift(r: int) -> int:
    """The inverse of one zero-byte step of the register: r = (s >> 8) ^ T[s & 0xff]."""
    j = _BY_TOP[r >> 24]
    return (((r ^ _TABLE[j]) << 8) & _MASK) | j


def _apply(columns: list[int], v: int) -> int:
    out, j = 0, 0
    while v:
        if v & 1:
            out ^= columns[j]
        v >>= 1
        j += 1
    return out


_POWERS: list[list[int]] = [[_unshift(1 << j) for j in range(32)]]
"""_POWERS[k]: the columns of unshift^(2^k)."""


def _unshift_many(v: int, count: int) -> int:
    """unshift^count (v): back over ``count`` zero bytes."""
    k = 0
    while count:
        while len(_POWERS) <= k:
            last = _POWERS[-1]
            _POWERS.append([_apply(last, c) for c in last])
        if count & 1:
            v = _apply(_POWERS[k], v)
        count >>= 1
        k += 1
    return v


def locate_single_bit(syndrome: int, length: int, ranges: Iterable[tuple[int, int]]
                      ) -> tuple[int, int] | None:
    """The (byte offset, bit) whose flip explains ``syndrome`` = stored ^ computed CRC-32 of a
    ``length``-byte input, searched in the byte ranges [start, stop) of ``ranges``; None when
    no single bit there explains it (the damage is elsewhere or more than one bit)."""
    if not syndrome:
        return None
    spans = sorted((max(0, a), min(length, b)) for a, b in ranges if b > a)
    v, at = syndrome, length         # v = unshift^(length - at)(syndrome), before byte `at`
    for start, stop in reversed(spans):
        if stop > at:                # overlapping ranges: continue below the last one
            stop = at
        if stop <= start:
            continue
        v = _unshift_many(v, at - stop)
        at = stop
        for i in range(stop - 1, start - 1, -1):
            bit = _FLIP.get(v)
            if bit is not None:
                return i, bit
            v = _unshift(v)
            at = i
    return None
