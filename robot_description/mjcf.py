"""The robot as MuJoCo MJCF: a second physics engine that shares no code with ours.

Written directly, not through MuJoCo's URDF importer, which merges the massless closure
frames away and knows no loop closures (docs/libraries.md).  What is written:

- the spanning tree of the URDF, one ``<body>`` per Pinocchio joint, with the joint's
  placement, the body's inertia (``model.inertias``: fixed links such as the payload
  merged, as the URDF defines them), a ``<joint type="hinge">`` about its axis, and a
  ``<freejoint>`` for the platform;
- each closure frame as a ``<site>`` on its body and each spherical closure as an
  ``<equality><connect site1 site2/>`` (stiff: ``solref`` 2 time steps, ``solimp`` near
  1), plus the tool centre point as a site ``tcp``;
- on the nine actuated hinges: ``armature`` (the reflected rotor inertia), ``damping``
  (viscous friction) and ``frictionloss`` (MuJoCo's dry friction: the Coulomb term,
  unsmoothed, made stiff by ``solreffriction`` of two steps: with MuJoCo's default of
  20 ms it acts as a damper below ~0.2 rad/s, which a prototype's bearings do not) and
  a ``<motor>`` of gear 1 (torque at the joint [N m]);
- the actuators limited to the robot's torque limit (``ctrlrange`` and ``forcerange``),
  the actuated hinges to its actuated range (``range``), when ``limits`` (the default);
- a ``home`` keyframe when ``keyframe`` is given (qpos of the assembled home pose and the
  holding torques as ctrl: :func:`sixplus3.control.drive.simulation.export_mjcf` computes
  them), so that the file starts assembled instead of at MuJoCo's qpos0, where the
  closures are 0.26 m open;
- gravity from the robot's mounting; contacts off by default (the clearance is a
  planner and gate constraint), or, with ``contacts``, with the collision model's radii
  (robot.collision) on the leg links, between the capsules of
  different legs (each leg its own ``contype`` bit, colliding with the other legs'
  bits); Newton solver, dense Jacobians.

The geometry is light capsules along the links for MuJoCo's viewer, with no mass
(``mass="0"``: the inertias above are the authority).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from sixplus3.cache import cached
from sixplus3.errors import InputError, check_number
from sixplus3.robot_description.model import closed_loop_model
from sixplus3.robot_description.robot import Robot, require_robot
from sixplus3.robot_description.urdf import _f, _vec, actuated_joint_names, closure_pairs

#: Simulation time step [s] of the exported model.
TIMESTEP = 1e-4


def _v(v: Sequence[float] | np.ndarray) -> str:
    return _vec(np.asarray(v, dtype=float).ravel())


def _quat_wxyz(R: np.ndarray) -> np.ndarray:
    q = pin.Quaternion(np.asarray(R, dtype=float))  # Pinocchio stores (x, y, z, w)
    return np.array([q.w, q.x, q.y, q.z])


def qpos_from_q(robot: Robot, q: np.ndarray) -> np.ndarray:
    """MuJoCo's qpos of the exported model from a Pinocchio configuration q: the same
    joints in the same order (hinges: the angle; the platform's free joint: position
    and the quaternion as (w, x, y, z), Pinocchio's being (x, y, z, w))."""
    m = closed_loop_model(robot).model
    q = np.asarray(q, dtype=float)
    out: list[float] = []
    for j in range(1, m.njoints):
        iq, nq = m.idx_qs[j], m.nqs[j]
        if nq == 7:
            x, y, z, w = q[iq + 3:iq + 7]
            out += [*q[iq:iq + 3], w, x, y, z]
        else:
            out += list(q[iq:iq + nq])
    return np.array(out)


def _leg_of(name: str) -> int | None:
    return int(name[3]) if name.startswith("leg") and name[3:4].isdigit() else None


def build_mjcf(robot: Robot, timestep: float = TIMESTEP,
               keyframe: tuple[np.ndarray, np.ndarray] | None = None,
               limits: bool = True, contacts: bool = False) -> str:
    """The MJCF text of ``robot``.

    ``keyframe``: (qpos, ctrl) of a ``home`` keyframe (:func:`qpos_from_q`); ``limits``:
    actuator and actuated-joint ranges from the robot's limits; ``contacts``: contact
    between the links of different legs (module doc)."""
    robot = require_robot(robot)
    check_number("timestep [s]", timestep, 1e-6, 1e-2)
    m = closed_loop_model(robot).model
    root = ET.Element("mujoco", model=robot.name)
    world = _options(root, robot, timestep, contacts)
    # sites: every frame that is a closure end or the TCP, on its parent joint's body
    site_frames = {name for pair in closure_pairs() for name in pair} | {"tcp"}
    sites: dict[int, list[tuple[str, pin.SE3]]] = {}
    for f in m.frames:
        if f.name in site_frames:
            sites.setdefault(int(f.parentJoint), []).append((f.name, f.placement))
    bodies = _bodies(world, m, robot, sites, timestep, limits)
    _capsules(bodies, m, sites, robot.collision, contacts)
    eq = ET.SubElement(root, "equality")
    for a, b in closure_pairs():
        ET.SubElement(eq, "connect", name=f"{a}-{b}", site1=a, site2=b)
    lim = robot.limits
    actuators = ET.SubElement(root, "actuator")
    for name in actuated_joint_names():
        attrs = {"name": name, "joint": name, "gear": "1"}
        if limits:
            attrs.update(ctrlrange=_v([-lim.torque, lim.torque]),
                         forcerange=_v([-lim.torque, lim.torque]))
        ET.SubElement(actuators, "motor", attrib=attrs)
    if keyframe is not None:
        qpos, ctrl = (np.asarray(k, dtype=float).ravel() for k in keyframe)
        if qpos.shape != (m.nq,) or ctrl.shape != (9,) or not (
                np.isfinite(qpos).all() and np.isfinite(ctrl).all()):
            raise InputError("the keyframe must be finite qpos of the model and 9 torques",
                             value=(qpos.shape, ctrl.shape), valid=f"({m.nq},), (9,)")
        keys = ET.SubElement(root, "keyframe")
        ET.SubElement(keys, "key", name="home", qpos=_v(qpos), ctrl=_v(ctrl))
    ET.indent(root, space="  ")
    return ("<!-- Generated by sixplus3 (robot_description/mjcf.py) for robot "
            f"{robot.hash[:12]}; do not edit -->\n" + ET.tostring(root, encoding="unicode")
            + "\n")


def _options(root: ET.Element, robot: Robot, timestep: float, contacts: bool
             ) -> ET.Element:
    """The compiler, the solver's options, the defaults, the light and the floor: the
    world body."""
    ET.SubElement(root, "compiler", angle="radian", autolimits="true",
                  boundmass="1e-9", boundinertia="1e-14")
    opt = ET.SubElement(root, "option", timestep=_f(timestep), gravity=_v(robot.gravity),
                        solver="Newton", jacobian="dense", integrator="implicitfast",
                        iterations="50", tolerance="1e-12")
    if not contacts:
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
    return world


def _bodies(world: ET.Element, m: Any, robot: Robot,
            sites: dict[int, list[tuple[str, pin.SE3]]], timestep: float, limits: bool
            ) -> dict[int, ET.Element]:
    """The spanning tree's bodies (Pinocchio's joints in order), their inertials,
    joints (the actuated ones with the motors' armature and friction) and sites."""
    act = actuated_joint_names()  # ordered: legs 0..2, each A, B, C
    mot, lim = robot.motors, robot.limits
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
                k = act.index(name)
                attrs.update(armature=_f(mot.armature_per_joint[k]),
                             damping=_f(mot.viscous_per_joint[k]),
                             frictionloss=_f(mot.coulomb_per_joint[k]),
                             # stiff dry friction: the friction row's time constant two
                             # steps (MuJoCo's default, 20 ms, regularises it into a
                             # damper below ~0.2 rad/s)
                             solreffriction=_f(2 * timestep) + " 1")
                if limits:
                    attrs.update(limited="true", range=_v([lim.theta_min, lim.theta_max]))
            ET.SubElement(body, "joint", **attrs)
        for sname, P in sites.get(j, []):
            ET.SubElement(body, "site", name=sname, pos=_v(P.translation),
                          quat=_v(_quat_wxyz(P.rotation)), size="0.004")
        bodies[j] = body
    return bodies


def _capsules(bodies: dict[int, ET.Element], m: Any,
              sites: dict[int, list[tuple[str, pin.SE3]]], cm: Any, contacts: bool) -> None:
    """Capsules from each body to its children's origins and its sites: visual, and
    with ``contacts`` the links of different legs collide (leg i: contype bit i,
    conaffinity the others), each leg link's capsule with the collision model's
    radius."""
    sizes = {"A": cm.link_radius, "Ds3": cm.link_radius, "B": cm.crank_radius,
             "C": cm.crank_radius, "Gb": cm.distal_radius, "Hb": cm.distal_radius}

    def capsule(j: int, size: str, t: np.ndarray) -> None:
        leg = _leg_of(m.names[j])
        attrs = {"type": "capsule", "size": size, "fromto": _v(np.r_[np.zeros(3), t])}
        if contacts and leg is not None:
            r = sizes.get(m.names[j].split("_", 1)[1])
            if r is not None:
                attrs["size"] = _f(r)
            attrs.update(contype=str(1 << leg), conaffinity=str(7 & ~(1 << leg)))
        ET.SubElement(bodies[j], "geom", attrs)

    for j in range(1, m.njoints):
        for c in range(j + 1, m.njoints):
            if m.parents[c] == j:
                t = m.jointPlacements[c].translation
                if np.linalg.norm(t) > 1e-4:
                    capsule(j, "0.006", t)
        for sname, P in sites.get(j, []):
            t = P.translation
            if sname != "tcp" and np.linalg.norm(t) > 1e-4:
                capsule(j, "0.005", t)


def mjcf(robot: Robot) -> str:
    """:func:`build_mjcf` at the default time step, cached by the robot's hash."""
    robot = require_robot(robot)
    return cached(("mjcf", f"{robot.hash}:{robot.name}"), lambda: build_mjcf(robot))
