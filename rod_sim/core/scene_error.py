"""The scene's error type, its number limits and the checks of single numbers and pairs.

Shared by :mod:`rod_sim.core.scene` (rods, nodes, hinges, loads, chains), :mod:`rod_sim.core.motion`
(prescribed motion profiles) and :mod:`rod_sim.core.spacecraft` (the base), so that every scene
error has the same form: a :class:`SceneError` whose ``key`` names the entry in the scene file's
terms and whose message is one line.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from .quote import quote

MAX_RODS = 1_000_000        # rods.count (over all chains); the run's memory estimate is checked at the edges too
MAX_MAGNITUDE = 1e12        # |value| of every scene number, SI units
MIN_POSITIVE = 1e-12        # smallest length [m], bending stiffness [N m^2], duration [s]


class SceneError(ValueError):
    """A scene entry is missing, unknown, of the wrong length or non-physical.

    ``key`` is the dotted path of the entry (e.g. ``rods.length``, ``chains[1].name``);
    ``reason`` the message without the key; ``str(err)`` is the one line ``"{key}: {reason}"``.
    """

    def __init__(self, key: str, message: str):
        self.key = key
        self.reason = message
        super().__init__(f"{key}: {message}")

    def under(self, prefix: str) -> "SceneError":
        """The same error with its key prefixed (``prefix + key``), for a checker that does not
        know where in the scene file its entry sits."""
        return SceneError(prefix + self.key, self.reason)


def _num(v) -> float:
    """float(v), with integers too large for a float read as +-inf (instead of OverflowError)."""
    try:
        return float(v)
    except OverflowError:
        return math.copysign(math.inf, v)


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)


def check_number(path: str, value: Any, *, positive: bool = False, minimum: float | None = None,
                 missing: str = "missing") -> float:
    """``value`` as a finite float of magnitude <= MAX_MAGNITUDE (and > 0 with ``positive``, at
    least MIN_POSITIVE; >= ``minimum`` if given), else a SceneError keyed ``path``. ``None`` is
    missing (message ``missing``)."""
    if value is None:
        raise SceneError(path, missing)
    if not _is_number(value):
        raise SceneError(path, f"must be a number (got {quote(value)})")
    x = _num(value)
    if not math.isfinite(x):
        raise SceneError(path, f"must be finite (got {quote(value)})")
    if abs(x) > MAX_MAGNITUDE:
        raise SceneError(path, f"magnitude must be <= {MAX_MAGNITUDE:g} (got {quote(value)})")
    if positive and not x > 0.0:
        raise SceneError(path, f"must be > 0 (got {quote(value)})")
    if positive and x < MIN_POSITIVE:
        raise SceneError(path, f"must be >= {MIN_POSITIVE:g} (got {quote(value)})")
    if minimum is not None and x < minimum:
        raise SceneError(path, f"must be >= {minimum:g} (got {quote(value)})")
    return x


def check_pair(path: str, value: Any) -> tuple[float, float]:
    """``value`` as a pair of finite floats of magnitude <= MAX_MAGNITUDE ([x, y] [m] or
    [m/s^2]), else a SceneError keyed ``path``."""
    if not (isinstance(value, (list, tuple, np.ndarray)) and len(value) == 2):
        raise SceneError(path, f"must be a pair [x, y] of numbers (got {quote(value)})")
    out = []
    for i, v in enumerate(value):
        if not _is_number(v):
            raise SceneError(path, f"must be a pair [x, y] of numbers (got {quote(value)})")
        x = _num(v)
        if not math.isfinite(x):
            raise SceneError(path, f"must be finite at index {i} (got {quote(value)})")
        if abs(x) > MAX_MAGNITUDE:
            raise SceneError(path, f"magnitude must be <= {MAX_MAGNITUDE:g} at index {i} "
                                   f"(got {quote(value)})")
        out.append(x)
    return out[0], out[1]


def check_keys(mapping: Any, allowed, path: str) -> None:
    """SceneError unless ``mapping`` is a mapping whose keys are all in ``allowed`` (the key of
    an unknown entry is ``path.key``)."""
    from collections.abc import Mapping
    if not isinstance(mapping, Mapping):
        raise SceneError(path, f"must be a mapping with keys {', '.join(sorted(allowed))} "
                               f"(got {quote(mapping)})")
    for key in mapping:
        if key not in allowed:
            name = key if isinstance(key, str) and len(key) <= 40 else quote(key, 40)
            raise SceneError(f"{path}.{name}" if path else str(name),
                             f"unknown key (allowed: {', '.join(sorted(allowed))})")
