"""The scene: chains of rods (node masses, hinges, initial state), the base they hang on,
gravity and scripted loads.

A :class:`Scene` is built once from plain Python data (``Scene.from_dict``) and validated
there; every error is a :class:`SceneError` whose ``key`` names the offending entry in the
scene file's terms (``rods.length``, ``loads[1].node``, ``chains[1].name``, ``base.mode``, ...).
Arrays are read-only.

Chains are flattened: the per-rod arrays hold all chains' rods one chain after the other, in
scene order, so n = ``Scene.n`` is the total number of rods; chain c owns the rods
``chains[c].start .. chains[c].start + chains[c].count - 1`` (``chain_slices()``). A scene
without ``chains:`` is one unnamed chain attached at the base frame's origin.

Indexing: rods and nodes 1..n in the paper are 0..n-1 in arrays (array index k is rod k+1,
node k+1); hinges 0..n-1 keep their paper numbers (hinge h sits at node h and joins rod h
to rod h+1; hinge 0 joins rod 1 to the ground). Within a chain the same holds with the chain's
own numbers (its hinge 0 joins its rod 1 to the base).
"""
from __future__ import annotations

import math
import re
from collections.abc import Mapping
import unicodedata
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .loadlaw import SHAPE_CODES, scripted_value
from .motion import MOTION_SHAPES, MotionProfile
from .quote import quote
from .scene_error import (MAX_MAGNITUDE, MAX_RODS, MIN_POSITIVE, SceneError, _is_number, _num,
                          check_keys, check_number, check_pair)
from .spacecraft import BASE_MODES, BaseSpec, WheelSpec

__all__ = ["BASE_MODES", "LOAD_AXES", "LOAD_SHAPES", "MAX_MAGNITUDE", "MAX_RODS", "MIN_POSITIVE",
           "MOTION_SHAPES", "BaseSpec", "ChainSpec", "Load", "MotionProfile", "Scene",
           "SceneError", "WheelSpec"]

LOAD_SHAPES = tuple(SHAPE_CODES)      # raised_cosine_pulse, constant, step
LOAD_AXES = ("x", "y")                 # a chain node's force components
LOAD_COLUMNS = ("x", "y", "moment")    # columns of the kernels' load table (Load.column)
BASE_LOAD_AXES = ("x", "y", "moment")
WHEEL_LOAD_AXES = ("moment",)
CHAIN_NAME_RE = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
MAX_CHAIN_NAME = 64                    # characters


@dataclass(frozen=True)
class Load:
    """A scripted load component.

    ``node`` is 1..count of chain ``chain`` (paper numbering; ``chain`` indexes
    ``Scene.chains``, default 0), with ``axis`` 'x' or 'y' (a force [N] in Oxy); or ``'base'``
    with ``axis`` 'x', 'y' (a force [N] in Oxy at the base's centre of mass) or 'moment'
    [N m] (free base only); or ``'wheel'`` with ``axis`` 'moment': the wheel motor's torque
    [N m], +T on the wheel and -T on the base. ``amplitude`` A [N or N m], ``start`` [s],
    ``duration`` [s] (``inf`` for a ``constant`` load).
    Shapes: ``raised_cosine_pulse`` A(1/2 - 1/2 cos(2 pi (t-start)/duration)) on
    [start, start+duration]; ``constant`` A for t >= start; ``step`` A on
    [start, start+duration), zero elsewhere.
    """

    node: int | str
    axis: str
    shape: str
    amplitude: float
    start: float = 0.0
    duration: float = math.inf
    chain: int = 0

    def value(self, t: float) -> float:
        """Force component [N] (or moment [N m]) at simulated time ``t`` [s]: the one
        scripted-load law, :func:`rod_sim.core.loadlaw.scripted_value` (which the kernels
        compile)."""
        return scripted_value(t, SHAPE_CODES[self.shape], self.amplitude, self.start,
                              self.duration, t)

    def breakpoints(self) -> tuple[float, ...]:
        """Times [s] where the force or one of its derivatives jumps."""
        if self.shape == "constant" or not math.isfinite(self.duration):
            return (self.start,)
        return (self.start, self.start + self.duration)

    def row(self, scene: "Scene") -> int:
        """Row of the kernels' load table (shape (n + 2, 3)) this load adds to:
        ``chains[chain].start + node - 1`` for a chain node, n for 'base', n + 1 for 'wheel'."""
        if self.node == "base":
            return scene.n
        if self.node == "wheel":
            return scene.n + 1
        return scene.chains[self.chain].start + int(self.node) - 1

    @property
    def column(self) -> int:
        """Column of the kernels' load table: 0 x, 1 y, 2 moment."""
        return LOAD_COLUMNS.index(self.axis)

    def to_dict(self, chain_name: str | None = None) -> dict[str, Any]:
        """The load as scene data; ``chain_name`` (a chain node's load in a scene with
        ``chains:``) is written first as ``chain``."""
        out: dict[str, Any] = {} if chain_name is None else {"chain": chain_name}
        out.update({"node": self.node, "axis": self.axis, "shape": self.shape,
                    "amplitude": self.amplitude, "start": self.start})
        if math.isfinite(self.duration):
            out["duration"] = self.duration
        return out


