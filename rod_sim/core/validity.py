"""Validity monitor: is the chosen model still right for what the scene is doing?

Pure (numpy only). Three checks, each giving :class:`Finding` records:

- **small bending**: |alpha|, |beta| above :data:`SMALL_BENDING_RAD`. The shape functions (1)
  are linear small-deflection beam theory: the curvature is taken as w'' instead of
  w'' / (1 + w'^2)^(3/2) (relative error ~ 3/2 theta^2: 6 % at 0.2 rad) and the chord is
  assumed not to shorten (relative shortening ~ theta^2 / 15: 0.3 % at 0.2 rad). 0.2 rad keeps
  the neglected geometric terms at a few per cent of the bending moments.
- **load spectrum near the first bending mode**: the reduced model drops the bending inertia,
  so it is only right while the loads change slowly compared with the first bending mode
  f1 of the rods. A harmonic load at f gives a dynamic amplification 1 / (1 - (f/f1)^2), i.e.
  the quasi-static bending is wrong by ~ (f/f1)^2: :data:`FREQUENCY_RATIO_WARN` = 0.1 keeps that
  below 1 %. A raised cosine pulse of duration D has its spectrum below ~2/D (main lobe); a
  jump of the forces (step loads, held commands changing at a control rate) excites every
  mode: the bending vibration it starts has the amplitude of the quasi-static slope jump, which
  :func:`force_jump_slopes` computes and :data:`JUMP_SLOPE_WARN_RAD` judges (the node gives
  the monitor that jump instead, from the slopes it solved on both sides of it, and the
  finding's time is the start of the period where the held inputs changed:
  :meth:`ValidityMonitor.update`'s ``jump``).
- **energy balance**: E - E0 - integral(P_load - P_damper + P_unpaired) dt + (kinetic energy
  lost in latch impacts) relative to the energy scale above :data:`ENERGY_RESIDUAL_WARN`
  (:class:`EnergyBalance`, fed with :func:`balance_sample` s; E includes the stop contacts'
  elastic energy, P_damper their damping, both with the latched hinges locked; P_unpaired is
  the power of the full model's velocity term that E does not account for,
  :func:`unpaired_power`). The integral is the trapezoid rule over the samples corrected by the
  powers' time derivatives, split at the hinge events where the power jumps, and by parts for
  the unpaired term where the samples do not resolve the first bending mode, so the residual is
  integration and quadrature error (docs/energy.md: figures of the shipped scenes). The
  reduced model conserves E only to first order in the bending (see test_physics), so there a
  growing residual also means the bending is no longer small.

Entry points: :func:`bending_frequencies` (per-rod, analytic), :func:`chain_bending_frequency`
(the full model's linearization), :func:`assess_trajectory` (a whole run: the hard-case
catalogue, the tests), :class:`ValidityMonitor` (incremental: ``simulate`` per sample, the node
per control period) and :class:`EnergyBalance` with :func:`balance_sample` (the energy ledger
both of them keep).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SMALL_BENDING_RAD = 0.2
"""[rad] largest end slope for which the small-bending shape functions are trusted."""
FREQUENCY_RATIO_WARN = 0.1
"""Load frequency / first bending frequency above which the quasi-static reduction is off by
more than ~1 %."""
JUMP_SLOPE_WARN_RAD = 1e-3
"""[rad] jump of the quasi-static end slopes (caused by a jump of the forces) above which the
unmodelled bending vibration is reported."""
ENERGY_RESIDUAL_WARN = 1e-2
"""Energy balance residual / energy scale above which the run is reported."""
ENERGY_FLOOR = 1e-10
"""Residuals below this fraction of the chain's reference energy (:func:`reference_energy`)
are round-off, never reported: a chain at rest has an energy scale of ~1e-13 J of noise, and
its ratio to the residual means nothing (measured: 0.99, n = 2048 at rest)."""


CHAIN_MODE_MAX_RODS = 4096
"""Largest chain whose first bending mode :func:`chain_bending_frequency` solves for."""


def reference_energy(scene) -> float:
    """[J] an energy of the chain's size: sum kappa_h + m_k l_k^3 / 3 + mu_k l_k^2, the hinge
    stiffnesses plus the moments of inertia of each rod and its end node about the rod's left
    end (twice the energy of every hinge bent by 1 rad and every rod turning at 1 rad/s)."""
    l = np.asarray(scene.length, float)
    return float(np.sum(np.asarray(scene.hinge_stiffness, float))
                 + np.sum(np.asarray(scene.mass_per_length, float) * l**3) / 3.0
                 + np.sum(np.asarray(scene.node_mass, float) * l**2))


@dataclass(frozen=True)
class Finding:
    """One validity warning: ``kind`` ('bending', 'frequency', 'force_jump', 'energy'), the
    simulated time ``t`` [s] (first occurrence), the rod 1..n (0 = the whole chain), the
    measured ``value`` and the ``limit`` it crossed, and a one-line ``message``."""

    kind: str
    t: float
    rod: int
    value: float
    limit: float
    message: str


def bending_frequencies(scene) -> np.ndarray:
    """First bending eigenfrequency of each rod [Hz] (n,), chord held fixed.

    With the slopes (alpha, beta) of the shape functions (1) and the chord fixed, the rod's
    mass matrix is m l^3 [[1/105, -1/140], [-1/140, 1/105]] and its stiffness
    2 EI / l [[2, 1], [1, 2]]; the antisymmetric mode alpha = -beta gives
    omega^2 = 120 EI / (m l^4) (the exact pinned-pinned beam has pi^4 = 97.4 instead of 120).
    Massless rods have no bending inertia: inf."""
    EI = np.asarray(scene.bending_stiffness, float)
    m = np.asarray(scene.mass_per_length, float)
    l = np.asarray(scene.length, float)
    with np.errstate(divide="ignore"):
        omega = np.sqrt(120.0 * EI / (m * l**4))
    return omega / (2.0 * math.pi)


def chain_bending_frequency(scene, phi=None) -> float:
    """Lowest eigenfrequency [Hz] of the full model linearized about ``phi`` (default the
    initial angles, at rest, no load) whose mode is mostly bending (more than half of its
    modal kinetic energy in alpha, beta). inf if a rod is massless.

    K is the elastic stiffness (hinge springs and bending; the prestress of a bent
    configuration and the stop contacts left out), M the inertia at phi; the modes come from
    :func:`rod_sim.core.linearization.lowest_bending_mode`: O(n) per iteration (shift-invert
    Lanczos on the chain solve), dense only for a few rods. The Lanczos iterations grow with
    the chain (0.5 s at 3000 rods, 40 s at 10 000): above :data:`CHAIN_MODE_MAX_RODS` rods
    (and ``phi`` not given) the lowest single-rod analytic frequency, with the chord held
    fixed (:func:`bending_frequencies`) stands for it (paper's rods, n = 1000 and 3000: 79.5775
    Hz against the chain's 79.5777 Hz), so that the node and ``simulate`` start in O(n)."""
    from .linearization import lowest_bending_mode
    from .models import FullModel  # local: the models import nothing from here

    if np.any(np.asarray(scene.mass_per_length) <= 0.0):
        return math.inf
    if scene.n > CHAIN_MODE_MAX_RODS and phi is None:
        return float(np.min(bending_frequencies(scene)))
    model = FullModel(scene.with_changes(loads=()))
    phi0 = np.asarray(scene.phi0 if phi is None else phi, dtype=float)
    guess = 2.0 * math.pi * float(np.min(bending_frequencies(scene)))
    return lowest_bending_mode(model, phi0, guess) / (2.0 * math.pi)


def load_frequency(scene) -> float:
    """Highest characteristic frequency [Hz] of the scripted loads: 2 / duration for a raised
    cosine pulse (edge of its spectrum's main lobe); inf for a step or a constant load switched
    on (a jump; judged by :func:`force_jump_slopes` instead); 0 without loads."""
    f = 0.0
    for ld in scene.loads:
        if ld.shape == "raised_cosine_pulse":
            f = max(f, 2.0 / ld.duration)
        elif ld.amplitude != 0.0:
            f = math.inf
    return f


def force_jump_slopes(scene, y_phi, phi_rate, before, after, y=None) -> np.ndarray:
    """|jump| of the quasi-static end slopes (2n,) [rad] when the held inputs jump from
    ``before`` to ``after`` (each (n, 2) nodal forces [N], or (n, 3) with the hinge motor
    moments T [N m]) at the rod angles/rates given (or at the reduced model's whole state
    ``y``, which a free base needs: its pose and rates are part of it): the amplitude of the
    bending vibration that such a jump starts (and the reduced model does not carry)."""
    model = _reduced_cache(scene)
    if y is None:
        y = np.concatenate([np.asarray(y_phi, float), np.asarray(phi_rate, float)])
    a0, b0 = model.bending(0.0, y, before)
    a1, b1 = model.bending(0.0, y, after)
    return np.abs(np.concatenate([a1 - a0, b1 - b0]))


_CACHE: dict = {}


def _reduced_cache(scene):
    from .models import ReducedModel

    key = id(scene)
    hit = _CACHE.get(key)
    if hit is None or hit[0] is not scene:
        if len(_CACHE) > 8:
            _CACHE.clear()
        hit = (scene, ReducedModel(scene.with_changes(loads=())))
        _CACHE[key] = hit
    return hit[1]


def frequency_findings(scene, model_name: str, command_rate_hz: float | None = None,
                       f1: float | None = None) -> list[Finding]:
    """Static check of the scene's load spectrum against the first bending mode (only the
    reduced model relies on the quasi-static bending; the rigid model has none, the full model
    carries the bending dynamics)."""
    if model_name != "reduced":
        return []
    f1 = chain_bending_frequency(scene) if f1 is None else f1
    out = []
    fl = load_frequency(scene)
    if math.isfinite(fl) and fl > FREQUENCY_RATIO_WARN * f1:
        out.append(Finding("frequency", 0.0, 0, fl, FREQUENCY_RATIO_WARN * f1,
                           f"scripted loads reach {fl:.3g} Hz, near the first bending mode "
                           f"{f1:.3g} Hz (ratio {fl / f1:.2g} > {FREQUENCY_RATIO_WARN}): the "
                           f"reduced model's quasi-static bending is off; use the full model"))
    if command_rate_hz and command_rate_hz > FREQUENCY_RATIO_WARN * f1:
        out.append(Finding("frequency", 0.0, 0, command_rate_hz, FREQUENCY_RATIO_WARN * f1,
                           f"held commands change at {command_rate_hz:.3g} Hz, near the first "
                           f"bending mode {f1:.3g} Hz: their jumps excite bending vibration "
                           f"the reduced model does not carry"))
    return out


class ValidityMonitor:
    """Incremental validity checks of one run. Feed it every state with :meth:`update`
    (``t`` [s], state ``y``, held forces (n, 2) [N], or held inputs (n, 3) with the hinge
    torques [N m]); :meth:`findings` lists the first
    occurrence of each kind of problem (per rod). ``energy_residual`` [J] and ``energy_scale``
    [J] come from the caller's energy ledger (optional)."""

    def __init__(self, model, command_rate_hz: float | None = None):
        self.model = model
        self.scene = model.scene
        self.f1 = (chain_bending_frequency(self.scene) if model.name == "reduced" else math.inf)
        self._found: dict[tuple[str, int], Finding] = {}
        for f in frequency_findings(self.scene, model.name, command_rate_hz, self.f1):
            self._found[(f.kind, f.rod)] = f
        self.max_abs_alpha = 0.0
        self.max_abs_beta = 0.0
        self._held = None
        self._no_held = np.zeros((model.n, 3))   # the held inputs of a state given none (read only)
        self._energy: Finding | None = None
        self.energy_residual = 0.0      # [J] the residual and scale last judged (update_energy)
        self.energy_scale = 0.0
        self.energy_floor = ENERGY_FLOOR * reference_energy(self.scene)    # [J]

    def _add(self, f: Finding) -> None:
        self._found.setdefault((f.kind, f.rod), f)

    def update(self, t: float, y, held=None, alpha=None, beta=None, jump=None) -> None:
        """Check one state (alpha, beta [rad] may be given to save recomputing them).

        A change of the held inputs since the last update is judged as a jump of the forces
        (:func:`force_jump_slopes`): by default solved here, at this state ``y``, and reported
        at ``t``. ``jump`` = (t_jump [s], |jump of the slopes| (2n,) [rad]): the caller has
        the states on both sides of the change (the node: the end of its last period and the
        start of this one, at the same time and state, with the old and the new held inputs,
        :class:`~rod_sim.ros.period.PeriodRunner`) and gives their slopes' difference, which is
        judged instead, at t_jump (where the jump happened); the held inputs are then not
        compared (the caller says they changed)."""
        n = self.model.n
        given = held
        if given is None:
            held = self._no_held          # the same zeros: no jump from the last such state
        elif np.shape(given) == (n, 3):
            held = np.array(given, dtype=float)      # its own copy
        else:
            held = np.zeros((n, 3))       # forces X, Y and hinge motor moments T
            given = np.asarray(given, float).reshape(n, -1)
            held[:, :given.shape[1]] = given
        if alpha is None or beta is None:
            alpha, beta = self.model.bending(t, y, held)
        a, b = np.abs(alpha), np.abs(beta)
        a_max, b_max = float(a.max(initial=0.0)), float(b.max(initial=0.0))
        self.max_abs_alpha = max(self.max_abs_alpha, a_max)
        self.max_abs_beta = max(self.max_abs_beta, b_max)
        if not (a_max <= SMALL_BENDING_RAD and b_max <= SMALL_BENDING_RAD):  # (or a nan)
            worst = np.maximum(a, b)
            for k in np.flatnonzero(worst > SMALL_BENDING_RAD):
                self._add(Finding("bending", float(t), int(k) + 1, float(worst[k]),
                                  SMALL_BENDING_RAD,
                                  f"rod {k + 1}: end slope {worst[k]:.3g} rad at t = {t:.4g} s "
                                  f"leaves the small-bending range (> {SMALL_BENDING_RAD} rad)"))
        if self.judges_jumps and jump is not None:
            self._judge_jump(*jump)
        elif (self.judges_jumps and self._held is not None and held is not self._held
                and not (held == self._held).all()):
            self._judge_jump(t, force_jump_slopes(self.scene, self.model.phi(y),
                                                  self.model.phi_rate(y), self._held, held,
                                                  y=np.asarray(y, float)))
        self._held = held                 # a fresh array, never written to again

    @property
    def judges_jumps(self) -> bool:
        """Whether jumps of the held inputs are judged (the reduced model only: the full
        model carries the bending vibration they start, the rigid model has none)."""
        return self.model.name == "reduced"

    def _judge_jump(self, t: float, jump) -> None:
        """A ``force_jump`` finding when the largest of the slopes' jumps ``jump`` (2n,)
        [rad] (alpha jumps, then beta jumps) at time ``t`` [s] exceeds
        :data:`JUMP_SLOPE_WARN_RAD`."""
        n = self.model.n
        k = int(np.argmax(jump))
        if jump[k] > JUMP_SLOPE_WARN_RAD:
            self._add(Finding("force_jump", float(t), k % n + 1, float(jump[k]),
                              JUMP_SLOPE_WARN_RAD,
                              f"a jump of the held forces or hinge torques at t = {t:.4g} s "
                              f"starts bending "
                              f"vibration of ~{jump[k]:.2g} rad at rod {k % n + 1} (first "
                              f"bending mode {self.f1:.3g} Hz) that the reduced model "
                              f"does not carry"))

    def update_energy(self, t: float, residual: float, scale: float,
                      unresolved: float = 0.0) -> None:
        """Judge the energy balance residual [J] against the energy scale [J] at time t [s].
        Unlike the other checks this one reflects the latest judgement (not the first
        occurrence): at the start of a run the scale is tiny and the ratio meaningless.
        ``unresolved`` [J] (:attr:`EnergyBalance.unresolved`): a residual no larger than the
        quadrature's own correction is not judged (the samples do not resolve the power)."""
        self._energy = None
        self.energy_residual, self.energy_scale = float(residual), float(scale)
        if scale > 0 and math.isfinite(residual) and abs(residual) > max(
                ENERGY_RESIDUAL_WARN * scale, self.energy_floor, float(unresolved)):
            self._energy = Finding(
                "energy", float(t), 0, abs(residual) / scale, ENERGY_RESIDUAL_WARN,
                f"energy balance residual {residual:.3g} J is {abs(residual) / scale:.2g}"
                f" of the energy scale {scale:.3g} J at t = {t:.4g} s (> "
                f"{ENERGY_RESIDUAL_WARN:g}): integration inaccurate, samples too sparse for "
                f"the energy exchange, or (reduced model) bending not small")

    def findings(self) -> list[Finding]:
        found = list(self._found.values()) + ([self._energy] if self._energy else [])
        return sorted(found, key=lambda f: (f.t, f.kind, f.rod))

    def summary(self) -> str:
        """One line: the findings' messages (first per kind), or '' when all is well."""
        seen, parts = set(), []
        for f in self.findings():
            if f.kind not in seen:
                seen.add(f.kind)
                parts.append(f.message)
        return "; ".join(parts)


def latch_losses(events, t_after: float = -math.inf, t_upto: float = math.inf) -> float:
    """[J] kinetic energy lost in the latch impacts among ``events`` (HingeEvent) with
    t_after <= t < t_upto (a sample at the latch's time is the state before the impact)."""
    return float(sum(e.data.get("kinetic_energy_loss", 0.0) for e in events
                     if e.kind == "latch" and t_after <= e.t < t_upto))


def _coefficients(s) -> np.ndarray:
    """A_j (n,) [kg m^2/s] of the State ``s`` with P_unpaired = -sum_j A_j (alpha_j' - beta_j'):
    A_j = C_j phi_j' sum_{k<j} l_k phi_k' sin(phi_k - phi_j), C_j = m_j l_j^2 / 12 (prefix
    sums, O(n)); on a moving base or with several chains, A_j = -C_j phi_j' e_j . v_{j-1}
    with v_{j-1} the velocity of rod j's first node at the state's time (the same sum plus
    its node 0's: a prescribed base moves it by its motion then)."""
    model = s.model
    n = model.n
    p = model.params
    if _plain(model):
        y = s.y
        phi, dphi = y[:n], y[3 * n:4 * n]
        c, sn = np.cos(phi), np.sin(phi)
        w = p.l * dphi
        before_c = np.concatenate([[0.0], np.cumsum(w * c)[:-1]])      # sum_{k<j}
        before_s = np.concatenate([[0.0], np.cumsum(w * sn)[:-1]])
        return p.m * p.l**2 / 12.0 * dphi * (before_s * c - before_c * sn)
    phi, dphi = s.phi, s.phi_rate
    v = s.velocities[model.rod_starts]
    return -p.m * p.l**2 / 12.0 * dphi * (np.cos(phi) * v[:, 0] + np.sin(phi) * v[:, 1])


def _plain(model) -> bool:
    """One chain on a fixed base at the origin (the paper's layout)."""
    return getattr(model, "base_mode", 0) == 0 and len(getattr(model, "seg", (0, 0))) == 2 \
        and not getattr(model, "nb", 0)


def unpaired_power(model, y, t: float = 0.0) -> float:
    """[W] power of the full model's velocity terms that its energy E does not account for:
    dE/dt = P_load - P_damper + P_unpaired along the model's own equations (rigid and reduced
    models: 0).

    The phi rows of eqs. (9)-(10) carry the Coriolis term 2 [g^{phi alpha}] Lambda alpha_dot
    (and its beta twin) without the partner a Lagrangian with the same kinetic energy would
    have (docs/verification.md); its net power is
    -sum_{k<j} l_k C_j phi_k' phi_j' (alpha_j' - beta_j') sin(phi_k - phi_j), C_j = m_j l_j^2 / 12,
    which is not small when a latch or a stop starts bending vibration: its rates
    alpha' ~ alpha omega_1 do not fall with EI (measured on config/deployment.yaml: the
    integral reaches -0.4 J of 35.8 J at EI = 2e3, 2e4 and 2e5 alike). The identity is checked
    against the model's right-hand side in test_energy_balance. O(n)."""
    return model.state(t, y).value(_unpaired_power)


def _unpaired_power(s) -> float:
    """:func:`unpaired_power` of the State ``s``."""
    model = s.model
    if getattr(model, "dof_per_rod", 1) != 3:
        return 0.0
    n, d = model.n, model.dof
    y = s.y
    return -float(np.dot(s.value(_coefficients), y[d + n:d + 2 * n] - y[d + 2 * n:d + 3 * n]))


def net_power(model, t: float, y, held=None, mode=None, state=None) -> float:
    """[W] P_load - P_damper + P_unpaired at (t, y) with the latched hinges ``mode`` locked:
    the rate of change of the model's mechanical energy between hinge events. ``state``: a
    :class:`~rod_sim.core.state.State` of the arguments to share."""
    return (model.state(t, y, held, mode) if state is None else state).value(_net_power)


def _net_power(s) -> float:
    """:func:`net_power` of the State ``s``."""
    model = s.model
    load, damper = s.powers
    full = getattr(model, "dof_per_rod", 1) == 3
    net = load - damper + (s.value(_unpaired_power) if full else 0.0)
    if _plain(model):
        return net
    if not model.prescribed_base:       # injected_power is 0.0: the same sum
        return net + 0.0
    from .momentum import injected_power        # local: momentum imports the models' kernels

    return net + injected_power(model, s.t, s.y, s.held, s.mode, state=s)


def load_jump_power(model, t: float, y, held=None, state=None) -> float:
    """[W] P_load(t-) - P_load(t+): the load power a span ending at t [s] must use when a
    scripted load jumps exactly at t (a step or a constant load switched on at a sample time;
    :func:`net_power` gives the value after the jump, which starts the next span). 0 elsewhere.
    ``state``: a :class:`~rod_sim.core.state.State` of the arguments to share."""
    if t not in model.breakpoints:
        return 0.0
    from .kernels import load_forces     # local: the kernels are only needed here

    s = model.state(t, y, held) if state is None else state
    n = model.n
    phi, dphi = s.phi, s.phi_rate
    held = model._held(held)
    before, after = np.zeros((n + 2, 3)), np.zeros((n + 2, 3))
    load_forces(t, model.loads, held, math.nextafter(t, -math.inf), before)
    load_forces(t, model.loads, held, t, after)
    d = before - after
    if _plain(model):
        l = model.params.l
        vx = np.cumsum(-l * np.sin(phi) * dphi)
        vy = np.cumsum(l * np.cos(phi) * dphi)
        return float(np.sum(d[:n, 0] * vx + d[:n, 1] * vy))
    v = s.velocities[model.table.ends]
    power = float(np.sum(d[:n, 0] * v[:, 0] + d[:n, 1] * v[:, 1]))
    if model.nb:
        st = s.base
        rc = s.base_com - np.array([st.x, st.y])
        power += float(d[n, 0] * (st.x_rate - st.psi_rate * rc[1])
                       + d[n, 1] * (st.y_rate + st.psi_rate * rc[0])
                       + d[n, 2] * st.psi_rate + d[n + 1, 2] * st.wheel_rate)
    return power


RATE_STEP = 1e-7
"""[s] step of the central differences of :func:`balance_sample`."""


def balance_terms(model, t: float, y, held=None, mode=None, bending=None) -> tuple[float, float]:
    """(total mechanical energy [J], net power [W] of :func:`net_power`) at (t, y) with the
    latched hinges ``mode`` locked (stop contacts included in both)."""
    s = model.state(t, y, held, mode, bending=bending)
    return s.energies.total, s.value(_net_power)


@dataclass(frozen=True)
class BalanceSample:
    """What the energy balance needs of one state (:func:`balance_sample`): time ``t`` [s],
    ``energy`` [J] (nan when the sample only starts a span), net power ``power`` [W] (after a
    load that jumps at t: it starts a span) and ``power_before`` (before it: it ends one),
    ``rate`` [W/s] its time derivative after t
    and ``rate_before`` before t (one-sided at a load breakpoint, where the load's derivative
    may jump; else both the central difference), and of the full model's unpaired term
    (zeros otherwise): ``unpaired``
    [W], ``unpaired_rate`` [W/s], ``boundary`` = -sum_j A_j u_j [J] and ``remainder`` =
    sum_j A_j' u_j [W] (u = alpha - beta; the integral of the unpaired power by parts)."""

    t: float
    energy: float
    power: float
    power_before: float
    rate: float
    rate_before: float
    unpaired: float = 0.0
    unpaired_rate: float = 0.0
    boundary: float = 0.0
    remainder: float = 0.0


def balance_sample(model, t: float, y, held=None, mode=None, bending=None,
                   f=None, state=None, energy: bool = True) -> BalanceSample:
    """The :class:`BalanceSample` of state ``y`` at ``t`` [s] with held inputs ``held`` and the
    latched hinges ``mode`` locked (``bending`` = (alpha, beta) and ``f`` = the right-hand
    side dy/dt there, if known: ``model.rhs_bending`` gives both at once; ``state``: a
    :class:`~rod_sim.core.state.State` of these arguments, whose quantities are shared, in
    place of them). One right-hand side and a few O(n) power evaluations; the rates are
    central differences of :data:`RATE_STEP` along the right-hand side (one-sided at a load
    breakpoint). ``energy`` False: the sample only starts a span (:meth:`EnergyBalance.add`
    reads the energy at a span's end only) and its energy is not computed (nan)."""
    s = model.state(t, y, held, mode, f, bending) if state is None else state
    t, y, held, mode, f = s.t, s.y, s.held, s.mode, s.f
    energy = s.energies.total if energy else math.nan
    power = s.value(_net_power)
    before = power + load_jump_power(model, t, y, held, state=s)
    h = RATE_STEP
    hf = h * f
    pair = s.moved_net_powers(t + h, t - h, hf)
    if pair is None:
        up, down = s.moved(t + h, y + hf), s.moved(t - h, y - hf)
        pair = up.value(_net_power), down.value(_net_power)
    p_up, p_down = pair
    if t in model.breakpoints:
        rate, rate_before = (p_up - power) / h, (before - p_down) / h
    else:
        rate = rate_before = (p_up - p_down) / (2.0 * h)
    if getattr(model, "dof_per_rod", 1) != 3:
        return BalanceSample(float(t), energy, power, before, rate, rate_before)
    n = model.n
    u = y[n:2 * n] - y[2 * n:3 * n]         # alpha - beta (q comes first in every layout)
    a = s.value(_coefficients)
    da = (up.value(_coefficients) - down.value(_coefficients)) / (2.0 * h)
    return BalanceSample(float(t), energy, power, before, rate, rate_before,
                         s.value(_unpaired_power),
                         (up.value(_unpaired_power) - down.value(_unpaired_power)) / (2.0 * h),
                         -float(np.dot(a, u)), float(np.dot(da, u)))


JUMP_EVENTS = ("latch", "stop_contact_begin")
"""Hinge events at which the net power jumps: a latch (the locked hinge's damper stops, the
velocities jump) and a stop contact's start (its damping moment starts at c theta')."""


class EnergyBalance:
    """Mechanical energy balance of a run: ``residual`` = E - E0 - W + D [J] with W the
    integral of the net power (loads and motors minus hinge and stop dampers, plus the full
    model's unpaired velocity term: :func:`net_power`) and D the kinetic energy dissipated in
    latch impacts; ~0 (quadrature and integration error) for an accurate run.
    ``scale`` = max(|E0|, |E|, sum |P| dt, D).

    ``simulate`` (per sample) and the node (per control period) both feed it
    :func:`balance_sample` s through :meth:`add`, so they book the same terms the same way."""

    def __init__(self, energy0: float = 0.0, omega: float = 0.0):
        self.omega = float(omega)
        """[rad/s] the first bending mode (full model; 0 otherwise): a span longer than
        1 / omega does not resolve the bending vibration, and the unpaired power is integrated
        by parts there (:meth:`add`)."""
        self.start(energy0)

    @classmethod
    def for_model(cls, model, energy0: float = 0.0):
        """A balance for runs of ``model``: omega from the rods' analytic bending frequencies
        (:func:`bending_frequencies`, the stiffest rod) for the full model, else 0."""
        omega = 0.0
        if getattr(model, "dof_per_rod", 1) == 3:
            omega = 2.0 * math.pi * float(np.max(bending_frequencies(model.scene)))
        return cls(energy0, omega)

    def start(self, energy0: float) -> None:
        self.energy0 = self.energy = float(energy0)
        self.work = self.abs_work = self.impacts = 0.0
        self.unresolved = 0.0
        """[J] sum of |dt^2 (d0 - d1) / 12|, the end-derivative corrections of the trapezoid
        rule: where the samples resolve the power it is a small part of the work and the
        corrected rule's error a small part of it; a residual no larger than it may be
        quadrature error alone (e.g. one 10 ms span at the start of a pulse, power ~ t^5), and
        :meth:`ValidityMonitor.update_energy` does not judge it."""

    def add_period(self, dt: float, p_start: float, p_end: float, energy_end: float,
                   impacts: float = 0.0, split: tuple[float, float] | None = None,
                   rates: tuple[float, float] | None = None) -> None:
        """One period of ``dt`` [s]: net powers [W] at its ends, energy [J] at its end and the
        kinetic energy [J] lost in latch impacts inside it. ``rates`` [W/s]: the powers' time
        derivatives at the ends (:attr:`BalanceSample.rate`): the work integral is then the corrected
        trapezoid rule dt (p0 + p1) / 2 + dt^2 (d0 - d1) / 12 (exact for cubics), else the
        plain one (also when a rate is nan). ``split`` = (a, b), 0 <= a <= b <= dt: the power
        jumps at a and b [s] after the period's start (hinge events): the start's Taylor
        expansion holds up to a, the end's from b on, their mean in between."""
        dt, p0, p1 = float(dt), float(p_start), float(p_end)
        d0, d1 = (0.0, 0.0) if rates is None else (float(rates[0]), float(rates[1]))
        if not (math.isfinite(d0) and math.isfinite(d1)):
            d0 = d1 = 0.0
            rates = None
        if split is None:
            work = 0.5 * dt * (p0 + p1)
            if rates is not None:
                correction = dt * dt * (d0 - d1) / 12.0
                work += correction
                self.unresolved += abs(correction)
            abs_work = abs(work)
        else:
            a, b = (min(max(float(x), 0.0), dt) for x in split)
            c = dt - b
            head = a * p0 + 0.5 * a * a * d0
            tail = c * p1 - 0.5 * c * c * d1
            mid = 0.5 * (b - a) * (p0 + p1)
            work = head + tail + mid
            abs_work = abs(head) + abs(tail) + abs(mid)
        self.work += work
        self.abs_work += abs_work
        self.impacts += float(impacts)
        self.energy = float(energy_end)

    def add_span(self, t_start: float, t_end: float, p_start: float, p_end: float,
                 energy_end: float, events=(), rates: tuple[float, float] | None = None) -> None:
        """One span of simulated time [s] between two states the caller holds (samples or
        control periods), with the net powers [W] there (and their time derivatives [W/s],
        ``rates``), the energy [J] at its end and the hinge events of the span (HingeEvent):
        the latch impacts' kinetic energy losses are booked and the work integral is split at
        the events where the power jumps."""
        jumps = [e.t for e in events if e.kind in JUMP_EVENTS]
        split = None if not jumps else (min(jumps) - t_start, max(jumps) - t_start)
        self.add_period(t_end - t_start, p_start, p_end, energy_end,
                        latch_losses(events), split, rates)

    def add(self, start: BalanceSample, end: BalanceSample, events=()) -> None:
        """The span between two :class:`BalanceSample` s with the hinge events inside it: the
        corrected trapezoid rule of :meth:`add_span`, except that when the span does not
        resolve the bending vibration (omega dt > 1) and no event makes the power jump, the
        unpaired power's integral is taken by parts, -[sum A_j u_j] + integral sum A_j' u_j
        dt: its integrand oscillates at the bending frequency with a mean much smaller than
        its amplitude, and the boundary term carries that oscillation exactly (measured at
        100 Hz samples: the whipping-tip hard case 4.7 % of the energy scale -> 0.5 %)."""
        dt = end.t - start.t
        jumps = any(e.kind in JUMP_EVENTS for e in events)
        if self.omega * dt > 1.0 and not jumps:
            self.add_period(dt, start.power - start.unpaired, end.power_before - end.unpaired,
                            end.energy, latch_losses(events), None,
                            (start.rate - start.unpaired_rate,
                             end.rate_before - end.unpaired_rate))
            work = end.boundary - start.boundary + 0.5 * dt * (start.remainder + end.remainder)
            self.work += work
            self.abs_work += abs(work)
        else:
            self.add_span(start.t, end.t, start.power, end.power_before, end.energy, events,
                          (start.rate, end.rate_before))

    def add_impact(self, loss: float) -> None:
        self.impacts += float(loss)

    @property
    def scale(self) -> float:
        return max(abs(self.energy0), abs(self.energy), self.abs_work, self.impacts)

    @property
    def residual(self) -> float:
        return self.energy - self.energy0 - self.work + self.impacts


def span_events(events, t_start: float, t_end: float) -> list:
    """The hinge events of the span between samples at t_start and t_end [s]: t_start <= t <
    t_end (a sample at an event's time is the state before it, as ``Simulator.run`` gives)."""
    return [e for e in events if t_start <= e.t < t_end]


def balance_run(model, t, y, held=None, modes=None, events=(), on_state=None):
    """The energy balance over samples ``t`` (N,) [s], states ``y`` (N, state_size), held
    inputs ``held`` ((n, 2) or (n, 3), or per sample (N, n, 2|3); None: zeros), latches
    ``modes`` (N, n) fired at each sample and the run's hinge ``events``, booked as
    ``simulate`` books it: yields (i, the :class:`EnergyBalance` after sample i, the end slopes
    (alpha, beta) (n,) each [rad] at sample i in its mode) for every sample (i = 0: started).
    The slopes are solved once per sample, for the balance and for the caller;
    ``on_state(i, held_i, mode_i, state)`` (if given) gets each sample's
    :class:`~rod_sim.core.state.State` to share (e.g. a momentum ledger)."""
    t = np.asarray(t, float)
    per_sample = held is not None and np.ndim(held) == 3
    balance = EnergyBalance.for_model(model)
    prev = None
    for i in range(t.size):
        h = held[i] if per_sample else held
        mode = None if modes is None else modes[i]
        state = model.state(t[i], y[i], h, mode)      # one right-hand side for both
        slopes = state.bending
        sample = balance_sample(model, t[i], y[i], h, mode, state=state)
        if on_state is not None:
            on_state(i, h, mode, state)
        if prev is None:
            balance.start(sample.energy)
        else:
            balance.add(prev, sample, span_events(events, prev.t, t[i]))
        prev = sample
        yield i, balance, slopes


def assess_trajectory(model, t, y, held=None, command_rate_hz: float | None = None,
                      modes=None, events=()) -> ValidityMonitor:
    """Run every check over samples ``t`` (N,) [s], states ``y`` (N, state_size) with held
    forces ``held`` ((n, 2), or (N, n, 2) per sample); the energy balance
    (:class:`EnergyBalance`, as ``simulate`` books it) runs over the samples, ``modes`` (N, n)
    are the latches fired at each sample and ``events`` the run's hinge events (latch impacts
    dissipate energy, the power jumps at them). Returns the monitor (``findings()``,
    ``summary()``); the energy finding is judged at the sample of the largest residual."""
    mon = ValidityMonitor(model, command_rate_hz)
    t = np.asarray(t, float)
    held = np.zeros((model.n, 2)) if held is None else np.asarray(held, float)
    per_sample = held.ndim == 3
    worst = None
    for i, balance, (alpha, beta) in balance_run(model, t, y, held, modes, events):
        mon.update(t[i], y[i], held[i] if per_sample else held, alpha, beta)
        if i and (worst is None or abs(balance.residual) > abs(worst[1])):
            worst = (t[i], balance.residual, balance.unresolved)
    if worst is not None:
        mon.update_energy(worst[0], worst[1], balance.scale, worst[2])
    return mon
