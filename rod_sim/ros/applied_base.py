"""``applied_base``: what acts on a free base and its wheel, as ``applied_forces`` is for the
chains' nodes (published when it changes, recorded every period, transient local).

std_msgs/Float64MultiArray, one dim ``base`` of 4 values [Fx, Fy, M, T_w]: the force [N] in
Oxy at the base's centre of mass, the moment [N m] on the base and the wheel motor's torque
[N m] (+T_w on the wheel, -T_w on the base), each the held command (``base_wrench`` turned
into Oxy, the ``wheel`` entry of ``hinge_torques``) plus the scene's scripted ``base`` /
``wheel`` loads at the period's start: rows n and n + 1 of the kernels' load table. With
``applied_forces`` and ``applied_torques`` it makes the log's input history complete, so that
the run can be re-simulated from the log alone.

An entry of :data:`rod_sim.ros.outputs.OUTPUTS` (free bases only), sent by
:meth:`rod_sim.ros.outputs.Outputs.applied`.
"""
from __future__ import annotations

import numpy as np

APPLIED_BASE_TOPIC = "applied_base"
APPLIED_BASE_TYPE = "std_msgs/msg/Float64MultiArray"
APPLIED_BASE_LABEL = "base"
"""Its one layout dim: [Fx, Fy, M, T_w]."""


def base_values(loads: np.ndarray) -> np.ndarray:
    """[Fx, Fy, M, T_w] (4,) from a load table (n + 2, 3) (rows n, n + 1)."""
    return np.array([loads[-2, 0], loads[-2, 1], loads[-2, 2], loads[-1, 2]], dtype=float)

