"""Generate the robot's URDF (a spanning tree) and its loop closures (Extended URDF YAML).

The committed files are written and checked by :mod:`sixplus3.robot_description.generated`
(``python -m sixplus3.robot_description.generated [--check]``).

Tree (every joint named here is in the URDF):

- ``base_link``, fixed;
- leg i: ``leg{i}_A`` (actuated, R at A about x_f) -> ``leg{i}_proximal`` -> U at D as
  ``leg{i}_Ds2`` (about x, th_s2) and ``leg{i}_Ds3`` (about z, th_s3, mounted at
  R_z(-pi/2) so that the body frame is Q of paper eq. 1) -> ``leg{i}_body`` (DEFP);
  ``leg{i}_B`` (actuated) -> ``leg{i}_crankB`` -> U at G as ``leg{i}_Ga`` (about x) and
  ``leg{i}_Gb`` (about z) -> ``leg{i}_distalB`` (along its y, E at its tip); the same for
  C, H and F;
- ``platform_free`` (floating) -> ``platform`` -> ``platform_crank{i}`` (about z_p,
  psi_i = 0 along the outward radius) -> ``platform_crank{i}_link`` (P_i at its tip).

Closures (all spherical, 3D point coincidence): for leg i, k = 3i + (0: E, 1: F, 2: P):
``closedloop{k}_A`` on the leg body at E / F / P, ``closedloop{k}_B`` at the tip of
distal link B / distal link C / platform crank i.  36 tree DoF - 27 constraint rows = 9.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sixplus3.cache import cached
from sixplus3.robot_description.masses import BodyInertials, MassModel
from sixplus3.robot_description.robot import Robot, require_robot
from sixplus3.robot_description.robot_geometry import NUM_LEGS, RobotGeometry

URDF_DIR = Path(__file__).resolve().parent / "urdf"
URDF_PATH = URDF_DIR / "sixplus3.urdf"
CLOSURES_PATH = URDF_DIR / "sixplus3_closures.yaml"
POINT_MASS_URDF_PATH = URDF_DIR / "sixplus3_pointmass.urdf"

ROD_RADIUS = 0.008
#: The base beams (visual and collision), in each leg's frame: inwards of the actuated
#: axis by BASE_GAP, BASE_WIDTH wide, centred BASE_Z below it [m].
BASE_GAP, BASE_WIDTH, BASE_THICKNESS, BASE_Z = 0.015, 0.05, 0.02, -0.04
JOINT_SPHERE = 0.014


#: A point or direction [m]: three numbers.
Point = Sequence[float] | np.ndarray

def actuated_joint_names() -> list[str]:
    """The 9 actuated joints, legs 0..2, each in the order A, B, C."""
    return [f"leg{i}_{s}" for i in range(NUM_LEGS) for s in "ABC"]


def closure_pairs() -> list[tuple[str, str]]:
    return [(f"closedloop{k}_A", f"closedloop{k}_B") for k in range(3 * NUM_LEGS)]


#: Significant digits of every number the generator writes. A stated precision, so that
#: the file does not depend on the last bit of a float (which a numpy or libm patch
#: release may change: 0.0706 came out as 0.07059999999999998 on one fresh machine);
#: 15 digits keep the closure frames within 1e-15 m of each other.
DIGITS = 15


def _f(x: float) -> str:
    """``x`` at :data:`DIGITS` significant digits (``-0`` written as ``0``)."""
    text = f"{float(x):.{DIGITS}g}"
    return "0" if float(text) == 0.0 else text


def _vec(v: Point) -> str:
    return " ".join(_f(x) for x in v)


def _rod_inertia(mass: float, start: Any, end: Any,
                 radius: float) -> tuple[np.ndarray, np.ndarray]:
    """COM and inertia tensor (about the COM, link axes) of a uniform rod."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    axis = end - start
    length = float(np.linalg.norm(axis))
    u = axis / length
    i_perp = mass * length**2 / 12.0 + mass * radius**2 / 4.0
    i_axis = mass * radius**2 / 2.0
    inertia = i_perp * (np.eye(3) - np.outer(u, u)) + i_axis * np.outer(u, u)
    return (start + end) / 2.0, inertia


