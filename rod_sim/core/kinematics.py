"""Positions of the chain: nodes (paper eq. (3)) and points of the bent rods (eqs. (1), (4))."""
from __future__ import annotations

import numpy as np


def node_positions(length: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Nodes 0..n of the chain, eq. (3): array (n+1, 2) [m]; node 0 at the origin.

    ``length`` (n,) [m], ``phi`` (n,) [rad].
    """
    out = np.zeros((len(phi) + 1, 2))
    out[1:, 0] = np.cumsum(length * np.cos(phi))
    out[1:, 1] = np.cumsum(length * np.sin(phi))
    return out


def chain_node_positions(length: np.ndarray, phi: np.ndarray, seg, attach, x: float,
                         y: float, psi: float) -> np.ndarray:
    """Every chain's nodes 0..n_c in scene order (n + nc, 2) [m] on a base frame at (x, y)
    [m] turned by psi [rad]: chain c (rods seg[c] .. seg[c+1] - 1) starts at its attach point
    (nc, 2) [m] of the base frame, then eq. (3) with the absolute angles phi."""
    c, s = np.cos(psi), np.sin(psi)
    seg = np.asarray(seg)
    out = np.empty((len(phi) + len(seg) - 1, 2))
    for ci in range(len(seg) - 1):
        a, b = int(seg[ci]), int(seg[ci + 1])
        ax, ay = attach[ci]
        nodes = node_positions(length[a:b], phi[a:b])
        nodes[:, 0] += x + c * ax - s * ay
        nodes[:, 1] += y + s * ax + c * ay
        out[a + ci:b + ci + 1] = nodes
    return out


def shape_functions(s: np.ndarray, length: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """sigma(s) and tau(s) of eq. (1) [m per rad of end slope]; ``s`` in [0, l]."""
    sigma = s * (length - s) ** 2 / length**2
    tau = -(s**2) * (length - s) / length**2
    return sigma, tau


def shape_table(length: np.ndarray, points_per_rod: int = 11
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(s, sigma, tau)`` at the points of :func:`rod_points`, each (n, points_per_rod): arc
    length [m] and the shape functions of eq. (1) there. They depend on the lengths only, so a
    caller drawing the same chain often can compute them once."""
    u = np.linspace(0.0, 1.0, points_per_rod)
    s = length[:, None] * u[None, :]                       # (n, P)
    sigma, tau = shape_functions(s, length[:, None])
    return s, sigma, tau


def rod_points(length: np.ndarray, phi: np.ndarray, alpha: np.ndarray, beta: np.ndarray,
               points_per_rod: int = 11, table=None, starts=None) -> np.ndarray:
    """Points of the bent rods, eq. (4): array (n, points_per_rod, 2) [m].

    Point j of rod k is at s = l_k j / (points_per_rod - 1); the first and last point of
    each rod are its end nodes. ``alpha``, ``beta`` (n,) are the end slopes [rad]. ``table``:
    ``shape_table(length, points_per_rod)`` if already computed (same result). ``starts``
    (n, 2) [m]: where each rod starts (several chains on a base; default: one chain from
    the origin, eq. (3)).
    """
    nodes = node_positions(length, phi) if starts is None else \
        np.concatenate([np.asarray(starts, dtype=float), np.zeros((1, 2))])
    s, sigma, tau = shape_table(length, points_per_rod) if table is None else table
    eta = alpha[:, None] * sigma + beta[:, None] * tau     # transverse deflection (n, P)
    c, sn = np.cos(phi)[:, None], np.sin(phi)[:, None]
    out = np.empty((len(phi), points_per_rod, 2))
    out[:, :, 0] = nodes[:-1, 0:1] + s * c - eta * sn
    out[:, :, 1] = nodes[:-1, 1:2] + s * sn + eta * c
    return out
