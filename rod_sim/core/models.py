"""The three fidelity levels behind one interface (:class:`Model`), hinge features inside.

- :class:`FullModel`: 3n second-order ODEs (9)-(10) in phi, alpha, beta;
  state y = [phi, alpha, beta, phi_dot, alpha_dot, beta_dot] (6n,).
- :class:`ReducedModel`: n ODEs (15) in phi, bending found quasi-statically from (14);
  state y = [phi, phi_dot] (2n,).
- :class:`RigidModel`: the limit EI -> infinity (alpha = beta = 0); state y = [phi, phi_dot].

Every model carries the scene's hinge features (rest angles, stops, locked hinges, rigid
rods, latches; :mod:`rod_sim.core.hinges`) in its compiled right-hand side. What changes
during a run — which latches have fired, the *mode*, an (n,) bool array — is owned by the
caller (``Simulator.mode``) and passed in; :meth:`ChainModel.plan` gives the kernels'
arguments and event table for a mode (cached, a pure function of it).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from . import hinges, kernels
from .kinematics import node_positions
from .matrices import ChainParams, reduction_matrices
from .scene import LOAD_AXES, Scene
from .snapshot import Snapshot

_SHAPE_CODES = {"raised_cosine_pulse": kernels.SHAPE_PULSE,
                "constant": kernels.SHAPE_CONSTANT, "step": kernels.SHAPE_STEP}


class ModelError(ValueError):
    """The scene cannot be run with the requested model (e.g. a massless rod in the full
    model, whose bending inertia would be zero)."""


@dataclass(frozen=True)
class Energies:
    """Mechanical energy [J]: kinetic, hinge springs (+ stop contacts), bending; ``total``
    their sum."""

    kinetic: float
    hinge: float
    bending: float

    @property
    def total(self) -> float:
        return self.kinetic + self.hinge + self.bending


@dataclass(frozen=True, eq=False)
class Plan:
    """What the compiled drivers need in one mode: ``extra`` (kernels' argument, see
    :mod:`rod_sim.core.kernels`), ``events`` (hinge (m,), angle (m,), kind (m,)) of
    :func:`hinges.event_table`, ``locked`` (n,) bool and the constraint basis ``T``
    (dof, r) or None when nothing is locked."""

    extra: tuple
    events: tuple
    locked: np.ndarray
    T: np.ndarray | None


class Model(Protocol):
    """The protocol every model implements (the driver and the tools use only this)."""

    name: str
    n: int
    dof_per_rod: int
    scene: Scene

    @property
    def state_size(self) -> int: ...
    def initial_state(self) -> np.ndarray: ...
    def plan(self, mode: np.ndarray | None = None) -> Plan: ...
    def rhs(self, t: float, y: np.ndarray, held=None, mode=None) -> np.ndarray: ...
    def project_velocity(self, y: np.ndarray, mode=None) -> np.ndarray: ...
    def kinetic_energy(self, t, y, held=None) -> float: ...
    def bending(self, t, y, held=None, mode=None) -> tuple[np.ndarray, np.ndarray]: ...
    def energies(self, t, y, held=None, bending=None, mode=None) -> Energies: ...
    def snapshot(self, t, y, held=None, mode=None) -> Snapshot: ...


def load_table(scene: Scene):
    """Scripted loads as the kernels' array tuple (node, axis, shape, amp, start, dur)."""
    loads = scene.loads
    return (np.array([ld.node - 1 for ld in loads], dtype=np.int64),
            np.array([LOAD_AXES.index(ld.axis) for ld in loads], dtype=np.int64),
            np.array([_SHAPE_CODES[ld.shape] for ld in loads], dtype=np.int64),
            np.array([ld.amplitude for ld in loads], dtype=float),
            np.array([ld.start for ld in loads], dtype=float),
            np.array([ld.duration for ld in loads], dtype=float))