@dataclass
class _Builder:
    geom: RobotGeometry
    masses: MassModel
    root: ET.Element
    inertials: BodyInertials | None = None

    # ------------------------------------------------------------------ elements
    def link(self, name: str, mass: float = 0.0, com: Point = (0, 0, 0),
             inertia: np.ndarray | None = None) -> ET.Element:
        own = self.inertials.get(name) if self.inertials is not None else None
        if own is not None:  # a lab's or an identification's values replace the model
            mass, com, inertia = own.mass, own.com, own.inertia_matrix
        return self._link(name, mass, com, inertia)

    def _link(self, name: str, mass: float = 0.0, com: Point = (0, 0, 0),
              inertia: np.ndarray | None = None) -> ET.Element:
        """A link; a massless one states its zero mass and inertia: a link without
        ``<inertial>`` is given 1 kg by PyBullet's importer (the 22 frame links made the
        robot 23.9 kg there), while Pinocchio and MuJoCo (which fuses static bodies)
        add exactly nothing for it."""
        el = ET.SubElement(self.root, "link", name=name)
        inertial = ET.SubElement(el, "inertial")
        ET.SubElement(inertial, "origin", xyz=_vec(com), rpy="0 0 0")
        ET.SubElement(inertial, "mass", value=_f(mass))
        inn = np.zeros((3, 3)) if inertia is None else inertia
        ET.SubElement(inertial, "inertia", ixx=_f(inn[0, 0]), ixy=_f(inn[0, 1]),
                      ixz=_f(inn[0, 2]), iyy=_f(inn[1, 1]), iyz=_f(inn[1, 2]),
                      izz=_f(inn[2, 2]))
        return el

    def rod_link(self, name: str, mass: float, start: Point, end: Point,
                 material: str,
                 radius: float = ROD_RADIUS, collision: float | None = None) -> ET.Element:
        if self.masses.point_mass:
            el = self.link(name)
        else:
            com, inertia = _rod_inertia(mass, start, end, radius)
            el = self.link(name, mass, com, inertia)
        self.cylinder(el, start, end, radius, material, collision)
        return el

    def cylinder(self, link: ET.Element, start: Point, end: Point, radius: float,
                 material: str,
                 collision: float | None = None) -> None:
        """A visual cylinder from ``start`` to ``end``; with ``collision`` (a radius
        [m]), also the collision model's body (robot.collision, kinematics.collision) as
        a collision cylinder of that radius (URDF has no capsule: the model's bodies
        also reach that radius beyond each end)."""
        vis = self._cylinder_element(link, "visual", start, end, radius)
        ET.SubElement(vis, "material", name=material)
        if collision is not None:
            self.collision_cylinder(link, start, end, collision)

    def collision_cylinder(self, link: ET.Element, start: Point, end: Point,
                           radius: float) -> None:
        """A collision cylinder only (a body of the collision model that has no visual of
        its own)."""
        self._cylinder_element(link, "collision", start, end, radius)

    @staticmethod
    def _cylinder_element(link: ET.Element, tag: str, start: Point, end: Point,
                          radius: float) -> ET.Element:
        """A ``tag`` (visual or collision) cylinder of ``radius`` from ``start`` to
        ``end``: the URDF cylinder's axis (z) rotated onto the segment, pitch then yaw."""
        start, end = np.asarray(start, float), np.asarray(end, float)
        axis = end - start
        length = float(np.linalg.norm(axis))
        u = axis / length
        pitch = math.acos(max(-1.0, min(1.0, u[2])))
        el = ET.SubElement(link, tag)
        ET.SubElement(el, "origin", xyz=_vec((start + end) / 2),
                      rpy=_vec((0.0, pitch, math.atan2(u[1], u[0]))))
        ET.SubElement(ET.SubElement(el, "geometry"), "cylinder", radius=_f(radius),
                      length=_f(length))
        return el

    def sphere(self, link: ET.Element, center: Point, radius: float,
               material: str) -> None:
        vis = ET.SubElement(link, "visual")
        ET.SubElement(vis, "origin", xyz=_vec(center), rpy="0 0 0")
        geo = ET.SubElement(vis, "geometry")
        ET.SubElement(geo, "sphere", radius=_f(radius))
        ET.SubElement(vis, "material", name=material)

    def joint(self, name: str, kind: str, parent: str, child: str,
              xyz: Point = (0, 0, 0), rpy: Point = (0, 0, 0),
              axis: Point | None = None, limits: tuple[float, float] | None = None,
              effort: float = 0.0, velocity: float = 0.0,
              dynamics: tuple[float, float] | None = None) -> None:
        el = ET.SubElement(self.root, "joint", name=name, type=kind)
        ET.SubElement(el, "parent", link=parent)
        ET.SubElement(el, "child", link=child)
        ET.SubElement(el, "origin", xyz=_vec(xyz), rpy=_vec(rpy))
        if axis is not None:
            ET.SubElement(el, "axis", xyz=_vec(axis))
        if limits is not None:
            ET.SubElement(el, "limit", lower=_f(limits[0]), upper=_f(limits[1]),
                          effort=_f(effort), velocity=_f(velocity))
        if dynamics is not None:
            ET.SubElement(el, "dynamics", damping=_f(dynamics[0]), friction=_f(dynamics[1]))

    def frame(self, name: str, parent: str, xyz: Point) -> None:
        """A massless frame link on ``parent`` (Pinocchio turns it into a frame)."""
        self.link(name)
        self.joint(f"{name}_fixed", "fixed", parent, name, xyz=xyz)

    def passive(self, name: str, parent: str, child: str, axis: Point,
                xyz: Point = (0, 0, 0), rpy: Point = (0, 0, 0),
                limit: float = math.pi) -> None:
        self.joint(name, "revolute", parent, child, xyz=xyz, rpy=rpy, axis=axis,
                   limits=(-limit, limit), effort=0.0, velocity=100.0)


