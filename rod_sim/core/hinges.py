"""Hinge rest angles, stops, latches, locked hinges and rigid rods (docs/hinges.md).

:class:`HingeModel` wraps one of the three models (``full``, ``reduced``, ``rigid``) and keeps
its state layout, so everything downstream (snapshots, topics, logs) is unchanged:

- rest angle theta_rest_h: the hinge spring acts on (Delta_h - theta_rest_h), Delta_h the
  paper's relative rotation (2) (= theta_h in the rigid model); a constant generalized force
  kappa_h theta_rest_h dDelta_h/dq added to the model's equations.
- stops [lo_h, hi_h] on the rigid hinge angle theta_h (phi_1 for hinge 0, phi_{h+1} - phi_h
  otherwise): a one-sided visco-elastic contact moment, see :func:`contact_moments`.
- locked hinges and rigid rods (alpha_k = beta_k = 0; full and reduced models) are linear
  constraints. A locked hinge keeps its relative rotation constant: Delta_h (ends of the rods,
  the limit kappa_h -> infinity) in the full model, theta_h in the rigid (where Delta = theta)
  and reduced models (whose bending is quasi-static: locking the chords is stiffer than
  kappa -> infinity by the rods' bending compliance, a gap O(1/EI), see docs/hinges.md). They
  are linear constraints on the coordinates x (phi, or [phi, alpha, beta] in the full
  model). With a basis T of the allowed motions (C T = 0) the accelerations are
  x'' = T (T^T M T)^{-1} T^T f, where M x'' = f are the model's equations: the projected
  (Lagrange) equations in the generalized coordinates q, x = T q + const. Explicit Runge-Kutta
  methods keep linear invariants C x = const, C x' = 0 exactly (to rounding), so the state
  stays on the constraint set. In the reduced model a rigid rod's quasi-static bending
  equations are removed (gamma = 0 for that rod) instead.
- latches: when theta_h crosses its latch angle the integration stops at the located crossing
  (solve_ivp's event location on the dense output), the hinge becomes locked and the velocity
  jumps by the impulsive constraint (M-orthogonal projection x'+ = T (T^T M T)^{-1} T^T M x'-).

Events (latch, stop contact begin/end) are appended, with their simulated time, to the list
passed to :meth:`HingeModel.integrate_events` (``Simulator.events``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import null_space

from . import kernels
from .models import ChainModel, Energies
from .matrices import reduction_matrices
from .scene import Scene

SCIPY_METHODS = ("RK45", "DOP853", "Radau", "BDF", "LSODA")


@dataclass(frozen=True)
class HingeEvent:
    """Something that happened to hinge ``hinge`` (0..n-1) at simulated time ``t`` [s].

    ``kind``: 'latch', 'stop_contact_begin' or 'stop_contact_end'; ``data``: angle [rad],
    rate [rad/s], and for a latch the kinetic energy lost in the impact [J]; for a contact
    which stop ('lower' or 'upper')."""

    t: float
    kind: str
    hinge: int
    data: dict = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"t": self.t, "event": self.kind, "hinge": self.hinge, **self.data}


def hinge_angles(phi: np.ndarray) -> np.ndarray:
    """Rigid hinge angles theta (n,) [rad] from rod angles phi (n,) (also rates from rates)."""
    return np.diff(phi, prepend=0.0)


def contact_moments(theta, dtheta, lower, upper, stiffness, damping) -> np.ndarray:
    """Stop contact moments m_h (n,) [N m] acting on theta_h (a generalized force for theta).

    Above the upper stop (penetration p = theta - hi > 0): m = -max(0, k p + c theta_dot);
    below the lower stop (p = lo - theta > 0): m = max(0, k p - c theta_dot); zero between the
    stops. Damping acts only while penetrating, and the max() keeps the contact from pulling
    (no sticking when the hinge leaves the stop fast). The elastic part derives from the
    potential k p^2 / 2; the rest only dissipates (power -(m - m_elastic) theta_dot >= 0)."""
    m = np.zeros_like(theta)
    p_hi = theta - upper
    hi = p_hi > 0.0
    m[hi] = -np.maximum(0.0, stiffness[hi] * p_hi[hi] + damping[hi] * dtheta[hi])
    p_lo = lower - theta
    lo = p_lo > 0.0
    m[lo] = np.maximum(0.0, stiffness[lo] * p_lo[lo] - damping[lo] * dtheta[lo])
    return m


def contact_penetration(theta, lower, upper) -> np.ndarray:
    """Penetration into the stops (n,) [rad], >= 0."""
    return np.maximum(0.0, theta - upper) + np.maximum(0.0, lower - theta)


class HingeModel(ChainModel):
    """A model with the scene's hinge features; same state layout as ``base_cls(scene)``.

    ``latched`` (n,) bool holds which latches have fired (mode of the model; reset with
    :meth:`reset_mode`)."""

    def __init__(self, scene: Scene, base_cls):
        base = base_cls(scene)
        self.base = base
        self.scene = scene
        self.name = base.name
        self.dof_per_rod = base.dof_per_rod
        self.params, self.n, self.chain, self.loads = base.params, base.n, base.chain, base.loads
        n = self.n
        self.kernel = base.kernel
        if base.name == "reduced" and scene.rod_rigid.any():
            keep = np.flatnonzero(np.concatenate([~scene.rod_rigid, ~scene.rod_rigid]))
            K_gp, B = reduction_matrices(self.params)
            B_inv = np.zeros((2 * n, 2 * n))
            B_inv[np.ix_(keep, keep)] = np.linalg.inv(B[np.ix_(keep, keep)])
            P = K_gp.T @ B_inv
            base.extra = (np.ascontiguousarray(P[:, :n]), np.ascontiguousarray(P[:, n:]), B_inv,
                          base.extra[3])
        self.extra = base.extra
        kappa = self.params.kappa
        kr = kappa * scene.hinge_rest_angle
        kr_next = np.append(kr[1:], 0.0)
        self._rest_phi = kr - kr_next                 # rest-angle forces on phi, alpha, beta
        self._rest_alpha = kr
        self._rest_beta = -kr_next
        self._stops = bool(np.any(np.isfinite(scene.stop_lower) | np.isfinite(scene.stop_upper)))
        self._dof = n * self.dof_per_rod
        self._bases: dict[bytes, np.ndarray | None] = {}
        self.reset_mode()

    # ----- mode -----
    def reset_mode(self) -> None:
        """No latch fired yet."""
        self.latched = np.zeros(self.n, dtype=bool)

    @property
    def locked(self) -> np.ndarray:
        """Hinges held rigid now (n,) bool: locked in the scene or latched."""
        return self.scene.hinge_locked | self.latched

    def constraint_matrix(self) -> np.ndarray:
        """C (rows, dof): C x' = 0 for the current locked hinges and rigid rods."""
        n, rows = self.n, []
        full = self.dof_per_rod == 3
        for h in np.flatnonzero(self.locked):
            r = np.zeros(self._dof)
            r[h] = 1.0
            if full:
                r[n + h] = 1.0               # Delta_h = phi_h + alpha_h - phi_{h-1} - beta_{h-1}
            if h > 0:
                r[h - 1] = -1.0
                if full:
                    r[2 * n + h - 1] = -1.0
            rows.append(r)
        if self.dof_per_rod == 3:
            for k in np.flatnonzero(self.scene.rod_rigid):
                for off in (n, 2 * n):
                    r = np.zeros(self._dof)
                    r[off + k] = 1.0
                    rows.append(r)
        return np.array(rows).reshape(len(rows), self._dof)

    def basis(self) -> np.ndarray | None:
        """T (dof, r): orthonormal basis of the allowed motions, None when unconstrained."""
        key = self.locked.tobytes()
        if key not in self._bases:
            C = self.constraint_matrix()
            self._bases[key] = null_space(C) if C.shape[0] else None
        return self._bases[key]

    # ----- equations -----
    def mass_matrix(self, y: np.ndarray) -> np.ndarray:
        """M (dof, dof) of the model's equations M x'' = f (reduced: the eliminated M_r)."""
        A, Ma, Mb = self.mass_blocks(self.phi(y))
        if self.name == "rigid":
            return A
        if self.name == "reduced":
            Pa, Pb = self.extra[0], self.extra[1]
            return A - Pa @ Ma.T - Pb @ Mb.T
        p = self.params
        ml3 = p.m * p.l**3
        Da, Db = np.diag(ml3 / 105.0), np.diag(-ml3 / 140.0)
        return np.block([[A, Ma, Mb], [Ma.T, Da, Db], [Mb.T, Db, Da]])

    def extra_forces(self, y: np.ndarray) -> np.ndarray:
        """Generalized forces (dof,) of the rest angles and stop contacts, in the model's
        equation space (reduced: the alpha/beta rest-angle forces eliminated through P)."""
        n = self.n
        s = self.scene
        f = np.zeros(self._dof)
        f[:n] = self._rest_phi
        if self.name == "full":
            f[n:2 * n] = self._rest_alpha
            f[2 * n:] = self._rest_beta
        elif self.name == "reduced":
            f[:n] -= self.extra[0] @ self._rest_alpha + self.extra[1] @ self._rest_beta
        if self._stops:
            m = self.contact_moments(y)
            f[:n] += m - np.append(m[1:], 0.0)
        return f

    def contact_moments(self, y: np.ndarray) -> np.ndarray:
        """Stop contact moments (n,) [N m] on theta (zero on locked hinges)."""
        s = self.scene
        m = contact_moments(hinge_angles(self.phi(y)), hinge_angles(self.phi_rate(y)),
                            s.stop_lower, s.stop_upper, s.stop_stiffness, s.stop_damping)
        m[self.locked] = 0.0
        return m

    def rhs_side(self, t: float, y: np.ndarray, held: np.ndarray, t_side: float) -> np.ndarray:
        """dy/dt (state_size,) with the load side ``t_side`` (see kernels)."""
        out = np.empty(self.state_size)
        y = np.ascontiguousarray(y, dtype=float)
        self.kernel(t, y, self.chain, self.extra, self.loads, held, t_side, out)
        d = self._dof
        extra = self.extra_forces(y)
        T = self.basis()
        if T is None and not extra.any():
            return out
        M = self.mass_matrix(y)
        f = M @ out[d:] + extra
        if T is None:
            out[d:] = np.linalg.solve(M, f)
        elif T.shape[1] == 0:
            out[d:] = 0.0
        else:
            out[d:] = T @ np.linalg.solve(T.T @ M @ T, T.T @ f)
        return out

    def rhs(self, t: float, y: np.ndarray, held: np.ndarray | None = None) -> np.ndarray:
        return self.rhs_side(t, y, self._held(held), t)

    def project_velocity(self, y: np.ndarray) -> np.ndarray:
        """y with its velocities replaced by the impulsive-constraint projection
        x'+ = T (T^T M T)^{-1} T^T M x'- (M-orthogonal for a symmetric M)."""
        T = self.basis()
        out = np.array(y, dtype=float)
        if T is None:
            return out
        d = self._dof
        M = self.mass_matrix(y)
        v = out[d:]
        out[d:] = 0.0 if T.shape[1] == 0 else T @ np.linalg.solve(T.T @ M @ T, T.T @ (M @ v))
        return out

    def initial_state(self) -> np.ndarray:
        """The scene's initial state, velocities projected onto the locked hinges' constraint."""
        return self.project_velocity(super().initial_state())

    # ----- derived quantities -----
    def bending(self, t, y, held=None):
        if self.name != "reduced":
            return self.base.bending(t, y, held)
        n = self.n
        phi, dphi = self.phi(y), self.phi_rate(y)
        phi_dd = self.rhs(t, y, held)[n:]
        A, Ma, Mb = self.mass_blocks(phi)
        gp, ga, tau = np.empty(n), np.empty(n), np.empty(n)
        phi_c, dphi_c = np.ascontiguousarray(phi), np.ascontiguousarray(dphi)
        kernels.rigid_velocity_terms(phi_c, dphi_c, self.chain, gp, ga)
        kernels.rigid_hinge_moments(phi_c, dphi_c, self.params.kappa, self.params.nu, tau)
        tau_next = np.append(tau[1:], 0.0)
        a = np.concatenate([Ma.T @ phi_dd + ga + tau - self._rest_alpha,
                            Mb.T @ phi_dd - ga - tau_next - self._rest_beta])
        gamma = -self.extra[2] @ a
        return gamma[:n], gamma[n:]

    def bending_rates(self, t, y, held=None):
        return self.base.bending_rates(t, y, held)

    def kinetic_energy(self, t, y, held=None) -> float:
        return self.base.kinetic_energy(t, y, held)

    def energies(self, t: float, y: np.ndarray, held=None, bending=None) -> Energies:
        """Kinetic, hinge (springs about their rest angles + stop contacts) and bending [J];
        ``bending`` = (alpha, beta) if already known at (t, y, held)."""
        if bending is None:
            bending = self.bending(t, y, held)
        e = super().energies(t, y, held, bending=bending)
        delta, _ = self.hinge_deflection(t, y, held, bending=bending)
        p, s = self.params, self.scene
        spring = 0.5 * float(np.sum(p.kappa * (delta - s.hinge_rest_angle) ** 2))
        pen = contact_penetration(hinge_angles(self.phi(y)), s.stop_lower, s.stop_upper)
        pen[self.locked] = 0.0
        contact = 0.5 * float(np.sum(s.stop_stiffness * pen**2))
        return Energies(e.kinetic, spring + contact, e.bending)

    def powers(self, t: float, y: np.ndarray, held=None) -> tuple[float, float]:
        """(load power, power dissipated in the hinge dampers and the stop contacts) [W]."""
        load, damper = super().powers(t, y, held)
        if not self._stops:
            return load, damper
        s = self.scene
        theta, dtheta = hinge_angles(self.phi(y)), hinge_angles(self.phi_rate(y))
        elastic = -s.stop_stiffness * (np.maximum(0.0, theta - s.stop_upper)
                                       - np.maximum(0.0, s.stop_lower - theta))
        elastic[self.locked] = 0.0
        m = self.contact_moments(y)
        return load, damper - float(np.sum((m - elastic) * dtheta))

    def snapshot(self, t: float, y: np.ndarray, held=None):
        """As the base model; hinge_moment = kappa (Delta - theta_rest) + nu Delta' minus the
        stop contact moment (the constraint reaction of a locked hinge is not included)."""
        snap = super().snapshot(t, y, held)
        moment = (snap.hinge_moment - self.params.kappa * self.scene.hinge_rest_angle
                  - self.contact_moments(y))
        return replace(snap, hinge_moment=moment)

    # ----- integration with events -----
    def initial_mode(self) -> np.ndarray:
        """The mode at t = 0: no latch fired, (n,) bool."""
        return np.zeros(self.n, dtype=bool)

    def integrate_events(self, integrator, y0, t0, t_out, held, events: list, mode=None):
        """States (len(t_out), state_size) at the sorted times t_out [s], integrating from
        (t0, y0) in ``mode`` (latched hinges, (n,) bool; None = the model's current one) with
        ``integrator``'s method and tolerances (``dop853-jit`` runs as scipy's DOP853),
        stopping at every latch crossing to lock the hinge and project the velocity.
        Events are appended to ``events``. Returns (states, mode at the end)."""
        if mode is not None:
            self.latched = np.array(mode, dtype=bool)
        name = integrator.name
        if name == "dop853-jit":
            method = "DOP853"
        elif name in SCIPY_METHODS:
            method = name
        else:
            raise ValueError(f"integrator: {name} cannot locate hinge events (latches, stops); "
                             f"use dop853-jit or one of {', '.join(SCIPY_METHODS)}")
        from .integrators import IntegrationError
        t_out = np.atleast_1d(np.asarray(t_out, dtype=float))
        held = self._held(held)
        Y = np.empty((t_out.size, self.state_size))
        y = np.array(y0, dtype=float)
        done = 0
        while done < t_out.size and t_out[done] <= t0:
            Y[done] = y
            done += 1
        y = self._latch_now(float(t0), y, events, initial=True)
        edges = [float(t0), *integrator._breaks(self, t0, t_out[-1]), float(t_out[-1])]
        for a, b in zip(edges[:-1], edges[1:]):
            side = 0.5 * (a + b)
            t = a
            while t < b:
                fns, kinds = self._event_functions()

                def fun(tt, yy, side=side):
                    return self.rhs_side(tt, yy, held, side)

                sol = solve_ivp(fun, (t, b), y, method=method, rtol=integrator.rtol,
                                atol=integrator.abs_tol, dense_output=True,
                                events=fns or None)
                integrator.stats.nfev += sol.nfev
                integrator.stats.steps += max(sol.t.size - 1, 0)
                if sol.status == -1 or not np.all(np.isfinite(sol.y)):
                    raise IntegrationError(sol.message if sol.status == -1
                                           else "non-finite state", float(sol.t[-1]))
                t_end = float(sol.t[-1])
                stop = done
                while stop < t_out.size and t_out[stop] <= t_end:
                    stop += 1
                if stop > done:
                    Y[done:stop] = sol.sol(t_out[done:stop]).T
                done = stop
                self._record_contacts(sol, kinds, events)
                y = sol.y[:, -1].copy()
                if sol.status == 1:
                    y = self._latch_now(t_end, y, events)
                t = t_end
        while done < t_out.size:
            Y[done] = y
            done += 1
        return Y, self.latched.copy()

    def _event_functions(self):
        """solve_ivp event functions: latch crossings (terminal) of unlocked hinges, and
        stop contact begin/end (recorded, not terminal) of unlocked hinges."""
        s, n = self.scene, self.n
        fns, kinds = [], []

        def theta_fn(h, offset):
            if h == 0:
                return lambda t, y: y[0] - offset
            return lambda t, y: y[h] - y[h - 1] - offset

        for h in range(n):
            if self.locked[h]:
                continue
            if math.isfinite(s.latch_angle[h]):
                f = theta_fn(h, s.latch_angle[h])
                f.terminal, f.direction = True, 0
                fns.append(f)
                kinds.append(("latch", h, None))
            for stop, angle, into in (("upper", s.stop_upper[h], 1.0),
                                      ("lower", s.stop_lower[h], -1.0)):
                if not math.isfinite(angle):
                    continue
                for kind, direction in (("stop_contact_begin", into), ("stop_contact_end", -into)):
                    f = theta_fn(h, angle)
                    f.terminal, f.direction = False, direction
                    fns.append(f)
                    kinds.append((kind, h, stop))
        return fns, kinds

    def _record_contacts(self, sol, kinds, events) -> None:
        found = []
        for (kind, h, stop), ts, ys in zip(kinds, sol.t_events or [], sol.y_events or []):
            if kind == "latch":
                continue
            for t, y in zip(ts, ys):
                found.append(HingeEvent(float(t), kind, int(h), {
                    "stop": stop, "angle": float(hinge_angles(self.phi(y))[h]),
                    "rate": float(hinge_angles(self.phi_rate(y))[h])}))
        events.extend(sorted(found, key=lambda e: e.t))

    def _latch_now(self, t: float, y: np.ndarray, events: list, initial: bool = False):
        """Lock every unlocked hinge whose latch angle is reached at (t, y) (on a terminal
        event: the closest one, which the event location put there); returns y with the
        velocity projected onto the new constraint."""
        s = self.scene
        theta = hinge_angles(self.phi(y))
        gap = np.abs(theta - s.latch_angle)
        free = ~self.locked & np.isfinite(s.latch_angle)
        if initial:
            hit = free & (gap == 0.0)
        else:
            hit = free & (gap <= max(1e-9, 1e-9 * float(np.max(np.abs(theta)))))
            if free.any() and not hit.any():
                hit[np.flatnonzero(free)[np.argmin(gap[free])]] = True
        if not hit.any():
            return y
        rate = hinge_angles(self.phi_rate(y))
        ke0 = self.kinetic_energy(t, y)
        self.latched = self.latched | hit
        y1 = self.project_velocity(y)
        loss = ke0 - self.kinetic_energy(t, y1)
        for h in np.flatnonzero(hit):
            events.append(HingeEvent(t, "latch", int(h), {
                "angle": float(theta[h]), "rate": float(rate[h]),
                "kinetic_energy_loss": float(loss)}))
        return y1