@dataclass(frozen=True)
class ChainSpec:
    """One chain of the scene: its ``name`` (None for the one chain of a scene without
    ``chains:``), the index ``start`` of its first rod in the scene's per-rod arrays, its
    number of rods ``count`` and the point ``attach`` [m] of the base frame where its hinge 0
    sits."""

    name: str | None
    start: int
    count: int
    attach: tuple[float, float] = (0.0, 0.0)


_FEATURE_DEFAULTS = {"hinge_rest_angle": 0.0, "stop_lower": -math.inf, "stop_upper": math.inf,
                     "stop_stiffness": 0.0, "stop_damping": 0.0, "latch_angle": math.nan,
                     "hinge_locked": False, "rod_rigid": False}
_ARRAY_FIELDS = ("length", "mass_per_length", "bending_stiffness", "node_mass",
                 "hinge_stiffness", "hinge_damping", "phi0", "phi_rate0")


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
    """A validated set of chains (n rods in all) on a base. All arrays have shape (n,) and SI
    units, the chains' rods concatenated in scene order (module docstring).

    length l_k [m], mass_per_length m_k [kg/m], bending_stiffness EI_k [N m^2] (rods 1..n);
    node_mass mu_k [kg] (nodes 1..n); hinge_stiffness kappa_h [N m/rad], hinge_damping
    nu_h [N m s/rad] (hinges 0..n-1); phi0 [rad], phi_rate0 [rad/s] (initial rod angles in
    Oxy). ``chains``: the chains (default: one unnamed chain of all n rods at the base frame's
    origin); ``base``: what they hang on (default: fixed at the origin); ``gravity``: (g_x, g_y)
    [m/s^2] in Oxy or None; ``base_given``: the scene data had a ``base:`` key (written back by
    ``to_dict`` even when it says what the default says).
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
    # The spacecraft (SPEC section 8); the defaults reproduce the chain on the ground exactly.
    chains: tuple[ChainSpec, ...] | None = None   # default (ChainSpec(None, 0, n, (0, 0)),)
    base: BaseSpec | None = None                  # default BaseSpec('fixed') at the origin
    gravity: tuple[float, float] | None = None    # (g_x, g_y) [m/s^2], None = no gravity
    base_given: bool = False                      # the scene data had a base: key

    def __post_init__(self):
        n = len(self.length)
        for name in _ARRAY_FIELDS:
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
        self._init_spacecraft(n)

    def _init_spacecraft(self, n: int) -> None:
        """Defaults and consistency of chains, base and gravity; the chain index arrays."""
        chains = (ChainSpec(None, 0, n, (0.0, 0.0)),) if self.chains is None else tuple(self.chains)
        if not chains:
            raise SceneError("chains", "must be a non-empty list of chains")
        if any(c.name is None for c in chains) and (
                len(chains) != 1 or chains[0].name is not None or tuple(chains[0].attach) != (0.0, 0.0)):
            raise SceneError("chains", "only a scene's single chain may be unnamed, and it is "
                                       "attached at the base frame's origin")
        starts = [0]
        for c, chain in enumerate(chains):
            if chain.start != starts[-1] or chain.count < 1:
                raise SceneError(f"chains[{c}]", f"must start at rod index {starts[-1]} and have "
                                                 f"at least one rod (got start {chain.start}, "
                                                 f"count {chain.count})")
            starts.append(starts[-1] + chain.count)
        if starts[-1] != n:
            raise SceneError("chains", f"the chains have {starts[-1]} rods, the arrays {n}")
        object.__setattr__(self, "chains", tuple(
            ChainSpec(ch.name, int(ch.start), int(ch.count),
                      check_pair(f"chains[{c}].attach", ch.attach))
            for c, ch in enumerate(chains)))
        base = BaseSpec() if self.base is None else self.base
        if not isinstance(base, BaseSpec):
            raise SceneError("base", f"must be a BaseSpec (got {quote(base)})")
        object.__setattr__(self, "base", base)
        if self.gravity is not None:
            object.__setattr__(self, "gravity", check_pair("gravity", self.gravity))
        chain_starts = np.array(starts, dtype=np.int64)
        chain_of_rod = np.repeat(np.arange(len(chains), dtype=np.int64), np.diff(chain_starts))
        chain_root = np.zeros(n, dtype=bool)
        chain_root[chain_starts[:-1]] = True
        for arr in (chain_starts, chain_of_rod, chain_root):
            arr.setflags(write=False)
        object.__setattr__(self, "_chain_starts", chain_starts)
        object.__setattr__(self, "_chain_of_rod", chain_of_rod)
        object.__setattr__(self, "_chain_root", chain_root)
        for i, load in enumerate(self.loads):       # Load.row must land in the load table
            if load.node == "base" and (base.mode != "free" or load.axis not in BASE_LOAD_AXES):
                raise SceneError(f"loads[{i}]", "a base load needs a free base and axis x, y "
                                                "or moment")
            if load.node == "wheel" and (base.wheel is None or load.axis != "moment"):
                raise SceneError(f"loads[{i}]", "a wheel load needs base.wheel and axis moment")
            if load.node not in ("base", "wheel") and not (
                    0 <= load.chain < len(self.chains) and isinstance(load.node, (int, np.integer))
                    and 1 <= load.node <= self.chains[load.chain].count and load.axis in LOAD_AXES):
                raise SceneError(f"loads[{i}]", f"chain {load.chain}, node {quote(load.node)}, "
                                                f"axis {quote(load.axis)} is not a chain node's "
                                                f"force")

    @property
    def has_hinge_features(self) -> bool:
        """True when a hinge or rod uses a feature beyond the plain chain (rest angle, stop,
        latch, locked hinge, rigid rod)."""
        return any(not _is_default(getattr(self, name), default)
                   for name, default in _FEATURE_DEFAULTS.items())

    @property
    def n(self) -> int:
        """Number of rods (over all chains)."""
        return len(self.length)

    @property
    def has_chains(self) -> bool:
        """True when the scene lists named ``chains:`` (False: one chain from the top-level
        rods, nodes, hinges, initial)."""
        return self.chains[0].name is not None

    @property
    def has_base(self) -> bool:
        """True when the scene has a ``base:`` (given in the data, or other than the fixed base
        at the origin)."""
        return self.base_given or not self.base.is_default

    @property
    def is_spacecraft(self) -> bool:
        """True with a ``base:``, ``chains:`` or ``gravity:`` (docs/spacecraft.md): the outputs
        then carry the base, the momentum and the energy ledger; a plain chain's outputs are
        what they always were."""
        return self.has_base or self.has_chains or self.gravity is not None

    @property
    def moving_base(self) -> bool:
        """True for a free or prescribed base (``base_odometry`` and the base's joints)."""
        return self.base.mode != "fixed"

    @property
    def chain_starts(self) -> np.ndarray:
        """int64 (number of chains + 1,): [start_0, start_1, ..., n]; chain c owns the rods
        chain_starts[c] .. chain_starts[c + 1] - 1 (read-only)."""
        return self._chain_starts

    def chain_slices(self) -> list[slice]:
        """One slice of the per-rod arrays per chain, in scene order."""
        s = self._chain_starts
        return [slice(int(s[c]), int(s[c + 1])) for c in range(len(self.chains))]

    @property
    def chain_of_rod(self) -> np.ndarray:
        """int64 (n,): the index in ``chains`` of each rod's chain (read-only)."""
        return self._chain_of_rod

    @property
    def chain_root(self) -> np.ndarray:
        """bool (n,): True for the first rod of each chain (its hinge 0 joins it to the base;
        the hinge angle is phi_k - psi there, phi_k - phi_{k-1} elsewhere) (read-only)."""
        return self._chain_root

    def initial_hinge_angles(self) -> np.ndarray:
        """The initial rigid hinge angles theta_h (n,) [rad]: phi_1 - psi_0 at each chain's
        hinge 0 (psi_0 = the base's initial angle), phi_{h+1} - phi_h otherwise."""
        theta = np.diff(self.phi0, prepend=0.0)
        roots = self._chain_starts[:-1]
        theta[roots] = self.phi0[roots] - self.base.psi
        return theta

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

    def motion_breakpoints(self) -> tuple[float, ...]:
        """Sorted times [s] where a prescribed base motion's formula changes (empty unless the
        base is prescribed)."""
        return self.base.breakpoints()

    def breakpoints(self) -> tuple[float, ...]:
        """Sorted times [s] where a scripted load or the base's prescribed motion may jump
        (:meth:`load_breakpoints` and :meth:`motion_breakpoints`): integrators end a step
        there and the ledgers book a sample there. Found once (the scene is immutable): every
        drive of the integrator asks."""
        found = self.__dict__.get("_breakpoints")
        if found is None:
            found = tuple(sorted(set(self.load_breakpoints()) | set(self.motion_breakpoints())))
            object.__setattr__(self, "_breakpoints", found)
        return found

    def scripted_forces(self, t: float) -> np.ndarray:
        """Scripted nodal forces at time ``t`` [s]: array (n, 2) of (X_k, Y_k) [N] (the chain
        nodes' loads; base and wheel loads are in :meth:`scripted_load_table`)."""
        f = np.zeros((self.n, 2))
        for load in self.loads:
            if not isinstance(load.node, str):
                f[load.row(self), load.column] += load.value(t)
        return f

    def scripted_load_table(self, t: float) -> np.ndarray:
        """Every scripted load at time ``t`` [s]: array (n + 2, 3), row ``Load.row`` (nodes
        1..n in scene order, then the base, then the wheel), column ``Load.column`` (force x,
        force y [N] in Oxy, moment [N m])."""
        f = np.zeros((self.n + 2, 3))
        for load in self.loads:
            f[load.row(self), load.column] += load.value(t)
        return f

    # ----- construction from plain data (the YAML layer parses text into this) -----

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "Scene":
        """Build and validate a scene from the structure of docs/interface.md section 1."""
        return _SceneParser().parse(data)

    def to_dict(self) -> dict[str, Any]:
        """The resolved scene (every per-rod value spelled out), as scene data
        (docs/interface.md section 1). A scene without base, chains and gravity gives the
        same dictionary as before they existed; ``Scene.from_dict(s.to_dict())`` gives ``s``
        back exactly."""
        out: dict[str, Any] = {"name": self.name}
        if self.has_base:
            out["base"] = self.base.to_dict()
        if self.gravity is not None:
            out["gravity"] = [self.gravity[0], self.gravity[1]]
        if self.has_chains:
            out["chains"] = [{"name": ch.name, "attach": [ch.attach[0], ch.attach[1]],
                              **self._chain_dict(sl)}
                             for ch, sl in zip(self.chains, self.chain_slices())]
        else:
            out.update(self._chain_dict(slice(0, self.n)))
        if self.loads:
            out["loads"] = [load.to_dict(self.chains[load.chain].name
                                         if isinstance(load.node, int) else None)
                            for load in self.loads]
        return out

    def _chain_dict(self, sl: slice) -> dict[str, Any]:
        """rods, nodes, hinges, initial of the rods ``sl`` (a chain) as scene data, with the
        hinge-feature keys that differ from their defaults in that chain."""

        def lst(a):
            return [float(v) for v in a[sl]]

        out: dict[str, Any] = {
            "rods": {"count": sl.stop - sl.start, "length": lst(self.length),
                     "mass_per_length": lst(self.mass_per_length),
                     "bending_stiffness": lst(self.bending_stiffness)},
            "nodes": {"mass": lst(self.node_mass)},
            "hinges": {"stiffness": lst(self.hinge_stiffness),
                       "damping": lst(self.hinge_damping)},
            "initial": {"phi": lst(self.phi0), "phi_rate": lst(self.phi_rate0)},
        }
        self._features_to_dict(out, sl)
        return out

    def _features_to_dict(self, out: dict[str, Any], sl: slice) -> None:
        """Add the hinge-feature keys of the rods ``sl`` that differ from their defaults (so a
        plain chain's dictionary is unchanged)."""
        hinges = out["hinges"]
        rest, lower, upper = self.hinge_rest_angle[sl], self.stop_lower[sl], self.stop_upper[sl]
        latch, locked, rigid = self.latch_angle[sl], self.hinge_locked[sl], self.rod_rigid[sl]
        if not _is_default(rest, 0.0):
            hinges["rest_angle"] = [float(v) for v in rest]
        has_stop = (lower > -math.inf) | (upper < math.inf)
        if has_stop.any():
            hinges["stop"] = {
                "angle": [[float(lo), float(hi)] if on else None
                          for lo, hi, on in zip(lower, upper, has_stop)],
                "stiffness": [float(v) for v in self.stop_stiffness[sl]],
                "damping": [float(v) for v in self.stop_damping[sl]]}
        if not _is_default(latch, math.nan):
            hinges["latch"] = [None if math.isnan(v) else float(v) for v in latch]
        if locked.any():
            hinges["locked"] = [bool(v) for v in locked]
        if rigid.any():
            out["rods"]["rigid"] = [bool(v) for v in rigid]


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


_TOP_KEYS = {"name", "rods", "nodes", "hinges", "initial", "loads", "base", "chains", "gravity"}
_CHAIN_SECTIONS = ("rods", "nodes", "hinges", "initial")
_CHAIN_KEYS = {"name", "attach", *_CHAIN_SECTIONS}
_SECTION_KEYS = {
    "rods": {"count", "length", "mass_per_length", "bending_stiffness", "rigid"},
    "nodes": {"mass"},
    "hinges": {"stiffness", "damping", "rest_angle", "stop", "latch", "locked"},
    "initial": {"phi", "phi_rate"},
}
_LOAD_KEYS = {"chain", "node", "axis", "shape", "amplitude", "start", "duration"}
_STOP_KEYS = {"angle", "stiffness", "damping"}


class _SceneParser:
    def parse(self, data: Mapping[str, Any]) -> Scene:
        if not isinstance(data, Mapping):
            raise SceneError("scene", "must be a mapping with keys rods, nodes, hinges, ...")
        self._unknown(data, _TOP_KEYS, "")
        base = None
        if "base" in data:
            base = BaseSpec.from_dict(data["base"])
        psi0 = 0.0 if base is None else base.psi
        gravity = None
        if data.get("gravity") is not None:
            gravity = check_pair("gravity", data["gravity"])
        if "chains" in data:
            for section in _CHAIN_SECTIONS:
                if section in data:
                    raise SceneError(section, "not allowed beside chains: (each chain has its "
                                              "own rods, nodes, hinges and initial)")
            name = self._name(data)
            chains, fields = self._chains(data["chains"], psi0)
            loads = self._loads(data.get("loads", []), chains, base)
        else:
            fields, n = self._chain(data, "", psi0, top_level=True,
                                    loads=lambda n: self._loads(data.get("loads", []),
                                                                (ChainSpec(None, 0, n),), base))
            name = self._name(data)
            loads = fields.pop("loads")
            chains = None
        return Scene(name=name, loads=loads, chains=chains, base=base, gravity=gravity,
                     base_given=base is not None, **fields)

    @staticmethod
    def _name(data) -> str:
        name = data.get("name", "scene")
        if not isinstance(name, str) or not name:
            raise SceneError("name", f"must be a non-empty string (got {quote(name)})")
        _check_name(name)
        return name

    def _chains(self, chains, psi0: float) -> tuple[tuple[ChainSpec, ...], dict[str, Any]]:
        """Parse ``chains:``; the chains and their per-rod arrays concatenated in order."""
        if not isinstance(chains, (list, tuple)) or not chains:
            raise SceneError("chains", f"must be a non-empty list of chains (got {quote(chains)})")
        specs, parts, names, total = [], [], {}, 0
        for c, entry in enumerate(chains):
            prefix = f"chains[{c}]."
            if not isinstance(entry, Mapping):
                raise SceneError(f"chains[{c}]", f"must be a mapping with keys name, attach, "
                                                 f"rods, nodes, hinges, initial (got {quote(entry)})")
            self._unknown(entry, _CHAIN_KEYS, prefix)
            name = entry.get("name")
            if name is None:
                raise SceneError(prefix + "name", "missing (each chain needs a name)")
            if not (isinstance(name, str) and CHAIN_NAME_RE.fullmatch(name)
                    and len(name) <= MAX_CHAIN_NAME):
                raise SceneError(prefix + "name", f"must match [A-Za-z][A-Za-z0-9_]* with at most "
                                                  f"{MAX_CHAIN_NAME} characters (got {quote(name)})")
            if name in names:
                raise SceneError(prefix + "name", f"duplicate chain name {name!r} (also "
                                                  f"chains[{names[name]}])")
            names[name] = c
            attach = check_pair(prefix + "attach", entry.get("attach", (0.0, 0.0)))
            fields, count = self._chain(entry, prefix, psi0, total=total)
            specs.append(ChainSpec(name, total, count, attach))
            parts.append(fields)
            total += count
        if len(parts) == 1:
            return tuple(specs), parts[0]
        return tuple(specs), {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}

    def _chain(self, data, prefix: str, psi0: float, *, top_level: bool = False, total: int = 0,
               loads=None) -> tuple[dict[str, Any], int]:
        """The per-rod arrays of one chain (the scene's top-level sections, or one entry of
        ``chains:``; keys prefixed with ``prefix``) and its rod count. ``total``: the rods of
        the chains before it (for the MAX_RODS limit); ``loads(n)``: called between the plain
        arrays and the hinge features (the order of a scene without chains)."""
        for section in ("rods", "nodes", "hinges"):
            if section not in data:
                raise SceneError(prefix + section, "missing section")
        sections = {}
        for section, keys in _SECTION_KEYS.items():
            value = data.get(section, {})
            if value is None:
                value = {}
            if not isinstance(value, Mapping):
                raise SceneError(prefix + section, "must be a mapping")
            self._unknown(value, keys, f"{prefix}{section}.")
            sections[section] = value
        rods = sections["rods"]
        if "count" not in rods:
            raise SceneError(prefix + "rods.count", "missing")
        count = rods["count"]
        if (not (isinstance(count, (int, np.integer)) and not isinstance(count, bool))
                or not 1 <= count <= MAX_RODS):
            raise SceneError(prefix + "rods.count", f"must be a whole number 1..{MAX_RODS} "
                                                    f"(got {quote(count)})")
        n = int(count)
        if total + n > MAX_RODS:
            raise SceneError(prefix + "rods.count", f"the chains have {total + n} rods up to this "
                                                    f"one; at most {MAX_RODS} in all")
        if top_level:
            self._name(data)

        def arr(section, key, *, default=None, minimum=None, strict=False):
            path = f"{prefix}{section}.{key}"
            value = sections[section].get(key, default)
            if value is None:
                raise SceneError(path, "missing")
            return self._array(path, value, n, minimum=minimum, strict=strict)

        fields: dict[str, Any] = dict(
            length=arr("rods", "length", minimum=0.0, strict=True),
            mass_per_length=arr("rods", "mass_per_length", minimum=0.0),
            bending_stiffness=arr("rods", "bending_stiffness", minimum=0.0, strict=True),
            node_mass=arr("nodes", "mass", minimum=0.0),
            hinge_stiffness=arr("hinges", "stiffness", minimum=0.0),
            hinge_damping=arr("hinges", "damping", minimum=0.0),
            phi0=arr("initial", "phi", default=0.0),
            phi_rate0=arr("initial", "phi_rate", default=0.0),
        )
        tip_mass = fields["node_mass"][-1] + fields["mass_per_length"][-1] * fields["length"][-1]
        if tip_mass <= 0.0:
            raise SceneError(prefix + "nodes.mass",
                             f"the chain has no inertia: rod {n} and node {n} are both massless")
        if loads is not None:
            fields["loads"] = loads(n)
        features = self._features(sections, n, fields, prefix, psi0)
        for name, default in _FEATURE_DEFAULTS.items():
            if name not in features:
                features[name] = np.full(n, default, dtype=bool if isinstance(default, bool)
                                         else float)
        fields.update(features)
        return fields, n

    def _features(self, sections, n, fields, prefix: str = "", psi0: float = 0.0) -> dict[str, Any]:
        """Hinge rest angles, stops, latches, locked hinges and rigid rods (docs/hinges.md)."""
        hinges = sections["hinges"]
        out: dict[str, Any] = {}
        if hinges.get("rest_angle") is not None:
            out["hinge_rest_angle"] = self._array(prefix + "hinges.rest_angle",
                                                  hinges["rest_angle"], n)
        if hinges.get("locked") is not None:
            out["hinge_locked"] = self._bools(prefix + "hinges.locked", hinges["locked"], n)
        if sections["rods"].get("rigid") is not None:
            out["rod_rigid"] = self._bools(prefix + "rods.rigid", sections["rods"]["rigid"], n)
        if hinges.get("latch") is not None:
            out["latch_angle"] = self._array(prefix + "hinges.latch", hinges["latch"], n,
                                             allow_null=True)
        stop = hinges.get("stop")
        if stop is not None:
            out.update(self._stop(stop, n, prefix))
            lower, upper = out["stop_lower"], out["stop_upper"]

            def check_inside(key: str, angle: np.ndarray, what: str, why: str = "") -> None:
                """SceneError at the first hinge whose angle (nan: none) is outside its stops."""
                with np.errstate(invalid="ignore"):
                    outside = np.flatnonzero((angle < lower) | (angle > upper))
                if outside.size:
                    h = int(outside[0])
                    raise SceneError(key, f"hinge {h}: the {what} {angle[h]:g} rad lies outside "
                                          f"its stops [{lower[h]:g}, {upper[h]:g}]{why}")

            # hinge 0 measures phi_1 - psi_0 (the base's initial angle), the others phi_{h+1} - phi_h
            check_inside(prefix + "hinges.stop.angle", np.diff(fields["phi0"], prepend=psi0),
                         "initial hinge angle")
            if out.get("latch_angle") is not None:
                check_inside(prefix + "hinges.latch", out["latch_angle"], "latch angle",
                             ", so it can never latch")
        return out

    def _stop(self, stop, n, prefix: str = "") -> dict[str, np.ndarray]:
        if not isinstance(stop, Mapping):
            raise SceneError(prefix + "hinges.stop",
                             "must be a mapping with keys angle, stiffness, damping")
        self._unknown(stop, _STOP_KEYS, prefix + "hinges.stop.")
        for req in ("angle", "stiffness"):
            if stop.get(req) is None:
                raise SceneError(f"{prefix}hinges.stop.{req}", "missing")
        angle = stop["angle"]
        path = prefix + "hinges.stop.angle"
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
        stiffness = self._array(prefix + "hinges.stop.stiffness", stop["stiffness"], n,
                                minimum=0.0, strict=True)
        damping = self._array(prefix + "hinges.stop.damping", stop.get("damping", 0.0), n,
                              minimum=0.0)
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

    def _loads(self, loads, chains: tuple[ChainSpec, ...], base: BaseSpec | None) -> tuple[Load, ...]:
        if loads is None:
            return ()
        if not isinstance(loads, (list, tuple)):
            raise SceneError("loads", "must be a list of load entries")
        base = BaseSpec() if base is None else base
        named = chains[0].name is not None
        index = {ch.name: c for c, ch in enumerate(chains)}
        out = []
        for i, entry in enumerate(loads):
            key = f"loads[{i}]"
            if not isinstance(entry, Mapping):
                raise SceneError(key, "must be a mapping")
            self._unknown(entry, _LOAD_KEYS, key + ".")
            for req in ("node", "axis", "shape", "amplitude"):
                if req not in entry:
                    raise SceneError(f"{key}.{req}", "missing")
            node, chain = entry["node"], 0
            if isinstance(node, str) and node in ("base", "wheel"):
                if "chain" in entry:
                    raise SceneError(f"{key}.chain", f"not allowed in a {node} load (it is on "
                                                     f"no chain)")
                if node == "base" and base.mode != "free":
                    raise SceneError(f"{key}.node", f"a base load needs a free base (a "
                                                    f"{base.mode} base absorbs it)")
                if node == "wheel" and base.wheel is None:
                    raise SceneError(f"{key}.node", "a wheel load needs base.wheel (the base "
                                                    "has no wheel)")
                axes = BASE_LOAD_AXES if node == "base" else WHEEL_LOAD_AXES
            else:
                if "chain" in entry:
                    name = entry["chain"]
                    if not named:
                        raise SceneError(f"{key}.chain", f"unknown chain {quote(name)} (the "
                                                         f"scene has no chains: list)")
                    if not isinstance(name, str) or name not in index:
                        raise SceneError(f"{key}.chain", f"unknown chain {quote(name)} (chains: "
                                         f"{quote(', '.join(index), plain=True)})")
                    chain = index[name]
                elif len(chains) > 1:
                    raise SceneError(f"{key}.chain", f"missing: the scene has {len(chains)} "
                                     f"chains ({quote(', '.join(index), plain=True)})")
                count = chains[chain].count
                if not (isinstance(node, (int, np.integer)) and not isinstance(node, bool)) or not 1 <= node <= count:
                    extra = ", 'base' or 'wheel'" if isinstance(node, str) else ""
                    where = f" of chain {chains[chain].name}" if named else ""
                    raise SceneError(f"{key}.node", f"must be a node number 1..{count}{where}"
                                                    f"{extra} (got {quote(node)})")
                node = int(node)
                axes = LOAD_AXES
            axis = entry["axis"]
            if axis not in axes:
                if axes == LOAD_AXES:
                    raise SceneError(f"{key}.axis", f"must be 'x' or 'y' (got {quote(axis)})")
                raise SceneError(f"{key}.axis", f"must be {'x, y or moment' if node == 'base' else 'moment'} "
                                                f"for a {node} load (got {quote(axis)})")
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
            out.append(Load(node=node, axis=axis, shape=shape, amplitude=numbers["amplitude"],
                            start=start, duration=duration, chain=chain))
        return tuple(out)