class ChainModel:
    """Shared machinery; subclasses set ``name``, ``kernel`` and the state layout."""

    name = "chain"
    kernel = None
    dof_per_rod = 1

    def __init__(self, scene: Scene):
        self.scene = scene
        self.params = ChainParams.from_scene(scene)
        p = self.params
        self.n = p.n
        self.chain = (p.l, p.m, p.mu, p.bending_stiffness_diag(), p.kappa, p.nu,
                      p.tail_mass(), p.m * p.l**2 / 12.0)
        self.loads = load_table(scene)
        kr = p.kappa * np.asarray(scene.hinge_rest_angle, dtype=float)
        kr_next = np.append(kr[1:], 0.0)
        # rest-angle generalized forces kappa theta_rest dDelta/dq on phi, alpha, beta
        self._rest = (kr - kr_next, kr, -kr_next)
        self._base_extra = self._reduction() + (self._workspace(),)
        self._plans: dict = {}
        self.has_latches = bool(np.isfinite(scene.latch_angle).any())
        self.extra = self.plan().extra

    def _reduction(self) -> tuple:
        """(P_alpha, P_beta, B_inv) of the kernels' ``extra`` (zeros: unused)."""
        z = np.zeros((self.n, self.n))
        return (z, z, np.zeros((2 * self.n, 2 * self.n)))

    def _workspace(self) -> np.ndarray:
        return np.zeros(kernels.workspace_size(self.n))

    # ----- layout -----
    @property
    def state_size(self) -> int:
        return 2 * self.dof_per_rod * self.n

    @property
    def dof(self) -> int:
        return self.dof_per_rod * self.n

    def initial_state(self) -> np.ndarray:
        """State at t = 0 from the scene's initial phi, phi_rate (bending at rest), velocities
        projected onto the locked hinges' constraint."""
        y = np.zeros(self.state_size)
        y[:self.n] = self.scene.phi0
        y[self.dof:self.dof + self.n] = self.scene.phi_rate0
        return self.project_velocity(y)

    def phi(self, y: np.ndarray) -> np.ndarray:
        """Rod angles (n,) [rad] (y may be (..., state_size))."""
        return y[..., :self.n]

    def phi_rate(self, y: np.ndarray) -> np.ndarray:
        """Rod angular rates (n,) [rad/s]."""
        return y[..., self.dof:self.dof + self.n]

    # ----- mode -----
    def plan(self, mode: np.ndarray | None = None, contact: np.ndarray | None = None) -> Plan:
        """The kernels' arguments and the event table with the latches ``mode`` (n,) bool
        fired (None: none) and the stop contacts ``contact`` (n,) int (+1 upper, -1 lower,
        0 free; None: all free)."""
        fast = (b"" if mode is None else np.asarray(mode, dtype=bool).tobytes(),
                b"" if contact is None else np.asarray(contact, dtype=np.int8).tobytes())
        plan = self._plans.get(fast)
        if plan is None:
            locked = hinges.locked_hinges(self.scene, mode)
            side = np.zeros(self.n, dtype=np.int8) if contact is None else \
                np.asarray(contact, dtype=np.int8)
            side = np.where(locked, 0, side).astype(np.int8)
            key = locked.tobytes() + side.tobytes()
            if key not in self._plans:
                self._plans[key] = self._make_plan(locked, side)
            plan = self._plans[fast] = self._plans[key]
        return plan

    def _make_plan(self, locked: np.ndarray, side: np.ndarray) -> Plan:
        s = self.scene
        C = hinges.constraint_matrix(s, self.dof_per_rod, locked)
        n, d = self.n, self.dof
        T = None
        if C.shape[0]:
            order = (list(range(n, 3 * n)) if self.dof_per_rod == 3 else []) + \
                list(range(n - 1, -1, -1))
            T = hinges.constraint_basis(C, order)
        lo = np.array(s.stop_lower, dtype=float)
        hi = np.array(s.stop_upper, dtype=float)
        stops = bool(np.any(side != 0))
        r = T.shape[1] if T is not None else 0
        rows, cols = np.nonzero(T) if T is not None else (np.zeros(0, int), np.zeros(0, int))
        vals = T[rows, cols] if T is not None else np.zeros(0)
        flags = np.array([int(stops), int(T is not None), r, C.shape[0]], dtype=np.int64)
        c_rows, c_cols = np.nonzero(C)
        scratch = np.zeros(3 * d * d + 2 * d if T is not None else 1)
        H = np.ascontiguousarray(np.vstack([*self._rest, lo, hi, s.stop_stiffness,
                                            s.stop_damping, side.astype(float)]))
        hinge = (H, flags, rows.astype(np.int64), cols.astype(np.int64),
                 np.ascontiguousarray(vals, dtype=float), c_rows.astype(np.int64),
                 c_cols.astype(np.int64), np.ascontiguousarray(C[c_rows, c_cols], dtype=float),
                 np.zeros(n, dtype=np.int64), scratch)
        return Plan(self._base_extra + hinge, hinges.event_table(s, locked), locked, T)

    # ----- evaluation -----
    def forces(self, t: float, held: np.ndarray | None = None) -> np.ndarray:
        """Applied nodal forces (n, 2) [N] at t: held command plus scripted loads."""
        out = np.zeros((self.n, 2))
        kernels.load_forces(t, self.loads, self._held(held), t, out)
        return out

    def _held(self, held):
        if held is None:
            return np.zeros((self.n, 2))
        return np.ascontiguousarray(held, dtype=float).reshape(self.n, 2)

    def contact_state(self, y: np.ndarray) -> np.ndarray:
        """Stop contacts (n,) int8 implied by the state: +1 above the upper stop (or on it and
        moving in), -1 below the lower one (or on it and moving in), 0 otherwise."""
        s = self.scene
        theta = hinges.hinge_angles(self.phi(y))
        rate = hinges.hinge_angles(self.phi_rate(y))
        up = (theta > s.stop_upper) | ((theta == s.stop_upper) & (rate > 0.0))
        down = (theta < s.stop_lower) | ((theta == s.stop_lower) & (rate < 0.0))
        return (up.astype(np.int8) - down.astype(np.int8)).astype(np.int8)

    def rhs(self, t: float, y: np.ndarray, held: np.ndarray | None = None,
            mode: np.ndarray | None = None, contact: np.ndarray | None = None) -> np.ndarray:
        """dy/dt (state_size,) at time t [s] with held nodal forces (n, 2) [N] in ``mode``
        with the stop contacts ``contact`` (None: as implied by y)."""
        out = np.empty(self.state_size)
        y = np.ascontiguousarray(y, dtype=float)
        side = self.contact_state(y) if contact is None else contact
        self.kernel(t, y, self.chain, self.plan(mode, side).extra, self.loads, self._held(held),
                    t, out)
        return out

    def mass_blocks(self, phi: np.ndarray):
        n = self.n
        A, Ma, Mb = np.empty((n, n)), np.empty((n, n)), np.empty((n, n))
        kernels.mass_blocks(np.ascontiguousarray(phi, dtype=float), self.chain, A, Ma, Mb)
        return A, Ma, Mb

    def mass_matrix(self, y: np.ndarray) -> np.ndarray:
        """M (dof, dof) of the model's equations M x'' = f (reduced: the eliminated M_r)."""
        return self.mass_blocks(self.phi(y))[0]

    def project_velocity(self, y: np.ndarray, mode: np.ndarray | None = None) -> np.ndarray:
        """y with its velocities replaced by the impulsive-constraint projection
        x'+ = T (T^T M T)^{-1} T^T M x'- (M-orthogonal for a symmetric M) in ``mode``."""
        T = self.plan(mode).T
        out = np.array(y, dtype=float)
        if T is None:
            return out
        d = self.dof
        M = self.mass_matrix(y)
        v = out[d:]
        out[d:] = 0.0 if T.shape[1] == 0 else T @ np.linalg.solve(T.T @ M @ T, T.T @ (M @ v))
        return out

    def bending(self, t, y, held=None, mode=None) -> tuple[np.ndarray, np.ndarray]:
        """End slopes (alpha, beta), each (n,) [rad]."""
        raise NotImplementedError

    def bending_rates(self, t, y, held=None) -> tuple[np.ndarray, np.ndarray]:
        """Rates of the end slopes as the model's equations carry them [rad/s]."""
        return np.zeros(self.n), np.zeros(self.n)

    def hinge_deflection(self, t, y, held=None, bending=None, mode=None):
        """Relative hinge rotations Delta phi_h of eq. (2) and their rates, each (n,).
        ``bending`` = (alpha, beta) if already known at (t, y, held)."""
        alpha, beta = self.bending(t, y, held, mode) if bending is None else bending
        phi = self.phi(y)
        left = np.concatenate([[0.0], phi[:-1] + beta[:-1]])
        return phi + alpha - left, self.hinge_deflection_rate(t, y, held)

    def hinge_deflection_rate(self, t, y, held=None) -> np.ndarray:
        """d/dt Delta phi_h (n,) [rad/s] (the reduced and rigid models carry no bending rates)."""
        dphi = self.phi_rate(y)
        dalpha, dbeta = self.bending_rates(t, y, held)
        dleft = np.concatenate([[0.0], dphi[:-1] + dbeta[:-1]])
        return dphi + dalpha - dleft

    def contact_moments(self, y: np.ndarray, mode=None) -> np.ndarray:
        """Stop contact moments (n,) [N m] on theta (zero on locked hinges)."""
        s = self.scene
        m = hinges.contact_moments(hinges.hinge_angles(self.phi(y)),
                                   hinges.hinge_angles(self.phi_rate(y)),
                                   s.stop_lower, s.stop_upper, s.stop_stiffness, s.stop_damping)
        m[self.plan(mode).locked] = 0.0
        return m

    def kinetic_energy(self, t, y, held=None) -> float:
        A, _, _ = self.mass_blocks(self.phi(y))
        v = self.phi_rate(y)
        return 0.5 * float(v @ A @ v)

    def energies(self, t: float, y: np.ndarray, held=None, bending=None, mode=None) -> Energies:
        """Kinetic, hinge (springs about their rest angles + stop contacts) and bending energy
        [J] at (t, y); ``bending`` = (alpha, beta) if already known at (t, y, held)."""
        alpha, beta = self.bending(t, y, held, mode) if bending is None else bending
        delta, _ = self.hinge_deflection(t, y, held, bending=(alpha, beta))
        p, s = self.params, self.scene
        hinge = 0.5 * float(np.sum(p.kappa * (delta - s.hinge_rest_angle) ** 2))
        pen = hinges.contact_penetration(hinges.hinge_angles(self.phi(y)), s.stop_lower,
                                         s.stop_upper)
        pen[self.plan(mode).locked] = 0.0
        hinge += 0.5 * float(np.sum(s.stop_stiffness * pen**2))
        bend = float(np.sum(2.0 * p.EI / p.l * (alpha**2 + beta**2 + alpha * beta)))
        return Energies(self.kinetic_energy(t, y, held), hinge, bend)

    def powers(self, t: float, y: np.ndarray, held=None, mode=None) -> tuple[float, float]:
        """(power of the nodal loads, power dissipated in the hinge dampers and the stop
        contacts) [W]."""
        phi, dphi = self.phi(y), self.phi_rate(y)
        f = self.forces(t, held)
        l = self.params.l
        vx = np.cumsum(-l * np.sin(phi) * dphi)
        vy = np.cumsum(l * np.cos(phi) * dphi)
        load_power = float(np.sum(f[:, 0] * vx + f[:, 1] * vy))
        ddelta = self.hinge_deflection_rate(t, y, held)
        damper = float(np.sum(self.params.nu * ddelta**2))
        s = self.scene
        if np.any(np.isfinite(s.stop_lower) | np.isfinite(s.stop_upper)):
            theta, dtheta = hinges.hinge_angles(phi), hinges.hinge_angles(dphi)
            elastic = -s.stop_stiffness * (np.maximum(0.0, theta - s.stop_upper)
                                           - np.maximum(0.0, s.stop_lower - theta))
            elastic[self.plan(mode).locked] = 0.0
            damper -= float(np.sum((self.contact_moments(y, mode) - elastic) * dtheta))
        return load_power, damper

    def snapshot(self, t: float, y: np.ndarray, held=None, mode=None) -> Snapshot:
        """Everything published about the chain at (t, y). hinge_moment = kappa (Delta -
        theta_rest) + nu Delta' minus the stop contact moment (the constraint reaction of a
        locked hinge is not included)."""
        phi = np.array(self.phi(y), dtype=float)
        dphi = np.array(self.phi_rate(y), dtype=float)
        alpha, beta = self.bending(t, y, held, mode)
        delta, ddelta = self.hinge_deflection(t, y, held, bending=(alpha, beta))
        p = self.params
        moment = (p.kappa * (delta - self.scene.hinge_rest_angle) + p.nu * ddelta
                  - self.contact_moments(y, mode))
        return Snapshot(
            t=float(t), phi=phi, phi_rate=dphi, alpha=np.asarray(alpha, float),
            beta=np.asarray(beta, float),
            hinge_angle=np.diff(phi, prepend=0.0), hinge_rate=np.diff(dphi, prepend=0.0),
            hinge_moment=moment, nodes=node_positions(p.l, phi), forces=self.forces(t, held))


