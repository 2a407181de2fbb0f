"""Robots as a real build differs from its model: perturbed plants for the virtual
prototype, and the conversion between a robot's bodies and the regressor's parameters."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from sixplus3.dynamics.regressor import N_BODY, N_MOTOR, Layout, body_links
from sixplus3.errors import InputError, check_number
from sixplus3.robot_description.masses import BODY_LINKS, BodyInertial, BodyInertials
from sixplus3.robot_description.model import closed_loop_model
from sixplus3.robot_description.physical import MotorModel, Payload
from sixplus3.robot_description.robot import Robot, require_robot


def link_inertials(robot: Robot) -> dict[str, BodyInertial]:
    """Each moving link's (mass, com, inertia about the com) as the robot's Pinocchio
    model has it (the link frame is its joint's frame; the payload is not a link)."""


    bare = robot if robot.payload.mass == 0.0 else replace(robot, payload=Payload())
    model = closed_loop_model(bare).model

    out = {}
    for j, link in enumerate(body_links(model), 1):
        Y = model.inertias[j]
        I = Y.inertia
        out[link] = BodyInertial(float(Y.mass), tuple(float(c) for c in Y.lever),  # type: ignore[arg-type]
                                 (I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]))
    return out


def body_to_inertial(p: np.ndarray) -> BodyInertial:
    """One body's 10 parameters (Pinocchio's order, about the frame origin) as mass,
    centre of mass and inertia about it (a massless body: all zero)."""
    m = float(p[0])
    if m <= 1e-12:
        return BodyInertial(0.0, (0.0, 0.0, 0.0), (0.0,) * 6)  # type: ignore[arg-type]
    c = np.asarray(p[1:4]) / m
    ixx, ixy, iyy, ixz, iyz, izz = p[4:10]
    Io = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    Ic = Io - m * (float(c @ c) * np.eye(3) - np.outer(c, c))
    Ic = 0.5 * (Ic + Ic.T)
    # the inertia about the com of a consistent body is PSD with the triangle
    # inequality; remove rounding below 1e-15 kg m^2
    w, V = np.linalg.eigh(Ic)
    w = np.maximum(w, 0.0)
    s = np.sort(w)
    if s[2] > s[0] + s[1]:
        w = np.where(w == s[2], s[0] + s[1], w)
    Ic = (V * w) @ V.T
    return BodyInertial(m, (float(c[0]), float(c[1]), float(c[2])),  # type: ignore[arg-type]
                        (float(Ic[0, 0]), float(Ic[1, 1]), float(Ic[2, 2]), float(Ic[0, 1]),
                         float(Ic[0, 2]), float(Ic[1, 2])))


def robot_with_parameters(robot: Robot, pi: np.ndarray, layout: Layout,
                          name: str | None = None) -> Robot:
    """``robot`` realising the parameters ``pi``: each body's inertial (the payload's
    share taken out of the platform's), each joint's rotor inertia and friction."""
    robot = require_robot(robot)
    pi = np.asarray(pi, dtype=float)
    if pi.shape != (layout.size,) or not np.all(np.isfinite(pi)):
        raise InputError("parameters of the wrong size or not finite", value=pi.shape,
                         valid=f"({layout.size},) finite")
    pl = robot.payload
    bodies = {}
    for b, link in enumerate(layout.bodies):
        p = pi[N_BODY * b:N_BODY * (b + 1)].copy()
        if link == "platform" and pl.mass > 0.0:
            p = p - _payload_parameters(pl)
        bodies[link] = body_to_inertial(p)
    mot = pi[N_BODY * len(layout.bodies):].reshape(-1, N_MOTOR)
    motors = per_joint_motors(robot.motors, mot[:, 0], mot[:, 1], mot[:, 2])
    return robot.replace(inertials=BodyInertials(bodies=tuple(bodies.items())),
                         motors=motors, name=name or robot.name)


def per_joint_motors(motors: MotorModel, armature: np.ndarray, viscous: np.ndarray,
                     coulomb: np.ndarray) -> MotorModel:
    """``motors`` with each joint's rotor inertia at the joint and friction set."""

    return replace(motors, joint_armature=tuple(float(x) for x in armature),
                   joint_viscous=tuple(float(x) for x in viscous),
                   joint_coulomb=tuple(float(x) for x in coulomb))


def _payload_parameters(pl: Payload) -> np.ndarray:
    """The payload's 10 parameters in the platform frame (Pinocchio's order)."""
    # deferred: Pinocchio loads only when this runs
    import pinocchio as pin

    Y = pin.Inertia(pl.mass, np.asarray(pl.com), pl.inertia_matrix)
    return np.asarray(Y.toDynamicParameters())


def perturbed_plant(robot: Robot, seed: int, mass: float = 0.3, com: float = 0.01,
                    rotor: float = 0.4, friction: float = 3.0,
                    name: str | None = None) -> Robot:
    """A plant as a real build differs from ``robot``: every link's mass and inertia
    scaled by its own factor in [1 - mass, 1 + mass], its centre of mass moved by up to
    ``com`` [m] per axis, each joint's rotor inertia scaled in [1 - rotor, 1 + rotor],
    its viscous and Coulomb friction multiplied by a factor in [1, friction] (seeded)."""
    for k, v, lo, hi in (("mass", mass, 0.0, 0.9), ("com", com, 0.0, 0.05),
                         ("rotor", rotor, 0.0, 0.9),
                         ("friction", friction, 1.0, 10.0)):  # a factor in [1, friction]
        check_number(k, v, lo, hi)
    check_number("seed", seed, 0, 2 ** 32 - 1, integer=True)
    rng = np.random.default_rng(seed)
    bodies = {}
    for link, b in link_inertials(robot).items():
        if link not in BODY_LINKS:
            continue
        s = 1.0 + rng.uniform(-mass, mass)
        c = np.asarray(b.com) + rng.uniform(-com, com, 3) * (b.mass > 0)
        bodies[link] = BodyInertial(b.mass * s, (float(c[0]), float(c[1]), float(c[2])),
                                    tuple(float(x) * s for x in b.inertia))  # type: ignore[arg-type]
    mot = robot.motors
    arm = mot.armature_per_joint * (1.0 + rng.uniform(-rotor, rotor, 9))
    visc = mot.viscous_per_joint * rng.uniform(1.0, friction, 9)
    coul = mot.coulomb_per_joint * rng.uniform(1.0, friction, 9)
    motors = per_joint_motors(mot, arm, visc, coul)
    return robot.replace(inertials=BodyInertials(bodies=tuple(bodies.items())),
                         motors=motors, name=name or f"plant-seed{seed}")


__all__ = ["body_to_inertial", "link_inertials", "per_joint_motors", "perturbed_plant",
           "robot_with_parameters"]
