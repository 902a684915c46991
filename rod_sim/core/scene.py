"""The chain description: rods, node masses, hinges, initial state and scripted loads.

A :class:`Scene` is built once from plain Python data (``Scene.from_dict``) and validated
there; every error is a :class:`SceneError` whose ``key`` names the offending entry in the
scene file's terms (``rods.length``, ``loads[1].node``, ...). Arrays are read-only.

Indexing: rods and nodes 1..n in the paper are 0..n-1 in arrays (array index k is rod k+1,
node k+1); hinges 0..n-1 keep their paper numbers (hinge h sits at node h and joins rod h
to rod h+1; hinge 0 joins rod 1 to the ground).
"""
from __future__ import annotations

import math
import unicodedata
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from .quote import quote

LOAD_SHAPES = ("raised_cosine_pulse", "constant", "step")
LOAD_AXES = ("x", "y")
MAX_RODS = 1_000_000        # rods.count; the run's memory estimate is checked at the edges too
MAX_MAGNITUDE = 1e12        # |value| of every scene number, SI units
MIN_POSITIVE = 1e-12        # smallest length [m] and bending stiffness [N m^2]


class SceneError(ValueError):
    """A scene entry is missing, unknown, of the wrong length or non-physical.

    ``key`` is the dotted path of the entry (e.g. ``rods.length``); ``str(err)`` is a
    one-line message that starts with it.
    """

    def __init__(self, key: str, message: str):
        self.key = key
        super().__init__(f"{key}: {message}")


@dataclass(frozen=True)
class Load:
    """A scripted nodal force component.

    ``node`` is 1..n (paper numbering), ``axis`` 'x' or 'y', ``amplitude`` A [N],
    ``start`` [s], ``duration`` [s] (``inf`` for a ``constant`` load).
    Shapes: ``raised_cosine_pulse`` A(1/2 - 1/2 cos(2 pi (t-start)/duration)) on
    [start, start+duration]; ``constant`` A for t >= start; ``step`` A on
    [start, start+duration), zero elsewhere.
    """

    node: int
    axis: str
    shape: str
    amplitude: float
    start: float = 0.0
    duration: float = math.inf

    def value(self, t: float) -> float:
        """Force component [N] at simulated time ``t`` [s]."""
        tau = t - self.start
        if tau < 0.0:
            return 0.0
        if self.shape == "constant":
            return self.amplitude
        if self.shape == "step":
            return self.amplitude if tau < self.duration else 0.0
        if tau > self.duration:
            return 0.0
        return self.amplitude * (0.5 - 0.5 * math.cos(2.0 * math.pi * tau / self.duration))

    def breakpoints(self) -> tuple[float, ...]:
        """Times [s] where the force or one of its derivatives jumps."""
        if self.shape == "constant" or not math.isfinite(self.duration):
            return (self.start,)
        return (self.start, self.start + self.duration)

    def to_dict(self) -> dict[str, Any]:
        out = {"node": self.node, "axis": self.axis, "shape": self.shape,
               "amplitude": self.amplitude, "start": self.start}
        if math.isfinite(self.duration):
            out["duration"] = self.duration
        return out


_FEATURE_DEFAULTS = {"hinge_rest_angle": 0.0, "stop_lower": -math.inf, "stop_upper": math.inf,
                     "stop_stiffness": 0.0, "stop_damping": 0.0, "latch_angle": math.nan,
                     "hinge_locked": False, "rod_rigid": False}


