"""The chains' momentum and first moment of mass, compiled: one pass over the rods.

:attr:`~rod_sim.core.state.State.momentum` adds a free base's terms to these, and
:meth:`~rod_sim.core.state.State.gravity_energy_with` takes the first moment. Rod k, with
chord direction e = (cos phi, sin phi), normal e_perp = (-sin phi, cos phi), start node r0
moving at v0 and end node r1 (node mass mu) moving at v1, has r(s) = r0 + s e + eta e_perp and
v(s) = v0 + (s phi' + eta') e_perp - eta phi' e; the integrals of m over s are in closed form
with the shape functions' moments (eq. (1)): ``eta1`` = int m eta, ``deta1`` = int m eta',
``Isd`` = int m s eta', ``Iee`` = int m eta^2 (all zero for straight chords). Sums run from
rod 0 to rod n - 1.
"""
from __future__ import annotations

from .jit import njit


@njit(inline="always")
def _first_moment(nodes, i, k, ex, ey, ml, half_l, mu, eta1):
    """int m r ds of rod k (start node at row i) plus its end node's mu r1 [kg m]: the mass
    m l at the chord's midpoint and int m eta ds along e_perp."""
    return (ml[k] * (nodes[i, 0] + half_l[k] * ex) + eta1[k] * -ey + mu[k] * nodes[i + 1, 0],
            ml[k] * (nodes[i, 1] + half_l[k] * ey) + eta1[k] * ex + mu[k] * nodes[i + 1, 1])


@njit
def chain_first_moment(nodes, starts, cos_phi, sin_phi, ml, half_l, mu, eta1, out):
    """Into ``out`` (2,): the chains' first moment of mass sum m r [kg m] (arguments as
    :func:`chain_momentum`'s)."""
    sx = sy = 0.0
    for k in range(starts.shape[0]):
        ax, ay = _first_moment(nodes, starts[k], k, cos_phi[k], sin_phi[k], ml, half_l, mu,
                               eta1)
        sx += ax
        sy += ay
    out[0] = sx
    out[1] = sy


@njit
def chain_momentum(nodes, vel, starts, cos_phi, sin_phi, dphi, ml, half_ml_l, half_l, l3_3,
                   mu, eta1, deta1, Isd, Iee, out):
    """Into ``out`` (5,): the chains' linear momentum (p_x, p_y) [kg m/s], angular momentum
    about the origin of Oxy [kg m^2/s] and first moment of mass (sum m r) [kg m].

    ``nodes``, ``vel`` (n + nc, 2): node positions [m] and velocities [m/s]; ``starts`` (n,)
    int: the row of each rod's start node (its end node is the next row); ``cos_phi``,
    ``sin_phi``, ``dphi`` [rad/s] (n,); per rod (n,): ``ml`` = m l [kg], ``half_ml_l`` =
    m l^2 / 2, ``half_l`` = l / 2 [m], ``l3_3`` = m l^3 / 3, ``mu`` the end node's mass [kg];
    the bending moments ``eta1``, ``deta1``, ``Isd``, ``Iee`` (n,) (module docstring)."""
    px = py = h = sx = sy = 0.0
    for k in range(dphi.shape[0]):
        i = starts[k]
        r0x, r0y = nodes[i, 0], nodes[i, 1]
        v0x, v0y = vel[i, 0], vel[i, 1]
        r1x, r1y = nodes[i + 1, 0], nodes[i + 1, 1]
        v1x, v1y = vel[i + 1, 0], vel[i + 1, 1]
        ex, ey = cos_phi[k], sin_phi[k]
        w = dphi[k]
        along = half_ml_l[k] * w + deta1[k]         # on e_perp
        back = eta1[k] * w                          # on -e
        lx = ml[k] * v0x + along * -ey - back * ex
        ly = ml[k] * v0y + along * ex - back * ey
        h += (r0x * ly - r0y * lx + half_ml_l[k] * (ex * v0y - ey * v0x)
              + eta1[k] * (-ey * v0y - ex * v0x) + l3_3[k] * w + Isd[k] + Iee[k] * w
              + mu[k] * (r1x * v1y - r1y * v1x))
        px += lx + mu[k] * v1x
        py += ly + mu[k] * v1y
        ax, ay = _first_moment(nodes, i, k, ex, ey, ml, half_l, mu, eta1)
        sx += ax
        sy += ay
    out[0] = px
    out[1] = py
    out[2] = h
    out[3] = sx
    out[4] = sy


