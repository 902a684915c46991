"""``applied_base``: what acts on a free base and its wheel, as ``applied_forces`` is for the
chains' nodes (published when it changes, recorded every period, transient local).

std_msgs/Float64MultiArray, one dim ``base`` of 4 values [Fx, Fy, M, T_w]: the force [N] in
Oxy at the base's centre of mass, the moment [N m] on the base and the wheel motor's torque
[N m] (+T_w on the wheel, -T_w on the base), each the held command (``base_wrench`` turned
into Oxy, the ``wheel`` entry of ``hinge_torques``) plus the scene's scripted ``base`` /
``wheel`` loads at the period's start: rows n and n + 1 of the kernels' load table. With
``applied_forces`` and ``applied_torques`` it makes the log's input history complete, so that
the run can be re-simulated from the log alone.

# TODO(lead, after merging sc-out): one entry of ros/outputs.py's OUTPUTS table (qos
# "applied") and ``rod-sim compare`` / replay reading it (held base rows = applied - scripted,
# as for /applied_forces); kept here so that sc-in does not edit outputs.py.
"""
from __future__ import annotations

import numpy as np

from rod_sim.io import cdr

APPLIED_BASE_TOPIC = "applied_base"
APPLIED_BASE_TYPE = "std_msgs/msg/Float64MultiArray"
APPLIED_BASE_LABEL = "base"
"""Its one layout dim: [Fx, Fy, M, T_w]."""


def base_values(loads: np.ndarray) -> np.ndarray:
    """[Fx, Fy, M, T_w] (4,) from a load table (n + 2, 3) (rows n, n + 1)."""
    return np.array([loads[-2, 0], loads[-2, 1], loads[-2, 2], loads[-1, 2]], dtype=float)


def base_array(values) -> dict:
    """The ``applied_base`` message dict of [Fx, Fy, M, T_w]."""
    data = [float(v) for v in values]
    return {"layout": {"dim": [{"label": APPLIED_BASE_LABEL, "size": len(data),
                                "stride": len(data)}], "data_offset": 0}, "data": data}


class AppliedBase:
    """Sends ``applied_base``: ``publisher`` (``publish(bytes)``, or None: record only),
    ``recording`` (:class:`~rod_sim.ros.recording.NodeRecording`), ``topic``: the resolved
    name."""

    def __init__(self, publisher, recording, topic: str):
        self.publisher = publisher
        self.recording = recording
        self.topic = topic
        self._encode = cdr.encoder(APPLIED_BASE_TYPE)
        self._last: np.ndarray | None = None

    def send(self, t_ns: int, loads: np.ndarray) -> None:
        """The base rows of the load table ``loads`` (n + 2, 3) acting from ``t_ns`` on:
        recorded, and published when they changed (and the first time)."""
        values = base_values(loads)
        data = self._encode(base_array(values))
        self.recording.record_cdr(self.topic, APPLIED_BASE_TYPE, t_ns, data)
        if self._last is None or not np.array_equal(values, self._last):
            self._last = values
            if self.publisher is not None:
                self.publisher.publish(data)

    def forget(self) -> None:
        """After a reset: the next values are published whatever they are."""
        self._last = None
