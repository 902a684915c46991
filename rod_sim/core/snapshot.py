"""One sampled instant of a chain: everything the topics and the log publish."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Snapshot:
    """The chain at simulated time ``t`` [s].

    Shapes use n = number of rods:
    phi, phi_rate (n,): chord angles [rad] and rates [rad/s] of rods 1..n;
    alpha, beta (n,): bending end slopes at the left/right end of each rod [rad];
    hinge_angle, hinge_rate (n,): relative rigid hinge angles [rad] (phi_1 for hinge 0,
    phi_{k+1} - phi_k otherwise) and their rates [rad/s];
    hinge_moment (n,): elastic + viscous moment of each hinge [N m], including the bending
    slopes in the hinge's relative rotation (paper eq. (2));
    nodes (n+1, 2): node positions (x_k, y_k) [m], node 0 at the origin;
    forces (n, 2): applied nodal forces (X_k, Y_k) at nodes 1..n [N].

    On a spacecraft scene (a ``base:``, ``chains:`` or ``gravity:``; docs/spacecraft.md) also,
    else None: ``base`` (6,) the base frame's origin and angle in Oxy (x, y [m], psi [rad]) and
    their rates (x_rate, y_rate [m/s], psi_rate [rad/s], in Oxy); ``wheel_rate`` [rad/s] the
    wheel's spin relative to the base (0 without a wheel); ``momentum`` (6,) = linear momentum
    (p_x, p_y) [kg m/s], angular momentum about the origin of Oxy and about the system's
    centre of mass [kg m^2/s], centre of mass (x, y) [m] (with a fixed or prescribed base: of
    the chains only); ``energy_terms``: the energy ledger's terms [J] by name
    (:data:`ENERGY_TERMS`).
    """

    t: float
    phi: np.ndarray
    phi_rate: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    hinge_angle: np.ndarray
    hinge_rate: np.ndarray
    hinge_moment: np.ndarray
    nodes: np.ndarray
    forces: np.ndarray
    base: np.ndarray | None = None
    wheel_rate: float | None = None
    momentum: np.ndarray | None = None
    energy_terms: dict | None = None

    @property
    def n(self) -> int:
        return len(self.phi)


ENERGY_TERMS = ("kinetic", "hinge", "bending", "gravity", "base_kinetic", "wheel_kinetic",
                "total")
"""Keys of :attr:`Snapshot.energy_terms` [J]: the model's kinetic energy (chains, a free base
and its wheel), hinge springs and stop contacts, bending, the potential of gravity, the free
base's own kinetic energy (translation of its centre of mass and rotation, wheel excluded) and
the wheel's (J_W (psi' + theta_w')^2 / 2; both parts of ``kinetic``), and the total."""
