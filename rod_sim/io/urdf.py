"""The chain as a URDF robot model (for robot_state_publisher, RViz, Foxglove, MoveIt), pure
XML from a :class:`~rod_sim.core.scene.Scene`, no ROS.

Frames follow REP 103/105: the root link is the fixed frame (``world`` by default, the node's
``frame_id``), x forward, z up; the chain moves in the x-y plane. Link ``rod_k`` (k = 1..n) has
its origin at node k-1 (the hinge k-1, the rod's proximal end) and its x axis along the rod's
chord; link ``tip`` is node n. Joint ``hinge_h`` (h = 0..n-1, the names of ``joint_states``) is
a continuous-range revolute joint about z from ``rod_h`` (``world`` for h = 0) to ``rod_{h+1}``,
at x = l_h of its parent (0 for hinge 0); its position is the relative rigid hinge angle
``joint_states`` publishes, so forward kinematics of this model and ``joint_states`` gives the
chord end points ``node_poses`` publishes. (Bending, alpha/beta, is not a joint: the URDF shows
the chords.)

Inertia of ``rod_k`` [kg, kg m^2] in its frame: the rod's mass m_k l_k spread uniformly along
the chord plus the node mass mu_k at its distal end (node k), centre of mass on the chord;
izz = iyy = the planar moment about the centre of mass; ixx = M r_k^2 / 2 of the display
cylinder. Visual: a cylinder of radius r_k = l_k / 50 along the chord and a sphere of radius
2 r_k for a node mass. Joint position limits are the hinge stops when the scene has them (else
+-1e6 rad); effort and velocity limits, which URDF requires on a revolute joint, are set far
beyond anything the simulator limits (1e12 N m, 1e6 rad/s).
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np

RADIUS_FRACTION = 1.0 / 50.0
"""Display radius of a rod as a fraction of its length."""
WIDE = 1.0e6
"""[rad] limits of a hinge without stops (a revolute joint must have limits)."""
UNLIMITED_EFFORT = 1.0e12
"""[N m] the effort limit URDF requires: the simulator limits no moment (1e12, the scene's
largest magnitude)."""
UNLIMITED_VELOCITY = 1.0e6
"""[rad/s] the velocity limit URDF requires: not enforced by the simulator."""


def _fmt(x: float) -> str:
    return repr(float(x))


def _origin(parent: ET.Element, xyz=(0.0, 0.0, 0.0), rpy=(0.0, 0.0, 0.0)) -> None:
    ET.SubElement(parent, "origin", xyz=" ".join(_fmt(v) for v in xyz),
                  rpy=" ".join(_fmt(v) for v in rpy))


def rod_inertia(length: float, rod_mass: float, node_mass: float) -> tuple[float, float, float]:
    """(mass [kg], centre of mass x_c [m] on the chord, planar moment about it [kg m^2]) of a rod
    of ``length`` [m] and mass ``rod_mass`` [kg] with ``node_mass`` [kg] at its distal end."""
    total = rod_mass + node_mass
    if total <= 0.0:
        return 0.0, 0.5 * length, 0.0
    xc = (rod_mass * 0.5 * length + node_mass * length) / total
    izz = (rod_mass * length ** 2 / 12.0 + rod_mass * (0.5 * length - xc) ** 2
           + node_mass * (length - xc) ** 2)
    return total, xc, izz


def _stops(scene, h: int) -> tuple[float, float]:
    lower = upper = None
    if scene.stop_lower is not None:
        lower = float(np.broadcast_to(np.asarray(scene.stop_lower, float), (scene.n,))[h])
    if scene.stop_upper is not None:
        upper = float(np.broadcast_to(np.asarray(scene.stop_upper, float), (scene.n,))[h])
    lower = lower if lower is not None and math.isfinite(lower) else -WIDE
    upper = upper if upper is not None and math.isfinite(upper) else WIDE
    return lower, upper


def scene_urdf(scene, fixed_frame: str = "world") -> str:
    """The URDF XML text of ``scene`` (see the module docstring); ``fixed_frame`` names the
    root link (the node's ``frame_id``)."""
    n = scene.n
    length = np.asarray(scene.length, dtype=float)
    rod_mass = np.asarray(scene.mass_per_length, dtype=float) * length
    node_mass = np.broadcast_to(np.asarray(scene.node_mass, dtype=float), (n,))
    robot = ET.Element("robot", name=scene.name)
    ET.SubElement(robot, "link", name=fixed_frame)
    for k in range(1, n + 1):
        l_k, m_k, mu_k = length[k - 1], rod_mass[k - 1], node_mass[k - 1]
        radius = RADIUS_FRACTION * l_k
        link = ET.SubElement(robot, "link", name=f"rod_{k}")
        inertial = ET.SubElement(link, "inertial")
        mass, xc, izz = rod_inertia(l_k, m_k, mu_k)
        _origin(inertial, (xc, 0.0, 0.0))
        ET.SubElement(inertial, "mass", value=_fmt(mass))
        ET.SubElement(inertial, "inertia", ixx=_fmt(0.5 * mass * radius ** 2), ixy="0.0",
                      ixz="0.0", iyy=_fmt(izz), iyz="0.0", izz=_fmt(izz))
        visual = ET.SubElement(link, "visual", name=f"rod_{k}_chord")
        _origin(visual, (0.5 * l_k, 0.0, 0.0), (0.0, 0.5 * math.pi, 0.0))
        ET.SubElement(ET.SubElement(visual, "geometry"), "cylinder", radius=_fmt(radius),
                      length=_fmt(l_k))
        if mu_k > 0.0:
            node = ET.SubElement(link, "visual", name=f"node_{k}")
            _origin(node, (l_k, 0.0, 0.0))
            ET.SubElement(ET.SubElement(node, "geometry"), "sphere", radius=_fmt(2 * radius))
        parent = fixed_frame if k == 1 else f"rod_{k - 1}"
        joint = ET.SubElement(robot, "joint", name=f"hinge_{k - 1}", type="revolute")
        _origin(joint, (0.0 if k == 1 else length[k - 2], 0.0, 0.0))
        ET.SubElement(joint, "parent", link=parent)
        ET.SubElement(joint, "child", link=f"rod_{k}")
        ET.SubElement(joint, "axis", xyz="0 0 1")
        lower, upper = _stops(scene, k - 1)
        ET.SubElement(joint, "limit", lower=_fmt(lower), upper=_fmt(upper),
                      effort=_fmt(UNLIMITED_EFFORT), velocity=_fmt(UNLIMITED_VELOCITY))
    ET.SubElement(robot, "link", name="tip")
    tip = ET.SubElement(robot, "joint", name="tip_joint", type="fixed")
    _origin(tip, (length[-1], 0.0, 0.0))
    ET.SubElement(tip, "parent", link=f"rod_{n}")
    ET.SubElement(tip, "child", link="tip")
    ET.indent(robot)
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"