def robot_urdf(robot: Robot) -> str:
    """The URDF text of ``robot``'s spanning tree (:func:`build_urdf`, cached by the
    robot's hash and name)."""
    return cached(("urdf", f"{robot.hash}:{robot.name}"), lambda: build_urdf(robot))


def build_urdf(robot: Robot) -> str:
    """The URDF text of the spanning tree of ``robot``.

    The actuated joints carry the robot's hardware limits (range, effort, velocity) and
    the joint-side friction (``<dynamics damping friction>``).  The reflected rotor
    inertia has no URDF element: the loaders set it as the joint's armature
    (``Robot.motors.armature``), as they set gravity from ``robot.gravity``.  A payload
    is a link fixed to the platform; the tool centre point is the massless frame ``tcp``.
    """
    robot = require_robot(robot)
    root = ET.Element("robot", name=robot.name)
    for mat, rgba in (("base", "0.25 0.25 0.28 1"), ("motor", "0.1 0.1 0.1 1"),
                      ("alu", "0.75 0.77 0.80 1"), ("carbon", "0.15 0.15 0.15 1"),
                      ("joint", "0.85 0.45 0.10 1"), ("platform", "0.20 0.45 0.80 1")):
        m = ET.SubElement(root, "material", name=mat)
        ET.SubElement(m, "color", rgba=rgba)
    b = _Builder(robot.geometry, robot.masses, root, robot.inertials)
    base = _base(b, robot.geometry)
    for i in range(NUM_LEGS):
        _leg(b, robot, base, i)
    _platform(b, robot)
    ET.indent(root, space="  ")
    return _HEADER + ET.tostring(root, encoding="unicode") + "\n"


_HEADER = ("<?xml version=\"1.0\"?>\n<!-- Generated by robot_description/urdf.py from the "
           "parametric geometry; do not edit.\n"
           "     This is the spanning tree only: the 9 loop closures (spherical joints, "
           "frame pairs closedloopK_A / closedloopK_B)\n"
           "     are in sixplus3_closures.yaml (Pinocchio: "
           "sixplus3.robot_description.model.load_model_from(urdf, closures));\n"
           "     'sixplus3 robot export mjcf' writes the same robot for MuJoCo with the "
           "closures as equality constraints.\n"
           "     PyBullet's importer has no floating joint: it fixes the platform joint "
           "and, like every URDF tool, ignores the closures. -->\n")


def _base(b: _Builder, geom: RobotGeometry) -> ET.Element:
    """The base link: a beam under each leg, the motor housings."""
    base = b.link("base_link")
    # The base under each leg: a beam below its actuated axis, on the side of the robot's
    # centre.  It fills the quadrant a crank may not enter, theta in (270, 360) deg
    # (towards the centre and down, the paper's base collision), and a crank pointing
    # down or outwards (theta in [180, 270]) passes beside it.  (A round plate of radius
    # 0.2 m was drawn before, and the cranks swung through it.)
    for i in range(NUM_LEGS):
        R = geom.leg_rotation(i)
        centre = geom.leg_origin(i) + R @ np.array(
            [(geom.leg.l6 - geom.leg.l7) / 2, BASE_GAP + BASE_WIDTH / 2, BASE_Z])
        # it is 0.10 m long, centred under A: with the axes turned (the default robot's
        # 28 deg) a neighbour's crank at B or C hangs down beside this leg's axis line
        # near its ends (tests/test_robot_description.py sweeps every crank)
        size = (geom.leg.l6 + geom.leg.l7 - 0.16, BASE_WIDTH, BASE_THICKNESS)
        for tag in ("visual", "collision"):
            beam = ET.SubElement(base, tag)
            ET.SubElement(beam, "origin", xyz=_vec(centre),
                          rpy=_vec((0.0, 0.0, geom.leg_yaw(i))))
            ET.SubElement(ET.SubElement(beam, "geometry"), "box", size=_vec(size))
            if tag == "visual":
                ET.SubElement(beam, "material", name="base")
    for p in geom.actuated_joint_positions():
        # motor housings along the actuated axes (visual only)
        b.sphere(base, p, 0.022, "motor")
    return base


