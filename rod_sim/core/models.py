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
from typing import Callable, NamedTuple, Protocol

import numpy as np

from . import erk, hinges, kernels, radau
from .kinematics import node_positions
from .matrices import ChainParams
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
    :mod:`rod_sim.core.kernels`), ``events`` (:class:`~rod_sim.core.kernels.EventTable`) of
    :func:`hinges.event_table` and ``locked`` (n,) bool (hinges held rigid)."""

    extra: kernels.Extra
    events: kernels.EventTable
    locked: np.ndarray


class Compiled(NamedTuple):
    """A model's compiled drivers (one specialisation per model kernel, cached on disk):
    ``dop853`` (erk.dop853_run), ``fixed`` (erk.fixed_run), ``radau`` (radau.radau_run_work
    with the O(n) Newton solve)."""

    dop853: Callable
    fixed: Callable
    radau: Callable


class Model(Protocol):
    """The protocol every model implements; the driver, the simulator and the tools use only
    this. Shapes: state (state_size,) = [q, q'] with q (dof,) = dof_per_rod blocks of n;
    ``held`` (n, 3) nodal forces X, Y [N] and hinge motor moments T [N m] (or None: zeros;
    (n, 2) forces); ``mode`` (n,) bool the latches fired (None: none); ``contact`` (n,) int8
    the stop contacts (+1 upper, -1 lower, 0 free)."""

    name: str
    n: int
    dof_per_rod: int
    scene: Scene
    params: ChainParams
    chain: kernels.Chain
    loads: tuple
    kernel: Callable
    compiled: Compiled
    has_latches: bool

    @property
    def state_size(self) -> int: ...
    @property
    def dof(self) -> int: ...
    def initial_state(self) -> np.ndarray: ...
    def phi(self, y: np.ndarray) -> np.ndarray: ...
    def phi_rate(self, y: np.ndarray) -> np.ndarray: ...
    def plan(self, mode: np.ndarray | None = None,
             contact: np.ndarray | None = None) -> Plan: ...
    def forces(self, t: float, held=None) -> np.ndarray: ...
    def contact_state(self, y: np.ndarray) -> np.ndarray: ...
    def rhs(self, t: float, y: np.ndarray, held=None, mode=None,
            contact=None) -> np.ndarray: ...
    def mass_times(self, y: np.ndarray, v: np.ndarray | None = None) -> np.ndarray: ...
    def project_velocity(self, y: np.ndarray, mode=None) -> np.ndarray: ...
    def bending(self, t, y, held=None, mode=None) -> tuple[np.ndarray, np.ndarray]: ...
    def bending_rates(self, t, y, held=None) -> tuple[np.ndarray, np.ndarray]: ...
    def hinge_deflection(self, t, y, held=None, bending=None,
                         mode=None) -> tuple[np.ndarray, np.ndarray]: ...
    def contact_moments(self, y: np.ndarray, mode=None) -> np.ndarray: ...
    def kinetic_energy(self, t, y, held=None) -> float: ...
    def energies(self, t, y, held=None, bending=None, mode=None) -> Energies: ...
    def powers(self, t, y, held=None, mode=None) -> tuple[float, float]: ...
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
    """Shared machinery (implements :class:`Model`); a subclass sets ``name``, ``kernel``,
    ``compiled`` and the state layout, and is registered in :data:`MODELS`."""

    name = "chain"
    kernel = None
    compiled: Compiled
    dof_per_rod = 1

    def __init__(self, scene: Scene):
        self.scene = scene
        self.params = ChainParams.from_scene(scene)
        p = self.params
        self.n = p.n
        self.chain = kernels.make_chain(p.l, p.m, p.mu, p.EI, p.kappa, p.nu)
        self.loads = load_table(scene)
        kr = p.kappa * np.asarray(scene.hinge_rest_angle, dtype=float)
        kr_next = np.append(kr[1:], 0.0)
        # rest-angle generalized forces kappa theta_rest dDelta/dq on phi, alpha, beta
        self._rest = np.array([kr - kr_next, kr, -kr_next])
        self._stops = np.array([scene.stop_lower, scene.stop_upper, scene.stop_stiffness,
                                scene.stop_damping], dtype=float)
        self._plans: dict = {}
        self.has_latches = bool(np.isfinite(scene.latch_angle).any())
        self.extra = self.plan().extra

    def _pinned(self) -> np.ndarray:
        """Rods whose end slopes are zero (n,) bool: the scene's rigid rods."""
        return np.asarray(self.scene.rod_rigid, dtype=bool)

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
        extra = kernels.make_extra(self._rest, self._stops, side, locked, self._pinned(),
                                   kind=self._kind)
        return Plan(extra, hinges.event_table(self.scene, locked), locked)

    # ----- evaluation -----
    def forces(self, t: float, held: np.ndarray | None = None) -> np.ndarray:
        """Applied nodal forces (n, 2) [N] at t: held command plus scripted loads."""
        out = np.zeros((self.n, 2))
        kernels.load_forces(t, self.loads, self._held(held), t, out)
        return out

    def _held(self, held):
        """The kernels' held inputs (n, 3): nodal forces X, Y [N] and hinge motor moments T
        [N m], from None (zeros), forces (n, 2) or flat (2n,), or (n, 3)."""
        out = np.zeros((self.n, 3))
        if held is None:
            return out
        h = np.asarray(held, dtype=float)
        if h.size == 3 * self.n:
            out[:, :] = h.reshape(self.n, 3)
        else:
            out[:, :2] = h.reshape(self.n, 2)
        return out

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

    _kind = kernels.KIND_REDUCED

    def mass_times(self, y: np.ndarray, v: np.ndarray | None = None) -> np.ndarray:
        """M v (dof,) for velocities v (dof,) (default y's own) with M the paper's inertia
        matrix of the model's coordinates at y (rigid and reduced: m^{phi phi}), in O(n)."""
        v = y[self.dof:] if v is None else v
        return kernels.inertia_times(self._kind, self.chain, self.phi(y), v)[:self.dof]

    def project_velocity(self, y: np.ndarray, mode: np.ndarray | None = None) -> np.ndarray:
        """y with its velocities replaced by the impulsive-constraint projection
        x'+ = T (T^T M T)^{-1} T^T M x'- (M-orthogonal for a symmetric M) in ``mode``, with T
        a basis of the locked hinges' constraints (the reduced model: M = M_r of eq. (15)),
        solved in O(n) by the kernels' chain solve with f = M x'-."""
        plan = self.plan(mode)
        out = np.array(y, dtype=float)
        if not plan.locked.any() and not (self.dof_per_rod == 3 and self._pinned().any()):
            return out
        n, d = self.n, self.dof
        phi = np.ascontiguousarray(self.phi(y), dtype=float)
        # reduced: (A v, m^{gamma phi} v) as right-hand sides give M_r x = M_r v
        f = kernels.inertia_times(kernels.KIND_FULL, self.chain, phi, out[d:])
        if self.name == "rigid":
            f[n:] = 0.0
        x = np.empty(3 * n)
        if not kernels.solve_with(self._kind, phi, self.chain, plan.extra, f[:n], f[n:2 * n],
                                  f[2 * n:], x[:n], x[n:2 * n], x[2 * n:]):
            raise np.linalg.LinAlgError("singular mass matrix in the velocity projection")
        out[d:] = x[:d]
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
        """(1/2) x'^T M x' [J] (rigid and reduced: rod motion only), O(n)."""
        return 0.5 * float(np.dot(y[self.dof:], self.mass_times(y)))

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
        """(power of the nodal loads and hinge motors, power dissipated in the hinge dampers and the stop
        contacts) [W]."""
        phi, dphi = self.phi(y), self.phi_rate(y)
        f = self.forces(t, held)
        l = self.params.l
        vx = np.cumsum(-l * np.sin(phi) * dphi)
        vy = np.cumsum(l * np.cos(phi) * dphi)
        load_power = float(np.sum(f[:, 0] * vx + f[:, 1] * vy))
        ddelta = self.hinge_deflection_rate(t, y, held)
        load_power += float(np.dot(self._held(held)[:, 2], ddelta))    # hinge motors
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
    compiled = Compiled(erk.dop853_rigid, erk.fixed_rigid, radau.radau_rigid)

    def _pinned(self) -> np.ndarray:
        return np.ones(self.n, dtype=bool)

    def bending(self, t, y, held=None, mode=None):
        return np.zeros(self.n), np.zeros(self.n)


class ReducedModel(ChainModel):
    """The paper's reduced model (15): bending inertia neglected, gamma from (14). A rigid
    rod's quasi-static bending equations are removed (gamma = 0 for it)."""

    name = "reduced"
    kernel = staticmethod(kernels.reduced_rhs)
    compiled = Compiled(erk.dop853_reduced, erk.fixed_reduced, radau.radau_reduced)

    def bending(self, t, y, held=None, mode=None):
        """gamma = (alpha, beta) (n,) each [rad] from the quasi-static rows of (14), which the
        kernel solves together with phi'' (left in its work array)."""
        self.rhs(t, y, held, mode)
        W = self.plan(mode, self.contact_state(np.asarray(y, dtype=float))).extra.work
        return W[:, kernels.W_A].copy(), W[:, kernels.W_B].copy()


class FullModel(ChainModel):
    """The paper's full model (9)-(10): 3n ODEs in phi, alpha, beta."""

    name = "full"
    kernel = staticmethod(kernels.full_rhs)
    compiled = Compiled(erk.dop853_full, erk.fixed_full, radau.radau_full)
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

    _kind = kernels.KIND_FULL


MODELS = {cls.name: cls for cls in (FullModel, ReducedModel, RigidModel)}
"""The model registry: name -> class. Its keys are :data:`rod_sim.core.names.MODEL_NAMES`
(a test checks), which the command line reads without importing numba."""


def make_model(name: str, scene: Scene) -> ChainModel:
    """The model called ``name`` ('full', 'reduced' or 'rigid') for ``scene``, with its hinge
    features (rest angles, stops, latches, locked hinges, rigid rods)."""
    try:
        cls = MODELS[name]
    except KeyError:
        raise ModelError(f"model: unknown model {name!r} (choose from {', '.join(MODELS)})") from None
    return cls(scene)
