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

import functools
from dataclasses import dataclass
from typing import Callable, NamedTuple, Protocol

import numpy as np

from .scipy_tables import light_dop853_tables

with light_dop853_tables():     # erk's tables without scipy.integrate's import
    from . import erk, hinges, kernels, radau, typed_call
from .kinematics import chain_table
from .loadlaw import Loads, make_loads
from .matrices import ChainParams
from .scene import LOAD_AXES, Scene
from .snapshot import Snapshot
from .state import State

class ModelError(ValueError):
    """The scene cannot be run with the requested model (e.g. a massless rod in the full
    model, whose bending inertia would be zero)."""


@dataclass(frozen=True)
class Energies:
    """Mechanical energy [J]: kinetic (rods, node masses, a free base and its wheel), hinge
    springs (+ stop contacts), bending, and the potential of gravity (-sum m g.r, zero without
    gravity); ``total`` their sum."""

    kinetic: float
    hinge: float
    bending: float
    gravity: float = 0.0

    @property
    def total(self) -> float:
        total = self.kinetic + self.hinge + self.bending
        return total + self.gravity if self.gravity != 0.0 else total


@dataclass(frozen=True)
class Momentum:
    """Linear momentum ``linear`` (2,) [kg m/s], angular momentum about the origin of Oxy
    ``angular_origin`` and about the system's centre of mass ``angular_com`` [kg m^2/s], the
    centre of mass ``com`` (2,) [m] and the total mass ``mass`` [kg] (with a fixed or
    prescribed base: of the chains only)."""

    linear: np.ndarray
    angular_origin: float
    angular_com: float
    com: np.ndarray
    mass: float


@dataclass(frozen=True)
class BaseState:
    """The base frame's pose in Oxy (x, y [m], psi [rad]) and rates (x_rate, y_rate [m/s],
    psi_rate [rad/s], all in Oxy), and the wheel's rate relative to the base [rad/s]."""

    x: float
    y: float
    psi: float
    x_rate: float
    y_rate: float
    psi_rate: float
    wheel_rate: float = 0.0


_MODES = {"fixed": kernels.MODE_FIXED, "free": kernels.MODE_FREE,
          "prescribed": kernels.MODE_PRESCRIBED}


def chain_layout(scene) -> tuple[np.ndarray, np.ndarray]:
    """(seg (nc + 1,) int64: each chain's first rod and then n; attach (nc, 2) [m])."""
    chains = getattr(scene, "chains", None)
    if not chains:
        return np.array([0, scene.n], dtype=np.int64), np.zeros((1, 2))
    seg = np.array([c.start for c in chains] + [scene.n], dtype=np.int64)
    return seg, np.array([c.attach for c in chains], dtype=float).reshape(-1, 2)


def base_table(scene) -> tuple[np.ndarray, np.ndarray]:
    """The kernels' base constants (N_BASE,) and prescribed profiles (3, N_MOTION) of a scene
    (a scene without a base: a fixed base at the origin, no gravity)."""
    k = kernels
    out = np.zeros(k.N_BASE)
    motion = np.zeros((3, k.N_MOTION))
    base = getattr(scene, "base", None)
    gravity = getattr(scene, "gravity", None)
    if gravity is not None and (gravity[0] != 0.0 or gravity[1] != 0.0):
        out[k.B_GX], out[k.B_GY] = float(gravity[0]), float(gravity[1])
        out[k.B_GRAVITY] = 1.0
    if base is None:
        return out, motion
    mode = _MODES[base.mode]
    out[k.B_MODE] = mode
    out[k.B_X], out[k.B_Y], out[k.B_PSI] = base.x, base.y, base.psi
    if mode == k.MODE_FREE:
        out[k.B_MASS], out[k.B_INERTIA] = base.mass, base.inertia
        out[k.B_CX], out[k.B_CY] = base.centre_of_mass
        out[k.B_NB] = 3
        if base.wheel is not None:
            out[k.B_WHEEL] = base.wheel.inertia
            out[k.B_NB] = 4
    for row, axis in enumerate(("x", "y", "psi")):
        prof = (base.motion or {}).get(axis) if mode == k.MODE_PRESCRIBED else None
        if prof is None:
            continue
        motion[row, 0] = prof.code
        motion[row, 1:4] = prof.parameters
    return out, motion