def _leg(b: _Builder, robot: Robot, base: ET.Element, i: int) -> None:
    """Leg i: its RU chain (A, the U joint at D, the body) and its RUS chains at B
    (closing at E) and C (closing at F), with the closures' frames."""
    geom, masses, lim, cm = robot.geometry, robot.masses, robot.limits, robot.collision
    leg = geom.leg
    pm = masses.point_mass
    A = geom.leg_origin(i)
    x = geom.leg_rotation(i)[:, 0]
    yaw = (0.0, 0.0, geom.leg_yaw(i))
    mot = robot.motors
    act: dict[str, Any] = {
        "limits": (lim.theta_min, lim.theta_max), "effort": lim.torque,
        "velocity": lim.velocity,
        "dynamics": (mot.viscous_per_joint[3 * i], mot.coulomb_per_joint[3 * i])}
    b.cylinder(base, A - (leg.l7 + 0.03) * x, A + (leg.l6 + 0.03) * x, 0.012, "motor")
    # the pulley stack at A (the collision model's hub)
    half = 0.5 * cm.hub_width * x
    b.cylinder(base, A - half, A + half, cm.hub_radius, "motor", collision=cm.hub_radius)
    # RU chain
    b.rod_link(f"leg{i}_proximal", masses.proximal, (0, 0, 0), (0, leg.l1, 0), "alu",
               collision=cm.link_radius)
    b.joint(f"leg{i}_A", "revolute", "base_link", f"leg{i}_proximal", xyz=A, rpy=yaw,
            axis=(1, 0, 0), **act)
    ucross_d = b.link(f"leg{i}_ucrossD", 0.0 if pm else masses.ucross, (0, 0, 0),
                      None if pm else np.eye(3) * 1e-6)
    b.sphere(ucross_d, (0, 0, 0), JOINT_SPHERE, "joint")
    b.passive(f"leg{i}_Ds2", f"leg{i}_proximal", f"leg{i}_ucrossD", (1, 0, 0),
              xyz=(0, leg.l1, 0))
    if pm:
        body = b.link(f"leg{i}_body", masses.point_mass_value, (leg.dp, 0, 0),
                      np.zeros((3, 3)))
    else:
        com, inertia = _rod_inertia(masses.body, (0, 0, 0), (leg.dp, 0, 0), ROD_RADIUS)
        body = b.link(f"leg{i}_body", masses.body, com, inertia)
    b.cylinder(body, (0, 0, 0), (leg.dp, 0, 0), ROD_RADIUS, "alu",
               collision=cm.link_radius)
    b.cylinder(body, (0, 0, 0), leg.e_b, ROD_RADIUS * 0.8, "alu")
    b.cylinder(body, (0, 0, 0), leg.f_b, ROD_RADIUS * 0.8, "alu")
    for pt in (leg.e_b, leg.f_b, (leg.dp, 0, 0)):
        b.sphere(body, pt, JOINT_SPHERE, "joint")
    b.passive(f"leg{i}_Ds3", f"leg{i}_ucrossD", f"leg{i}_body", (0, 0, 1),
              rpy=(0, 0, -math.pi / 2))
    b.frame(f"closedloop{3 * i}_A", f"leg{i}_body", leg.e_b)
    b.frame(f"closedloop{3 * i + 1}_A", f"leg{i}_body", leg.f_b)
    b.frame(f"closedloop{3 * i + 2}_A", f"leg{i}_body", (leg.dp, 0, 0))
    b.frame(f"leg{i}_P", f"leg{i}_body", (leg.dp, 0, 0))
    # RUS chains at B (closing at E) and C (closing at F)
    for side, off, crank, link_len, k in (("B", leg.l6, leg.l2, leg.l4, 3 * i),
                                          ("C", -leg.l7, leg.l3, leg.l5, 3 * i + 1)):
        uj = "G" if side == "B" else "H"
        b.rod_link(f"leg{i}_crank{side}", masses.crank, (0, 0, 0), (0, crank, 0), "alu",
                   collision=cm.crank_radius)
        jk = 3 * i + (1 if side == "B" else 2)
        b.joint(f"leg{i}_{side}", "revolute", "base_link", f"leg{i}_crank{side}",
                xyz=A + off * x, rpy=yaw, axis=(1, 0, 0),
                **{**act, "dynamics": (mot.viscous_per_joint[jk],
                                       mot.coulomb_per_joint[jk])})
        ucross = b.link(f"leg{i}_ucross{uj}", 0.0 if pm else masses.ucross, (0, 0, 0),
                        None if pm else np.eye(3) * 1e-6)
        b.sphere(ucross, (0, 0, 0), JOINT_SPHERE, "joint")
        b.passive(f"leg{i}_{uj}a", f"leg{i}_crank{side}", f"leg{i}_ucross{uj}", (1, 0, 0),
                  xyz=(0, crank, 0))
        b.rod_link(f"leg{i}_distal{side}", masses.distal, (0, 0, 0), (0, link_len, 0),
                   "carbon", radius=ROD_RADIUS * 0.75, collision=cm.distal_radius)
        b.passive(f"leg{i}_{uj}b", f"leg{i}_ucross{uj}", f"leg{i}_distal{side}", (0, 0, 1))
        b.frame(f"closedloop{k}_B", f"leg{i}_distal{side}", (0, link_len, 0))


