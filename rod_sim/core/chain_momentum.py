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