class RodConstants(NamedTuple):
    """Per-rod factors of the momentum, gravity and bending-energy laws (each (n,)), computed
    once per model by the laws' own expressions: ``ml`` = m l, ``half_l`` = l / 2, ``mu``
    the end node's mass, ``C`` = m l^2 / 12, ``l3_k`` = m l^3 / k (``l3_70`` = 2 m l^3 /
    140), ``half_ml_l`` = m l^2 / 2, ``EI2_l`` = 2 EI / l, ``mass`` the chains' mass [kg],
    ``zeros``."""

    ml: np.ndarray
    half_l: np.ndarray
    mu: np.ndarray
    C: np.ndarray
    l3_3: np.ndarray
    l3_20: np.ndarray
    l3_30: np.ndarray
    l3_105: np.ndarray
    l3_70: np.ndarray
    half_ml_l: np.ndarray
    EI2_l: np.ndarray
    mass: float
    zeros: np.ndarray

    @classmethod
    def of(cls, p: ChainParams) -> "RodConstants":
        ml = p.m * p.l
        l3 = p.m * p.l**3
        return cls(ml, 0.5 * p.l, np.ascontiguousarray(p.mu, dtype=float),
                   p.m * p.l**2 / 12.0, l3 / 3.0, l3 / 20.0, l3 / 30.0, l3 / 105.0,
                   2.0 * l3 / 140.0, 0.5 * ml * p.l, 2.0 * p.EI / p.l, float(np.sum(ml + p.mu)),
                   np.zeros(p.n))


@dataclass(frozen=True, eq=False)
class Plan:
    """What the compiled drivers need in one mode: ``extra`` (kernels' argument, see
    :mod:`rod_sim.core.kernels`), ``events`` (:class:`~rod_sim.core.kernels.EventTable`) of
    :func:`hinges.event_table` and ``locked`` (n,) bool (hinges held rigid).

    A model's own plans (:meth:`ChainModel.plan`) are constants: their ``extra`` has the
    mode's hinge features and no scratch (its scratch fields are None, so that a compiled
    call with it fails to type instead of writing into memory shared by every user of the
    model); :meth:`ModelData.plan` gives the same plan with the data's scratch bound in."""

    extra: kernels.Extra
    events: kernels.EventTable
    locked: np.ndarray


SCRATCH_FIELDS = ("work", "small", "forces", "tau", "bk", "roots")
"""The fields of :class:`~rod_sim.core.kernels.Extra` the kernels write (scratch, nothing
kept from one call to the next): a :class:`ModelData`'s, never a model's."""


class ModelData:
    """The mutable part of running a model (the Model/Data split of Pinocchio): the kernels'
    scratch arrays (:data:`SCRATCH_FIELDS`: work (n, N_WORK), small (N_SMALL,), forces
    (n + 2, 3), tau (n + 1,), bk (N_BK,), roots (nc, N_ROOT)) and, per mode, the model's plan
    with that scratch bound in. A model is immutable after construction and may be shared
    by any number of simulators (and threads): each owns one ModelData
    (:meth:`ChainModel.new_data`); a kernel call writes only into its data's scratch."""

    def __init__(self, model: "ChainModel"):
        self.model = model
        template = kernels.make_extra(np.zeros((3, model.n)), np.zeros((4, model.n)),
                                      np.zeros(model.n), np.zeros(model.n, dtype=bool),
                                      np.zeros(model.n, dtype=bool), kind=model._kind,
                                      nchains=len(model.seg) - 1)
        self.scratch = {f: getattr(template, f) for f in SCRATCH_FIELDS}
        self._bound: dict[int, Plan] = {}
        self._extra_types: dict[int, object] = {}

    def extra_type(self, plan: Plan):
        """The numba type of ``plan.extra`` (:mod:`~rod_sim.core.typed_call`), ``plan`` one
        of this data's bound plans (:meth:`plan`; None for any other)."""
        return self._extra_types.get(id(plan))      # _bound keeps the plan: its id is stable

    def plan(self, mode: np.ndarray | None = None, contact: np.ndarray | None = None) -> Plan:
        """:meth:`ChainModel.plan` of the model with this data's scratch in its ``extra``."""
        const = self.model.plan(mode, contact)
        bound = self._bound.get(id(const))
        if bound is None:
            bound = Plan(const.extra._replace(**self.scratch), const.events, const.locked)
            self._bound[id(const)] = bound       # the model keeps ``const``: its id is stable
            self._extra_types[id(bound)] = self.model.bound_extra_type(const, bound)
        return bound


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
    loads: Loads
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
    def new_data(self) -> "ModelData": ...
    def forces(self, t: float, held=None) -> np.ndarray: ...
    def contact_state(self, y: np.ndarray, t: float = 0.0) -> np.ndarray: ...
    def rhs(self, t: float, y: np.ndarray, held=None, mode=None,
            contact=None, data=None) -> np.ndarray: ...
    def mass_times(self, y: np.ndarray, v: np.ndarray | None = None) -> np.ndarray: ...
    def project_velocity(self, y: np.ndarray, mode=None, t: float = 0.0) -> np.ndarray: ...
    def bending(self, t, y, held=None, mode=None) -> tuple[np.ndarray, np.ndarray]: ...
    def rhs_bending(self, t, y, held=None, mode=None, contact=None,
                    data=None) -> tuple[np.ndarray, tuple]: ...
    def bending_rates(self, t, y, held=None) -> tuple[np.ndarray, np.ndarray]: ...
    def hinge_deflection(self, t, y, held=None, bending=None,
                         mode=None) -> tuple[np.ndarray, np.ndarray]: ...
    def contact_moments(self, y: np.ndarray, mode=None) -> np.ndarray: ...
    def kinetic_energy(self, t, y, held=None) -> float: ...
    def energies(self, t, y, held=None, bending=None, mode=None) -> Energies: ...
    def powers(self, t, y, held=None, mode=None) -> tuple[float, float]: ...
    def snapshot(self, t, y, held=None, mode=None, bending=None,
                 state=None) -> Snapshot: ...
    def state(self, t, y, held=None, mode=None, f=None, bending=None,
              data=None) -> State: ...