def _platform(b: _Builder, robot: Robot) -> None:
    """The platform (a free body), its cranks, the plate's collision model, the payload
    and the tool centre point."""
    geom, masses, cm = robot.geometry, robot.masses, robot.collision
    pm = masses.point_mass
    if pm:
        platform = b.link("platform")
    else:
        rad, thick, mp = geom.platform_radius + 0.01, 0.01, masses.platform
        ixx = mp * (3 * rad * rad + thick * thick) / 12.0
        platform = b.link("platform", mp, (0, 0, 0), np.diag([ixx, ixx, mp * rad * rad / 2.0]))
    vis = ET.SubElement(platform, "visual")
    ET.SubElement(vis, "origin", xyz="0 0 0", rpy="0 0 0")
    ET.SubElement(ET.SubElement(vis, "geometry"), "cylinder",
                  radius=_f(geom.platform_radius + 0.012), length="0.01")
    ET.SubElement(vis, "material", name="platform")
    b.joint("platform_free", "floating", "base_link", "platform")
    for i in range(NUM_LEGS):
        beta = geom.crank_axis_angle(i)
        c = geom.platform_crank
        b.rod_link(f"platform_crank{i}_link", masses.platform_crank, (0, 0, 0), (c, 0, 0),
                   "platform", collision=cm.link_radius)
        # the plate's spoke O -> R_i and edge R_i -> R_{i+1} (collision model)
        up = np.array([0.0, 0.0, cm.plate_offset])
        r_i = geom.crank_axis_position(i) + up
        r_j = geom.crank_axis_position((i + 1) % NUM_LEGS) + up
        for a_pt, b_pt in ((up, r_i), (r_i, r_j)):
            b.collision_cylinder(platform, a_pt, b_pt, cm.plate_radius)
        b.passive(f"platform_crank{i}", "platform", f"platform_crank{i}_link", (0, 0, 1),
                  xyz=geom.crank_axis_position(i), rpy=(0, 0, beta))
        b.frame(f"closedloop{3 * i + 2}_B", f"platform_crank{i}_link", (c, 0, 0))
    if robot.payload.mass > 0.0:
        pl = robot.payload
        b.link("payload", pl.mass, pl.com, pl.inertia_matrix)
        b.joint("payload_fixed", "fixed", "platform", "payload")
    b.link("tcp")
    b.joint("tcp_fixed", "fixed", "platform", "tcp", xyz=robot.tool.xyz, rpy=robot.tool.rpy)


def build_closures_yaml() -> str:
    """Loop closures in the Extended URDF schema of Gepetto's example-parallel-robots."""
    pairs = closure_pairs()
    lines = [
        "# Loop closures of sixplus3.urdf (Extended URDF schema of Gepetto's",
        "# example-parallel-robots). Generated by robot_description/urdf.py; do not edit.",
        "# Every closure is a spherical joint: 3D coincidence of the two frame origins.",
        "closed_loop: [" + ", ".join(f"['{a}', '{b}']" for a, b in pairs) + "]",
        "type: [" + ", ".join("'3d'" for _ in pairs) + "]",
        "name_mot: [" + ", ".join(f"'{n}'" for n in actuated_joint_names()) + "]",
    ]
    return "\n".join(lines) + "\n"

