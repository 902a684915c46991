"""Hinge rest angles, stops, latches, locked hinges and rigid rods: the data the compiled
models use (docs/hinges.md). Pure functions of the scene and of the *mode* (which latches
have fired, an (n,) bool array owned by the driver); no model state.

- rest angle theta_rest_h: the hinge spring acts on (Delta_h - theta_rest_h), Delta_h the
  paper's relative rotation (2); a constant generalized force kappa_h theta_rest_h dDelta_h/dq
  (kernels: ``rest_alpha``/``rest_beta`` enter the reduced model's quasi-static bending).
- stops [lo_h, hi_h] on the rigid hinge angle theta_h (phi_1 for hinge 0, phi_{h+1} - phi_h
  otherwise): a one-sided visco-elastic contact moment, see :func:`contact_moments`.
- locked hinges (scene or latched) and rigid rods (full model) are linear constraints
  C x' = 0 on the coordinates x (phi, or [phi, alpha, beta] in the full model): the kernels
  solve M x'' = f + C^T lambda, C x'' = 0 in O(n) (a multiplier per locked hinge, the pinned
  slopes of a rigid rod dropped), which equals the projected equations
  x'' = T (T^T M T)^{-1} T^T f for any basis T of null(C). Explicit Runge-Kutta keeps C x
  constant to rounding.
- latches: a terminal event theta_h = latch_h located by the driver; the hinge joins the
  locked set and the velocities jump by the impulsive constraint x'+ = T (T^T M T)^{-1}
  T^T M x'-.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .kernels import N_MOTION, EventTable
from .scene import Scene

# event kinds of the compiled drivers' event tables (erk.py)
EV_LATCH, EV_UPPER, EV_LOWER = 0, 1, 2


@dataclass(frozen=True)
class HingeEvent:
    """Something that happened to hinge ``hinge`` (0..n-1) at simulated time ``t`` [s].

    ``kind``: 'latch', 'stop_contact_begin' or 'stop_contact_end'; ``data``: angle [rad],
    rate [rad/s], and for a latch its share of the kinetic energy lost in the impact [J]
    (``kinetic_energy_loss``; the impact's whole loss and the hinges it latched:
    ``impact_kinetic_energy_loss``, ``impact_hinges``); for a contact
    which stop ('lower' or 'upper')."""

    t: float
    kind: str
    hinge: int
    data: dict = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"t": self.t, "event": self.kind, "hinge": self.hinge, **self.data}


def hinge_angles(phi: np.ndarray) -> np.ndarray:
    """Rigid hinge angles theta (..., n) [rad] from rod angles phi (..., n) (rates from rates):
    phi_1 - 0, phi_2 - phi_1, ... (the values of ``np.diff(phi, prepend=0.0)``, without its
    concatenation: this runs several times per sample)."""
    a = np.asarray(phi)
    dtype = a.dtype if a.dtype == np.float64 else np.result_type(a.dtype, np.float64)
    out = np.empty(a.shape, dtype=dtype)
    np.subtract(a[..., :1], 0.0, out=out[..., :1])
    np.subtract(a[..., 1:], a[..., :-1], out=out[..., 1:])
    return out


def contact_moments(theta, dtheta, lower, upper, stiffness, damping) -> np.ndarray:
    """Stop contact moments m_h (n,) [N m] acting on theta_h (a generalized force for theta).

    Above the upper stop (penetration p = theta - hi > 0): m = -max(0, k p + c theta_dot);
    below the lower stop (p = lo - theta > 0): m = max(0, k p - c theta_dot); zero between the
    stops. Damping acts only while penetrating, and the max() keeps the contact from pulling
    (no sticking when the hinge leaves the stop fast). The elastic part derives from the
    potential k p^2 / 2; the rest only dissipates (power -(m - m_elastic) theta_dot >= 0).
    The compiled kernels evaluate the same law (kernels.contact_forces)."""
    m = np.zeros_like(theta)
    p_hi = theta - upper
    hi = p_hi > 0.0
    if hi.any():
        m[hi] = -np.maximum(0.0, stiffness[hi] * p_hi[hi] + damping[hi] * dtheta[hi])
    p_lo = lower - theta
    lo = p_lo > 0.0
    if lo.any():
        m[lo] = np.maximum(0.0, stiffness[lo] * p_lo[lo] - damping[lo] * dtheta[lo])
    return m


def contact_penetration(theta, lower, upper) -> np.ndarray:
    """Penetration into the stops (n,) [rad], >= 0."""
    return np.maximum(0.0, theta - upper) + np.maximum(0.0, lower - theta)


def locked_hinges(scene: Scene, mode: np.ndarray | None) -> np.ndarray:
    """Hinges held rigid (n,) bool: locked in the scene or latched (``mode``)."""
    locked = np.array(scene.hinge_locked, dtype=bool)
    return locked if mode is None else locked | np.asarray(mode, dtype=bool)


def event_table(scene: Scene, locked: np.ndarray, other: np.ndarray | None = None,
                offset: np.ndarray | None = None,
                ground: np.ndarray | None = None) -> EventTable:
    """The compiled drivers' event functions g = y[h] - y[other_h] - (angle + offset_h) for
    the unlocked hinges (kind EV_LATCH terminal, EV_UPPER and EV_LOWER stop crossings,
    recorded). ``other`` (n,) int: the state index on each hinge's other side (-1: the
    ground; default: the rod before, one chain on the ground); ``offset`` (n,) [rad]: a fixed
    angle on that side (a fixed base's psi, a prescribed one's psi_0), default 0; ``ground``
    (N_MOTION,): the profile p(t) of a prescribed base's psi = psi_0 + p(t), which the
    ground side's angle adds (g = y[h] - p(t) - (angle + offset_h) where other_h = -1;
    :class:`~rod_sim.core.kernels.EventTable`), default none (p = 0)."""
    n = scene.n
    other = np.arange(-1, n - 1) if other is None else np.asarray(other)
    hinge, angle, kind, oth = [], [], [], []
    features = np.isfinite(scene.latch_angle) | np.isfinite(scene.stop_upper) \
        | np.isfinite(scene.stop_lower)
    for h in np.flatnonzero(features & ~np.asarray(locked, dtype=bool)):
        h = int(h)
        for value, code in ((scene.latch_angle[h], EV_LATCH), (scene.stop_upper[h], EV_UPPER),
                            (scene.stop_lower[h], EV_LOWER)):
            if math.isfinite(value):
                hinge.append(h)
                angle.append(float(value) + (0.0 if offset is None else float(offset[h])))
                kind.append(code)
                oth.append(int(other[h]))
    ground = np.zeros(N_MOTION) if ground is None else \
        np.ascontiguousarray(ground, dtype=float).reshape(N_MOTION)
    return EventTable(np.array(hinge, dtype=np.int64), np.array(angle, dtype=float),
                      np.array(kind, dtype=np.int64), np.array(oth, dtype=np.int64), ground)


def crossing_kind(kind: int, rising: bool) -> tuple[str, str | None]:
    """(event name, stop) of a located crossing of an event function of ``kind`` that goes
    up (``rising``) or down."""
    if kind == EV_LATCH:
        return "latch", None
    if kind == EV_UPPER:
        return ("stop_contact_begin" if rising else "stop_contact_end"), "upper"
    return ("stop_contact_end" if rising else "stop_contact_begin"), "lower"
