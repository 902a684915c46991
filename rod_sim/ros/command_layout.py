"""What the node's command topics hold for a scene, and their validation (no ROS entity).

A scene's rods are flattened chain after chain in scene order (:mod:`rod_sim.core.scene`), and
so are the commands:

- ``nodal_forces`` (std_msgs/Float64MultiArray): 2 values per rod, [X_1, Y_1, ..., X_c, Y_c]
  [N] of each chain in scene order (n nodes in all);
- ``hinge_torques`` (std_msgs/Float64MultiArray): one value per hinge, [T_0, ..., T_{c-1}]
  [N m] of each chain in scene order, then, when the scene has a reaction wheel, one more
  entry ``wheel``: the wheel motor's torque [N m] (+T on the wheel, -T on the base);
- ``base_wrench`` (geometry_msgs/WrenchStamped): force x, y [N] at the base's centre of mass
  and torque z [N m] on a free base; ``header.frame_id`` the node's ``frame_id`` (inertial,
  default ``world``) or ``base`` (the base frame: the force is turned into Oxy by the base's
  angle psi at the start of every control period it is held for). Force z and torque x, y
  must be 0 (a planar base has no use for them; a command that sets them is rejected rather
  than half applied).

The layout dims of an array command are optional. When they are labelled with the scene's
chain names (and ``wheel`` last for the torques), in scene order, each dim's ``size`` is the
number of values of that chain and is checked chain by chain, so that a wrong count names its
chain; other dims are ignored, as before. Every refusal is a :class:`CommandError` with one
line naming the problem (and, with several chains, the chain).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from rod_sim.ros.conversions import CommandError

WHEEL = "wheel"
"""The last entry of ``hinge_torques`` on a scene with a reaction wheel (and its dim label)."""
BODY_FRAME = "base"
"""``header.frame_id`` of a ``base_wrench`` given in the base frame."""
_PLANAR_ZERO = (("force", "z"), ("torque", "x"), ("torque", "y"))


@dataclass(frozen=True)
class CommandLayout:
    """The commands of a scene: ``chains`` ((name or None, rod count), ...) in scene order,
    the base's ``base_mode`` ('fixed', 'free' or 'prescribed') and whether it has a ``wheel``."""

    chains: tuple[tuple[str | None, int], ...]
    base_mode: str = "fixed"
    wheel: bool = False

    @classmethod
    def single(cls, n: int) -> "CommandLayout":
        """One unnamed chain of ``n`` rods on the fixed ground (the paper's chain)."""
        return cls(((None, int(n)),))

    @classmethod
    def of_scene(cls, scene) -> "CommandLayout":
        base = scene.base
        return cls(tuple((c.name, c.count) for c in scene.chains), base.mode,
                   base.wheel is not None)

    @property
    def n(self) -> int:
        """Rods (= nodes 1..n = hinges) over all chains."""
        return sum(count for _, count in self.chains)

    @property
    def named(self) -> bool:
        return self.chains[0][0] is not None

    @property
    def free_base(self) -> bool:
        return self.base_mode == "free"

    @property
    def rows(self) -> int:
        """Rows of the held inputs: n (chains only), or n + 2 with a free base (row n: the
        base's Fx, Fy [N] in Oxy and moment [N m]; row n + 1: the wheel's motor torque in
        column 2 [N m]), the kernels' load-table rows."""
        return self.n + 2 if self.free_base else self.n

    def values(self, width: int) -> int:
        """Values of a ``nodal_forces`` (``width`` 2) or ``hinge_torques`` (``width`` 1)
        command."""
        return width * self.n + (1 if width == 1 and self.wheel else 0)

    # ----- array commands -----

    def forces(self, msg: Any) -> np.ndarray:
        """Validated nodal forces (n, 2) [N] of a ``nodal_forces`` command."""
        return self._values(msg, 2).reshape(self.n, 2)

    def torques(self, msg: Any) -> np.ndarray:
        """Validated hinge torques (n,) [N m], followed by the wheel's motor torque [N m] when
        the scene has a wheel ((n + 1,)), of a ``hinge_torques`` command."""
        return self._values(msg, 1)

    def _segments(self, width: int) -> list[tuple[str | None, int, str, bool]]:
        """(chain name, or 'wheel', its number of values, what they are, whether it is the
        wheel entry) in command order."""
        if width == 2:
            out = [(name, 2 * c, f"[X_1, Y_1, ..., X_{c}, Y_{c}]", False)
                   for name, c in self.chains]
        else:
            out = [(name, c, f"[T_0, ..., T_{c - 1}]", False) for name, c in self.chains]
        if width == 1 and self.wheel:
            out.append((WHEEL, 1, "[T_wheel] [N m]", True))
        return out

    @staticmethod
    def _label(name: str | None, wheel: bool) -> str:
        return "the wheel entry" if wheel else f"chain {name}" if name else "the chain"

    def _expected(self, width: int) -> str:
        """The expected values of a command, in words."""
        n = self.n
        if not self.named and not self.wheel:      # the chain on the ground: the old words
            return (f"[X_1, Y_1, ..., X_{n}, Y_{n}] for {n} nodes" if width == 2 else
                    f"[T_0, ..., T_{n - 1}] [N m] for hinges hinge_0..hinge_{n - 1}")
        return "in scene order: " + ", ".join(
            f"{self._label(name, wheel)} {size} {what}"
            for name, size, what, wheel in self._segments(width))

    def _values(self, msg: Any, width: int) -> np.ndarray:
        """The command's finite values after ``layout.data_offset`` (a copy), checked chain by
        chain when the layout dims name the chains; else CommandError. ``msg.data``: a
        sequence of floats (rclpy's ``array.array``) or a float64 numpy array (possibly a
        read-only view of the received bytes: :mod:`rod_sim.ros.command_cdr`)."""
        offset = int(getattr(getattr(msg, "layout", None), "data_offset", 0) or 0)
        data = np.asarray(msg.data, dtype=float)[offset:]
        size = self.values(width)
        segments = self._segments(width)
        self._check_dims(msg, segments)
        if data.size != size:
            hint = ""
            if width == 1 and not self.wheel and data.size == size + 1:
                hint = " (the scene has no reaction wheel: no 'wheel' entry)"
            raise CommandError(f"expected {size} values {self._expected(width)}, got "
                               f"{data.size}{hint}")
        bad = np.flatnonzero(~np.isfinite(data))
        if bad.size:
            i = int(bad[0])
            raise CommandError(f"non-finite value {float(data[i])!r} at data[{i + offset}]"
                               + self._where(i, width))
        return data.copy()

    def _check_dims(self, msg: Any, segments) -> None:
        """Per-chain sizes when the layout dims are labelled with the chain names."""
        if not self.named:
            return
        dims = list(getattr(getattr(msg, "layout", None), "dim", None) or [])
        names = [name for name, _, _, _ in segments]
        labels = [str(d.label) for d in dims]
        if not any(label in names for label in labels):
            return                                  # not a per-chain layout: dims ignored
        if labels != names:
            raise CommandError(f"layout dims {labels} must name the chains in scene order: "
                               f"{names}")
        for dim, (name, size, what, wheel) in zip(dims, segments):
            if int(dim.size) != size:
                raise CommandError(f"{self._label(name, wheel)}: layout dim of {int(dim.size)} "
                                   f"values, expected {size} {what}")

    def _where(self, i: int, width: int) -> str:
        """' (chain c, X_k)' for entry i of a command of several chains or with a wheel."""
        if not self.named and not self.wheel:
            return ""
        start = 0
        for name, size, _, wheel in self._segments(width):
            if i < start + size:
                j = i - start
                if wheel:
                    return " (the wheel entry)"
                entry = f"{'XY'[j % 2]}_{j // 2 + 1}" if width == 2 else f"T_{j}"
                return f" (chain {name}, {entry})" if name else f" ({entry})"
            start += size
        return ""

    # ----- base wrench -----

    def wrench(self, msg: Any, inertial_frame: str) -> tuple[np.ndarray, bool]:
        """Validated ``base_wrench``: ([Fx, Fy, M] [N, N, N m] in the command's frame, whether
        that frame is the base frame). ``inertial_frame``: the node's ``frame_id``."""
        if self.base_mode != "free":
            why = ("fixed" if self.base_mode == "fixed" else
                   "prescribed (its motion is given by base.motion)")
            raise CommandError(f"the scene's base is {why}: a base wrench cannot act on it "
                               f"(base.mode free takes one)")
        frame = str(msg.header.frame_id)
        if frame not in (inertial_frame, BODY_FRAME):
            raise CommandError(f"header.frame_id {frame!r}: expected {inertial_frame!r} "
                               f"(inertial) or {BODY_FRAME!r} (the base frame)")
        w = msg.wrench
        for part in ("force", "torque"):
            for axis in "xyz":
                value = float(getattr(getattr(w, part), axis))
                if not math.isfinite(value):
                    raise CommandError(f"non-finite value {value!r} in wrench.{part}.{axis}")
        for part, axis in _PLANAR_ZERO:
            value = float(getattr(getattr(w, part), axis))
            if value != 0.0:
                raise CommandError(f"wrench.{part}.{axis} = {value:g}: a planar base takes "
                                   "force x, y and torque z only (the others must be 0)")
        return np.array([w.force.x, w.force.y, w.torque.z], dtype=float), frame == BODY_FRAME


def to_inertial(wrench: np.ndarray, body: bool, psi: float) -> np.ndarray:
    """The wrench [Fx, Fy, M] in Oxy: a base-frame force turned by the base's angle ``psi``
    [rad] (the moment about z is the same in both frames)."""
    if not body:
        return wrench
    c, s = math.cos(psi), math.sin(psi)
    fx, fy, m = wrench
    return np.array([c * fx - s * fy, s * fx + c * fy, m])