class RigidModel(ChainModel):
    """Rigid rods (EI -> infinity): n ODEs, alpha = beta = 0."""

    name = "rigid"
    kernel = staticmethod(kernels.rigid_rhs)

    def bending(self, t, y, held=None, mode=None):
        return np.zeros(self.n), np.zeros(self.n)


class ReducedModel(ChainModel):
    """The paper's reduced model (15): bending inertia neglected, gamma from (14). A rigid
    rod's quasi-static bending equations are removed (gamma = 0 for it)."""

    name = "reduced"
    kernel = staticmethod(kernels.reduced_rhs)

    def _reduction(self) -> tuple:
        n = self.n
        K_gp, B = reduction_matrices(self.params)
        rigid = np.asarray(self.scene.rod_rigid, dtype=bool)
        if rigid.any():
            keep = np.flatnonzero(np.concatenate([~rigid, ~rigid]))
            B_inv = np.zeros((2 * n, 2 * n))
            B_inv[np.ix_(keep, keep)] = np.linalg.inv(B[np.ix_(keep, keep)])
        else:
            B_inv = np.linalg.inv(B)
        P = K_gp.T @ B_inv                       # (n, 2n), constant
        return (np.ascontiguousarray(P[:, :n]), np.ascontiguousarray(P[:, n:]), B_inv)

    def mass_matrix(self, y: np.ndarray) -> np.ndarray:
        A, Ma, Mb = self.mass_blocks(self.phi(y))
        return A - self.extra[0] @ Ma.T - self.extra[1] @ Mb.T

    def bending(self, t, y, held=None, mode=None):
        """gamma = -[b]^{-1} (m^{gamma phi} phi_ddot + (g Lambda + v) phi_dot + kappa phi
        - kappa theta_rest dDelta/dgamma)."""
        n = self.n
        phi = np.ascontiguousarray(self.phi(y))
        dphi = np.ascontiguousarray(self.phi_rate(y))
        phi_dd = self.rhs(t, y, held, mode)[n:]
        _, Ma, Mb = self.mass_blocks(phi)
        gp, ga, tau = np.empty(n), np.empty(n), np.empty(n)
        kernels.rigid_velocity_terms(phi, dphi, self.chain, gp, ga)
        kernels.rigid_hinge_moments(phi, dphi, self.params.kappa, self.params.nu, tau)
        tau_next = np.append(tau[1:], 0.0)
        _, rest_alpha, rest_beta = self._rest
        a = np.concatenate([Ma.T @ phi_dd + ga + tau - rest_alpha,
                            Mb.T @ phi_dd - ga - tau_next - rest_beta])
        gamma = -self.extra[2] @ a
        return gamma[:n], gamma[n:]