@njit
def chain_base_reaction(nodes, acc, starts, roots, chain_of_rod, cos_phi, sin_phi, dphi, ddphi,
                        dgam, dgam_rate, alpha, beta, ddal, ddbe, half_l, ml, C, l3_3, l3_20,
                        l3_30, half_ml_l, mu, loads, gx, gy, full, bent, force, moment):
    """Into ``force`` (nc, 2) [N] and ``moment`` (nc,) [N m]: what each chain needs from its
    base (:func:`~rod_sim.core.momentum.base_reaction`): the force at its node 0 is the rate
    of the chain's momentum less its loads and weight; the moment is the moment about node 0
    of the loads and weight less the rate of the moment of momentum about node 0.

    ``nodes``, ``acc`` (n + nc, 2): node positions [m] and accelerations [m/s^2]; ``starts``
    (n,) int: each rod's start node row; ``roots`` (nc,) int: each chain's node 0 row;
    ``chain_of_rod`` (n,) int; ``cos_phi``, ``sin_phi``, ``dphi`` [rad/s], ``ddphi``
    [rad/s^2] (n,); ``dgam`` = alpha'' - beta'' and ``dgam_rate`` = alpha' - beta' (n,) (zeros
    but in the full model); the end slopes ``alpha``, ``beta`` [rad] and the full model's
    ``ddal``, ``ddbe`` [rad/s^2] (n,); per rod (n,) the
    :class:`~rod_sim.core.models.RodConstants` ``half_l``, ``ml``, ``C``, ``l3_3``, ``l3_20``,
    ``l3_30``, ``half_ml_l``, ``mu``; ``loads`` (n + 2, 3) (nodal X, Y [N] in rows 0..n-1);
    gravity (``gx``, ``gy``) [m/s^2]; ``full``: the full model's bending inertia terms;
    ``bent``: gravity acts on the bent rods (int m eta ds = C (alpha - beta) along e_perp: the
    full and the reduced model, whose slopes are quasi-static), else on the chords. Rods are
    summed in order, each chain from 0."""
    force[:, :] = 0.0
    moment[:] = 0.0
    for k in range(dphi.shape[0]):
        i = starts[k]
        c = chain_of_rod[k]
        o = roots[c]
        ex, ey = cos_phi[k], sin_phi[k]
        px, py = -ey, ex                            # e_perp
        w2 = dphi[k] * dphi[k]
        dd = ddphi[k]
        a0x, a0y = acc[i, 0], acc[i, 1]
        a1x, a1y = acc[i + 1, 0], acc[i + 1, 1]
        d0x, d0y = nodes[i, 0] - nodes[o, 0], nodes[i, 1] - nodes[o, 1]
        d1x, d1y = nodes[i + 1, 0] - nodes[o, 0], nodes[i + 1, 1] - nodes[o, 1]
        hm = half_ml_l[k]
        cd = C[k] * dgam[k]
        cr = 2.0 * C[k] * dphi[k] * dgam_rate[k]
        # int m a ds over the rod: its start node's acceleration plus the chord's turning
        fx = ml[k] * a0x + (hm * (dd * px - w2 * ex) + cd * px - cr * ex)
        fy = ml[k] * a0y + (hm * (dd * py - w2 * ey) + cd * py - cr * ey)
        rate = (d0x * fy - d0y * fx) + hm * (ex * a0y - ey * a0x) + l3_3[k] * dd
        if full:
            rate = rate + l3_30[k] * ddal[k] - l3_20[k] * ddbe[k]
        rate = rate + mu[k] * (d1x * a1y - d1y * a1x)
        wx, wy = d0x + half_l[k] * ex, d0y + half_l[k] * ey       # chord midpoint
        grav = ml[k] * (wx * gy - wy * gx) + mu[k] * (d1x * gy - d1y * gx)
        if bent:
            grav = grav + (C[k] * (alpha[k] - beta[k])) * (px * gy - py * gx)
        lx, ly = loads[k, 0], loads[k, 1]
        mass = ml[k] + mu[k]
        force[c, 0] += fx + mu[k] * a1x - lx - mass * gx
        force[c, 1] += fy + mu[k] * a1y - ly - mass * gy
        moment[c] += (d1x * ly - d1y * lx) + grav - rate
