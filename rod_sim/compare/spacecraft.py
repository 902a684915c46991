"""``rod-sim compare`` on a spacecraft scene: the base and every chain against the full model.

Per sample of ``/rod_states`` (with its ``/base_odometry`` when the base moves): the base's
angle error |psi_log - psi_full| [rad] (wrapped to (-pi, pi]) and position error
|r_log - r_full| [m] of the base frame's origin, and per chain the largest hinge angle error
|theta_log - theta_full| [rad] over its hinges (theta = phi_1 - psi at hinge 0, phi_{k+1} -
phi_k elsewhere: the ``joint_states`` angles). A log fails when a chain's hinge error or the
base's angle error exceeds the tolerance [rad], or the base's position error exceeds the
tolerance times :func:`length_scale` (the angle error at the tip of the longest chain).
Pure numpy on the reference states; O(n) per sample.
"""
from __future__ import annotations

import math

import numpy as np


def length_scale(scene) -> float:
    """[m] the longest chain's length: converts the angle tolerance [rad] to the base's
    position tolerance [m]."""
    lengths = np.asarray(scene.length, dtype=float)
    return float(max(lengths[sl].sum() for sl in scene.chain_slices()))


def hinge_angles(roots: np.ndarray, phi: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """(N, n) rigid hinge angles (the ``joint_states`` positions) of rod angles ``phi`` (N, n)
    [rad] on a base at angle ``psi`` (N,) [rad]; ``roots`` (n,) bool: each chain's first rod
    (``Scene.chain_root``), whose hinge 0 measures phi_1 - psi."""
    prev = np.concatenate([np.zeros((phi.shape[0], 1)), phi[:, :-1]], axis=1)
    prev[:, roots] = psi[:, None]
    return phi - prev


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


class SpacecraftCheck:
    """Running maxima of the base's and the chains' errors (module docstring)."""

    def __init__(self, scene, model, tolerance: float):
        self.scene, self.model, self.tol = scene, model, float(tolerance)
        self.names = [c.name or "chain" for c in scene.chains]
        self.roots = np.asarray(scene.chain_root, dtype=bool)
        self.chain_of_rod = np.asarray(scene.chain_of_rod)
        self.position_tolerance = self.tol * length_scale(scene)
        self.chain_max = np.zeros(len(self.names))
        self.chain_t = np.zeros(len(self.names))
        self.chain_hinge = np.zeros(len(self.names), dtype=int)
        self.psi_max = self.pos_max = 0.0
        self.psi_t = self.pos_t = 0.0
        self.base_samples = 0
        self.moving = bool(scene.moving_base)

    def reference_base(self, ts: np.ndarray, y: np.ndarray) -> np.ndarray:
        """(N, 3) the full model's base (x, y, psi) at times ``ts`` [s] and states ``y``."""
        out = np.empty((ts.size, 3))
        for i in range(ts.size):
            st = self.model.base_state(float(ts[i]), y[i])
            out[i] = st.x, st.y, st.psi
        return out

    def hinge_angles(self, phi: np.ndarray, psi: np.ndarray) -> np.ndarray:
        return hinge_angles(self.roots, phi, psi)

    def add(self, ts: np.ndarray, phi_log: np.ndarray, y_ref: np.ndarray,
            base_log: np.ndarray) -> None:
        """One window: sample times ``ts`` (N,) [s], logged phi (N, n), the full model's states
        (N, state_size) and the logged base (N, 3) (x, y, psi; NaN rows where the log has no
        ``/base_odometry`` at that time: the base is then not judged there, and on a fixed
        base its constant pose is used for the hinge angles)."""
        n = self.scene.n
        ref = self.reference_base(ts, y_ref)
        have = np.all(np.isfinite(base_log), axis=1)
        psi_log = np.where(have, base_log[:, 2], ref[:, 2]) if self.moving else ref[:, 2]
        err = np.abs(_wrap(self.hinge_angles(phi_log, psi_log)
                           - self.hinge_angles(y_ref[:, :n], ref[:, 2])))
        err = np.where(np.isfinite(err), err, np.inf)
        for c in range(len(self.names)):
            cols = np.flatnonzero(self.chain_of_rod == c)
            block = err[:, cols]
            i, j = np.unravel_index(int(np.argmax(block)), block.shape)
            if block[i, j] > self.chain_max[c]:
                self.chain_max[c], self.chain_t[c], self.chain_hinge[c] = \
                    block[i, j], ts[i], j
        if not (self.moving and have.any()):
            return
        self.base_samples += int(have.sum())
        d_psi = np.abs(_wrap(base_log[have, 2] - ref[have, 2]))
        d_pos = np.linalg.norm(base_log[have, :2] - ref[have, :2], axis=1)
        d_psi = np.where(np.isfinite(d_psi), d_psi, np.inf)
        d_pos = np.where(np.isfinite(d_pos), d_pos, np.inf)
        th = ts[have]
        if d_psi.max() > self.psi_max:
            self.psi_max, self.psi_t = float(d_psi.max()), float(th[np.argmax(d_psi)])
        if d_pos.max() > self.pos_max:
            self.pos_max, self.pos_t = float(d_pos.max()), float(th[np.argmax(d_pos)])

    def failures(self) -> list[str]:
        """One sentence per chain or base quantity over its tolerance (empty: all within)."""
        out = []
        for c, name in enumerate(self.names):
            if self.chain_max[c] > self.tol:
                out.append(f"chain {name}: max |hinge angle error| {self.chain_max[c]:.3g} rad "
                           f"(hinge {self.chain_hinge[c]}, t = {self.chain_t[c]:.6g} s) exceeds "
                           f"the tolerance {self.tol:g} rad")
        if self.psi_max > self.tol:
            out.append(f"base: max |psi error| {self.psi_max:.3g} rad (t = {self.psi_t:.6g} s) "
                       f"exceeds the tolerance {self.tol:g} rad")
        if self.pos_max > self.position_tolerance:
            out.append(f"base: max |position error| {self.pos_max:.3g} m (t = "
                       f"{self.pos_t:.6g} s) exceeds {self.position_tolerance:.3g} m (the "
                       "tolerance times the longest chain's length)")
        return out

    def summary(self) -> dict:
        """The JSON ``spacecraft`` entry of the report."""
        return {"chains": [{"chain": name, "max_hinge_angle_error": float(self.chain_max[c]),
                            "hinge": int(self.chain_hinge[c]), "t": float(self.chain_t[c])}
                           for c, name in enumerate(self.names)],
                "base": ({"samples": self.base_samples, "max_psi_error": self.psi_max,
                          "psi_t": self.psi_t, "max_position_error": self.pos_max,
                          "position_t": self.pos_t,
                          "position_tolerance": self.position_tolerance}
                         if self.moving else None),
                "failures": self.failures()}

    def lines(self) -> list[str]:
        """The text report's lines: one per chain, one for the base."""
        out = [f"chain {name}: max |hinge angle error| {self.chain_max[c]:.3e} rad (hinge "
               f"{self.chain_hinge[c]}, t = {self.chain_t[c]:.6g} s)"
               for c, name in enumerate(self.names)]
        if self.moving:
            out.append(f"base: max |psi error| {self.psi_max:.3e} rad (t = {self.psi_t:.6g} s),"
                       f" max |position error| {self.pos_max:.3e} m (t = {self.pos_t:.6g} s; "
                       f"limit {self.position_tolerance:.3g} m), {self.base_samples} samples")
        return out