def load_table(scene: Scene) -> Loads:
    """The scene's scripted loads as the kernels' :class:`~rod_sim.core.loadlaw.Loads` (rows
    and columns of Extra.forces)."""
    loads = scene.loads

    def row(ld):
        return ld.row(scene) if hasattr(ld, "row") else ld.node - 1

    def col(ld):
        return ld.column if hasattr(ld, "column") else LOAD_AXES.index(ld.axis)

    return make_loads([row(ld) for ld in loads], [col(ld) for ld in loads],
                      [ld.shape for ld in loads], [ld.amplitude for ld in loads],
                      [ld.start for ld in loads], [ld.duration for ld in loads])


class ChainModel:
    """Shared machinery (implements :class:`Model`); a subclass sets ``name``, ``kernel``,
    ``compiled`` and the state layout, and is registered in :data:`MODELS`.

    Several chains and a base: the rods of every chain are concatenated in scene order (n
    rods in all, ``seg`` marks each chain's first rod), and a free base adds its coordinates
    after the chains' in q: x_B, y_B, psi (the base frame's pose in Oxy) and, with a wheel,
    theta_w (the wheel's angle relative to the base). q has size ``dof``; y = [q, q']."""

    name = "chain"
    kernel = None
    compiled: Compiled
    dof_per_rod = 1

    def __init__(self, scene: Scene):
        self.scene = scene
        self.params = ChainParams.from_scene(scene)
        p = self.params
        self.n = p.n
        self.seg, attach = chain_layout(scene)
        base, motion = base_table(scene)
        self.base_mode = int(base[kernels.B_MODE])
        self.nb = int(base[kernels.B_NB])
        self.chain = kernels.make_chain(p.l, p.m, p.mu, p.EI, p.kappa, p.nu, self.seg, attach,
                                        base, motion)
        self.prev = np.asarray(self.chain.prev)
        self.first = self.prev < 0                  # each chain's first rod (hinge 0)
        self.loads = load_table(scene)
        self._bound_types: dict[int, object] = {}
        """id of a plan of :attr:`_plans` -> numba type of its Extra with scratch bound in."""
        kr = p.kappa * np.asarray(scene.hinge_rest_angle, dtype=float)
        kr_next = np.append(kr[1:], 0.0)
        kr_next[np.append(self.first[1:], True)] = 0.0
        # rest-angle generalized forces kappa theta_rest dDelta/dq on phi, alpha, beta
        self._rest = np.array([kr - kr_next, kr, -kr_next])
        self._stops = np.array([scene.stop_lower, scene.stop_upper, scene.stop_stiffness,
                                scene.stop_damping], dtype=float)
        self._plans: dict = {}
        self.has_latches = bool(np.isfinite(scene.latch_angle).any())
        self.has_stops = bool(np.any(np.isfinite(scene.stop_lower)
                                     | np.isfinite(scene.stop_upper)))
        """Whether any hinge has a finite stop (else no contact ever: contact_state is 0)."""
        self.extra = self.plan().extra         # the features of the unlatched mode (no scratch)
        self._layout()

    def _layout(self) -> None:
        """Constants of the per-state laws (:class:`~rod_sim.core.state.State`): where the
        chains' rods and nodes are and which shortcuts the base allows."""
        k, b = kernels, self.chain.base
        self.table = chain_table(self.seg)
        """The chains' :class:`~rod_sim.core.kinematics.ChainTable`."""
        self.rod_starts = self.table.ends - 1
        """Row of :meth:`node_positions` where each rod starts (n,) int."""
        self._first_rods = np.flatnonzero(self.first)
        self._before = np.maximum(np.arange(self.n) - 1, 0)     # rod k - 1 (0 for rod 0)
        one_fixed = self.base_mode == k.MODE_FIXED and len(self.seg) == 2
        self._plain_powers = self._plain_rates = one_fixed
        self.paired_balance = self.dof_per_rod != 3
        """Whether a balance sample evaluates its two moved states in one call
        (:meth:`~rod_sim.core.state.State.moved_net_powers`): any base, number of chains and
        hinge features, no slope rates in the state (the reduced and rigid models)."""
        self._plain_angles = one_fixed and b[k.B_PSI] == 0.0
        self._plain_nodes = one_fixed and not b[k.B_X:k.B_PSI + 1].any() \
            and not self.chain.attach.any()
        self._moving_hinge0 = bool(self.nb) or not one_fixed
        self._turned_hinge0 = self._moving_hinge0 or b[k.B_PSI] != 0.0
        self.prescribed_base = self.base_mode == k.MODE_PRESCRIBED
        """Whether the base follows a prescribed motion (its pose and twist depend on t)."""
        self._fixed_base = BaseState(float(b[k.B_X]), float(b[k.B_Y]), float(b[k.B_PSI]),
                                     0.0, 0.0, 0.0)
        self.scripted_loads = bool(self.loads.row.size)
        """Whether the scene has scripted loads (else the loads are the held inputs alone)."""
        self.breakpoints = tuple(self.scene.load_breakpoints())
        """Times [s] where a scripted load or one of its derivatives jumps."""
        self.neg_l = -self.params.l
        self.attach_columns = (self.chain.attach[:, 0].copy(), self.chain.attach[:, 1].copy())
        """The chains' attach points in the base frame: (x (nc,), y (nc,)) [m]."""
        self.base_com_offset = (float(b[k.B_CX]), float(b[k.B_CY]))
        """The base's centre of mass in its frame (x, y) [m]."""
        self.rod_constants = RodConstants.of(self.params)
        """Per-rod factors of the per-state laws (:class:`RodConstants`)."""

    slopes_need_rhs = False
    """Whether :meth:`bending` solves the right-hand side (then a :class:`State` keeps both)."""

    def state(self, t: float, y: np.ndarray, held=None, mode=None, f=None,
              bending=None, data: ModelData | None = None) -> State:
        """The model's quantities at (t, y, held, mode), each computed once on first use
        (:class:`~rod_sim.core.state.State`); ``f`` = dy/dt and ``bending`` = (alpha, beta)
        there if known; ``data``: scratch for its right-hand side (a simulator's own, between
        its steps; None: fresh)."""
        return State(self, t, y, held, mode, f, bending, data)

    def new_data(self) -> ModelData:
        """Fresh scratch for one user of this model (a simulator, a thread):
        :class:`ModelData`."""
        return ModelData(self)

    def _pinned(self) -> np.ndarray:
        """Rods whose end slopes are zero (n,) bool: the scene's rigid rods."""
        return np.asarray(self.scene.rod_rigid, dtype=bool)

    # ----- layout -----
    @property
    def state_size(self) -> int:
        return 2 * self.dof

    @property
    def dof(self) -> int:
        return self.dof_per_rod * self.n + self.nb

    @property
    def base_index(self) -> int:
        """Index of x_B in q (a free base; the chains' coordinates come first)."""
        return self.dof_per_rod * self.n

    def initial_state(self) -> np.ndarray:
        """State at t = 0 from the scene's initial phi, phi_rate (bending at rest) and a free
        base's initial pose and twist (wheel at angle 0 with its rate), velocities projected
        onto the locked hinges' constraint."""
        y = np.zeros(self.state_size)
        y[:self.n] = self.scene.phi0
        y[self.dof:self.dof + self.n] = self.scene.phi_rate0
        if self.nb:
            b, i, d = self.scene.base, self.base_index, self.dof
            y[i:i + 3] = b.x, b.y, b.psi
            y[d + i:d + i + 3] = b.x_rate, b.y_rate, b.psi_rate
            if self.nb > 3:
                y[d + i + 3] = b.wheel.rate
        return self.project_velocity(y)

    def phi(self, y: np.ndarray) -> np.ndarray:
        """Rod angles (n,) [rad] (y may be (..., state_size))."""
        return y[..., :self.n]

    def phi_rate(self, y: np.ndarray) -> np.ndarray:
        """Rod angular rates (n,) [rad/s]."""
        return y[..., self.dof:self.dof + self.n]

    def base_state(self, t: float, y: np.ndarray) -> BaseState:
        """The base frame's pose and twist at (t, y) (a fixed base: its constant pose)."""
        k, b = kernels, self.chain.base
        if self.base_mode == k.MODE_FREE:
            i, d = self.base_index, self.dof
            w = float(y[d + i + 3]) if self.nb > 3 else 0.0
            x, yb, psi = y[i:i + 3].tolist()
            vx, vy, wz = y[d + i:d + i + 3].tolist()
            return BaseState(x, yb, psi, vx, vy, wz, w)
        if self.base_mode == k.MODE_PRESCRIBED:
            vals = [k.motion_eval(self.chain.motion, r, float(t)) for r in range(3)]
            return BaseState(b[k.B_X] + vals[0][0], b[k.B_Y] + vals[1][0],
                             b[k.B_PSI] + vals[2][0], vals[0][1], vals[1][1], vals[2][1])
        return self._fixed_base

    def _base_angle(self, y: np.ndarray, t: float = 0.0) -> tuple:
        """(psi, psi_rate) of the base for hinge angles (y may be (..., state_size))."""
        if self.base_mode == kernels.MODE_FREE:
            i, d = self.base_index, self.dof
            return y[..., i + 2], y[..., d + i + 2]
        if self.base_mode == kernels.MODE_PRESCRIBED:
            st = self.base_state(t, y)
            return st.psi, st.psi_rate
        return float(self.chain.base[kernels.B_PSI]), 0.0

    def _relative(self, a: np.ndarray, psi) -> np.ndarray:
        """a_k - a_{prev(k)} along the last axis, a_k - psi at each chain's first rod."""
        a = np.asarray(a)
        first = self._first_rods
        if a.ndim == 1 and a.dtype == np.float64:
            out = a - a[self._before]
            out[first] = a[first] - psi
            return out
        out = np.empty(a.shape, dtype=np.result_type(a.dtype, np.float64))
        np.subtract(a[..., 1:], a[..., :-1], out=out[..., 1:])
        out[..., first] = a[..., first] - np.asarray(psi)[..., None] if np.ndim(psi) else \
            a[..., first] - psi
        return out

    def hinge_angles(self, y: np.ndarray, t: float = 0.0) -> np.ndarray:
        """Rigid hinge angles theta (..., n) [rad]: phi_{k+1} - phi_k inside a chain, phi_1 -
        psi at its hinge 0 (psi the base's angle; 0 for a scene without a base)."""
        if self._plain_angles:
            return hinges.hinge_angles(self.phi(y))
        return self._relative(self.phi(y), self._base_angle(y, t)[0])

    def hinge_rates(self, y: np.ndarray, t: float = 0.0) -> np.ndarray:
        """Rates of :meth:`hinge_angles` [rad/s]."""
        if self._plain_rates:
            return hinges.hinge_angles(self.phi_rate(y))
        return self._relative(self.phi_rate(y), self._base_angle(y, t)[1])

    # ----- mode -----
    def plan(self, mode: np.ndarray | None = None, contact: np.ndarray | None = None) -> Plan:
        """The kernels' arguments and the event table with the latches ``mode`` (n,) bool
        fired (None: none) and the stop contacts ``contact`` (n,) int (+1 upper, -1 lower,
        0 free; None: all free). Constants, cached per mode (a pure function of it); a
        compiled call needs them with scratch bound in: :meth:`ModelData.plan`."""
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
                                   kind=self._kind, nchains=len(self.seg) - 1)
        extra = extra._replace(**dict.fromkeys(SCRATCH_FIELDS))    # constants only
        other = self.prev.copy()
        offset = None
        if self.base_mode == kernels.MODE_FREE:
            other[self.first] = self.base_index + 2
        elif self.chain.base[kernels.B_PSI] != 0.0:
            offset = np.where(self.first, float(self.chain.base[kernels.B_PSI]), 0.0)
        # a prescribed base's psi(t) = psi_0 + p(t): hinge 0's event functions subtract p(t)
        # by the kernels' own profile (Chain.motion's psi row; zeros unless prescribed)
        return Plan(extra, hinges.event_table(self.scene, locked, other, offset,
                                              self.chain.motion[kernels.MO_PSI]), locked)

    # ----- evaluation -----
    def forces(self, t: float, held: np.ndarray | None = None) -> np.ndarray:
        """Applied nodal forces (n, 2) [N] at t: held command plus scripted loads."""
        return self.loads_at(t, held)[:self.n, :2].copy()

    def loads_at(self, t: float, held: np.ndarray | None = None) -> np.ndarray:
        """Every applied load (n + 2, 3) at t (rows as :meth:`_held`): held inputs plus
        scripted loads, by the kernels' one scripted-load law."""
        return self.loads_of(t, self._held(held))

    def loads_of(self, t: float, rows: np.ndarray) -> np.ndarray:
        """:meth:`loads_at` from the kernels' held inputs ``rows`` (n + 2, 3) (:meth:`_held`;
        read only): the held inputs plus the scripted loads at t (a new array)."""
        out = np.empty((self.n + 2, 3))         # every element written
        kernels.load_forces(t, self.loads, rows, t, out)
        return out

    def _held(self, held):
        """The kernels' held inputs (n + 2, 3): rows 0..n-1 nodal forces X, Y [N] and hinge
        motor moments T [N m]; row n the base's Fx, Fy [N] (inertial, at its centre of mass)
        and moment [N m]; row n + 1 the wheel's motor torque in column 2 [N m]. From None
        (zeros), forces (n, 2) or flat (2n,), (n, 3) or (n + 2, 3)."""
        out = np.zeros((self.n + 2, 3))
        if held is None:
            return out
        h = np.asarray(held, dtype=float)
        if h.size == 3 * (self.n + 2):
            out[:, :] = h.reshape(self.n + 2, 3)
        elif h.size == 3 * self.n:
            out[:self.n, :] = h.reshape(self.n, 3)
        else:
            out[:self.n, :2] = h.reshape(self.n, 2)
        return out

    def contact_state(self, y: np.ndarray, t: float = 0.0) -> np.ndarray:
        """Stop contacts (n,) int8 implied by the state y at time t [s] (t matters on a
        prescribed base, whose psi(t) hinge 0 measures against): +1 above the upper stop (or
        on it and moving in), -1 below the lower one (or on it and moving in), 0 otherwise."""
        if not self.has_stops:      # every stop at -inf / +inf: never touched
            return np.zeros(self.n, dtype=np.int8)
        return self.contact_of(self.hinge_angles(y, t), self.hinge_rates(y, t))

    def contact_of(self, theta: np.ndarray, rate: np.ndarray) -> np.ndarray:
        """:meth:`contact_state` from the hinge angles theta (n,) [rad] and their rates."""
        s = self.scene
        up = (theta > s.stop_upper) | ((theta == s.stop_upper) & (rate > 0.0))
        down = (theta < s.stop_lower) | ((theta == s.stop_lower) & (rate < 0.0))
        return (up.astype(np.int8) - down.astype(np.int8)).astype(np.int8)

    def rhs(self, t: float, y: np.ndarray, held: np.ndarray | None = None,
            mode: np.ndarray | None = None, contact: np.ndarray | None = None,
            data: ModelData | None = None) -> np.ndarray:
        """dy/dt (state_size,) at time t [s] with held inputs (see :meth:`_held`) in ``mode``
        with the stop contacts ``contact`` (None: as implied by y), in the scratch of
        ``data`` (None: fresh scratch)."""
        return self._evaluate(t, y, held, mode, contact, data)[0]

    def _evaluate(self, t, y, held=None, mode=None, contact=None, data=None):
        """(dy/dt, the kernel's Extra after the call) at (t, y) in scratch of ``data`` (None:
        fresh scratch, so that a shared model is never written to)."""
        out = np.empty(self.state_size)
        y = np.ascontiguousarray(y, dtype=float)
        if y.shape != out.shape:        # the kernel does not check its bounds
            raise ValueError(f"y: a state of {self.name} model has {self.state_size} "
                             f"components, got shape {y.shape}")
        side = self.contact_state(y, t) if contact is None else contact
        if data is None:
            extra = self.new_data().plan(mode, side).extra
            self.kernel(t, y, self.chain, extra, self.loads, self._held(held), t, out)
            return out, extra
        plan = data.plan(mode, side)
        t = float(t)
        chain_type, loads_type, held_type, out_type = self._arg_types
        typed_call.call(self.kernel, (typed_call.FLOAT64, typed_call.array_type(y), chain_type,
                                      data.extra_type(plan), loads_type, held_type,
                                      typed_call.FLOAT64, out_type),
                        t, y, self.chain, plan.extra, self.loads, self._held(held), t, out)
        return out, plan.extra

    def bound_extra_type(self, const: Plan, bound: Plan):
        """The numba type of ``bound.extra``: ``const`` (one of this model's plans) with a
        :class:`ModelData`'s scratch bound in. Found once per plan of the model: every
        ModelData's scratch arrays are made alike (dtype, rank, C order, writeable)."""
        found = self._bound_types.get(id(const))       # _plans keeps const: its id is stable
        if found is None:
            found = self._bound_types[id(const)] = typed_call.typeof(bound.extra)
        return found

    @functools.cached_property
    def _arg_types(self) -> tuple:
        """numba types of the kernels' Chain and Loads (constants of the model) and of the
        held rows (n + 2, 3) and dy/dt arrays made for each call (:mod:`typed_call`)."""
        return (typed_call.typeof(self.chain), typed_call.typeof(self.loads),
                typed_call.array_type(np.zeros((self.n + 2, 3))),
                typed_call.array_type(np.empty(self.state_size)))

    _kind = kernels.KIND_REDUCED

    def _velocities_full(self, y, v=None) -> np.ndarray:
        """The velocities in the full model's layout (3n + nb,): [phi', alpha', beta', base']
        from the model's own (dof,) (zero slope rates for the rigid and reduced models)."""
        v = y[self.dof:] if v is None else np.asarray(v, dtype=float)
        if self.dof_per_rod == 3:
            return v
        out = np.zeros(3 * self.n + self.nb)
        out[:self.n] = v[:self.n]
        out[3 * self.n:] = v[self.n:]
        return out

    def _model_rows(self, f3: np.ndarray) -> np.ndarray:
        """The model's (dof,) rows of a full-layout (3n + nb,) vector."""
        if self.dof_per_rod == 3:
            return f3
        return np.concatenate([f3[:self.n], f3[3 * self.n:]])

    def mass_times(self, y: np.ndarray, v: np.ndarray | None = None) -> np.ndarray:
        """M v (dof,) for velocities v (dof,) (default y's own) with M the paper's inertia
        matrix of the model's coordinates at y (rigid and reduced: m^{phi phi}; with a free
        base its rows and columns), in O(n)."""
        v = y[self.dof:] if v is None else v
        psi = self._base_angle(y)[0] if self.nb else 0.0
        if not self.nb:
            return kernels.inertia_times(self._kind, self.chain, self.phi(y), v)[:self.dof]
        out = kernels.inertia_times(self._kind, self.chain, self.phi(y),
                                    self._velocities_full(y, v), psi)
        return self._model_rows(out)

    def project_velocity(self, y: np.ndarray, mode: np.ndarray | None = None,
                         t: float = 0.0) -> np.ndarray:
        """y with its velocities replaced by the impulsive-constraint projection
        x'+ = T (T^T M T)^{-1} T^T M x'- (M-orthogonal for a symmetric M) in ``mode``, with T
        a basis of the locked hinges' constraints (the reduced model: M = M_r of eq. (15)),
        solved in O(n) by the kernels' chain solve with f = M x'- (a free base moves with
        the chains: momentum is kept).

        On a prescribed base (infinite mass, its motion unchanged by the impact) a locked
        hinge 0 holds phi_1' = psi'(t) at time t [s], a constraint C x' = c(t) that is not
        homogeneous: the projection acts on the velocities relative to the base's rotation,
        x' - psi' r (r: every rod's phi' = 1, a rigid turn with the base, so that C r = 1 at a
        hinge 0 and 0 at the other hinges), and psi' r is added back; the base's own velocity
        terms of the impulse balance cancel (it does not jump)."""
        plan = self.new_data().plan(mode)
        out = np.array(y, dtype=float)
        if not plan.locked.any() and not (self.dof_per_rod == 3 and self._pinned().any()):
            return out
        n, d = self.n, self.dof
        turn = 0.0
        if self.prescribed_base and (plan.locked & self.first).any():
            turn = self.base_state(t, y).psi_rate
            out[d:d + n] -= turn
        phi = np.ascontiguousarray(self.phi(y), dtype=float)
        psi = float(self._base_angle(y)[0]) if self.nb else 0.0
        # reduced: (A v, m^{gamma phi} v) as right-hand sides give M_r x = M_r v
        f = kernels.inertia_times(kernels.KIND_FULL, self.chain, phi,
                                  self._velocities_full(out), psi)
        if self.name == "rigid":
            f[n:3 * n] = 0.0
        x = np.empty(3 * n)
        fb = np.zeros(4)
        fb[:self.nb] = f[3 * n:]
        xb = np.zeros(4)
        if not kernels.solve_with(self._kind, phi, self.chain, plan.extra, f[:n], f[n:2 * n],
                                  f[2 * n:3 * n], x[:n], x[n:2 * n], x[2 * n:], fb, xb, psi):
            raise np.linalg.LinAlgError("singular mass matrix in the velocity projection")
        if self.nb:
            x_all = np.concatenate([x[:self.dof_per_rod * n], xb[:self.nb]])
            out[d:] = x_all
        else:
            out[d:] = x[:d]
        if turn != 0.0:
            out[d:d + n] += turn
        return out

    def bending(self, t, y, held=None, mode=None) -> tuple[np.ndarray, np.ndarray]:
        """End slopes (alpha, beta), each (n,) [rad]."""
        raise NotImplementedError

    def rhs_bending(self, t, y, held=None, mode=None, contact=None,
                    data=None) -> tuple[np.ndarray, tuple]:
        """(:meth:`rhs`, :meth:`bending`) at (t, y): dy/dt (state_size,) and (alpha, beta)
        (n,) each [rad], the same values as the two calls give (a sample needs both: the
        snapshot and the energy balance's power rate; the reduced model gets both from one
        right-hand side); ``contact`` and ``data`` as :meth:`rhs` takes them."""
        return self.rhs(t, y, held, mode, contact, data), self.bending(t, y, held, mode)

    def bending_rates(self, t, y, held=None) -> tuple[np.ndarray, np.ndarray]:
        """Rates of the end slopes as the model's equations carry them [rad/s]."""
        return np.zeros(self.n), np.zeros(self.n)

    def hinge_deflection(self, t, y, held=None, bending=None, mode=None):
        """Relative hinge rotations Delta phi_h of eq. (2) and their rates, each (n,).
        ``bending`` = (alpha, beta) if already known at (t, y, held)."""
        return State(self, t, y, held, mode, bending=bending).deflection

    def hinge_deflection_rate(self, t, y, held=None) -> np.ndarray:
        """d/dt Delta phi_h (n,) [rad/s] (the reduced and rigid models carry no bending rates)."""
        return State(self, t, y, held).deflection_rate

    def contact_moments(self, y: np.ndarray, mode=None) -> np.ndarray:
        """Stop contact moments (n,) [N m] on theta (zero on locked hinges)."""
        return State(self, 0.0, y, None, mode).contact_moments

    def kinetic_energy(self, t, y, held=None) -> float:
        """(1/2) x'^T M x' [J] (rigid and reduced: rod motion only; a free base and its wheel
        included; on a prescribed base the chains' motion with their node 0's velocity
        v_0: + v_0 . P_rel + M_c |v_0|^2 / 2 per chain, P_rel = sum_j (l_j M_j phi_j' +
        C_j (alpha_j' - beta_j')) e_j^perp), O(n)."""
        return State(self, t, y, held).kinetic_energy

    def gravity_energy(self, t, y, bending=None) -> float:
        """-sum m g.r over every mass point [J] (rods with their ``bending`` (alpha, beta),
        None: straight; node masses, a free base), 0 without gravity."""
        return State(self, t, y).gravity_energy_with(bending)

    def _base_com(self, st: BaseState) -> np.ndarray:
        b = self.chain.base
        c, s = np.cos(st.psi), np.sin(st.psi)
        return np.array([st.x + c * b[kernels.B_CX] - s * b[kernels.B_CY],
                         st.y + s * b[kernels.B_CX] + c * b[kernels.B_CY]])

    def _node_index_of_rod_start(self) -> np.ndarray:
        """Row of :meth:`node_positions` where each rod starts (n,) int (:attr:`rod_starts`)."""
        return self.rod_starts

    def node_positions(self, t: float, y: np.ndarray) -> np.ndarray:
        """Every chain's nodes 0..n_c in scene order, (n + nc, 2) [m] (one chain: (n + 1, 2),
        node 0 at its attach point on the base)."""
        return State(self, t, y).nodes

    def energies(self, t: float, y: np.ndarray, held=None, bending=None, mode=None) -> Energies:
        """Kinetic, hinge (springs about their rest angles + stop contacts), bending and
        gravity energy [J] at (t, y); ``bending`` = (alpha, beta) if already known at (t, y,
        held)."""
        return State(self, t, y, held, mode, bending=bending).energies

    def node_velocities(self, t: float, y: np.ndarray) -> np.ndarray:
        """Velocities of the nodes of :meth:`node_positions` (n + nc, 2) [m/s]."""
        return State(self, t, y).velocities

    def powers(self, t: float, y: np.ndarray, held=None, mode=None) -> tuple[float, float]:
        """(power of the applied loads and motors — nodal forces, hinge motors, gravity is in
        the energy — and of a free base's loads and wheel motor; power dissipated in the
        hinge dampers and the stop contacts) [W]."""
        return State(self, t, y, held, mode).powers

    def momentum(self, t: float, y: np.ndarray, held=None) -> Momentum:
        """Linear and angular momentum of the whole system and its centre of mass, O(n): node
        masses, a free base and its wheel, and the rods as the model moves them — the rigid
        and reduced models their chords (the quantities they conserve: their inertia is the
        chords'), the full model the bent rods of eq. (4) with their bending rates."""
        return State(self, t, y, held).momentum

    def snapshot(self, t: float, y: np.ndarray, held=None, mode=None, bending=None,
                 state: State | None = None) -> Snapshot:
        """Everything published about the chain at (t, y). hinge_moment = kappa (Delta -
        theta_rest) + nu Delta' minus the stop contact moment (the constraint reaction of a
        locked hinge is not included). ``bending`` = (alpha, beta) if already known at (t, y,
        held, mode); ``state``: the :class:`~rod_sim.core.state.State` of these arguments, if
        one is kept (its quantities are shared; the other arguments are then ignored)."""
        s = State(self, t, y, held, mode, bending=bending) if state is None else state
        return s.snapshot()

    @property
    def is_spacecraft(self) -> bool:
        """A scene with a ``base:``, ``chains:`` or ``gravity:`` (its snapshots carry the base,
        the momentum and the energy terms; a plain chain's snapshot is what it always was)."""
        return self.scene.is_spacecraft

    def base_energies(self, t: float, y: np.ndarray) -> tuple[float, float]:
        """(kinetic energy of a free base: m_B |v_C|^2 / 2 + J_B psi'^2 / 2, of its wheel:
        J_W (psi' + theta_w')^2 / 2) [J]; zeros for a fixed or prescribed base."""
        return State(self, t, y).base_energies


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
    slopes_need_rhs = True

    def bending(self, t, y, held=None, mode=None):
        """gamma = (alpha, beta) (n,) each [rad] from the quasi-static rows of (14), which the
        kernel solves together with phi'' (left in its work array)."""
        return self.rhs_bending(t, y, held, mode)[1]

    def rhs_bending(self, t, y, held=None, mode=None, contact=None, data=None):
        """dy/dt and gamma = (alpha, beta) from one right-hand side (its work array)."""
        f, extra = self._evaluate(t, y, held, mode, contact, data)
        W = extra.work
        return f, (W[:, kernels.W_A].copy(), W[:, kernels.W_B].copy())


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
        d = self.dof
        return np.array(y[d + n:d + 2 * n]), np.array(y[d + 2 * n:d + 3 * n])

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