class FullModel(ChainModel):
    """The paper's full model (9)-(10): 3n ODEs in phi, alpha, beta."""

    name = "full"
    kernel = staticmethod(kernels.full_rhs)
    dof_per_rod = 3

    def __init__(self, scene: Scene):
        bad = np.flatnonzero(np.asarray(scene.mass_per_length) <= 0.0)
        if bad.size:
            raise ModelError(f"rods.mass_per_length: the full model needs every rod to have mass "
                             f"(rod {bad[0] + 1} has m = 0, so its bending has no inertia); "
                             f"use the reduced or rigid model")
        super().__init__(scene)

    def bending(self, t, y, held=None, mode=None):
        n = self.n
        return np.array(y[n:2 * n]), np.array(y[2 * n:3 * n])

    def bending_rates(self, t, y, held=None):
        n = self.n
        return np.array(y[4 * n:5 * n]), np.array(y[5 * n:6 * n])

    def mass_matrix(self, y: np.ndarray) -> np.ndarray:
        A, Ma, Mb = self.mass_blocks(self.phi(y))
        p = self.params
        ml3 = p.m * p.l**3
        Da, Db = np.diag(ml3 / 105.0), np.diag(-ml3 / 140.0)
        return np.block([[A, Ma, Mb], [Ma.T, Da, Db], [Mb.T, Db, Da]])

    def kinetic_energy(self, t, y, held=None) -> float:
        n = self.n
        A, Ma, Mb = self.mass_blocks(self.phi(y))
        p = self.params
        ml3 = p.m * p.l**3
        v, va, vb = y[3 * n:4 * n], y[4 * n:5 * n], y[5 * n:]
        return 0.5 * float(v @ A @ v + 2 * v @ Ma @ va + 2 * v @ Mb @ vb
                           + np.sum(ml3 / 105 * (va**2 + vb**2) - 2 * ml3 / 140 * va * vb))


MODELS = {"full": FullModel, "reduced": ReducedModel, "rigid": RigidModel}


def make_model(name: str, scene: Scene) -> ChainModel:
    """The model called ``name`` ('full', 'reduced' or 'rigid') for ``scene``, with its hinge
    features (rest angles, stops, latches, locked hinges, rigid rods)."""
    try:
        cls = MODELS[name]
    except KeyError:
        raise ModelError(f"model: unknown model {name!r} (choose from {', '.join(MODELS)})") from None
    return cls(scene)