def _is_default(arr: np.ndarray, default) -> bool:
    if isinstance(default, float) and math.isnan(default):
        return bool(np.all(np.isnan(arr)))
    return bool(np.all(arr == default))


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Scene:
    """A validated chain of n rods. All arrays have shape (n,) and SI units.

    length l_k [m], mass_per_length m_k [kg/m], bending_stiffness EI_k [N m^2] (rods 1..n);
    node_mass mu_k [kg] (nodes 1..n); hinge_stiffness kappa_h [N m/rad], hinge_damping
    nu_h [N m s/rad] (hinges 0..n-1); phi0 [rad], phi_rate0 [rad/s] (initial rod angles).
    """

    name: str
    length: np.ndarray
    mass_per_length: np.ndarray
    bending_stiffness: np.ndarray
    node_mass: np.ndarray
    hinge_stiffness: np.ndarray
    hinge_damping: np.ndarray
    phi0: np.ndarray
    phi_rate0: np.ndarray
    loads: tuple[Load, ...] = field(default_factory=tuple)
    # Hinge features (docs/hinges.md); the defaults reproduce the plain chain exactly.
    hinge_rest_angle: np.ndarray | None = None    # theta_rest_h [rad], default 0
    stop_lower: np.ndarray | None = None          # stop angles [rad], default -inf / +inf
    stop_upper: np.ndarray | None = None
    stop_stiffness: np.ndarray | None = None      # contact stiffness [N m/rad], default 0
    stop_damping: np.ndarray | None = None        # contact damping [N m s/rad], default 0
    latch_angle: np.ndarray | None = None         # latch angle [rad], NaN = no latch
    hinge_locked: np.ndarray | None = None        # bool (n,), default False
    rod_rigid: np.ndarray | None = None           # bool (n,), default False

    def __post_init__(self):
        n = len(self.length)
        for name in ("length", "mass_per_length", "bending_stiffness", "node_mass",
                     "hinge_stiffness", "hinge_damping", "phi0", "phi_rate0"):
            arr = _readonly(getattr(self, name))
            if arr.shape != (n,):
                raise SceneError(name, f"expected {n} values, got shape {arr.shape}")
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "loads", tuple(self.loads))
        for name, default in _FEATURE_DEFAULTS.items():
            value = getattr(self, name)
            value = default if value is None else value
            arr = np.array(np.broadcast_to(np.asarray(value), (n,)),
                           dtype=bool if isinstance(default, bool) else float)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def has_hinge_features(self) -> bool:
        """True when a hinge or rod uses a feature beyond the plain chain (rest angle, stop,
        latch, locked hinge, rigid rod)."""
        return any(not _is_default(getattr(self, name), default)
                   for name, default in _FEATURE_DEFAULTS.items())

    @property
    def n(self) -> int:
        """Number of rods."""
        return len(self.length)

    def with_changes(self, **changes) -> "Scene":
        """A copy with some fields replaced (arrays are broadcast to (n,))."""
        data = {f: getattr(self, f) for f in self.__dataclass_fields__}
        for key, value in changes.items():
            if key not in data:
                raise SceneError(key, "unknown scene field")
            if isinstance(data[key], np.ndarray):
                dtype = bool if data[key].dtype == bool else float
                value = np.broadcast_to(np.asarray(value, dtype=dtype), (self.n,))
            data[key] = value
        return Scene(**data)

    def load_breakpoints(self) -> tuple[float, ...]:
        """Sorted times [s] where a scripted load or one of its derivatives jumps."""
        return tuple(sorted({b for load in self.loads for b in load.breakpoints()}))

    def scripted_forces(self, t: float) -> np.ndarray:
        """Scripted nodal forces at time ``t`` [s]: array (n, 2) of (X_k, Y_k) [N]."""
        f = np.zeros((self.n, 2))
        for load in self.loads:
            f[load.node - 1, LOAD_AXES.index(load.axis)] += load.value(t)
        return f

    # ----- construction from plain data (the YAML layer parses text into this) -----

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "Scene":
        """Build and validate a scene from the structure of docs/interface.md section 1."""
        return _SceneParser().parse(data)

    def to_dict(self) -> dict[str, Any]:
        """The resolved scene (every per-rod value spelled out), as scene data (docs/interface.md section 1)."""

        def lst(a):
            return [float(v) for v in a]

        out: dict[str, Any] = {
            "name": self.name,
            "rods": {"count": self.n, "length": lst(self.length),
                     "mass_per_length": lst(self.mass_per_length),
                     "bending_stiffness": lst(self.bending_stiffness)},
            "nodes": {"mass": lst(self.node_mass)},
            "hinges": {"stiffness": lst(self.hinge_stiffness),
                       "damping": lst(self.hinge_damping)},
            "initial": {"phi": lst(self.phi0), "phi_rate": lst(self.phi_rate0)},
        }
        if self.loads:
            out["loads"] = [load.to_dict() for load in self.loads]
        self._features_to_dict(out)
        return out

    def _features_to_dict(self, out: dict[str, Any]) -> None:
        """Add the hinge-feature keys that differ from their defaults (so a plain scene's
        dictionary is unchanged)."""
        hinges = out["hinges"]
        if not _is_default(self.hinge_rest_angle, 0.0):
            hinges["rest_angle"] = [float(v) for v in self.hinge_rest_angle]
        has_stop = (self.stop_lower > -math.inf) | (self.stop_upper < math.inf)
        if has_stop.any():
            hinges["stop"] = {
                "angle": [[float(lo), float(hi)] if on else None
                          for lo, hi, on in zip(self.stop_lower, self.stop_upper, has_stop)],
                "stiffness": [float(v) for v in self.stop_stiffness],
                "damping": [float(v) for v in self.stop_damping]}
        if not _is_default(self.latch_angle, math.nan):
            hinges["latch"] = [None if math.isnan(v) else float(v) for v in self.latch_angle]
        if self.hinge_locked.any():
            hinges["locked"] = [bool(v) for v in self.hinge_locked]
        if self.rod_rigid.any():
            out["rods"]["rigid"] = [bool(v) for v in self.rod_rigid]


