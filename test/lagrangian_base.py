"""An independent exact Lagrangian of several chains on a moving base, for the tests.

Nothing here comes from rod_sim (no import of it at all). It extends ``lagrangian.py`` (the
fixed chain, paper eqs. (1)-(4)) to SPEC section 8: k chains hang on a planar rigid base.

Generalized coordinates (0-based, N = total rods of all chains in scene order, each chain's
rods contiguous):

    q = [phi (N), alpha (N), beta (N), x_B, y_B, psi, theta_w]          (3N + 4,)

* base frame origin r_B = (x_B, y_B), attitude psi, R(psi) the rotation;
* node 0 of chain c:           r_0 = r_B + R(psi) a_c        (a_c: attach point, base frame)
* node k of chain c:           r_k = r_0 + sum_{j<=k} l_j e1(phi_j)      (eq. (3))
* point s of rod k:            r   = r_{k-1} + s e1(phi_k) + eta_k(s) e2(phi_k)   (eq. (4))
  eta = alpha sigma + beta tau, sigma = s (l - s)^2 / l^2, tau = -s^2 (l - s) / l^2 (eq. (1));
* the base's centre of mass:  r_C = r_B + R(psi) c, mass m_B, inertia J_B about it;
* the wheel (its mass is in m_B): kinetic energy J_w (psi' + theta_w')^2 / 2.

Kinetic energy T = sum_rods m_k/2 int |r'|^2 ds + sum_nodes mu_k/2 |r_k'|^2
+ m_B/2 |r_C'|^2 + J_B/2 psi'^2 + J_w/2 (psi' + theta_w')^2, so the exact inertial force
d/dt dT/dq' - dT/dq = sum over mass points dm J^T (J q'' + d2r[q', q']) + the base's rotor
terms J_B psi'' (psi row) and J_w (psi'' + theta_w'') (psi and theta_w rows).

Potential Pi = 1/2 sum_h kappa_h (Delta_h - theta_rest_h)^2 + sum_k EI_k/2 int (eta_k'')^2 ds
+ V_g, hinge 0 of a chain measuring Delta_0 = phi_1 + alpha_1 - psi (the base is its left
side), Delta_h = (phi_{h+1} + alpha_{h+1}) - (phi_h + beta_h) else (eq. (2));
V_g = - sum over every mass point dm g . r (rods with the exact bent position, nodes, base).
Rayleigh R = 1/2 sum_h nu_h Delta_h'^2.

Generalized loads (virtual work): nodal force F_k at node k: J_k^T F_k; hinge motor moment
T_h: T_h dDelta_h/dq (+T on rod h+1, -T on rod h or the base); base force F at r_C: J_C^T F;
base moment M: M on the psi row; wheel motor torque T (+T on the wheel, -T on the base):
virtual work T (dpsi + dtheta_w) - T dpsi, i.e. T on the theta_w row.

``held`` (N + 2, 3) as in the model API: rows 0..N-1 (X_k, Y_k at the chain's node k, T_h at
hinge h) in the flat rod order (row i: rod i's far node and its own hinge, i.e. the hinge
between rod i and the rod/base before it), row N the base (Fx, Fy, moment), row N + 1 (0, 0,
wheel torque).

Quadrature: every integrand is a polynomial of degree <= 6 in s (see lagrangian.py), so 4
Gauss-Legendre points per rod are exact.

A fixed base is the same Lagrangian with the base coordinates held (rows dropped), a
prescribed base the same with the base coordinates known functions of t: their velocities and
accelerations enter the chain rows as known terms (``accelerations(..., free=...)``).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

GAUSS_POINTS = 4


def _mat(f):
    def g(*args):
        return np.asarray(f(*args), dtype=float)
    return g


def _vec(f):
    def g(*args):
        return np.asarray(f(*args), dtype=float).reshape(-1)
    return g


@dataclass(frozen=True)
class _Compiled:
    ns: tuple
    rod_pos: tuple      # i -> f(s, q, P) -> (2,)
    rod_jac: tuple      # i -> f(s, q, P) -> (2, nq)
    rod_acc: tuple      # i -> f(s, q, qd, P) -> (2,)
    node_pos: tuple     # i -> f(q, P) -> (2,)   far node of rod i
    node_jac: tuple
    node_acc: tuple
    com_pos: object     # base centre of mass
    com_jac: object
    com_acc: object
    hinge: object       # f(q, P) -> Delta (N,)
    hinge_jac: object   # f(q, P) -> dDelta/dq (N, nq)


@functools.lru_cache(maxsize=None)
def compiled(ns: tuple) -> _Compiled:
    """Symbolic kinematics of chains with rod counts ``ns`` on a base (cached per ns).

    Parameter vector P = [l (N), a_x (C), a_y (C), c_x, c_y]."""
    N, C = int(sum(ns)), len(ns)
    phi = sp.symbols(f"phi0:{N}", real=True)
    al = sp.symbols(f"alpha0:{N}", real=True)
    be = sp.symbols(f"beta0:{N}", real=True)
    xb, yb, psi, thw = sp.symbols("x_B y_B psi theta_w", real=True)
    q = list(phi) + list(al) + list(be) + [xb, yb, psi, thw]
    qd = list(sp.symbols(f"dq0:{len(q)}", real=True))
    L = sp.symbols(f"l0:{N}", positive=True)
    ax = sp.symbols(f"ax0:{C}", real=True)
    ay = sp.symbols(f"ay0:{C}", real=True)
    cx, cy = sp.symbols("c_x c_y", real=True)
    P = list(L) + list(ax) + list(ay) + [cx, cy]
    s = sp.Symbol("s", real=True)
    qv, qdv = sp.Matrix(q), sp.Matrix(qd)

    def e1(a):
        return sp.Matrix([sp.cos(a), sp.sin(a)])

    def e2(a):
        return sp.Matrix([-sp.sin(a), sp.cos(a)])

    rB = sp.Matrix([xb, yb])
    Rm = sp.Matrix([[sp.cos(psi), -sp.sin(psi)], [sp.sin(psi), sp.cos(psi)]])

    def parts(r, with_s):
        J = r.jacobian(qv)
        acc = (J * qdv).jacobian(qv) * qdv
        args = (s, q, P) if with_s else (q, P)
        argsd = (s, q, qd, P) if with_s else (q, qd, P)
        return (_vec(sp.lambdify(args, r, "numpy")), _mat(sp.lambdify(args, J, "numpy")),
                _vec(sp.lambdify(argsd, acc, "numpy")))

    rod_pos, rod_jac, rod_acc, node_pos, node_jac, node_acc = [], [], [], [], [], []
    delta = []
    i = 0
    for c, n in enumerate(ns):
        node = rB + Rm * sp.Matrix([ax[c], ay[c]])
        for k in range(n):
            lk = L[i]
            sigma = s * (lk - s) ** 2 / lk ** 2
            tau = -s ** 2 * (lk - s) / lk ** 2
            eta = al[i] * sigma + be[i] * tau
            r = node + s * e1(phi[i]) + eta * e2(phi[i])
            f = parts(r, True)
            rod_pos.append(f[0]), rod_jac.append(f[1]), rod_acc.append(f[2])
            node = node + lk * e1(phi[i])
            f = parts(node, False)
            node_pos.append(f[0]), node_jac.append(f[1]), node_acc.append(f[2])
            left = psi if k == 0 else phi[i - 1] + be[i - 1]
            delta.append(phi[i] + al[i] - left)
            i += 1
    com = rB + Rm * sp.Matrix([cx, cy])
    cf = parts(com, False)
    dm = sp.Matrix(delta)
    return _Compiled(
        ns=ns, rod_pos=tuple(rod_pos), rod_jac=tuple(rod_jac), rod_acc=tuple(rod_acc),
        node_pos=tuple(node_pos), node_jac=tuple(node_jac), node_acc=tuple(node_acc),
        com_pos=cf[0], com_jac=cf[1], com_acc=cf[2],
        hinge=_vec(sp.lambdify((q, P), dm, "numpy")),
        hinge_jac=_mat(sp.lambdify((q, P), dm.jacobian(qv), "numpy")))


@dataclass
class ChainData:
    """One chain: per-rod arrays (n,) l [m], m [kg/m], mu [kg] (node k = far node of rod k),
    EI [N m^2], kappa [N m/rad], nu [N m s/rad], rest [rad]; attach (2,) [m] in the base frame."""
    l: np.ndarray
    m: np.ndarray
    mu: np.ndarray
    EI: np.ndarray
    kappa: np.ndarray
    nu: np.ndarray
    attach: np.ndarray = field(default_factory=lambda: np.zeros(2))
    rest: np.ndarray | None = None

    def __post_init__(self):
        self.l = np.atleast_1d(np.asarray(self.l, float))
        n = len(self.l)
        for name in ("m", "mu", "EI", "kappa", "nu"):
            v = np.asarray(getattr(self, name), float)
            setattr(self, name, np.broadcast_to(v, (n,)).copy())
        self.rest = np.zeros(n) if self.rest is None else \
            np.broadcast_to(np.asarray(self.rest, float), (n,)).copy()
        self.attach = np.asarray(self.attach, float).reshape(2)

    @property
    def n(self) -> int:
        return len(self.l)


@dataclass
class BaseData:
    """The base: mass m_B [kg], inertia J_B about its centre of mass [kg m^2], centre of mass
    c (2,) in the base frame [m], wheel axial inertia J_w [kg m^2] (0: no wheel)."""
    mass: float = 0.0
    inertia: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.zeros(2))
    wheel: float = 0.0

    def __post_init__(self):
        self.com = np.asarray(self.com, float).reshape(2)


class BaseLagrangian:
    """Exact generalized forces of chains on a base; q, qd, qdd are (3N + 4,) (see module)."""

    def __init__(self, chains, base: BaseData, gravity=(0.0, 0.0),
                 gauss_points: int = GAUSS_POINTS):
        self.chains = list(chains)
        self.base = base
        self.g = np.asarray(gravity, float).reshape(2)
        self.ns = tuple(c.n for c in self.chains)
        self.N = int(sum(self.ns))
        self.nq = 3 * self.N + 4
        self.c = compiled(self.ns)
        cat = lambda name: np.concatenate([getattr(c, name) for c in self.chains])  # noqa: E731
        self.l, self.m, self.mu = cat("l"), cat("m"), cat("mu")
        self.EI, self.kappa, self.nu, self.rest = cat("EI"), cat("kappa"), cat("nu"), cat("rest")
        self.P = (list(self.l) + [c.attach[0] for c in self.chains]
                  + [c.attach[1] for c in self.chains] + list(base.com))
        x, w = np.polynomial.legendre.leggauss(gauss_points)
        self.s = 0.5 * self.l[:, None] * (x[None, :] + 1.0)
        self.w = 0.5 * self.l[:, None] * w[None, :]
        # index helpers
        self.i_phi = np.arange(self.N)
        self.i_bend = np.arange(self.N, 3 * self.N)
        self.i_base = np.arange(3 * self.N, 3 * self.N + 3)
        self.i_wheel = 3 * self.N + 3
        self.i_psi = 3 * self.N + 2

    # ----- mass points: (mass, jac, acc-function args) -----
    def _points(self, q):
        """Yield (dm, i or None, s or None) for every mass point (rods by quadrature, nodes)."""
        for i in range(self.N):
            for s, w in zip(self.s[i], self.w[i]):
                yield self.m[i] * w, "rod", i, s
            yield self.mu[i], "node", i, None
        yield self.base.mass, "com", None, None

    def _pos(self, kind, i, s, q):
        qq = list(q)
        if kind == "rod":
            return self.c.rod_pos[i](s, qq, self.P)
        if kind == "node":
            return self.c.node_pos[i](qq, self.P)
        return self.c.com_pos(qq, self.P)

    def _jac(self, kind, i, s, q):
        qq = list(q)
        if kind == "rod":
            return self.c.rod_jac[i](s, qq, self.P)
        if kind == "node":
            return self.c.node_jac[i](qq, self.P)
        return self.c.com_jac(qq, self.P)

    def _acc(self, kind, i, s, q, qd):
        qq, dd = list(q), list(qd)
        if kind == "rod":
            return self.c.rod_acc[i](s, qq, dd, self.P)
        if kind == "node":
            return self.c.node_acc[i](qq, dd, self.P)
        return self.c.com_acc(qq, dd, self.P)

    def _rotor(self):
        """The rotors' constant mass matrix (J_B on psi, J_w on psi + theta_w)."""
        M = np.zeros((self.nq, self.nq))
        p, w = self.i_psi, self.i_wheel
        M[p, p] += self.base.inertia + self.base.wheel
        M[p, w] += self.base.wheel
        M[w, p] += self.base.wheel
        M[w, w] += self.base.wheel
        return M

    # ----- inertia -----
    def mass_matrix(self, q) -> np.ndarray:
        q = self._check(q)
        M = self._rotor()
        for dm, kind, i, s in self._points(q):
            if dm == 0.0:
                continue
            J = self._jac(kind, i, s, q)
            M += dm * (J.T @ J)
        return M

    def inertial_force(self, q, qd, qdd) -> np.ndarray:
        """Exact d/dt dT/dq' - dT/dq (3N + 4,)."""
        q, qd, qdd = self._check(q), self._check(qd), self._check(qdd)
        f = self._rotor() @ qdd
        for dm, kind, i, s in self._points(q):
            if dm == 0.0:
                continue
            J = self._jac(kind, i, s, q)
            f += dm * (J.T @ (J @ qdd + self._acc(kind, i, s, q, qd)))
        return f

    def kinetic_energy(self, q, qd) -> float:
        qd = self._check(qd)
        return 0.5 * float(qd @ self.mass_matrix(q) @ qd)

    # ----- potential -----
    def hinge_deflections(self, q) -> np.ndarray:
        return self.c.hinge(list(self._check(q)), self.P)

    def _curv(self, i, s, q):
        """eta_i''(s) and its gradient (3N + 4,) (linear in alpha_i, beta_i)."""
        l = self.l[i]
        s2 = (6 * s - 4 * l) / l ** 2        # sigma''
        t2 = (6 * s - 2 * l) / l ** 2        # tau''  (tau = (s^3 - l s^2)/l^2)
        g = np.zeros(self.nq)
        g[self.N + i], g[2 * self.N + i] = s2, t2
        return q[self.N + i] * s2 + q[2 * self.N + i] * t2, g

    def gravity_potential(self, q) -> float:
        q = self._check(q)
        return -sum(dm * float(self.g @ self._pos(kind, i, s, q))
                    for dm, kind, i, s in self._points(q))

    def potential(self, q) -> float:
        """Hinges + bending (quadrature) + gravity [J]."""
        q = self._check(q)
        d = self.hinge_deflections(q) - self.rest
        e = 0.5 * float(np.sum(self.kappa * d ** 2))
        for i in range(self.N):
            for s, w in zip(self.s[i], self.w[i]):
                e += 0.5 * self.EI[i] * w * self._curv(i, s, q)[0] ** 2
        return e + self.gravity_potential(q)

    def potential_gradient(self, q) -> np.ndarray:
        q = self._check(q)
        d = self.hinge_deflections(q) - self.rest
        g = self.c.hinge_jac(list(q), self.P).T @ (self.kappa * d)
        for i in range(self.N):
            for s, w in zip(self.s[i], self.w[i]):
                k, dk = self._curv(i, s, q)
                g = g + self.EI[i] * w * k * dk
        return g - self.gravity_force(q)

    def gravity_force(self, q) -> np.ndarray:
        """-dV_g/dq = sum dm J^T g (exact, bending included)."""
        q = self._check(q)
        f = np.zeros(self.nq)
        if not np.any(self.g):
            return f
        for dm, kind, i, s in self._points(q):
            if dm:
                f += dm * (self._jac(kind, i, s, q).T @ self.g)
        return f

    # ----- damping, loads -----
    def dissipation_force(self, q, qd) -> np.ndarray:
        D = self.c.hinge_jac(list(self._check(q)), self.P)
        return D.T @ (self.nu * (D @ self._check(qd)))

    def load_force(self, q, held) -> np.ndarray:
        q = self._check(q)
        h = np.zeros((self.N + 2, 3))
        if held is not None:
            h[:] = np.asarray(held, float).reshape(self.N + 2, 3)
        f = np.zeros(self.nq)
        for i in range(self.N):
            f += self.c.node_jac[i](list(q), self.P).T @ h[i, :2]
        f += self.c.hinge_jac(list(q), self.P).T @ h[:self.N, 2]
        f += self.c.com_jac(list(q), self.P).T @ h[self.N, :2]
        f[self.i_psi] += h[self.N, 2]
        f[self.i_wheel] += h[self.N + 1, 2]
        return f

    def residual(self, q, qd, qdd, held=None, zero_bending_inertia=False) -> np.ndarray:
        """Exact inertia + dPi/dq + dR/dq' - loads (incl. gravity); zero on a solution.
        ``zero_bending_inertia``: evaluate the inertial force at alpha = beta = 0 (the paper's
        approximation: its mass matrix and velocity terms are the exact ones at zero bending),
        everything else at q."""
        q = self._check(q)
        qi = self.unbent(q) if zero_bending_inertia else q
        return (self.inertial_force(qi, qd, qdd) + self.potential_gradient(q)
                + self.dissipation_force(q, qd) - self.load_force(q, held))

    def accelerations(self, q, qd, held=None, free=None, known_qdd=None,
                      zero_bending_inertia=False) -> np.ndarray:
        """qdd (3N + 4,) solving the rows ``free`` (index array; default all with positive
        inertia) with the other accelerations = ``known_qdd`` (default 0)."""
        qdd = np.zeros(self.nq) if known_qdd is None else np.array(known_qdd, float)
        if free is None:
            free = np.arange(self.nq)
        free = np.asarray(free)
        qi = self.unbent(q) if zero_bending_inertia else self._check(q)
        qdd[free] = 0.0
        r0 = self.residual(q, qd, qdd, held, zero_bending_inertia)
        M = self.mass_matrix(qi)
        qdd[free] = np.linalg.solve(M[np.ix_(free, free)], -r0[free])
        return qdd

    def unbent(self, q) -> np.ndarray:
        q = np.array(self._check(q))
        q[self.i_bend] = 0.0
        return q

    # ----- momentum -----
    def momentum(self, q, qd):
        """(P (2,) [kg m/s], H_O [kg m^2/s] about O, H_cm about the centre of mass, com (2,),
        mass) exact, from the mass points and the two rotors."""
        q, qd = self._check(q), self._check(qd)
        P = np.zeros(2)
        H = 0.0
        mr = np.zeros(2)
        mass = 0.0
        for dm, kind, i, s in self._points(q):
            if dm == 0.0:
                continue
            r = self._pos(kind, i, s, q)
            v = self._jac(kind, i, s, q) @ qd
            P += dm * v
            H += dm * (r[0] * v[1] - r[1] * v[0])
            mr += dm * r
            mass += dm
        p, w = qd[self.i_psi], qd[self.i_wheel]
        H += self.base.inertia * p + self.base.wheel * (p + w)
        com = mr / mass
        Hc = H - (com[0] * P[1] - com[1] * P[0])
        return P, H, Hc, com, mass

    def momentum_rate(self, q, qd, qdd, scale=False):
        """Exact (dP/dt (2,), dH_O/dt) along (q', q''): sum dm a, sum dm r x a + the rotors'
        J_B psi'' + J_w (psi'' + theta_w'') (v x v = 0), a = J q'' + d2r[q', q'].
        ``scale``: also the sizes sum |dm a| and sum |dm r x a| + |rotor terms| (for relative
        tolerances when the sums cancel)."""
        q, qd, qdd = self._check(q), self._check(qd), self._check(qdd)
        dP, dH, sP, sH = np.zeros(2), 0.0, 0.0, 0.0
        for dm, kind, i, s in self._points(q):
            if dm == 0.0:
                continue
            r = self._pos(kind, i, s, q)
            a = self._jac(kind, i, s, q) @ qdd + self._acc(kind, i, s, q, qd)
            dP += dm * a
            dH += dm * (r[0] * a[1] - r[1] * a[0])
            sP += dm * float(np.hypot(*a))
            sH += dm * float(np.hypot(*r) * np.hypot(*a))
        p, w = qdd[self.i_psi], qdd[self.i_wheel]
        rot = (self.base.inertia * p, self.base.wheel * (p + w))
        dH += sum(rot)
        if scale:
            return dP, dH, max(sP, 1e-300), max(sH + sum(abs(x) for x in rot), 1e-300)
        return dP, dH

    def external_wrench(self, q, held):
        """Total external force (2,) and moment about O of ``held`` (nodal forces, base force at
        its centre of mass, base moment; hinge and wheel motor moments are internal) plus gravity
        on every mass point."""
        q = self._check(q)
        h = np.zeros((self.N + 2, 3)) if held is None else np.asarray(held, float).reshape(-1, 3)
        F, M = np.zeros(2), 0.0
        for i in range(self.N):
            r = self.c.node_pos[i](list(q), self.P)
            F += h[i, :2]
            M += r[0] * h[i, 1] - r[1] * h[i, 0]
        rc = self.c.com_pos(list(q), self.P)
        F += h[self.N, :2]
        M += rc[0] * h[self.N, 1] - rc[1] * h[self.N, 0] + h[self.N, 2]
        for dm, kind, i, s in self._points(q):
            if dm:
                r = self._pos(kind, i, s, q)
                F += dm * self.g
                M += dm * (r[0] * self.g[1] - r[1] * self.g[0])
        return F, M

    def rigid_inertia(self, q) -> tuple[float, np.ndarray, float]:
        """(mass, centre of mass (2,), inertia about it) of everything rigidly frozen at q,
        the wheel's axial inertia excluded (the base's J_B included)."""
        q = self._check(q)
        pts = [(dm, self._pos(kind, i, s, q)) for dm, kind, i, s in self._points(q) if dm]
        M = sum(dm for dm, _ in pts)
        com = sum(dm * r for dm, r in pts) / M
        I = sum(dm * float((r - com) @ (r - com)) for dm, r in pts) + self.base.inertia
        return M, com, I

    def node_positions(self, q) -> np.ndarray:
        """Far nodes of all rods (N, 2) [m]."""
        return np.array([f(list(self._check(q)), self.P) for f in self.c.node_pos])

    def _check(self, q):
        q = np.asarray(q, float)
        assert q.shape == (self.nq,), q.shape
        return q
