"""The quantities of a model at one state, each computed once (what one sample needs).

A sample of a run (``simulate``'s log, a control period of the node) publishes the snapshot,
books the energy balance and the momentum ledger and writes the diagnostics; all of them need
the node positions and velocities, the hinge angles, the loads, the momentum, the powers of
one state. :class:`State` computes each of these on first use and keeps it for the other
users of that state. The laws of the energies, the momentum, the powers and the snapshot are
written once, here (the hinge rates and the powers compiled, in
:mod:`~rod_sim.core.chain_power`): :class:`~rod_sim.core.models.ChainModel`'s methods of the
same names evaluate them on a fresh State, so a separate call and a shared State give the
same values, bit for bit. O(n), no Python loop over rods or chains (but over the chains of a
prescribed base's kinetic energy: their sums keep numpy's pairwise order).
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from . import chain_momentum, chain_power, hinges, kernels
from .kinematics import chain_node_positions, chain_nodes, node_positions, pairs
from .snapshot import Snapshot


class cached:
    """A property computed on first use and then kept in the instance (what
    ``functools.cached_property`` does, without its lock: a State belongs to one thread)."""

    def __init__(self, compute):
        self.compute = compute
        self.name = compute.__name__
        self.__doc__ = compute.__doc__

    def __set_name__(self, owner, name):
        self.name = name

    def __get__(self, obj, owner=None):
        if obj is None:
            return self
        value = obj.__dict__[self.name] = self.compute(obj)
        return value


def cross(a, b):
    """z component of a x b over the last axis (2,)."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


_NO_RODS = np.empty(0, dtype=np.int64)
"""No rod turns against a moving base (:func:`~rod_sim.core.chain_power.deflection_rates`)."""


