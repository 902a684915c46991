"""Prescribed motion profiles of a base coordinate (psi [rad], x or y [m]) as functions of time.

A prescribed base follows q(t) = q_0 + p(t), q_0 its initial value (``base.initial``) and p a
:class:`MotionProfile`. The integrators need q, its rate and its acceleration to be continuous
(a jump of the value or of the rate is an impulse the chain cannot follow), so every shape here
has p = p' = 0 before its start and a continuous value and rate everywhere; its acceleration is
continuous too except where said, and :meth:`MotionProfile.breakpoints` lists every time where
the formula changes, so that a driver can end a step there. Shapes (tau = t - start):

- ``hold``: p = 0 (the coordinate stays at its initial value). No parameters.
- ``spin_up`` (``rate`` r [rad/s or m/s], ``duration`` T [s], ``start`` [s], default 0):
  the classical spin-up profile (Kane, Ryan and Banerjee 1987)
  p'(t) = (r/T)(tau - (T/2 pi) sin(2 pi tau/T)) for 0 <= tau < T, then r;
  p = (r/T)(tau^2/2 + (T/2 pi)^2 (cos(2 pi tau/T) - 1)), then r T/2 + r (tau - T);
  p'' = (r/T)(1 - cos(2 pi tau/T)), then 0. Value, rate, acceleration and jerk are continuous;
  the fourth derivative jumps at start and start + T (the breakpoints).
- ``cycloidal`` (``amplitude`` D [rad or m], ``duration`` T [s], ``start``): a rest-to-rest move
  by D, p = D (tau/T - sin(2 pi tau/T)/(2 pi)) for 0 <= tau < T, then D;
  p' = (D/T)(1 - cos(2 pi tau/T)); p'' = (D/T)(2 pi/T) sin(2 pi tau/T). Value, rate and
  acceleration are continuous; the jerk jumps at start and start + T (the breakpoints).
- ``harmonic`` (``amplitude`` A, ``frequency`` f [Hz], ``start``): an oscillation about
  q_0 + A that starts at rest, p = A (1 - cos(2 pi f tau)); p' = 2 pi f A sin(2 pi f tau);
  p'' = (2 pi f)^2 A cos(2 pi f tau). The acceleration jumps at start (from 0 to (2 pi f)^2 A),
  the one breakpoint; value and rate are continuous.

Refused as not smooth enough for the integrator: ``sine`` (A sin(2 pi f tau): its rate jumps
at start; ``harmonic`` is the smooth oscillation), ``step`` and ``constant`` (the value jumps),
``ramp`` and ``linear`` (the rate jumps; ``spin_up`` is the smooth ramp), and a ``duration`` of
0 (the value or the rate would jump).
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from .quote import quote
from .scene_error import SceneError, check_keys, check_number

MOTION_SHAPES = ("hold", "spin_up", "cycloidal", "harmonic")
# parameters of each shape; all are required but ``start`` (default 0)
MOTION_PARAMETERS = {"hold": (), "spin_up": ("rate", "duration", "start"),
                     "cycloidal": ("amplitude", "duration", "start"),
                     "harmonic": ("amplitude", "frequency", "start")}
# shapes refused because the value or the rate jumps, with the reason and the smooth alternative
NOT_SMOOTH = {
    "sine": "its rate jumps at start (from 0 to 2 pi f A); use harmonic, A (1 - cos(2 pi f t))",
    "step": "its value jumps; use cycloidal, a smooth rest-to-rest move",
    "constant": "its value jumps at start; set base.initial instead, or use cycloidal",
    "ramp": "its rate jumps at start; use spin_up, the smooth ramp of the rate",
    "linear": "its rate jumps at start; use spin_up, the smooth ramp of the rate",
}
_NOT_SMOOTH = "not smooth enough for the integrator"


@dataclass(frozen=True)
class MotionProfile:
    """The prescribed part p(t) of a base coordinate q(t) = q_0 + p(t) (module docstring).

    ``shape`` is one of MOTION_SHAPES; the parameters a shape does not use are 0. Units: ``rate``
    [rad/s] for psi, [m/s] for x, y; ``amplitude`` [rad] or [m]; ``duration``, ``start`` [s];
    ``frequency`` [Hz]. Validated on construction (SceneError keyed by the parameter's name;
    the scene parser prefixes the entry's path)."""

    shape: str
    rate: float = 0.0
    duration: float = 0.0
    amplitude: float = 0.0
    frequency: float = 0.0
    start: float = 0.0

    def __post_init__(self):
        if not isinstance(self.shape, str):
            raise SceneError("shape", f"must be one of {', '.join(MOTION_SHAPES)} "
                                      f"(got {quote(self.shape)})")
        if self.shape in NOT_SMOOTH:
            raise SceneError("shape", f"{self.shape!r} is {_NOT_SMOOTH}: {NOT_SMOOTH[self.shape]}")
        if self.shape not in MOTION_SHAPES:
            raise SceneError("shape", f"must be one of {', '.join(MOTION_SHAPES)} "
                                      f"(got {quote(self.shape)})")
        used = MOTION_PARAMETERS[self.shape]
        for name in ("rate", "duration", "amplitude", "frequency", "start"):
            value = getattr(self, name)
            if name not in used:
                if value != 0.0:
                    raise SceneError(name, f"not a parameter of shape {self.shape} "
                                           f"(it takes {', '.join(used) or 'none'})")
                continue
            if name == "duration":
                value = check_number(name, value)
                if not value > 0.0:
                    jumps = "rate" if self.shape == "spin_up" else "value"
                    raise SceneError(name, f"must be > 0 (got {value:g}): a zero duration makes "
                                           f"the {jumps} jump, {_NOT_SMOOTH}")
                value = check_number(name, value, positive=True)
            elif name == "frequency":
                value = check_number(name, value, positive=True)
            elif name == "start":
                value = check_number(name, value, minimum=0.0)
            else:
                value = check_number(name, value)
            object.__setattr__(self, name, float(value))

    @property
    def code(self) -> int:
        """The shape as an integer for compiled code: its index in MOTION_SHAPES."""
        return MOTION_SHAPES.index(self.shape)

    @property
    def parameters(self) -> tuple[float, float, float]:
        """(a, b, start) of :func:`profile_at`: (rate, duration) for spin_up, (amplitude,
        duration) for cycloidal, (amplitude, frequency) for harmonic, (0, 0) for hold."""
        a, b = {"hold": (0.0, 0.0), "spin_up": (self.rate, self.duration),
                "cycloidal": (self.amplitude, self.duration),
                "harmonic": (self.amplitude, self.frequency)}[self.shape]
        return a, b, self.start

    def evaluate(self, t: float) -> tuple[float, float, float]:
        """(p, p', p'') at time ``t`` [s]: the profile's value [rad or m], rate [/s] and
        acceleration [/s^2] (zero before ``start``)."""
        return profile_at(self.code, *self.parameters, t)

    def breakpoints(self) -> tuple[float, ...]:
        """Times [s] where the profile's formula changes (a derivative jumps: the fourth for
        spin_up, the third for cycloidal, the second (the acceleration) for harmonic); value
        and rate are continuous everywhere."""
        if self.shape == "hold":
            return ()
        if self.shape == "harmonic":
            return (self.start,)
        return (self.start, self.start + self.duration)

    def to_dict(self) -> dict[str, Any]:
        """The profile as scene data: ``shape`` and its parameters (``start`` always written)."""
        out: dict[str, Any] = {"shape": self.shape}
        for name in MOTION_PARAMETERS[self.shape]:
            out[name] = getattr(self, name)
        return out

    @classmethod
    def from_dict(cls, data: Any, path: str) -> "MotionProfile":
        """Parse one profile entry (``{shape: spin_up, rate: 6.0, duration: 15.0}``) at the
        scene path ``path`` (e.g. ``base.motion.psi``)."""
        if not isinstance(data, Mapping):
            raise SceneError(path, f"must be a mapping with a shape and its parameters "
                                   f"(got {quote(data)})")
        if "shape" not in data:
            raise SceneError(f"{path}.shape", f"missing (one of {', '.join(MOTION_SHAPES)})")
        shape = data["shape"]
        try:
            cls(shape)                       # the shape's own checks first (unknown, not smooth)
        except SceneError as err:
            if err.key == "shape":
                raise err.under(path + ".") from None
        if shape in MOTION_SHAPES:
            check_keys(data, {"shape", *MOTION_PARAMETERS[shape]}, path)
            for name in MOTION_PARAMETERS[shape]:
                if name != "start" and name not in data:
                    raise SceneError(f"{path}.{name}", f"missing (shape {shape} needs "
                                     f"{', '.join(p for p in MOTION_PARAMETERS[shape] if p != 'start')})")
                if name in data:
                    check_number(f"{path}.{name}", data[name])
        try:
            return cls(**{k: v for k, v in data.items()})
        except SceneError as err:
            raise err.under(path + ".") from None


def profile_at(code: int, a: float, b: float, start: float, t: float) -> tuple[float, float, float]:
    """(p, p', p'') of the profile with shape ``MOTION_SHAPES[code]`` and parameters (a, b)
    (:attr:`MotionProfile.parameters`) at time ``t`` [s]. Plain floats and ``math`` only, so
    that compiled code can use this very function (``numba.njit(profile_at)``): one law for
    Python and kernels."""
    tau = t - start
    if code == 0 or tau <= 0.0:
        return 0.0, 0.0, 0.0
    if code == 3:                                   # harmonic: a = A, b = f
        w = 2.0 * math.pi * b
        half = math.sin(0.5 * w * tau)
        return 2.0 * a * half * half, a * w * math.sin(w * tau), a * w * w * math.cos(w * tau)
    big_t = b
    w = 2.0 * math.pi / big_t
    if code == 1:                                   # spin_up: a = r, b = T
        if tau >= big_t:
            return a * big_t / 2.0 + a * (tau - big_t), a, 0.0
        half = math.sin(0.5 * w * tau)
        return ((a / big_t) * (0.5 * tau * tau - 2.0 * half * half / (w * w)),
                (a / big_t) * (tau - math.sin(w * tau) / w),
                (a / big_t) * 2.0 * half * half)
    if tau >= big_t:                                # cycloidal: a = D, b = T
        return a, 0.0, 0.0
    half = math.sin(0.5 * w * tau)
    return (a * (tau / big_t - math.sin(w * tau) / (2.0 * math.pi)),
            (a / big_t) * 2.0 * half * half,
            (a / big_t) * w * math.sin(w * tau))
