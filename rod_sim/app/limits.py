"""Resource limits of the command line: what ``rod-sim`` refuses before it allocates.

Every figure here is stated in docs/interface.md ("Limits") and the README ("Reliability").
A refusal is a :class:`~rod_sim.app.common.UsageError` naming the option; the memory check
(:mod:`rod_sim.core.memory`, shared with the node) a SceneError keyed ``rods.count``.
"""
from __future__ import annotations

import math

from rod_sim.core.memory import gib

from .common import UsageError

MAX_T_END = 1e6                     # [s] of simulated time (--t-end)
MAX_RATE = 1e9                      # [Hz]: log times are whole nanoseconds
RTOL_RANGE = (1e-14, 1e-2)          # --rtol, the same range as the node's parameter
MAX_OUTPUT_BYTES = 4 * 1024 ** 3    # estimated (uncompressed) size of a simulate log
LOG_RECORD_BYTES = 47                # an MCAP message record's header (31) and index entry (16)
MAX_FIXED_STEPS = 1e8               # --t-end / --step of a fixed-step integrator
MARKERS_RATE_HZ = 50.0              # [Hz] default --markers-rate and node markers_rate_hz
MAX_MARKERS_RATE_HZ = 1e4           # --markers-rate, the same range as the node's parameter


def check_rtol(rtol: float | None) -> None:
    """--rtol within RTOL_RANGE (None: the default)."""
    lo, hi = RTOL_RANGE
    if rtol is not None and not lo <= rtol <= hi:
        raise UsageError(f"--rtol: must be between {lo:g} and {hi:g} (got {rtol:g})")


def check_sampling(t_end: float, rate_hz: float, n: int, *, sample_bytes: int,
                   markers_bytes: int, markers_every: int) -> int:
    """Refuse a --t-end / --rate whose log would exceed MAX_OUTPUT_BYTES; returns the number
    of samples the log will hold. ``sample_bytes``: the uncompressed bytes of one sample's
    messages and records but the markers, ``markers_bytes`` those of its markers, which go
    with every ``markers_every``-th sample from t = 0."""
    if t_end > MAX_T_END:
        raise UsageError(f"--t-end: at most {MAX_T_END:g} s (got {t_end:g})")
    if rate_hz > MAX_RATE:
        raise UsageError(f"--rate: at most {MAX_RATE:g} Hz, since log times are whole "
                         f"nanoseconds (got {rate_hz:g})")
    samples = math.floor(t_end * rate_hz + 1e-9) + 2          # t = 0, the grid and t_end
    size = samples * sample_bytes + math.ceil(samples / markers_every) * markers_bytes
    if size > MAX_OUTPUT_BYTES:
        raise UsageError(f"--rate x --t-end: the log would hold {samples:.3g} samples of "
                         f"{n} rods, about {gib(size)}; the limit is {gib(MAX_OUTPUT_BYTES)} "
                         "(lower --rate or --t-end)")
    return samples
