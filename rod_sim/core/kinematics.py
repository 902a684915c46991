"""Positions of the chain: nodes (paper eq. (3)) and points of the bent rods (eqs. (1), (4))."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np


def node_positions(length: np.ndarray, phi: np.ndarray, trig=None) -> np.ndarray:
    """Nodes 0..n of the chain, eq. (3): array (n+1, 2) [m]; node 0 at the origin.

    ``length`` (n,) [m], ``phi`` (n,) [rad]; ``trig`` = (cos phi, sin phi) if known.
    """
    c, s = (np.cos(phi), np.sin(phi)) if trig is None else trig
    out = np.zeros((len(phi) + 1, 2))
    out[1:, 0] = (length * c).cumsum()      # np.cumsum's own call, without its wrapper
    out[1:, 1] = (length * s).cumsum()
    return out


def pairs(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n, 2) C-ordered with columns a, b (n,): ``np.stack([a, b], axis=-1)``, cheaper."""
    out = np.empty((len(a), 2))
    out[:, 0] = a
    out[:, 1] = b
    return out


class ChainTable(NamedTuple):
    """Where each chain's rods and nodes are (:func:`chain_table`): ``index`` (nc, L) int, row
    c = chain c's rods seg[c] .. seg[c+1] - 1 then n (a zero pad) up to L, the longest chain's
    rod count; ``valid`` (nc, L) bool, False on the pads; ``chain`` (n,) int, each rod's
    chain; ``roots`` (nc,) int, the row of each chain's node 0 among the n + nc nodes;
    ``ends`` (n,) int, the row of each rod's end node (its start node is the row before);
    ``even``: every chain has L rods (no pads)."""

    index: np.ndarray
    valid: np.ndarray
    chain: np.ndarray
    roots: np.ndarray
    ends: np.ndarray
    even: bool


def chain_table(seg) -> ChainTable:
    """The :class:`ChainTable` of chains whose first rods are ``seg`` (nc + 1,) (then n)."""
    seg = np.asarray(seg, dtype=np.int64)
    counts = np.diff(seg)
    j = np.arange(int(counts.max(initial=0)))
    valid = j[None, :] < counts[:, None]
    index = np.where(valid, seg[:-1, None] + j[None, :], seg[-1])
    rods = np.arange(seg[-1])
    chain = np.searchsorted(seg[1:], rods, side="right")
    return ChainTable(index, valid, chain, seg[:-1] + np.arange(len(seg) - 1), rods + chain + 1,
                      bool(valid.all()))


def chain_cumsum(values: np.ndarray, table: ChainTable) -> np.ndarray:
    """Cumulative sums of ``values`` (n, ...) along the rods, restarting at each chain's first
    rod: the values of ``np.cumsum`` over each chain's slice, bit for bit (each chain's sums
    are accumulated in the same order; the pads come after them), in one pass over every
    chain (n, ...)."""
    if table.index.shape[0] == 1:
        return np.cumsum(values, axis=0)
    if table.even:               # chains of one length: a view of (nc, L, ...)
        rows = values.reshape(table.index.shape + values.shape[1:])
        return np.cumsum(rows, axis=1).reshape(values.shape)
    padded = np.concatenate([values, np.zeros((1,) + values.shape[1:])])[table.index]
    return np.cumsum(padded, axis=1)[table.valid]


def chain_nodes(origin: np.ndarray, steps: np.ndarray, table: ChainTable,
                root: np.ndarray | None = None) -> np.ndarray:
    """Every chain's nodes (n + nc, 2) in scene order from each chain's node 0 ``origin``
    (nc, 2) and the rods' steps (n, 2): node k of chain c at origin[c] + the sum of the
    chain's steps up to rod k (``origin + np.cumsum(steps of the chain)``, bit for bit), node 0
    at ``root`` (nc, 2) (default ``origin``)."""
    root = origin if root is None else root
    nc = len(origin)
    if table.even:               # chains of one length: slices of (nc, L + 1, 2)
        L = table.index.shape[1]
        out = np.empty((nc, L + 1, 2))
        out[:, 0] = root
        np.add(origin[:, None], np.cumsum(steps.reshape(nc, L, 2), axis=1), out=out[:, 1:])
        return out.reshape(-1, 2)
    out = np.empty((len(steps) + nc, 2))
    out[table.roots] = root
    out[table.ends] = origin[table.chain] + chain_cumsum(steps, table)
    return out


def chain_node_positions(length: np.ndarray, phi: np.ndarray, seg, attach, x: float,
                         y: float, psi: float, table: ChainTable | None = None,
                         trig=None) -> np.ndarray:
    """Every chain's nodes 0..n_c in scene order (n + nc, 2) [m] on a base frame at (x, y)
    [m] turned by psi [rad]: chain c (rods seg[c] .. seg[c+1] - 1) starts at its attach point
    (nc, 2) [m] of the base frame, then eq. (3) with the absolute angles phi. ``table``:
    :func:`chain_table` of ``seg`` and ``trig`` = (cos phi, sin phi) if already known. No
    loop over chains."""
    table = chain_table(seg) if table is None else table
    c, s = np.cos(psi), np.sin(psi)
    attach = np.asarray(attach, dtype=float).reshape(-1, 2)
    ax, ay = attach[:, 0], attach[:, 1]
    origin = pairs(x + c * ax - s * ay, y + s * ax + c * ay)                     # (nc, 2)
    cphi, sphi = (np.cos(phi), np.sin(phi)) if trig is None else trig
    steps = pairs(length * cphi, length * sphi)                                 # (n, 2)
    return chain_nodes(origin, steps, table, 0.0 + origin)


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
               points_per_rod: int = 11, table=None, starts=None, z: bool = False) -> np.ndarray:
    """Points of the bent rods, eq. (4): array (n, points_per_rod, 2) [m] (``z``: (n,
    points_per_rod, 3) with z = 0, as a 3-D message takes them).

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
    out = np.zeros((len(phi), points_per_rod, 3)) if z else \
        np.empty((len(phi), points_per_rod, 2))
    out[:, :, 0] = nodes[:-1, 0:1] + s * c - eta * sn
    out[:, :, 1] = nodes[:-1, 1:2] + s * sn + eta * c
    return out