MAX_NAME_CHARS = 200
"""Longest scene name (characters): it is the URDF robot name, the log's scene title and the
diagnostics' name."""


def _check_name(name: str) -> None:
    """Refuse a scene name that some writer could not carry as it is: more than
    MAX_NAME_CHARS characters, or any character of Unicode category C (control, format,
    surrogate, private use, unassigned: "a\\0b" is not XML, a newline breaks a log line) or a
    line / paragraph separator. Checked once here, so every writer (URDF, logs, markers,
    diagnostics) gets a name it can write as it is."""
    if len(name) > MAX_NAME_CHARS:
        raise SceneError("name", f"at most {MAX_NAME_CHARS} characters (got {len(name)})")
    for i, ch in enumerate(name):
        if unicodedata.category(ch)[0] == "C" or unicodedata.category(ch) in ("Zl", "Zp"):
            raise SceneError("name", f"character {i + 1} is U+{ord(ch):04X} (control, format or "
                             "unassigned characters are not allowed; printable text only)")


_TOP_KEYS = {"name", "rods", "nodes", "hinges", "initial", "loads"}
_SECTION_KEYS = {
    "rods": {"count", "length", "mass_per_length", "bending_stiffness", "rigid"},
    "nodes": {"mass"},
    "hinges": {"stiffness", "damping", "rest_angle", "stop", "latch", "locked"},
    "initial": {"phi", "phi_rate"},
}
_LOAD_KEYS = {"node", "axis", "shape", "amplitude", "start", "duration"}
_STOP_KEYS = {"angle", "stiffness", "damping"}


def _num(v) -> float:
    """float(v), with integers too large for a float read as +-inf (instead of OverflowError)."""
    try:
        return float(v)
    except OverflowError:
        return math.copysign(math.inf, v)


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)


