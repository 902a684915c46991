"""The three fidelity levels behind one interface.

- :class:`FullModel`: 3n second-order ODEs (9)-(10) in phi, alpha, beta;
  state y = [phi, alpha, beta, phi_dot, alpha_dot, beta_dot] (6n,).
- :class:`ReducedModel`: n ODEs (15) in phi, bending found quasi-statically from (14);
  state y = [phi, phi_dot] (2n,).
- :class:`RigidModel`: the limit EI -> infinity (alpha = beta = 0); state y = [phi, phi_dot].

Every model offers the compiled right-hand side (``kernel`` with its argument tuples), and
in Python: ``rhs``, ``bending``, ``energies``, ``powers`` and ``snapshot``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import kernels
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
    """Mechanical energy [J]: kinetic, hinge springs, bending; ``total`` their sum."""

    kinetic: float
    hinge: float
    bending: float

    @property
    def total(self) -> float:
        return self.kinetic + self.hinge + self.bending


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
        z = np.zeros((self.n, self.n))
        self.extra = (z, z, np.zeros((2 * self.n, 2 * self.n)), self._workspace())

    def _workspace(self) -> np.ndarray:
        return np.zeros(kernels.workspace_size(self.n))

    # ----- layout -----
    @property
    def state_size(self) -> int:
        return 2 * self.dof_per_rod * self.n

    def initial_state(self) -> np.ndarray:
        """State at t = 0 from the scene's initial phi, phi_rate (bending at rest)."""
        y = np.zeros(self.state_size)
        y[:self.n] = self.scene.phi0
        y[self.state_size // 2:self.state_size // 2 + self.n] = self.scene.phi_rate0
        return y

    def phi(self, y: np.ndarray) -> np.ndarray:
        """Rod angles (n,) [rad] (y may be (..., state_size))."""
        return y[..., :self.n]

    def phi_rate(self, y: np.ndarray) -> np.ndarray:
        """Rod angular rates (n,) [rad/s]."""
        h = self.state_size // 2
        return y[..., h:h + self.n]

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

    def rhs(self, t: float, y: np.ndarray, held: np.ndarray | None = None) -> np.ndarray:
        """dy/dt (state_size,) at time t [s] with held nodal forces (n, 2) [N]."""
        out = np.empty(self.state_size)
        self.kernel(t, np.ascontiguousarray(y, dtype=float), self.chain, self.extra,
                    self.loads, self._held(held), t, out)
        return out

    def bending(self, t, y, held=None) -> tuple[np.ndarray, np.ndarray]:
        """End slopes (alpha, beta), each (n,) [rad]."""
        raise NotImplementedError

    def bending_rates(self, t, y, held=None) -> tuple[np.ndarray, np.ndarray]:
        """Rates of the end slopes as the model's equations carry them [rad/s]."""
        return np.zeros(self.n), np.zeros(self.n)

    def mass_blocks(self, phi: np.ndarray):
        n = self.n
        A, Ma, Mb = np.empty((n, n)), np.empty((n, n)), np.empty((n, n))
        kernels.mass_blocks(np.ascontiguousarray(phi, dtype=float), self.chain, A, Ma, Mb)
        return A, Ma, Mb

    def hinge_deflection(self, t, y, held=None, bending=None) -> tuple[np.ndarray, np.ndarray]:
        """Relative hinge rotations Delta phi_h of eq. (2) and their rates, each (n,).
        ``bending`` = (alpha, beta) if already known at (t, y, held)."""
        alpha, beta = self.bending(t, y, held) if bending is None else bending
        phi = self.phi(y)
        left = np.concatenate([[0.0], phi[:-1] + beta[:-1]])
        return phi + alpha - left, self.hinge_deflection_rate(t, y, held)

    def hinge_deflection_rate(self, t, y, held=None) -> np.ndarray:
        """d/dt Delta phi_h (n,) [rad/s] (the reduced and rigid models carry no bending rates)."""
        dphi = self.phi_rate(y)
        dalpha, dbeta = self.bending_rates(t, y, held)
        dleft = np.concatenate([[0.0], dphi[:-1] + dbeta[:-1]])
        return dphi + dalpha - dleft

    def kinetic_energy(self, t, y, held=None) -> float:
        A, _, _ = self.mass_blocks(self.phi(y))
        v = self.phi_rate(y)
        return 0.5 * float(v @ A @ v)

    def energies(self, t: float, y: np.ndarray, held=None, bending=None) -> Energies:
        """Kinetic, hinge-spring and bending energy [J] at (t, y); ``bending`` = (alpha, beta)
        if already known at (t, y, held)."""
        alpha, beta = self.bending(t, y, held) if bending is None else bending
        delta, _ = self.hinge_deflection(t, y, held, bending=(alpha, beta))
        p = self.params
        hinge = 0.5 * float(np.sum(p.kappa * delta**2))
        bend = float(np.sum(2.0 * p.EI / p.l * (alpha**2 + beta**2 + alpha * beta)))
        return Energies(self.kinetic_energy(t, y, held), hinge, bend)

    def powers(self, t: float, y: np.ndarray, held=None) -> tuple[float, float]:
        """(power of the nodal loads, power dissipated in the hinge dampers) [W]."""
        phi, dphi = self.phi(y), self.phi_rate(y)
        f = self.forces(t, held)
        l = self.params.l
        vx = np.cumsum(-l * np.sin(phi) * dphi)
        vy = np.cumsum(l * np.cos(phi) * dphi)
        load_power = float(np.sum(f[:, 0] * vx + f[:, 1] * vy))
        ddelta = self.hinge_deflection_rate(t, y, held)
        return load_power, float(np.sum(self.params.nu * ddelta**2))

    def snapshot(self, t: float, y: np.ndarray, held=None) -> Snapshot:
        """Everything published about the chain at (t, y)."""
        phi = np.array(self.phi(y), dtype=float)
        dphi = np.array(self.phi_rate(y), dtype=float)
        alpha, beta = self.bending(t, y, held)
        delta, ddelta = self.hinge_deflection(t, y, held, bending=(alpha, beta))
        p = self.params
        return Snapshot(
            t=float(t), phi=phi, phi_rate=dphi, alpha=np.asarray(alpha, float),
            beta=np.asarray(beta, float),
            hinge_angle=np.diff(phi, prepend=0.0), hinge_rate=np.diff(dphi, prepend=0.0),
            hinge_moment=p.kappa * delta + p.nu * ddelta,
            nodes=node_positions(p.l, phi), forces=self.forces(t, held))


class RigidModel(ChainModel):
    """Rigid rods (EI -> infinity): n ODEs, alpha = beta = 0."""

    name = "rigid"
    kernel = staticmethod(kernels.rigid_rhs)

    def bending(self, t, y, held=None):
        return np.zeros(self.n), np.zeros(self.n)


class ReducedModel(ChainModel):
    """The paper's reduced model (15): bending inertia neglected, gamma from (14)."""

    name = "reduced"
    kernel = staticmethod(kernels.reduced_rhs)

    def __init__(self, scene: Scene):
        super().__init__(scene)
        K_gp, B = reduction_matrices(self.params)
        B_inv = np.linalg.inv(B)
        P = K_gp.T @ B_inv                       # (n, 2n), constant
        n = self.n
        self.extra = (np.ascontiguousarray(P[:, :n]), np.ascontiguousarray(P[:, n:]), B_inv,
                      self._workspace())

    def bending(self, t, y, held=None):
        """gamma = -[b]^{-1} (m^{gamma phi} phi_ddot + (g Lambda + v) phi_dot + kappa phi)."""
        n = self.n
        phi, dphi = self.phi(y), self.phi_rate(y)
        phi_dd = self.rhs(t, y, held)[n:]
        _, Ma, Mb = self.mass_blocks(phi)
        gp, ga = np.empty(n), np.empty(n)
        kernels.rigid_velocity_terms(np.ascontiguousarray(phi), np.ascontiguousarray(dphi),
                                     self.chain, gp, ga)
        tau = np.empty(n)
        kernels.rigid_hinge_moments(np.ascontiguousarray(phi), np.ascontiguousarray(dphi),
                                    self.params.kappa, self.params.nu, tau)
        tau_next = np.append(tau[1:], 0.0)
        a = np.concatenate([Ma.T @ phi_dd + ga + tau, Mb.T @ phi_dd - ga - tau_next])
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

    def bending(self, t, y, held=None):
        n = self.n
        return np.array(y[n:2 * n]), np.array(y[2 * n:3 * n])

    def bending_rates(self, t, y, held=None):
        n = self.n
        return np.array(y[4 * n:5 * n]), np.array(y[5 * n:6 * n])

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
    """The model called ``name`` ('full', 'reduced' or 'rigid') for ``scene``."""
    try:
        cls = MODELS[name]
    except KeyError:
        raise ModelError(f"model: unknown model {name!r} (choose from {', '.join(MODELS)})") from None
    if scene.has_hinge_features:
        from .hinges import HingeModel   # rest angles, stops, latches, locked hinges, rigid rods
        return HingeModel(scene, cls)
    return cls(scene)
