"""The paper's matrices, transcribed literally (section 1, after eqs. (9)-(10); section 2).

This module is the readable reference: dense (n, n) blocks built entry by entry exactly as
printed, 1-based formulas mapped to 0-based arrays (rod k of the paper is index k-1; hinge h
keeps its number h = 0..n-1, kappa_n = nu_n = 0). The fast right-hand sides in
:mod:`rod_sim.core.kernels` are checked against it, and it is checked against an
independent Lagrangian derivation in the tests.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ChainParams:
    """Per-rod constants of a chain, arrays of shape (n,), SI units.

    l [m], m [kg/m], mu [kg] (node masses at nodes 1..n), EI [N m^2],
    kappa [N m/rad] and nu [N m s/rad] of hinges 0..n-1.
    """

    l: np.ndarray
    m: np.ndarray
    mu: np.ndarray
    EI: np.ndarray
    kappa: np.ndarray
    nu: np.ndarray

    @classmethod
    def from_scene(cls, scene) -> "ChainParams":
        return cls(l=np.asarray(scene.length, float), m=np.asarray(scene.mass_per_length, float),
                   mu=np.asarray(scene.node_mass, float),
                   EI=np.asarray(scene.bending_stiffness, float),
                   kappa=np.asarray(scene.hinge_stiffness, float),
                   nu=np.asarray(scene.hinge_damping, float))

    @property
    def n(self) -> int:
        return len(self.l)

    def tail_mass(self) -> np.ndarray:
        """M_k = sum_{i>=k} (mu_i + m_i l_i) - m_k l_k / 2 [kg], shape (n,)."""
        ml = self.m * self.l
        return np.cumsum((self.mu + ml)[::-1])[::-1] - ml / 2.0

    def bending_stiffness_diag(self) -> np.ndarray:
        """K~ = diag(4 EI_k / l_k) [N m/rad], returned as its diagonal (n,)."""
        return 4.0 * self.EI / self.l


def inertia_blocks(p: ChainParams, phi: np.ndarray) -> dict[str, np.ndarray]:
    """The nine (n, n) inertia blocks m^{ab}, a, b in {phi, alpha, beta} [kg m^2]."""
    n, l, m = p.n, p.l, p.m
    M = p.tail_mass()
    blocks = _pair_blocks(p, np.cos(phi[:, None] - phi[None, :]))
    for key in ("aa", "ab", "ba", "bb"):
        blocks[key] = np.zeros((n, n))
    for k in range(n):
        blocks["pp"][k, k] = l[k] ** 2 * (M[k] - m[k] * l[k] / 2) + m[k] * l[k] ** 3 / 3
        blocks["pa"][k, k] = blocks["ap"][k, k] = m[k] * l[k] ** 3 / 30
        blocks["pb"][k, k] = blocks["bp"][k, k] = -m[k] * l[k] ** 3 / 20
        blocks["aa"][k, k] = blocks["bb"][k, k] = m[k] * l[k] ** 3 / 105
        blocks["ab"][k, k] = blocks["ba"][k, k] = -m[k] * l[k] ** 3 / 140
    return blocks


def velocity_blocks(p: ChainParams, phi: np.ndarray) -> dict[str, np.ndarray]:
    """The nonlinear-part blocks g^{pp}, g^{pa}, g^{pb}, g^{ap}, g^{bp} (n, n) [kg m^2]."""
    return _pair_blocks(p, np.sin(phi[:, None] - phi[None, :]))


def _pair_blocks(p: ChainParams, trig: np.ndarray) -> dict[str, np.ndarray]:
    """Off-diagonal entries of the pp, pa, pb, ap, bp blocks (n, n) [kg m^2] (diagonals
    zero), with ``trig[k, j]`` = cos(phi_k - phi_j) for the mass matrix, sin for the velocity
    terms: (k, j) couples rod k with a rod j below it (j < k) or above it (j > k)."""
    n, l, m = p.n, p.l, p.m
    M = p.tail_mass()
    b = {k: np.zeros((n, n)) for k in ("pp", "pa", "pb", "ap", "bp")}
    for k in range(n):
        for j in range(n):
            t = trig[k, j]
            if j < k:
                b["pp"][k, j] = l[k] * l[j] * t * M[k]
                b["ap"][k, j] = m[k] * l[k] ** 2 / 12 * l[j] * t
                b["bp"][k, j] = -m[k] * l[k] ** 2 / 12 * l[j] * t
            elif j > k:
                b["pp"][k, j] = l[k] * l[j] * t * M[j]
                b["pa"][k, j] = m[j] * l[j] ** 2 / 12 * l[k] * t
                b["pb"][k, j] = -m[j] * l[j] ** 2 / 12 * l[k] * t
    return b


def hinge_blocks(c: np.ndarray) -> dict[str, np.ndarray]:
    """Stiffness [kappa^{ab}] (or damping [nu^{ab}]) blocks from hinge constants ``c`` (n,).

    ``c[h]`` is kappa_h (or nu_h) of hinge h = 0..n-1; kappa_n = 0. The printed rules
    "x_{k,j+1}" and "x_{k+1,j}" are read as the entries (k, k+1) and (k+1, k).
    """
    n = len(c)
    cc = np.append(c, 0.0)          # cc[k] = kappa_k, kappa_n = 0
    b = {k: np.zeros((n, n)) for k in ("pp", "pa", "pb", "ap", "aa", "ab", "bp", "ba", "bb")}
    for r in range(n):              # r = k - 1 for the paper's rod k
        k_left, k_right = cc[r], cc[r + 1]      # kappa_{k-1}, kappa_k
        b["pp"][r, r] = k_left + k_right
        b["pa"][r, r] = k_left
        b["pb"][r, r] = k_right
        b["ap"][r, r] = k_left
        b["aa"][r, r] = k_left
        b["bp"][r, r] = k_right
        b["bb"][r, r] = k_right
        if r + 1 < n:
            b["pp"][r, r + 1] = b["pp"][r + 1, r] = -k_right
            b["pa"][r, r + 1] = -k_right
            b["pb"][r + 1, r] = -k_right
            b["ap"][r + 1, r] = -k_right
            b["ab"][r + 1, r] = -k_right
            b["bp"][r, r + 1] = -k_right
            b["ba"][r, r + 1] = -k_right
    return b


def generalized_forces(p: ChainParams, phi: np.ndarray, forces: np.ndarray) -> np.ndarray:
    """Q_k = l_k c_k sum_{j>=k} Y_j - l_k s_k sum_{j>=k} X_j [N m], shape (n,).

    ``forces`` (n, 2) holds (X_k, Y_k) [N] at nodes 1..n.
    """
    tail = np.cumsum(forces[::-1], axis=0)[::-1]
    return p.l * np.cos(phi) * tail[:, 1] - p.l * np.sin(phi) * tail[:, 0]


def full_system(p: ChainParams, q: np.ndarray, qdot: np.ndarray, forces: np.ndarray):
    """Mass matrix and right-hand side of the full model (9)-(10): M(q) qddot = F.

    ``q`` = [phi, alpha, beta] and ``qdot`` (3n,) each. Returns (M (3n, 3n), F (3n,)).
    """
    n = p.n
    phi, alpha, beta = q[:n], q[n:2 * n], q[2 * n:]
    dphi, dalpha, dbeta = qdot[:n], qdot[n:2 * n], qdot[2 * n:]
    mb, g = inertia_blocks(p, phi), velocity_blocks(p, phi)
    kb, vb = hinge_blocks(p.kappa), hinge_blocks(p.nu)
    Kt = np.diag(p.bending_stiffness_diag())
    lam = dphi                                  # Lambda = diag(phi_dot): Lambda x = phi_dot * x
    M = np.block([[mb["pp"], mb["pa"], mb["pb"]],
                  [mb["ap"], mb["aa"], mb["ab"]],
                  [mb["bp"], mb["ba"], mb["bb"]]])

    def row(a):
        return (vb[a + "p"] @ dphi + vb[a + "a"] @ dalpha + vb[a + "b"] @ dbeta
                + kb[a + "p"] @ phi + kb[a + "a"] @ alpha + kb[a + "b"] @ beta)

    F_phi = (generalized_forces(p, phi, forces) - g["pp"] @ (lam * dphi)
             - 2 * g["pa"] @ (lam * dalpha) - 2 * g["pb"] @ (lam * dbeta) - row("p"))
    F_alpha = -g["ap"] @ (lam * dphi) - row("a") - Kt @ (alpha + beta / 2)
    F_beta = -g["bp"] @ (lam * dphi) - row("b") - Kt @ (alpha / 2 + beta)
    return M, np.concatenate([F_phi, F_alpha, F_beta])


def reduction_matrices(p: ChainParams) -> tuple[np.ndarray, np.ndarray]:
    """[kappa^{gamma phi}] (2n, n) and [b^{gamma gamma}] (2n, 2n) of eq. (12)."""
    kb = hinge_blocks(p.kappa)
    Kt = np.diag(p.bending_stiffness_diag())
    K_gp = np.vstack([kb["ap"], kb["bp"]])
    B = np.block([[kb["aa"] + Kt, kb["ab"] + Kt / 2],
                  [kb["ba"] + Kt / 2, kb["bb"] + Kt]])
    return K_gp, B


def reduced_system(p: ChainParams, phi: np.ndarray, dphi: np.ndarray, forces: np.ndarray):
    """Eq. (15): reduced mass matrix M_r (n, n) and right-hand side F_r (n,) with
    M_r phi_ddot = F_r, plus the function that recovers gamma = [alpha, beta] (2n,) from
    phi_ddot via the first equation of (14)."""
    mb, g = inertia_blocks(p, phi), velocity_blocks(p, phi)
    kb, vb = hinge_blocks(p.kappa), hinge_blocks(p.nu)
    K_gp, B = reduction_matrices(p)
    P = K_gp.T @ np.linalg.inv(B)
    m_gp = np.vstack([mb["ap"], mb["bp"]])
    g_gp = np.vstack([g["ap"], g["bp"]])
    v_gp = np.vstack([vb["ap"], vb["bp"]])
    lam_dphi = dphi * dphi
    M_r = mb["pp"] - P @ m_gp
    F_r = (generalized_forces(p, phi, forces) - (g["pp"] - P @ g_gp) @ lam_dphi
           - (vb["pp"] - P @ v_gp) @ dphi - (kb["pp"] - P @ K_gp) @ phi)

    def gamma(phi_ddot):
        return -np.linalg.solve(B, m_gp @ phi_ddot + g_gp @ lam_dphi + v_gp @ dphi + K_gp @ phi)

    return M_r, F_r, gamma
