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

    @property
    def n(self) -> int:
        return len(self.phi)
