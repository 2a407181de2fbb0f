"""The robot as MuJoCo MJCF: a second physics engine that shares no code with ours.

Written directly, not through MuJoCo's URDF importer, which merges the massless closure
frames away and knows no loop closures (LIBRARY-NOTES.md).  What is written:

- the spanning tree of the URDF, one ``<body>`` per Pinocchio joint, with the joint's
  placement, the body's inertia (``model.inertias``: fixed links such as the payload
  merged, as the URDF defines them), a ``<joint type="hinge">`` about its axis, and a
  ``<freejoint>`` for the platform;
- each closure frame as a ``<site>`` on its body and each spherical closure as an
  ``<equality><connect site1 site2/>`` (stiff: ``solref`` 2 time steps, ``solimp`` near
  1), plus the tool centre point as a site ``tcp``;
- on the nine actuated hinges: ``armature`` (the reflected rotor inertia), ``damping``
  (viscous friction) and ``frictionloss`` (MuJoCo's dry friction: the Coulomb term,
  unsmoothed) and a ``<motor>`` of gear 1 (torque at the joint [N m]);
- gravity from the robot's mounting; contacts off (the legs' clearance is a planner
  constraint, not a contact); Newton solver, dense Jacobians.

The geometry is light capsules along the links for MuJoCo's viewer, with no mass
(``mass="0"``: the inertias above are the authority).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin

from sixplus3.robot_description.robot import Robot, _cached
from sixplus3.robot_description.urdf import _f, _vec, actuated_joint_names, closure_pairs

#: Simulation time step [s] of the exported model.
TIMESTEP = 1e-4


def _v(v) -> str:
    return _vec(np.asarray(v, dtype=float).ravel())


def _quat_wxyz(R: np.ndarray) -> np.ndarray:
    q = pin.Quaternion(np.asarray(R, dtype=float))  # Pinocchio stores (x, y, z, w)
    return np.array([q.w, q.x, q.y, q.z])


def build_mjcf(robot: Robot | None = None, timestep: float = TIMESTEP) -> str:
    """The MJCF text of ``robot`` (default ``Robot.default()``)."""
    robot = robot or Robot.default()
    if not (math.isfinite(timestep) and 1e-6 <= timestep <= 1e-2):
        from sixplus3.errors import InputError

        raise InputError(f"timestep {timestep!r} s out of range", value=timestep,
                         valid="[1e-6, 1e-2] s")
    clm = robot.closed_loop_model()
    m = clm.model
    act = set(actuated_joint_names())
    mot = robot.motors
    root = ET.Element("mujoco", model=robot.name)
    ET.SubElement(root, "compiler", angle="radian", autolimits="true",
                  boundmass="1e-9", boundinertia="1e-14")
    opt = ET.SubElement(root, "option", timestep=_f(timestep), gravity=_v(robot.gravity),
                        solver="Newton", jacobian="dense", integrator="implicitfast",
                        iterations="50", tolerance="1e-12")
    ET.SubElement(opt, "flag", contact="disable")
    default = ET.SubElement(root, "default")
    ET.SubElement(default, "geom", contype="0", conaffinity="0", mass="0",
                  rgba="0.7 0.7 0.75 1")
    ET.SubElement(default, "equality", solref=_f(2 * timestep) + " 1",
                  solimp="0.9999 0.9999 0.001 0.5 2")
    world = ET.SubElement(root, "worldbody")
    ET.SubElement(world, "light", pos="0 0 1.5", dir="0 0 -1")
    ET.SubElement(world, "geom", type="cylinder", size="0.2 0.01", pos="0 0 -0.04",
                  rgba="0.25 0.25 0.28 1")

    # sites: every frame that is a closure end or the TCP, on its parent joint's body
    site_frames = {name for pair in closure_pairs() for name in pair} | {"tcp"}
    sites: dict[int, list[tuple[str, pin.SE3]]] = {}
    for f in m.frames:
        if f.name in site_frames:
            sites.setdefault(int(f.parentJoint), []).append((f.name, f.placement))

    bodies: dict[int, ET.Element] = {0: world}
    for j in range(1, m.njoints):
        name = m.names[j]
        M = m.jointPlacements[j]
        parent = bodies[m.parents[j]]
        body = ET.SubElement(parent, "body", name=name, pos=_v(M.translation),
                             quat=_v(_quat_wxyz(M.rotation)))
        Y = m.inertias[j]
        I = Y.inertia
        ET.SubElement(body, "inertial", pos=_v(Y.lever), mass=_f(max(Y.mass, 0.0)),
                      fullinertia=_v([I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2],
                                      I[1, 2]]))
        kind = m.joints[j].shortname()
        if kind == "JointModelFreeFlyer":
            ET.SubElement(body, "freejoint", name=name)
        else:
            axis = "1 0 0" if kind == "JointModelRX" else "0 0 1"
            attrs = {"name": name, "type": "hinge", "axis": axis, "limited": "false"}
            if name in act:
                attrs.update(armature=_f(mot.armature), damping=_f(mot.viscous),
                             frictionloss=_f(mot.coulomb))
            ET.SubElement(body, "joint", **attrs)
        for sname, P in sites.get(j, []):
            ET.SubElement(body, "site", name=sname, pos=_v(P.translation),
                          quat=_v(_quat_wxyz(P.rotation)), size="0.004")
        bodies[j] = body
    # visual capsules from each body to its children's origins
    for j in range(1, m.njoints):
        for c in range(j + 1, m.njoints):
            if m.parents[c] == j:
                t = m.jointPlacements[c].translation
                if np.linalg.norm(t) > 1e-4:
                    ET.SubElement(bodies[j], "geom", type="capsule", size="0.006",
                                  fromto=_v(np.r_[np.zeros(3), t]))
        for sname, P in sites.get(j, []):
            t = P.translation
            if sname != "tcp" and np.linalg.norm(t) > 1e-4:
                ET.SubElement(bodies[j], "geom", type="capsule", size="0.005",
                              fromto=_v(np.r_[np.zeros(3), t]))

    eq = ET.SubElement(root, "equality")
    for a, b in closure_pairs():
        ET.SubElement(eq, "connect", name=f"{a}-{b}", site1=a, site2=b)
    actuators = ET.SubElement(root, "actuator")
    for name in actuated_joint_names():
        ET.SubElement(actuators, "motor", name=name, joint=name, gear="1")
    ET.indent(root, space="  ")
    return ("<!-- Generated by sixplus3 (robot_description/mjcf.py) for robot "
            f"{robot.hash[:12]}; do not edit -->\n" + ET.tostring(root, encoding="unicode")
            + "\n")


def mjcf(robot: Robot | None = None) -> str:
    """:func:`build_mjcf` at the default time step, cached by the robot's hash."""
    robot = robot or Robot.default()
    return _cached(("mjcf", f"{robot.hash}:{robot.name}"), lambda: build_mjcf(robot))