class State:
    """A model's quantities at time ``t`` [s], state ``y`` (state_size,), held inputs ``held``
    (as the model's methods take them: None, (n, 2), (n, 3) or (n + 2, 3)) and latches
    ``mode`` (n,) bool (None: none fired). ``f`` (dy/dt, state_size,) and ``bending`` =
    (alpha, beta) (n,) each [rad] may be given when already known at these arguments
    (``model.rhs_bending`` gives both); ``data`` (:class:`~rod_sim.core.models.ModelData`):
    scratch for the right-hand side (None: fresh).

    Each attribute below is computed on first use and kept; the arrays are shared by every
    user of the state (the snapshot included) and must not be written to. :meth:`value` keeps
    the derived quantities of other modules (the net power, the momentum rates, ...) the same
    way. ``y`` must not change while the object is in use."""

    def __init__(self, model, t: float, y, held=None, mode=None, f=None, bending=None,
                 data=None):
        self.model = model
        self.data = data
        self.t = t
        self.y = np.asarray(y, dtype=float)
        self.held = held
        self.mode = mode
        self._memo: dict = {}
        self._moves: dict = {}          # the States moved from this one, by their time
        self._source: State | None = None   # the State this one is with other held inputs
        if f is not None:
            self.f = f
        if bending is not None:
            self.bending = bending

    def moved(self, t: float, y) -> "State":
        """The State at another time and state with the same held inputs, latches and scratch
        (the central difference of a balance sample): it shares the locked hinges and, when
        the scene has no scripted load (the loads then do not depend on t), the loads. When
        this State is another one with other held inputs (:meth:`with_held`) and that one
        was moved to the same time with the same rod angles, bit for bit (a balance sample
        on each side of a jump of the commands: the angles move by h phi', which the held
        inputs do not change), their cosines and sines are shared too."""
        out = State(self.model, t, y, self.held, self.mode, data=self.data)
        out.locked = self.locked
        if not self.model.scripted_loads:
            out.loads = self.loads
        else:
            out.held_rows = self.held_rows
        self._moves[t] = out
        twin = None if self._source is None else self._source._moves.get(t)
        if twin is not None and twin.phi.tobytes() == out.phi.tobytes():
            mine, theirs = twin.__dict__, out.__dict__
            for name in ANGLE_ONLY:
                if name in mine:
                    theirs[name] = mine[name]
        return out

    def with_held(self, held) -> "State":
        """The State at the same time, state, latches and scratch with other held inputs
        ``held`` (a jump of the commands: the span that starts there): it shares every
        quantity already computed that the held inputs do not change (:data:`HELD_FREE`;
        with the slopes of the full and rigid models, which do not depend on them,
        :data:`HELD_FREE_SLOPES` too)."""
        out = State(self.model, self.t, self.y, held, self.mode, data=self.data)
        out._source = self
        mine, theirs = self.__dict__, out.__dict__
        names = HELD_FREE if self.model.slopes_need_rhs else HELD_FREE + HELD_FREE_SLOPES
        for name in names:
            if name in mine:
                theirs[name] = mine[name]
        return out

    def value(self, law: Callable[["State"], object]):
        """``law(self)``, computed once per state (keyed by the function)."""
        memo = self._memo
        if law in memo:
            return memo[law]
        out = memo[law] = law(self)
        return out

    # ----- inputs of every law -----
    @cached
    def phi(self) -> np.ndarray:
        """Rod angles (n,) [rad] (a view of y)."""
        return self.model.phi(self.y)

    @cached
    def phi_rate(self) -> np.ndarray:
        """Rod angular rates (n,) [rad/s] (a view of y)."""
        return self.model.phi_rate(self.y)

    @cached
    def cos_phi(self) -> np.ndarray:
        """cos phi (n,)."""
        return np.cos(self.phi)

    @cached
    def sin_phi(self) -> np.ndarray:
        """sin phi (n,)."""
        return np.sin(self.phi)

    @cached
    def axes(self) -> tuple[np.ndarray, np.ndarray]:
        """(e, e_perp) (n, 2) each: each rod's chord direction and its normal."""
        c, s = self.cos_phi, self.sin_phi
        return pairs(c, s), pairs(-s, c)

    @cached
    def f(self) -> np.ndarray:
        """dy/dt (state_size,) (and the slopes, when not known yet: one right-hand side)."""
        m = self.model
        if "bending" in self.__dict__:
            return m.rhs(self.t, self.y, self.held, self.mode, self.contact, self.data)
        f, self.bending = m.rhs_bending(self.t, self.y, self.held, self.mode, self.contact,
                                        self.data)
        return f

    @cached
    def bending(self) -> tuple[np.ndarray, np.ndarray]:
        """End slopes (alpha, beta), (n,) each [rad] (the reduced model's from a right-hand
        side, which is kept as :attr:`f`)."""
        m = self.model
        if m.slopes_need_rhs:
            f, bending = m.rhs_bending(self.t, self.y, self.held, self.mode, self.contact,
                                       self.data)
            self.__dict__.setdefault("f", f)
            return bending
        return m.bending(self.t, self.y, self.held, self.mode)

    @cached
    def bending_rates(self) -> tuple[np.ndarray, np.ndarray]:
        """Rates of the end slopes as the model carries them (n,) each [rad/s] (zeros but in
        the full model)."""
        m = self.model
        if m.dof_per_rod != 3:
            zeros = m.rod_constants.zeros
            return zeros, zeros
        return m.bending_rates(self.t, self.y, self.held)

    @cached
    def contact(self) -> np.ndarray:
        """The stop contacts the state implies (n,) int8 (:meth:`ChainModel.contact_state`)."""
        m = self.model
        if not m.has_stops:
            return np.zeros(m.n, dtype=np.int8)
        theta, s = self.hinge_angles, m.scene
        if not self.penetrating and not ((theta == s.stop_upper).any()
                                         or (theta == s.stop_lower).any()):
            return np.zeros(m.n, dtype=np.int8)     # beyond no stop, on none
        return m.contact_of(theta, self.hinge_rates)

    @cached
    def base(self):
        """The base's pose and twist (:class:`~rod_sim.core.models.BaseState`)."""
        return self.model.base_state(self.t, self.y)

    @cached
    def base_trig(self) -> tuple:
        """(cos psi, sin psi) of the base's angle."""
        psi = self.base.psi
        return np.cos(psi), np.sin(psi)

    @cached
    def base_com(self) -> np.ndarray:
        """The base's centre of mass in Oxy (2,) [m]."""
        return self.model._base_com(self.base)

    @cached
    def base_angle(self) -> tuple:
        """(psi [rad], psi_rate [rad/s]) of the base, as the hinge angles take them."""
        return self.model._base_angle(self.y, self.t)

    @cached
    def hinge_angles(self) -> np.ndarray:
        """Rigid hinge angles theta (n,) [rad]."""
        m = self.model
        if m._plain_angles:
            return hinges.hinge_angles(self.phi)
        return m._relative(self.phi, self.base_angle[0])

    @cached
    def hinge_rates(self) -> np.ndarray:
        """Their rates (n,) [rad/s]."""
        m = self.model
        if m._plain_rates:
            return hinges.hinge_angles(self.phi_rate)
        return m._relative(self.phi_rate, self.base_angle[1])

    @cached
    def locked(self) -> np.ndarray:
        """Hinges held rigid in this mode (n,) bool."""
        return self.model.plan(self.mode).locked

    @cached
    def penetrating(self) -> bool:
        """Whether a hinge is beyond one of its stops. If not, every stop term is zero: the
        contact moments, their elastic energy and their power (adding those +-0.0 terms to the
        hinge energy and the damper power, both >= +0.0, changes neither, bit for bit)."""
        m = self.model
        if not m.has_stops:
            return False
        s, theta = m.scene, self.hinge_angles
        return bool(((theta - s.stop_upper) > 0.0).any() or ((s.stop_lower - theta) > 0.0).any())

    @cached
    def contact_moments(self) -> np.ndarray:
        """Stop contact moments (n,) [N m] on theta (zero on locked hinges)."""
        m = self.model
        if not self.penetrating:
            return np.zeros(m.n)
        s = m.scene
        out = hinges.contact_moments(self.hinge_angles, self.hinge_rates, s.stop_lower,
                                     s.stop_upper, s.stop_stiffness, s.stop_damping)
        out[self.locked] = 0.0
        return out

    @cached
    def held_rows(self) -> np.ndarray:
        """The held inputs as the kernels take them (n + 2, 3) (:meth:`ChainModel._held`)."""
        return self.model._held(self.held)

    @cached
    def loads(self) -> np.ndarray:
        """Every applied load (n + 2, 3) at t (:meth:`ChainModel.loads_at`)."""
        return self.model.loads_of(self.t, self.held_rows)

    @cached
    def nodes(self) -> np.ndarray:
        """Every chain's nodes 0..n_c in scene order (n + nc, 2) [m] (one chain: (n + 1, 2),
        node 0 at its attach point on the base), eq. (3)."""
        m = self.model
        trig = (self.cos_phi, self.sin_phi)
        if m._plain_nodes:
            return node_positions(m.params.l, self.phi, trig)
        st = self.base
        return chain_node_positions(m.params.l, self.phi, m.seg, m.chain.attach, st.x, st.y,
                                    st.psi, m.table, trig)

    @cached
    def velocities(self) -> np.ndarray:
        """Velocities of the nodes of :attr:`nodes` (n + nc, 2) [m/s]."""
        m = self.model
        dphi = self.phi_rate
        st = self.base
        c, s = self.base_trig
        ax, ay = m.attach_columns
        v0 = pairs(st.x_rate - st.psi_rate * (s * ax + c * ay),
                   st.y_rate + st.psi_rate * (c * ax - s * ay))                  # (nc, 2)
        steps = pairs(m.neg_l * self.sin_phi * dphi, m.params.l * self.cos_phi * dphi)
        return chain_nodes(v0, steps, m.table)

    # ----- hinges -----
    @cached
    def deflection_rate(self) -> np.ndarray:
        """d/dt Delta phi_h (n,) [rad/s] (the reduced and rigid models carry no bending
        rates)."""
        m = self.model
        dalpha, dbeta = self.bending_rates
        out = np.empty(m.n)
        if m._moving_hinge0:
            chain_power.deflection_rates(self.phi_rate, dalpha, dbeta, m._first_rods,
                                         float(self.base_angle[1]), out)
        else:
            chain_power.deflection_rates(self.phi_rate, dalpha, dbeta, _NO_RODS, 0.0, out)
        return out

    @cached
    def deflection(self) -> tuple[np.ndarray, np.ndarray]:
        """Relative hinge rotations Delta phi_h of eq. (2) with the slopes of :attr:`bending`
        and their rates, each (n,)."""
        m = self.model
        alpha, beta = self.bending
        phi = self.phi
        left = np.empty(m.n)
        left[:1] = 0.0
        np.add(phi[:-1], beta[:-1], out=left[1:])
        if m._turned_hinge0:
            left[m._first_rods] = self.base_angle[0]
        return phi + alpha - left, self.deflection_rate

    # ----- energies -----
    @cached
    def kinetic_energy(self) -> float:
        """(1/2) x'^T M x' [J] (:meth:`ChainModel.kinetic_energy`)."""
        m = self.model
        y = self.y
        ke = 0.5 * float(np.dot(y[m.dof:], m.mass_times(y)))
        if m.base_mode != kernels.MODE_PRESCRIBED:
            return ke
        ch = m.chain
        phi, dphi = self.phi, self.phi_rate
        w = ch.l * ch.Mt * dphi
        if m.dof_per_rod == 3:
            da, db = self.bending_rates
            w = w + ch.C * (da - db)
        px, py = -w * self.sin_phi, w * self.cos_phi
        v = self.velocities
        for ci in range(len(m.seg) - 1):        # numpy's pairwise sums of each chain
            a, b = m.seg[ci], m.seg[ci + 1]
            v0 = v[a + ci]
            ke += float(v0[0] * px[a:b].sum() + v0[1] * py[a:b].sum()
                        + 0.5 * ch.Mc[ci] * (v0[0] ** 2 + v0[1] ** 2))
        return ke

    def gravity_energy_with(self, bending) -> float:
        """-sum m g.r over every mass point [J] with the slopes ``bending`` (alpha, beta) (or
        None: straight rods), 0 without gravity."""
        m = self.model
        b = m.chain.base
        if b[kernels.B_GRAVITY] == 0.0:
            return 0.0
        g = np.array([b[kernels.B_GX], b[kernels.B_GY]])
        k = m.rod_constants
        # a rod's int m eta ds = C (alpha - beta) along e_perp
        eta1 = k.zeros if bending is None else k.C * (bending[0] - bending[1])
        total = np.empty(2)
        chain_momentum.chain_first_moment(self.nodes, m.rod_starts, self.cos_phi, self.sin_phi,
                                          k.ml, k.half_l, k.mu, eta1, total)
        energy = -float(np.dot(g, total))
        if m.nb:
            energy -= float(b[kernels.B_MASS] * np.dot(g, self.base_com))
        return energy

    @cached
    def energies(self):
        """Kinetic, hinge (springs + stop contacts), bending and gravity energy [J]
        (:class:`~rod_sim.core.models.Energies`) with the slopes of :attr:`bending`."""
        from .models import Energies

        m = self.model
        p, s = m.params, m.scene
        alpha, beta = self.bending
        delta, _ = self.deflection
        hinge = 0.5 * float((p.kappa * (delta - s.hinge_rest_angle) ** 2).sum())
        if self.penetrating:      # the stop contacts' elastic energy (none outside them)
            pen = hinges.contact_penetration(self.hinge_angles, s.stop_lower, s.stop_upper)
            pen[self.locked] = 0.0
            hinge += 0.5 * float((s.stop_stiffness * pen**2).sum())
        bend = float((m.rod_constants.EI2_l * (alpha**2 + beta**2 + alpha * beta)).sum())
        return Energies(self.kinetic_energy, hinge, bend, self.gravity_energy_with(self.bending))

    @cached
    def base_energies(self) -> tuple[float, float]:
        """(kinetic energy of a free base: m_B |v_C|^2 / 2 + J_B psi'^2 / 2, of its wheel:
        J_W (psi' + theta_w')^2 / 2) [J]; zeros for a fixed or prescribed base."""
        m = self.model
        if not m.nb:
            return 0.0, 0.0
        b = m.chain.base
        st = self.base
        off = self.base_com - np.array([st.x, st.y])
        vc = (st.x_rate - st.psi_rate * off[1], st.y_rate + st.psi_rate * off[0])
        base = 0.5 * float(b[kernels.B_MASS]) * (vc[0] ** 2 + vc[1] ** 2) \
            + 0.5 * float(b[kernels.B_INERTIA]) * st.psi_rate ** 2
        wheel = 0.5 * float(b[kernels.B_WHEEL]) * (st.psi_rate + st.wheel_rate) ** 2
        return base, wheel

    # ----- momentum and powers -----
    @cached
    def momentum(self):
        """Linear and angular momentum of the whole system and its centre of mass
        (:class:`~rod_sim.core.models.Momentum`, :meth:`ChainModel.momentum`), O(n)."""
        from .models import Momentum

        m = self.model
        k = m.rod_constants
        dphi = self.phi_rate
        if m.dof_per_rod == 3:
            alpha, beta = self.bending
            dalpha, dbeta = self.bending_rates
            eta1 = k.C * (alpha - beta)                                 # int m eta
            deta1 = k.C * (dalpha - dbeta)                              # int m eta'
            Isd = k.l3_30 * dalpha - k.l3_20 * dbeta                    # int m s eta'
            Iee = k.l3_105 * (alpha**2 + beta**2) - k.l3_70 * alpha * beta    # int m eta^2
        else:       # straight chords: the same terms, each +0.0
            eta1 = deta1 = Isd = Iee = k.zeros
        sums = np.empty(5)
        chain_momentum.chain_momentum(self.nodes, self.velocities, m.rod_starts, self.cos_phi,
                                      self.sin_phi, dphi, k.ml, k.half_ml_l, k.half_l, k.l3_3,
                                      k.mu, eta1, deta1, Isd, Iee, sums)
        P = sums[:2]
        H = float(sums[2])
        com_sum = sums[3:]
        mass = k.mass
        if m.nb:
            b = m.chain.base
            st = self.base
            mB = float(b[kernels.B_MASS])
            rc = self.base_com
            off = rc - np.array([st.x, st.y])
            vc = np.array([st.x_rate - st.psi_rate * off[1], st.y_rate + st.psi_rate * off[0]])
            P = P + mB * vc
            H += mB * float(cross(rc, vc)) + float(b[kernels.B_INERTIA]) * st.psi_rate
            H += float(b[kernels.B_WHEEL]) * (st.psi_rate + st.wheel_rate)
            com_sum = com_sum + mB * rc
            mass += mB
        com = com_sum / mass
        return Momentum(P, H, H - float(cross(com, P)), com, mass)

    @cached
    def end_velocities(self) -> np.ndarray:
        """(2, n) [m/s]: the velocity (vx, vy) of each rod's end node."""
        return self.velocities[self.model.table.ends].T.copy()

    @cached
    def chain_powers(self) -> tuple[float, float]:
        """(power of the chains' nodal forces and hinge motors, power dissipated in the hinge
        dampers) [W] (:func:`~rod_sim.core.chain_power.chain_powers`; one chain on a fixed
        base: :func:`~rod_sim.core.chain_power.plain_powers`)."""
        m = self.model
        out = np.empty(2)
        if m._plain_powers:
            chain_power.plain_powers(m.neg_l, m.params.l, m.params.nu, self.sin_phi,
                                     self.cos_phi, self.phi_rate, self.deflection_rate,
                                     self.loads, out)
        else:
            v = self.end_velocities
            chain_power.chain_powers(v[0], v[1], self.deflection_rate, m.params.nu,
                                     self.loads, out)
        return float(out[0]), float(out[1])

    def moved_net_powers(self, t_up: float, t_down: float, hf: np.ndarray
                         ) -> tuple[float, float] | None:
        """The net power [W] (:func:`~rod_sim.core.validity.net_power`) at (t_up, y + hf) and
        (t_down, y - hf) with this State's held inputs and latches (the central difference of
        a balance sample) in one compiled call
        (:func:`~rod_sim.core.chain_power.net_power_pair`, the laws of :meth:`moved` States;
        its sines and cosines are numba's and its sums run rod by rod, so the values agree with
        theirs to rounding) when the model allows it (:attr:`ChainModel.paired_balance`: no
        slope rates in the state); else None (move the States). On a prescribed base
        the power it delivers needs the accelerations at the two moved states: two right-hand
        sides in this State's scratch, then one compiled call
        (:func:`~rod_sim.core.chain_power.prescribed_net_power_pair`)."""
        m = self.model
        if not m.paired_balance:
            return None
        if m.prescribed_base:
            return self._prescribed_pair(t_up, t_down, hf)
        out = np.empty(2)
        b = m.chain.base
        ax, ay = m.attach_columns
        cx, cy = m.base_com_offset
        chain_power.net_power_pair(self.y, hf, m.n, m.dof, m.seg, m.neg_l, m.params.l,
                                   m.params.nu, m.loads, self.held_rows, t_up, t_down,
                                   b[kernels.B_X:kernels.B_PSI + 1], bool(m.nb), m.nb, ax, ay,
                                   cx, cy, m._stops, self.locked, m.has_stops, out)
        return float(out[0]), float(out[1])

    def _prescribed_pair(self, t_up: float, t_down: float, hf: np.ndarray
                         ) -> tuple[float, float]:
        """:meth:`moved_net_powers` on a prescribed base."""
        m = self.model
        y = self.y
        contact = None if m.has_stops else self.contact     # None: each moved state's own
        f_up, (a_up, b_up) = m.rhs_bending(t_up, y + hf, self.held, self.mode, contact,
                                           self.data)
        f_down, (a_down, b_down) = m.rhs_bending(t_down, y - hf, self.held, self.mode, contact,
                                                 self.data)
        b = m.chain.base
        k = m.rod_constants
        gravity = b[kernels.B_GRAVITY] != 0.0
        gx, gy = (float(b[kernels.B_GX]), float(b[kernels.B_GY])) if gravity else (0.0, 0.0)
        # gravity acts on the reduced model's bent rods (its quasi-static slopes), as in
        # momentum._base_reaction
        bent = bool(gravity and m.name == "reduced")
        ax, ay = m.attach_columns
        table = m.table
        out = np.empty(2)
        chain_power.prescribed_net_power_pair(
            y, hf, f_up, f_down, a_up, b_up, a_down, b_down, m.n, m.dof, m.seg, m._first_rods,
            m.rod_starts, table.roots, table.chain, m.neg_l, m.params.l, m.params.nu, m.loads,
            self.held_rows, t_up, t_down, b[kernels.B_X:kernels.B_PSI + 1], m.chain.motion, ax,
            ay, k.half_l, k.ml, k.C, k.l3_3, k.l3_20, k.l3_30, k.half_ml_l, k.mu, gx, gy, bent,
            m._stops, self.locked, m.has_stops, out)
        return float(out[0]), float(out[1])

    @cached
    def damper_power(self) -> float:
        """Power dissipated in the hinge dampers and the stop contacts [W] (the second of
        :attr:`powers`)."""
        m = self.model
        damper = self.chain_powers[1]
        if m.has_stops and self.penetrating:
            s = m.scene
            theta, dtheta = self.hinge_angles, self.hinge_rates
            elastic = -s.stop_stiffness * (np.maximum(0.0, theta - s.stop_upper)
                                           - np.maximum(0.0, s.stop_lower - theta))
            elastic[self.locked] = 0.0
            damper -= float(((self.contact_moments - elastic) * dtheta).sum())
        return damper

    @cached
    def powers(self) -> tuple[float, float]:
        """(power of the applied loads and motors, and of a free base's loads and wheel
        motor; power dissipated in the hinge dampers and the stop contacts) [W]
        (:meth:`ChainModel.powers`)."""
        m = self.model
        n = m.n
        loads = self.loads
        load_power = self.chain_powers[0]
        if m.nb:
            st = self.base
            c, s = self.base_trig
            cx, cy = m.base_com_offset
            load_power += chain_power.base_load_power(loads, n, c, s, cx, cy, st.x_rate,
                                                      st.y_rate, st.psi_rate, st.wheel_rate)
        return load_power, self.damper_power

    # ----- what is published -----
    def snapshot(self) -> Snapshot:
        """Everything published about the chain (:meth:`ChainModel.snapshot`): hinge_moment =
        kappa (Delta - theta_rest) + nu Delta' minus the stop contact moment (the constraint
        reaction of a locked hinge is not included); a spacecraft scene's base, momentum and
        energy terms."""
        m = self.model
        alpha, beta = self.bending
        delta, ddelta = self.deflection
        p = m.params
        moment = p.kappa * (delta - m.scene.hinge_rest_angle) + p.nu * ddelta
        if self.penetrating:        # else zeros, and x - (+0.0) is x, bit for bit
            moment = moment - self.contact_moments
        extra = self._spacecraft_fields() if m.is_spacecraft else {}
        return Snapshot(
            t=float(self.t), phi=np.array(self.phi, dtype=float),
            phi_rate=np.array(self.phi_rate, dtype=float), alpha=np.asarray(alpha, float),
            beta=np.asarray(beta, float), hinge_angle=self.hinge_angles,
            hinge_rate=self.hinge_rates, hinge_moment=moment, nodes=self.nodes,
            forces=self.loads[:m.n, :2].copy(), **extra)

    def _spacecraft_fields(self) -> dict:
        """The :class:`Snapshot` fields of a spacecraft scene (see its docstring), O(n)."""
        st = self.base
        mom = self.momentum
        e = self.energies
        base_ke, wheel_ke = self.base_energies
        return {"base": np.array([st.x, st.y, st.psi, st.x_rate, st.y_rate, st.psi_rate]),
                "wheel_rate": float(st.wheel_rate),
                "momentum": np.array([mom.linear[0], mom.linear[1], mom.angular_origin,
                                      mom.angular_com, mom.com[0], mom.com[1]]),
                "energy_terms": {"kinetic": e.kinetic, "hinge": e.hinge, "bending": e.bending,
                                 "gravity": e.gravity, "base_kinetic": base_ke,
                                 "wheel_kinetic": wheel_ke, "total": e.total}}


HELD_FREE = ("phi", "phi_rate", "cos_phi", "sin_phi", "axes", "contact", "base", "base_trig",
             "base_com", "base_angle", "hinge_angles", "hinge_rates", "locked", "penetrating",
             "contact_moments", "nodes", "velocities", "bending_rates", "deflection_rate",
             "kinetic_energy", "base_energies", "end_velocities", "damper_power", "momentum")
"""The :class:`State` quantities that depend on the time, the state and the latches only,
not on the held inputs (:meth:`State.with_held` shares them; the momentum takes the slopes
of the full model only, which it carries in its state)."""
HELD_FREE_SLOPES = ("bending", "deflection", "energies")
"""The quantities that depend on the held inputs only through the slopes: shared too when
the slopes do not depend on them (the full model carries them in its state, the rigid
model has none; the reduced model solves them from the loads)."""
ANGLE_ONLY = ("cos_phi", "sin_phi", "axes")
"""The :class:`State` quantities of the rod angles alone (:meth:`State.moved` shares them
between two States with the same angles)."""
