"""What the chains hang on: the base (fixed, free or prescribed) and its reaction wheel.

The base is a rigid body moving in the plane Oxy. Its *base frame* has its origin at
(x, y) and is turned by psi from Oxy; chains attach at points of this frame (``ChainSpec.attach``)
and its centre of mass sits at ``centre_of_mass`` in it. Modes:

- ``fixed``: the base frame stays at its initial pose (default: Oxy itself); rates are 0.
- ``free``: the base moves under the chains' hinge moments and attachment forces, the base
  loads and the wheel's motor torque; needs ``mass`` m_B [kg] and ``inertia`` J_B [kg m^2]
  about its centre of mass (without the wheel); may carry a reaction ``wheel``.
- ``prescribed``: q(t) = q_0 + p(t) for q in psi, x, y with a :class:`MotionProfile` p for at
  least one of them (the others stay at q_0); the initial rates are the profiles' (0), so
  nonzero ``initial`` rates are refused.

Every error is a :class:`SceneError` keyed ``base.<entry>``.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from .motion import MotionProfile
from .quote import quote
from .scene_error import SceneError, check_keys, check_number, check_pair

BASE_MODES = ("fixed", "free", "prescribed")
MOTION_COORDINATES = ("psi", "x", "y")
POSE_KEYS = ("x", "y", "psi")
RATE_KEYS = ("x_rate", "y_rate", "psi_rate")
_BASE_KEYS = {"mode", "mass", "inertia", "centre_of_mass", "initial", "motion", "wheel"}
_WHEEL_KEYS = {"inertia", "rate"}


class FrozenMapping(Mapping):
    """A read-only mapping (a dict's copy) that pickles and deep-copies (a MappingProxyType
    does neither, and scenes go to sweep workers and into copies)."""

    def __init__(self, data: Mapping = ()):
        self._data = dict(data)

    def __getitem__(self, key):
        return self._data[key]

    def __iter__(self):
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def __hash__(self) -> int:
        return hash(tuple(self._data.items()))

    def __repr__(self) -> str:
        return f"FrozenMapping({self._data!r})"


@dataclass(frozen=True)
class WheelSpec:
    """A reaction wheel about z on a free base: ``inertia`` J_W > 0 [kg m^2] (its spin axis),
    ``rate`` its initial spin relative to the base [rad/s]. The motor torque (a ``wheel``
    load) acts +T on the wheel and -T on the base."""

    inertia: float
    rate: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "inertia", check_number("inertia", self.inertia, positive=True))
        object.__setattr__(self, "rate", check_number("rate", self.rate))

    def to_dict(self) -> dict[str, Any]:
        return {"inertia": self.inertia, "rate": self.rate}


@dataclass(frozen=True, eq=False)
class BaseSpec:
    """The base (module docstring). Units: ``mass`` [kg], ``inertia`` [kg m^2] about the centre
    of mass (NaN = not given; required > 0 for ``free``), ``centre_of_mass`` [m] in the base
    frame, initial pose ``x``, ``y`` [m], ``psi`` [rad] of the base frame's origin in Oxy and its
    rates ``x_rate``, ``y_rate`` [m/s], ``psi_rate`` [rad/s]; ``motion`` maps 'psi', 'x', 'y'
    to profiles (prescribed only); ``wheel`` (free only). Validated on construction."""

    mode: str = "fixed"
    mass: float = math.nan
    inertia: float = math.nan
    centre_of_mass: tuple[float, float] = (0.0, 0.0)
    x: float = 0.0
    y: float = 0.0
    psi: float = 0.0
    x_rate: float = 0.0
    y_rate: float = 0.0
    psi_rate: float = 0.0
    motion: Mapping[str, MotionProfile] = field(default_factory=dict)
    wheel: WheelSpec | None = None

    def __post_init__(self):
        if not isinstance(self.mode, str) or self.mode not in BASE_MODES:
            raise SceneError("base.mode", f"must be one of {', '.join(BASE_MODES)} "
                                          f"(got {quote(self.mode)})")
        for name, what in (("mass", "its mass m_B [kg]"),
                           ("inertia", "its inertia J_B about its centre of mass [kg m^2]")):
            value = getattr(self, name)
            if isinstance(value, float) and math.isnan(value):
                if self.mode == "free":
                    raise SceneError(f"base.{name}", f"missing (a free base needs {what})")
                continue
            object.__setattr__(self, name, check_number(f"base.{name}", value, positive=True))
        object.__setattr__(self, "centre_of_mass",
                           check_pair("base.centre_of_mass", self.centre_of_mass))
        for name in POSE_KEYS + RATE_KEYS:
            object.__setattr__(self, name, check_number(f"base.initial.{name}", getattr(self, name)))
        if self.mode != "free":
            for name in RATE_KEYS:
                if getattr(self, name) != 0.0:
                    why = ("a fixed base does not move" if self.mode == "fixed" else
                           "the rates of a prescribed base come from base.motion")
                    raise SceneError(f"base.initial.{name}",
                                     f"must be 0 for a {self.mode} base: {why} "
                                     f"(got {getattr(self, name):g})")
        if not isinstance(self.motion, Mapping):
            raise SceneError("base.motion", f"must be a mapping of psi, x, y to motion profiles "
                                            f"(got {quote(self.motion)})")
        check_keys(self.motion, set(MOTION_COORDINATES), "base.motion")
        for coord, profile in self.motion.items():
            if not isinstance(profile, MotionProfile):
                raise SceneError(f"base.motion.{coord}", f"must be a motion profile "
                                                         f"(got {quote(profile)})")
        if self.motion and self.mode != "prescribed":
            raise SceneError("base.motion", f"only a prescribed base has a motion "
                                            f"(the mode is {self.mode})")
        if not self.motion and self.mode == "prescribed":
            raise SceneError("base.motion", "missing (a prescribed base needs a motion for "
                                            "psi, x or y)")
        ordered = {c: self.motion[c] for c in MOTION_COORDINATES if c in self.motion}
        object.__setattr__(self, "motion", FrozenMapping(ordered))
        if self.wheel is not None:
            if not isinstance(self.wheel, WheelSpec):
                raise SceneError("base.wheel", f"must be a wheel (got {quote(self.wheel)})")
            if self.mode != "free":
                raise SceneError("base.wheel", f"only a free base has a wheel "
                                               f"(the mode is {self.mode})")

    def _key(self) -> tuple:
        """The fields, with NaN (mass or inertia not given) as None so that equal specs
        compare equal after a copy or pickle."""
        return tuple(None if isinstance(v, float) and math.isnan(v) else v
                     for v in (getattr(self, f) for f in self.__dataclass_fields__))

    def __eq__(self, other) -> bool:
        if not isinstance(other, BaseSpec):
            return NotImplemented
        return self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    @property
    def is_default(self) -> bool:
        """True for the fixed base at the origin with nothing else given (a scene without
        ``base:``)."""
        return (self.mode == "fixed" and math.isnan(self.mass) and math.isnan(self.inertia)
                and self.centre_of_mass == (0.0, 0.0) and self.x == self.y == self.psi == 0.0)

    def pose(self, t: float) -> tuple[tuple[float, float, float], tuple[float, float, float],
                                      tuple[float, float, float]]:
        """The prescribed pose at time ``t`` [s]: ((x, y, psi), rates, accelerations) in
        [m, m, rad] and per s, per s^2; the initial pose (rates 0) for a fixed base. Only for
        fixed and prescribed bases (a free base's pose is state)."""
        if self.mode == "free":
            raise ValueError("a free base's pose is part of the state, not prescribed")
        q, dq, ddq = [self.x, self.y, self.psi], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
        for i, coord in enumerate(("x", "y", "psi")):
            if coord in self.motion:
                p, dp, ddp = self.motion[coord].evaluate(t)
                q[i] += p
                dq[i], ddq[i] = dp, ddp
        return tuple(q), tuple(dq), tuple(ddq)

    def breakpoints(self) -> tuple[float, ...]:
        """Sorted times [s] where a motion profile's formula changes."""
        return tuple(sorted({b for p in self.motion.values() for b in p.breakpoints()}))

    def to_dict(self) -> dict[str, Any]:
        """The base as scene data (``base:`` of docs/interface.md section 1), every value spelled
        out but the unset mass and inertia of a fixed or prescribed base."""
        out: dict[str, Any] = {"mode": self.mode}
        for name in ("mass", "inertia"):
            if not math.isnan(getattr(self, name)):
                out[name] = getattr(self, name)
        out["centre_of_mass"] = [self.centre_of_mass[0], self.centre_of_mass[1]]
        out["initial"] = {name: getattr(self, name) for name in POSE_KEYS + RATE_KEYS}
        if self.motion:
            out["motion"] = {c: p.to_dict() for c, p in self.motion.items()}
        if self.wheel is not None:
            out["wheel"] = self.wheel.to_dict()
        return out

    @classmethod
    def from_dict(cls, data: Any) -> "BaseSpec":
        """Parse the ``base:`` entry of a scene (errors keyed ``base.<entry>``)."""
        if data is None:
            raise SceneError("base", "must be a mapping with at least a mode (fixed, free or "
                                     "prescribed)")
        check_keys(data, _BASE_KEYS, "base")
        if "mode" not in data:
            raise SceneError("base.mode", f"missing (one of {', '.join(BASE_MODES)})")
        kwargs: dict[str, Any] = {"mode": data["mode"]}
        if not isinstance(data["mode"], str) or data["mode"] not in BASE_MODES:
            cls(mode=data["mode"])                     # raises the mode's error
        for name in ("mass", "inertia"):
            if name in data:
                kwargs[name] = check_number(f"base.{name}", data[name], positive=True)
        if data.get("centre_of_mass") is not None:
            kwargs["centre_of_mass"] = check_pair("base.centre_of_mass", data["centre_of_mass"])
        initial = data.get("initial")
        if initial is not None:
            check_keys(initial, set(POSE_KEYS + RATE_KEYS), "base.initial")
            for name, value in initial.items():
                kwargs[name] = check_number(f"base.initial.{name}", value)
        if data.get("motion") is not None:
            motion = data["motion"]
            check_keys(motion, set(MOTION_COORDINATES), "base.motion")
            kwargs["motion"] = {c: MotionProfile.from_dict(p, f"base.motion.{c}")
                                for c, p in motion.items()}
        if data.get("wheel") is not None:
            wheel = data["wheel"]
            check_keys(wheel, _WHEEL_KEYS, "base.wheel")
            if "inertia" not in wheel:
                raise SceneError("base.wheel.inertia", "missing (the wheel's inertia about its "
                                                       "axis [kg m^2])")
            try:
                kwargs["wheel"] = WheelSpec(**wheel)
            except SceneError as err:
                raise err.under("base.wheel.") from None
        return cls(**kwargs)
