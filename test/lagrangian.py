"""An independent derivation of the chain's equations of motion, for the tests.

Nothing here uses rod_sim's matrices. Starting from the kinematics alone,

* node k (paper eq. (3)):      r_k = sum_{j<=k} l_j e1(phi_j),
* point s of rod k (eq. (4)):  r = r_{k-1} + s e1(phi_k) + eta_k(s) e2(phi_k),
  e1 = (cos, sin), e2 = (-sin, cos), eta_k = alpha_k sigma_k(s) + beta_k tau_k(s),
  sigma = s (l - s)^2 / l^2, tau = -s^2 (l - s) / l^2   (eq. (1)),

(eq. (4) written from the far node, x = x_k - (l_k - s) cos phi_k - eta sin phi_k, is the same
point because x_k = x_{k-1} + l_k cos phi_k), sympy builds the positions as functions of the
3n generalized coordinates q = [phi, alpha, beta] (0-based: rod k of the paper is index k-1),
differentiates them symbolically (Jacobian dr/dq and the second derivative of r along qdot)
and lambdifies the result. The mass integrals over each rod are then done numerically with
Gauss-Legendre quadrature.

Quadrature: the integrands are polynomials in s times factors that do not depend on s. The
entries of dr/dq are of degree <= 3 in s (1, s, sigma, tau), so are those of the
velocity-dependent acceleration (s phi_dot^2, eta phi_dot^2, eta_dot phi_dot); J^T J and
J^T r_ddot are therefore of degree <= 6, and (eta'')^2 of degree 2. An N-point Gauss-Legendre
rule integrates degree <= 2N - 1 exactly, so N = 4 points per rod (exact to degree 7) make
every integral here exact up to rounding (the tests check that 10 points change nothing).

Generalized forces (principle of virtual work / d'Alembert-Lagrange, eq. (5)):

* inertia:  f_i = sum_rods m_k int_0^{l_k} r_ddot . dr/dq_i ds + sum_nodes mu_k r_k_ddot . dr_k/dq_i,
  with r_ddot = J q_ddot + sum_{ij} d2r/dq_i dq_j qdot_i qdot_j -- the exact Lagrangian
  d/dt dT/dqdot - dT/dq, without any small-bending approximation in the inertia;
* elasticity: gradient of Pi = 1/2 sum_h kappa_h Delta_h^2 + sum_k EI_k/2 int (eta_k'')^2 ds,
  Delta_h = (phi_{h+1} + alpha_{h+1}) - (phi_h + beta_h), phi_0 = beta_0 = 0 (eq. (2)); the
  bending energy is integrated by quadrature, not taken from the paper's closed form (6);
* damping: gradient w.r.t. qdot of the Rayleigh function R = 1/2 sum_h nu_h (d Delta_h/dt)^2;
* loads: sum_k F_k . dr_k/dq for nodal forces F_k = (X_k, Y_k) (eq. (8)).

Usage::

    lag = Lagrangian(l=..., m=..., mu=..., EI=..., kappa=..., nu=...)   # arrays (n,)
    lag = Lagrangian.from_params(chain_params)                         # any object with them
    lag.exact_mass_matrix(q); lag.exact_inertial_force(q, qdot, qddot); ...

The lambdified functions depend only on n and are cached per n (n <= 4 keeps sympy fast).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import sympy as sp

GAUSS_POINTS = 4   # exact for polynomial integrands of degree <= 7 (ours: <= 6)


@dataclass(frozen=True)
class _Compiled:
    n: int
    rod_jac: tuple          # k -> f(s, q, l) -> (2, 3n)
    rod_acc: tuple          # k -> f(s, q, qd, l) -> (2,)  second derivative of r along qdot
    node_jac: tuple         # k -> f(q, l) -> (2, 3n)
    node_acc: tuple         # k -> f(q, qd, l) -> (2,)
    node_pos: tuple         # k -> f(q, l) -> (2,)
    curv: tuple             # k -> f(s, q, l) -> eta_k''(s)
    curv_grad: tuple        # k -> f(s, q, l) -> d eta_k''(s) / dq (3n,)
    hinge: object           # f(q) -> Delta (n,)
    hinge_grad: object      # f(q, kappa) -> d/dq 1/2 sum kappa Delta^2 (3n,)
    rayleigh_grad: object   # f(q, qd, nu) -> d/dqdot 1/2 sum nu Delta_dot^2 (3n,)


def _vec(f):
    """Wrap a lambdified Matrix-valued function so it returns a flat float array."""
    def g(*args):
        return np.asarray(f(*args), dtype=float).reshape(-1)
    return g


def _mat(f):
    def g(*args):
        return np.asarray(f(*args), dtype=float)
    return g


@functools.lru_cache(maxsize=None)
def compiled(n: int) -> _Compiled:
    """Symbolic kinematics of an n-rod chain, differentiated and lambdified (cached per n)."""
    phi = sp.symbols(f"phi0:{n}", real=True)
    al = sp.symbols(f"alpha0:{n}", real=True)
    be = sp.symbols(f"beta0:{n}", real=True)
    dphi = sp.symbols(f"dphi0:{n}", real=True)
    dal = sp.symbols(f"dalpha0:{n}", real=True)
    dbe = sp.symbols(f"dbeta0:{n}", real=True)
    L = sp.symbols(f"l0:{n}", positive=True)
    kap = sp.symbols(f"kappa0:{n}", nonnegative=True)
    nus = sp.symbols(f"nu0:{n}", nonnegative=True)
    s = sp.Symbol("s", real=True)
    q = list(phi) + list(al) + list(be)
    qd = list(dphi) + list(dal) + list(dbe)
    qv, qdv = sp.Matrix(q), sp.Matrix(qd)

    def e1(a):
        return sp.Matrix([sp.cos(a), sp.sin(a)])

    def e2(a):
        return sp.Matrix([-sp.sin(a), sp.cos(a)])

    # nodes, eq. (3): node 0 at the origin, node k = sum_{j<=k} l_j e1(phi_j)
    nodes = [sp.zeros(2, 1)]
    for k in range(n):
        nodes.append(nodes[-1] + L[k] * e1(phi[k]))

    def second_along(r):
        """J qd and sum_ij d2r/dq_i dq_j qd_i qd_j for a position r(q)."""
        J = r.jacobian(qv)
        rdot = J * qdv
        acc = rdot.jacobian(qv) * qdv
        return J, acc

    rod_jac, rod_acc, node_jac, node_acc, node_pos, curv, curv_grad = [], [], [], [], [], [], []
    for k in range(n):
        lk = L[k]
        sigma = s * (lk - s) ** 2 / lk ** 2
        tau = -s ** 2 * (lk - s) / lk ** 2
        eta = al[k] * sigma + be[k] * tau
        r = nodes[k] + s * e1(phi[k]) + eta * e2(phi[k])
        J, acc = second_along(r)
        rod_jac.append(_mat(sp.lambdify((s, q, L), J, "numpy")))
        rod_acc.append(_vec(sp.lambdify((s, q, qd, L), acc, "numpy")))
        rn = nodes[k + 1]
        Jn, accn = second_along(rn)
        node_jac.append(_mat(sp.lambdify((q, L), Jn, "numpy")))
        node_acc.append(_vec(sp.lambdify((q, qd, L), accn, "numpy")))
        node_pos.append(_vec(sp.lambdify((q, L), rn, "numpy")))
        kappa_s = sp.diff(eta, s, 2)
        curv.append(sp.lambdify((s, q, L), kappa_s, "numpy"))
        curv_grad.append(_vec(sp.lambdify((s, q, L), sp.Matrix([kappa_s]).jacobian(qv), "numpy")))

    # hinges, eq. (2), with phi_0 = beta_0 = 0 (the ground)
    delta = []
    for h in range(n):
        left = 0 if h == 0 else phi[h - 1] + be[h - 1]
        delta.append(phi[h] + al[h] - left)
    delta_m = sp.Matrix(delta)
    Pi_h = sp.Rational(1, 2) * sum(kap[h] * delta[h] ** 2 for h in range(n))
    grad_h = sp.Matrix([Pi_h]).jacobian(qv)
    # Rayleigh function of the hinge dampers: d Delta / dt along qdot
    delta_dot = delta_m.jacobian(qv) * qdv
    R = sp.Rational(1, 2) * sum(nus[h] * delta_dot[h] ** 2 for h in range(n))
    grad_R = sp.Matrix([R]).jacobian(qdv)

    return _Compiled(
        n=n, rod_jac=tuple(rod_jac), rod_acc=tuple(rod_acc), node_jac=tuple(node_jac),
        node_acc=tuple(node_acc), node_pos=tuple(node_pos), curv=tuple(curv),
        curv_grad=tuple(curv_grad),
        hinge=_vec(sp.lambdify((q,), delta_m, "numpy")),
        hinge_grad=_vec(sp.lambdify((q, kap), grad_h, "numpy")),
        rayleigh_grad=_vec(sp.lambdify((q, qd, nus), grad_R, "numpy")))


class Lagrangian:
    """Exact generalized forces of a chain with per-rod arrays (n,) l, m, mu, EI, kappa, nu."""

    def __init__(self, l, m, mu, EI, kappa, nu, gauss_points: int = GAUSS_POINTS):
        self.l = np.asarray(l, float)
        self.m = np.asarray(m, float)
        self.mu = np.asarray(mu, float)
        self.EI = np.asarray(EI, float)
        self.kappa = np.asarray(kappa, float)
        self.nu = np.asarray(nu, float)
        self.n = len(self.l)
        for a in (self.m, self.mu, self.EI, self.kappa, self.nu):
            assert a.shape == (self.n,)
        self.c = compiled(self.n)
        x, w = np.polynomial.legendre.leggauss(gauss_points)
        # nodes s and weights on [0, l_k] for every rod: (n, N) each
        self.s = 0.5 * self.l[:, None] * (x[None, :] + 1.0)
        self.w = 0.5 * self.l[:, None] * w[None, :]

    @classmethod
    def from_params(cls, p, **kw) -> "Lagrangian":
        return cls(p.l, p.m, p.mu, p.EI, p.kappa, p.nu, **kw)

    def _split(self, q):
        q = np.asarray(q, float)
        assert q.shape == (3 * self.n,)
        return list(q)

    # ----- positions -----
    def node_positions(self, q) -> np.ndarray:
        """Nodes 1..n (n, 2) [m]."""
        qq = self._split(q)
        return np.array([f(qq, list(self.l)) for f in self.c.node_pos])

    # ----- inertia -----
    def exact_mass_matrix(self, q) -> np.ndarray:
        """sum over all mass points of J^T J dm (3n, 3n) [kg m^2 and mixed units]."""
        qq, ll = self._split(q), list(self.l)
        M = np.zeros((3 * self.n, 3 * self.n))
        for k in range(self.n):
            for s, w in zip(self.s[k], self.w[k]):
                J = self.c.rod_jac[k](s, qq, ll)
                M += self.m[k] * w * (J.T @ J)
            Jn = self.c.node_jac[k](qq, ll)
            M += self.mu[k] * (Jn.T @ Jn)
        return M

    def exact_inertial_force(self, q, qdot, qddot) -> np.ndarray:
        """sum of int r_ddot . dr/dq_i dm, r_ddot = J qddot + d2r[qdot, qdot] (3n,)."""
        qq, qd, ll = self._split(q), self._split(qdot), list(self.l)
        qdd = np.asarray(qddot, float)
        f = np.zeros(3 * self.n)
        for k in range(self.n):
            for s, w in zip(self.s[k], self.w[k]):
                J = self.c.rod_jac[k](s, qq, ll)
                a = J @ qdd + self.c.rod_acc[k](s, qq, qd, ll)
                f += self.m[k] * w * (J.T @ a)
            Jn = self.c.node_jac[k](qq, ll)
            an = Jn @ qdd + self.c.node_acc[k](qq, qd, ll)
            f += self.mu[k] * (Jn.T @ an)
        return f

    # ----- elasticity -----
    def hinge_deflections(self, q) -> np.ndarray:
        """Delta_h, h = 0..n-1 (n,) [rad], eq. (2)."""
        return self.c.hinge(self._split(q))

    def hinge_energy(self, q) -> float:
        d = self.hinge_deflections(q)
        return 0.5 * float(np.sum(self.kappa * d ** 2))

    def bending_energy(self, q) -> float:
        """sum_k EI_k / 2 int_0^{l_k} (eta_k'')^2 ds by quadrature [J]."""
        qq, ll = self._split(q), list(self.l)
        e = 0.0
        for k in range(self.n):
            for s, w in zip(self.s[k], self.w[k]):
                e += 0.5 * self.EI[k] * w * float(self.c.curv[k](s, qq, ll)) ** 2
        return e

    def potential(self, q) -> float:
        """Pi(q) = hinge springs + bending [J]."""
        return self.hinge_energy(q) + self.bending_energy(q)

    def potential_gradient(self, q) -> np.ndarray:
        """dPi/dq (3n,): symbolic for the hinges, quadrature of EI eta'' d eta''/dq for bending."""
        qq, ll = self._split(q), list(self.l)
        g = self.c.hinge_grad(qq, list(self.kappa))
        for k in range(self.n):
            for s, w in zip(self.s[k], self.w[k]):
                g = g + self.EI[k] * w * float(self.c.curv[k](s, qq, ll)) \
                    * self.c.curv_grad[k](s, qq, ll)
        return g

    # ----- damping and loads -----
    def dissipation_force(self, q, qdot) -> np.ndarray:
        """dR/dqdot, R = 1/2 sum_h nu_h (d Delta_h / dt)^2 (3n,)."""
        return self.c.rayleigh_grad(self._split(q), self._split(qdot), list(self.nu))

    def load_force(self, q, forces) -> np.ndarray:
        """sum_k F_k . dr_k/dq for nodal forces ``forces`` (n, 2) = (X_k, Y_k) [N] (3n,)."""
        qq, ll = self._split(q), list(self.l)
        F = np.asarray(forces, float).reshape(self.n, 2)
        out = np.zeros(3 * self.n)
        for k in range(self.n):
            out += self.c.node_jac[k](qq, ll).T @ F[k]
        return out

    def residual(self, q, qdot, qddot, forces) -> np.ndarray:
        """Lagrange's equations: inertia + dPi/dq + dR/dqdot - loads (zero on a solution)."""
        return (self.exact_inertial_force(q, qdot, qddot) + self.potential_gradient(q)
                + self.dissipation_force(q, qdot) - self.load_force(q, forces))
