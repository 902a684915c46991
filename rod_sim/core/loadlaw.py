"""The scripted-load law, written once: plain Python here, compiled by the kernels.

:func:`scripted_value` is the value of one scripted load (docs/interface.md section 1) at a
time; the scene's Python side (:meth:`rod_sim.core.scene.Load.value`, ``Scene.scripted_forces``,
``Scene.scripted_load_table``) calls it as it is, and :mod:`rod_sim.core.kernels` compiles this
very function (``njit(inline="always")(scripted_value)``, as :func:`rod_sim.core.motion.profile_at`
for the prescribed base motion), so the two sides cannot drift apart. The module is pure
Python (no numba import): the scene and the command line use it without compiling anything.

Shapes (A the amplitude [N or N m], tau = t - start [s], T the duration [s]):

- ``raised_cosine_pulse``: A (1/2 - 1/2 cos(2 pi tau / T)) on [start, start + T], else 0;
- ``constant``: A from ``start`` on (0 before);
- ``step``: A on [start, start + T), else 0.

:class:`Loads` is the kernels' table of a scene's scripted loads (one entry per load).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

SHAPE_PULSE, SHAPE_CONSTANT, SHAPE_STEP = 0, 1, 2
SHAPE_CODES = {"raised_cosine_pulse": SHAPE_PULSE, "constant": SHAPE_CONSTANT,
               "step": SHAPE_STEP}
"""Shape name (scene data) -> the code :func:`scripted_value` and :class:`Loads` use."""


def scripted_value(t, shape, amp, start, dur, t_side):
    """One scripted load's value at time ``t`` [s]: shape code ``shape`` (SHAPE_*), amplitude
    ``amp``, ``start`` [s], duration ``dur`` [s] (inf for a constant load). Which side of a
    jump applies is decided at ``t_side`` [s] (a time strictly inside the current segment
    between load breakpoints for an integrator; ``t`` itself for a value at a time: a step is
    then A at its start and 0 at its end, as on [start, start + T))."""
    if t_side < start:
        return 0.0
    tau = t - start
    if shape == SHAPE_CONSTANT:
        return amp
    if shape == SHAPE_STEP:
        return amp if t_side < start + dur else 0.0
    if t_side > start + dur:
        return 0.0
    return amp * (0.5 - 0.5 * math.cos(2.0 * math.pi * tau / dur))


class Loads(NamedTuple):
    """A scene's scripted loads as the kernels read them, arrays (m,) for m loads: ``row``
    int64 and ``col`` int64 (where the load adds in the (n + 2, 3) load table: rows 0..n-1 the
    chain nodes, n the base, n + 1 the wheel; columns x, y [N], moment [N m]), ``shape``
    int64 (SHAPE_*), ``amp`` [N or N m], ``start`` [s], ``dur`` [s]."""

    row: np.ndarray
    col: np.ndarray
    shape: np.ndarray
    amp: np.ndarray
    start: np.ndarray
    dur: np.ndarray


def make_loads(rows, cols, shapes, amps, starts, durs) -> Loads:
    """:class:`Loads` from sequences (shape names or codes)."""
    codes = [SHAPE_CODES[s] if isinstance(s, str) else int(s) for s in shapes]
    return Loads(np.array(rows, dtype=np.int64), np.array(cols, dtype=np.int64),
                 np.array(codes, dtype=np.int64), np.array(amps, dtype=float),
                 np.array(starts, dtype=float), np.array(durs, dtype=float))