class _SceneParser:
    def parse(self, data: Mapping[str, Any]) -> Scene:
        if not isinstance(data, Mapping):
            raise SceneError("scene", "must be a mapping with keys rods, nodes, hinges, ...")
        self._unknown(data, _TOP_KEYS, "")
        for section in ("rods", "nodes", "hinges"):
            if section not in data:
                raise SceneError(section, "missing section")
        sections = {}
        for section, keys in _SECTION_KEYS.items():
            value = data.get(section, {})
            if value is None:
                value = {}
            if not isinstance(value, Mapping):
                raise SceneError(section, "must be a mapping")
            self._unknown(value, keys, section + ".")
            sections[section] = value
        rods = sections["rods"]
        if "count" not in rods:
            raise SceneError("rods.count", "missing")
        count = rods["count"]
        if (not (isinstance(count, (int, np.integer)) and not isinstance(count, bool))
                or not 1 <= count <= MAX_RODS):
            raise SceneError("rods.count", f"must be a whole number 1..{MAX_RODS} "
                                           f"(got {quote(count)})")
        n = int(count)
        name = data.get("name", "scene")
        if not isinstance(name, str) or not name:
            raise SceneError("name", f"must be a non-empty string (got {quote(name)})")
        _check_name(name)

        def arr(section, key, *, default=None, minimum=None, strict=False):
            path = f"{section}.{key}"
            value = sections[section].get(key, default)
            if value is None:
                raise SceneError(path, "missing")
            return self._array(path, value, n, minimum=minimum, strict=strict)

        scene_fields = dict(
            length=arr("rods", "length", minimum=0.0, strict=True),
            mass_per_length=arr("rods", "mass_per_length", minimum=0.0),
            bending_stiffness=arr("rods", "bending_stiffness", minimum=0.0, strict=True),
            node_mass=arr("nodes", "mass", minimum=0.0),
            hinge_stiffness=arr("hinges", "stiffness", minimum=0.0),
            hinge_damping=arr("hinges", "damping", minimum=0.0),
            phi0=arr("initial", "phi", default=0.0),
            phi_rate0=arr("initial", "phi_rate", default=0.0),
        )
        tip_mass = scene_fields["node_mass"][-1] + scene_fields["mass_per_length"][-1] * scene_fields["length"][-1]
        if tip_mass <= 0.0:
            raise SceneError("nodes.mass",
                             f"the chain has no inertia: rod {n} and node {n} are both massless")
        loads = self._loads(data.get("loads", []), n)
        scene_fields.update(self._features(sections, n, scene_fields))
        return Scene(name=name, loads=loads, **scene_fields)

    def _features(self, sections, n, fields) -> dict[str, Any]:
        """Hinge rest angles, stops, latches, locked hinges and rigid rods (docs/hinges.md)."""
        hinges = sections["hinges"]
        out: dict[str, Any] = {}
        if hinges.get("rest_angle") is not None:
            out["hinge_rest_angle"] = self._array("hinges.rest_angle", hinges["rest_angle"], n)
        if hinges.get("locked") is not None:
            out["hinge_locked"] = self._bools("hinges.locked", hinges["locked"], n)
        if sections["rods"].get("rigid") is not None:
            out["rod_rigid"] = self._bools("rods.rigid", sections["rods"]["rigid"], n)
        if hinges.get("latch") is not None:
            out["latch_angle"] = self._array("hinges.latch", hinges["latch"], n, allow_null=True)
        stop = hinges.get("stop")
        if stop is not None:
            out.update(self._stop(stop, n))
            lower, upper = out["stop_lower"], out["stop_upper"]

            def check_inside(key: str, angle: np.ndarray, what: str, why: str = "") -> None:
                """SceneError at the first hinge whose angle (nan: none) is outside its stops."""
                with np.errstate(invalid="ignore"):
                    outside = np.flatnonzero((angle < lower) | (angle > upper))
                if outside.size:
                    h = int(outside[0])
                    raise SceneError(key, f"hinge {h}: the {what} {angle[h]:g} rad lies outside "
                                          f"its stops [{lower[h]:g}, {upper[h]:g}]{why}")

            check_inside("hinges.stop.angle", np.diff(fields["phi0"], prepend=0.0),
                         "initial hinge angle")
            if out.get("latch_angle") is not None:
                check_inside("hinges.latch", out["latch_angle"], "latch angle",
                             ", so it can never latch")
        return out

    def _stop(self, stop, n) -> dict[str, np.ndarray]:
        if not isinstance(stop, Mapping):
            raise SceneError("hinges.stop", "must be a mapping with keys angle, stiffness, damping")
        self._unknown(stop, _STOP_KEYS, "hinges.stop.")
        for req in ("angle", "stiffness"):
            if stop.get(req) is None:
                raise SceneError(f"hinges.stop.{req}", "missing")
        angle = stop["angle"]
        path = "hinges.stop.angle"
        if isinstance(angle, (list, tuple)) and len(angle) == 2 and all(
                v is None or _is_number(v) for v in angle):
            pairs, per_hinge = [angle] * n, False
        elif isinstance(angle, (list, tuple)) and len(angle) == n:
            pairs, per_hinge = list(angle), True
        else:
            raise SceneError(path, f"must be one [lower, upper] pair or a list of {n} pairs "
                                   f"(null for a hinge without stops) (got {quote(angle)})")
        lower = np.full(n, -math.inf)
        upper = np.full(n, math.inf)
        for i, pair in enumerate(pairs):
            if pair is None:
                continue
            where = f" at index {i}" if per_hinge else ""
            if not (isinstance(pair, (list, tuple)) and len(pair) == 2):
                raise SceneError(path, f"must be a [lower, upper] pair{where} (got {quote(pair)})")
            lo, hi = pair
            lo = -math.inf if lo is None else lo
            hi = math.inf if hi is None else hi
            for v in (lo, hi):
                if not _is_number(v) or math.isnan(_num(v)):
                    raise SceneError(path, f"angles must be numbers{where} (got {quote(pair)})")
            if not _num(lo) < _num(hi) or _num(lo) == math.inf or _num(hi) == -math.inf:
                raise SceneError(path, f"needs lower < upper{where} (got {quote(pair)})")
            lower[i], upper[i] = _num(lo), _num(hi)
        stiffness = self._array("hinges.stop.stiffness", stop["stiffness"], n, minimum=0.0,
                                strict=True)
        damping = self._array("hinges.stop.damping", stop.get("damping", 0.0), n, minimum=0.0)
        return {"stop_lower": lower, "stop_upper": upper, "stop_stiffness": stiffness,
                "stop_damping": damping}

    @staticmethod
    def _bools(path, value, n) -> np.ndarray:
        if isinstance(value, (bool, np.bool_)):
            return np.full(n, bool(value))
        if not isinstance(value, (list, tuple)):
            raise SceneError(path, f"must be true/false or a list of {n} booleans (got {quote(value)})")
        if len(value) != n:
            raise SceneError(path, f"expected a boolean or a list of {n} booleans, got {len(value)}")
        for i, v in enumerate(value):
            if not isinstance(v, (bool, np.bool_)):
                raise SceneError(path, f"must be true or false at index {i} (got {quote(v)})")
        return np.array(value, dtype=bool)

    @staticmethod
    def _unknown(mapping: Mapping, allowed: set, prefix: str) -> None:
        for key in mapping:
            if key not in allowed:
                name = key if isinstance(key, str) and len(key) <= 40 else quote(key, 40)
                raise SceneError(f"{prefix}{name}",
                                 f"unknown key (allowed: {', '.join(sorted(allowed))})")

    @staticmethod
    def _array(path, value, n, *, minimum=None, strict=False, allow_null=False) -> np.ndarray:
        if allow_null and isinstance(value, (list, tuple)):
            if len(value) != n:
                raise SceneError(path, f"expected a scalar or a list of {n} values, got {len(value)}")
            nulls = [v is None for v in value]
            values = _SceneParser._array(path, [0.0 if v is None else v for v in value], n,
                                         minimum=minimum, strict=strict)
            values[nulls] = math.nan
            return values
        if _is_number(value):
            values = [value]          # one check, then broadcast (O(1) Python work per key)
        elif isinstance(value, (list, tuple)):
            if len(value) != n:
                raise SceneError(path, f"expected a scalar or a list of {n} values, got {len(value)}")
            values = list(value)
        else:
            raise SceneError(path, f"must be a number or a list of {n} numbers (got {quote(value)})")
        for i, v in enumerate(values):
            where = f" at index {i}" if len(values) > 1 and not _is_number(value) else ""
            if not _is_number(v):
                raise SceneError(path, f"must be a number{where} (got {quote(v)})")
            x = _num(v)
            if not math.isfinite(x):
                raise SceneError(path, f"must be finite{where} (got {quote(v)})")
            if abs(x) > MAX_MAGNITUDE:
                raise SceneError(path, f"magnitude must be <= {MAX_MAGNITUDE:g}{where} "
                                       f"(got {quote(v)})")
            if minimum is not None and (x <= minimum if strict else x < minimum):
                op = ">" if strict else ">="
                raise SceneError(path, f"must be {op} {minimum:g}{where} (got {quote(v)})")
            if strict and x < MIN_POSITIVE:
                raise SceneError(path, f"must be >= {MIN_POSITIVE:g}{where} (got {quote(v)})")
        if len(values) != n:
            return np.full(n, _num(value), dtype=float)
        return np.asarray(values, dtype=float)

    def _loads(self, loads, n) -> tuple[Load, ...]:
        if loads is None:
            return ()
        if not isinstance(loads, (list, tuple)):
            raise SceneError("loads", "must be a list of load entries")
        out = []
        for i, entry in enumerate(loads):
            key = f"loads[{i}]"
            if not isinstance(entry, Mapping):
                raise SceneError(key, "must be a mapping")
            self._unknown(entry, _LOAD_KEYS, key + ".")
            for req in ("node", "axis", "shape", "amplitude"):
                if req not in entry:
                    raise SceneError(f"{key}.{req}", "missing")
            node = entry["node"]
            if not (isinstance(node, (int, np.integer)) and not isinstance(node, bool)) or not 1 <= node <= n:
                raise SceneError(f"{key}.node", f"must be a node number 1..{n} (got {quote(node)})")
            axis = entry["axis"]
            if axis not in LOAD_AXES:
                raise SceneError(f"{key}.axis", f"must be 'x' or 'y' (got {quote(axis)})")
            shape = entry["shape"]
            if shape not in LOAD_SHAPES:
                raise SceneError(f"{key}.shape", f"must be one of {', '.join(LOAD_SHAPES)} (got {quote(shape)})")
            numbers = {}
            for k in ("amplitude", "start", "duration"):
                if k not in entry:
                    continue
                v = entry[k]
                if not _is_number(v) or not abs(_num(v)) <= MAX_MAGNITUDE:
                    raise SceneError(f"{key}.{k}", f"must be a finite number of magnitude <= "
                                                   f"{MAX_MAGNITUDE:g} (got {quote(v)})")
                numbers[k] = float(v)
            start = numbers.get("start", 0.0)
            if start < 0.0:
                raise SceneError(f"{key}.start", f"must be >= 0 (got {start:g})")
            duration = numbers.get("duration", math.inf)
            if shape == "raised_cosine_pulse" and "duration" not in numbers:
                raise SceneError(f"{key}.duration", "missing (a pulse needs a duration)")
            if duration <= 0.0:
                raise SceneError(f"{key}.duration", f"must be > 0 (got {duration:g})")
            out.append(Load(node=int(node), axis=axis, shape=shape,
                            amplitude=numbers["amplitude"], start=start, duration=duration))
        return tuple(out)
