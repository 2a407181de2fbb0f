"""Symbolic (CasADi) kinematics and dynamics of the whole robot in minimal coordinates.

pinocchio.casadi is not in the pip wheel (docs/libraries.md), so the dynamics are built
here from two ingredients that cannot drift from the numeric model:

1. the closed-form inverse kinematics (docs/conventions.md conventions, same branches as
   :mod:`kinematics.leg`) written with CasADi symbols, giving every tree joint as a
   function of the minimal coordinates x = (platform position p [m], rotation vector r
   [rad], crank angles psi [rad]);
2. a symbolic forward kinematics of the spanning tree that reads the joint placements,
   joint types and body inertias from the *Pinocchio model of the URDF*.

Dynamics: a symbolic recursive Newton-Euler pass over the tree (world frame, joint
rates qd = Jq xd from the IK) gives the tree's generalized forces; by virtual work
Q(x, xd, xdd) = Jq^T tau_tree + (platform force, E^T platform moment) and the actuator
torques satisfy tau^T d(theta) = Q^T dx, i.e. tau = (d theta / d x)^-T Q, plus the
motors' own term I_a theta_ddot + b theta_dot + tau_c tanh(theta_dot / omega_c).
tests/test_planner.py
checks tau against Pinocchio's constrained inverse dynamics (tau = G^T rnea).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from sixplus3.cache import cached
from sixplus3.dynamics.clearance import clearance_rows
from sixplus3.dynamics.platform_rows import platform_line_det_normalised
from sixplus3.dynamics.symbolic_ik import ik_expressions
from sixplus3.dynamics.tree import (
    N_BODY_PARAMETERS,
    SETUP_BODIES,
    revolute_joints,
    tree_forces,
    tree_placements,
)
from sixplus3.kinematics.collision import hub_segments
from sixplus3.kinematics.spherical import spherical_reference
from sixplus3.robot_description.assembly import AssemblyMode
from sixplus3.robot_description.model import closed_loop_model
from sixplus3.robot_description.robot import Robot, require_robot
from sixplus3.robot_description.robot_geometry import NUM_LEGS

NX = 9  # minimal coordinates: p (3), r (3), psi (3)


@dataclass(frozen=True)
class SymbolicRobot:
    """CasADi functions of the robot in minimal coordinates (all SX, cached)."""

    theta: ca.Function  # x -> theta (9)
    theta_dot: ca.Function  # (x, xd) -> theta_dot (9)
    theta_ddot: ca.Function  # (x, xd, xdd) -> theta_ddot (9)
    tau: ca.Function  # (x, xd, xdd) -> actuator torques (9) [N m]
    q: ca.Function  # x -> Pinocchio configuration (37)
    reach: ca.Function  # x -> (9,) q2 >= 0 reachability measures, 3 per leg
    margins: ca.Function  # x -> (leg type I (9,), leg type II det (3,), platform line det)
    spherical_cos: ca.Function  # x -> (9,) cosines of the S-joint tilts
    node: ca.Function  # (x, xd, u, tau) -> the 70 path-constraint rows of one point
    #: ``node`` with the setup as a last input p (:func:`setup_parameters`): one compiled
    #: library serves every payload, mounting and motor model of a structure
    node_p: ca.Function
    params: np.ndarray  # this robot's p

    #: Row layout of ``node``: name -> (start, stop)
    NODE_ROWS = {"dynamics": (0, 9), "theta_dot": (9, 18), "theta_ddot": (18, 27),
                 "theta": (27, 36), "reach": (36, 45), "spherical_cos": (45, 54),
                 "type1": (54, 63), "type2_det": (63, 66), "platform_det": (66, 67),
                 "clearance": (67, 70)}


#: The tree's bodies (Pinocchio joints 1..31: 9 per leg, the platform, its 3 cranks).
N_BODIES = 31
#: Layout of the setup parameters p: gravity (3); every body's ten inertial parameters
#: (Pinocchio's order, the payload merged into the platform's; :data:`tree.SETUP_BODIES`
#: on); per actuated joint its rotor inertia at the joint (9), viscous (9) and Coulomb
#: (9) friction; the Coulomb law's smoothing speed (1).
SETUP_MOTORS = SETUP_BODIES + N_BODY_PARAMETERS * N_BODIES
N_SETUP = SETUP_MOTORS + 27 + 1


def structure(robot: Robot) -> Robot:
    """The robot without what :func:`setup_parameters` carries (masses and per-body
    inertials, payload, mounting, motors) and what the constraint functions never see
    (limits, tool): its symbolic model and compiled code are shared by every robot of the
    same structure, so that a robot with other masses (an identified one) plans at once.
    The home pose stays: it defines the spherical joints' mounting axes."""
    return Robot(geometry=robot.geometry, mode=robot.mode, collision=robot.collision,
                 home_position=robot.home_position, home_psi=robot.home_psi)


def setup_parameters(robot: Robot) -> np.ndarray:
    """(N_SETUP,) the setup of ``robot`` as the symbolic model's parameter vector: its
    gravity, its Pinocchio model's body inertias (from its URDF: masses, per-body
    inertials, payload) and its motors per joint."""
    robot = require_robot(robot)

    def make() -> np.ndarray:
        model = closed_loop_model(robot).model
        if model.njoints - 1 != N_BODIES:
            raise ValueError(f"the tree has {model.njoints - 1} bodies, not {N_BODIES}")
        bodies = np.concatenate([model.inertias[j].toDynamicParameters()
                                 for j in range(1, model.njoints)])
        mot = robot.motors
        return np.r_[robot.gravity, bodies, mot.armature_per_joint, mot.viscous_per_joint,
                     mot.coulomb_per_joint, mot.coulomb_velocity].astype(float)

    return np.array(cached(("setup-parameters", robot.hash), make))


def symbolic_robot(robot: Robot) -> SymbolicRobot:
    """The CasADi functions of ``robot``.

    The expressions are built once per process and *structure* (:func:`structure`),
    with the setup (payload, gravity, motors) as parameters; each robot's functions fix
    them to its values (cached by the robot's hash; CasADi functions are immutable)."""
    robot = require_robot(robot)
    return cached(("symbolic", robot.hash), lambda: _specialise(robot))


def _core(robot: Robot) -> _Core:
    """The structure's symbolic model, built once per process."""
    return cached(("symbolic-core", structure(robot).hash), lambda: _build(structure(robot)))


def holding_function(robot: Robot) -> ca.Function:
    """(x (9,), p (N_SETUP,)) -> the static holding torques (9,) [N m] of the robot's
    structure at rest in minimal coordinates x: tau = (d theta / d x)^-T Q(x) with only
    gravity in Q (the symbolic model above at xd = xdd = 0, where the motor terms vanish;
    the setup p from :func:`setup_parameters` carries gravity, payload and mounting).
    The atlas's torque check; tests/test_atlas.py checks it against Pinocchio's
    closed-loop statics."""
    def make() -> ca.Function:
        x, p, zero = ca.SX.sym("x", NX), ca.SX.sym("p", N_SETUP), ca.SX.zeros(NX, 1)
        return ca.Function("hold_p", [x, p], [_core(robot).tau(x, zero, zero, p)],
                           {"cse": True})

    return cached(("symbolic-hold", structure(robot).hash), make)


def acceleration_function(robot: Robot) -> ca.Function:
    """(x (9,), p (N_SETUP,)) -> (tau_0 (9,), A (9, 3)): at rest in minimal coordinates
    x, the actuator torques [N m] are tau_0 + A a for a platform-centre acceleration a
    [m/s^2] (no angular or crank acceleration; with no velocity terms at rest the
    Jacobian A is exact); tau_0 is :func:`holding_function`'s and A includes the motors'
    reflected rotor inertia.  The atlas's optional dynamic criterion;
    tests/test_atlas.py checks it against Pinocchio."""
    def make() -> ca.Function:
        x, p, a = ca.SX.sym("x", NX), ca.SX.sym("p", N_SETUP), ca.SX.sym("a", 3)
        zero = ca.SX.zeros(NX, 1)
        tau = _core(robot).tau
        A = ca.jacobian(tau(x, zero, ca.vertcat(a, ca.SX.zeros(6, 1)), p), a)
        return ca.Function("accel_p", [x, p],
                           [tau(x, zero, zero, p), ca.substitute(A, a, ca.SX.zeros(3, 1))],
                           {"cse": True})

    return cached(("symbolic-accel", structure(robot).hash), make)


def profile_function(robot: Robot) -> ca.Function:
    """(x, xd, xdd, p) -> (theta_dot, theta_ddot, tau, tau_gravity), each (9,): the
    actuated rates [rad/s], accelerations [rad/s^2], torques and gravity torques [N m] of
    a state in minimal coordinates, with the setup p (:func:`setup_parameters`).  One
    function for the planner's profiles (time stretches, warm starts, the baseline's
    TOPP-RA), compiled by :func:`dynamics.codegen.compiled_small`; the same expressions as
    :class:`SymbolicRobot`'s (tests/test_planner.py)."""
    def make() -> ca.Function:
        core = _core(robot)
        x, xd, xdd = ca.SX.sym("x", NX), ca.SX.sym("xd", NX), ca.SX.sym("xdd", NX)
        p, zero = ca.SX.sym("p", N_SETUP), ca.SX.zeros(NX, 1)
        return ca.Function("profile_p", [x, xd, xdd, p],
                           [core.theta_dot(x, xd), core.theta_ddot(x, xd, xdd),
                            core.tau(x, xd, xdd, p), core.tau(x, zero, zero, p)],
                           {"cse": True})

    return cached(("symbolic-profile", structure(robot).hash), make)


def observer_function(robot: Robot) -> ca.Function:
    """(x, xd, p) -> (theta (9), J_x (9, 9), Q_0 (9), Q_a (9, 9), c (9)): at minimal
    coordinates x and rates xd, the actuated angles, d theta / d x, the generalized
    forces at zero acceleration, their slope in xdd (Q is linear in xdd: Q = Q_0 + Q_a
    xdd) and the actuated acceleration at xdd = 0 (theta_ddot = J_x xdd + c).  The
    per-tick state of the wrench observer in compiled form
    (:mod:`sixplus3.interaction.observer.compiled_state`): M = J_x^-T Q_a J_x^-1 + I_a and
    h = J_x^-T (Q_0 - Q_a J_x^-1 c) + friction follow by two 9 x 9 solves."""
    def make() -> ca.Function:
        x, xd, xdd, setup, Q, theta, Jth, th_ddot = _core(robot).sym
        zero = ca.SX.zeros(NX, 1)
        Qa = ca.substitute(ca.jacobian(Q, xdd), xdd, zero)
        return ca.Function("observer_p", [x, xd, setup],
                           [theta, ca.densify(Jth), ca.densify(ca.substitute(Q, xdd, zero)),
                            ca.densify(Qa), ca.densify(ca.substitute(th_ddot, xdd, zero))],
                           {"cse": True})

    return cached(("symbolic-observer", structure(robot).hash), make)


def kinematics_function(robot: Robot) -> ca.Function:
    """x -> (theta (9), J_x (9, 9)): the actuated angles of minimal coordinates x and
    d theta / d x (a Newton step of forward kinematics: x += J_x^-1 (theta_meas -
    theta(x)))."""
    def make() -> ca.Function:
        x, _, _, _, _, theta, Jth, _ = _core(robot).sym
        return ca.Function("kin_x", [x], [theta, ca.densify(Jth)], {"cse": True})

    return cached(("symbolic-kin", structure(robot).hash), make)


def configuration_function(robot: Robot) -> ca.Function:
    """x -> q: the closed configuration (Pinocchio's, of ``closed_loop_model``) at
    minimal coordinates x."""
    def make() -> ca.Function:
        f = _core(robot).q
        xs = ca.SX.sym("x", NX)
        return ca.Function("q_x", [xs], [ca.densify(f(xs))], {"cse": True})

    return cached(("symbolic-q", structure(robot).hash), make)


def _specialise(robot: Robot) -> SymbolicRobot:
    core = _core(robot)
    p = setup_parameters(robot)
    opts = {"cse": True}
    x, xd, xdd = ca.SX.sym("x", NX), ca.SX.sym("xd", NX), ca.SX.sym("xdd", NX)
    tau = ca.SX.sym("tau", NX)
    return SymbolicRobot(
        theta=core.theta, theta_dot=core.theta_dot, theta_ddot=core.theta_ddot,
        tau=ca.Function("tau", [x, xd, xdd], [core.tau(x, xd, xdd, p)], opts),
        q=core.q, reach=core.reach, margins=core.margins,
        spherical_cos=core.spherical_cos,
        node=ca.Function("node", [x, xd, xdd, tau], [core.node_p(x, xd, xdd, tau, p)], opts),
        node_p=core.node_p, params=p)


@dataclass(frozen=True)
class _Core:
    theta: ca.Function
    theta_dot: ca.Function
    theta_ddot: ca.Function
    tau: ca.Function  # (x, xd, xdd, p)
    q: ca.Function
    reach: ca.Function
    margins: ca.Function
    spherical_cos: ca.Function
    node_p: ca.Function  # (x, xd, u, tau, p)
    # the generalized forces Q(x, xd, xdd; p) and the symbols they are built on, kept for
    # functions built on demand (observer_function)
    sym: tuple[Any, ...] = ()


def motor_torques(setup: Any, th_dot: Any, th_ddot: Any) -> Any:
    """The motors' own torques at the joints (robot_description.physical): reflected
    rotor inertia and joint friction, from the setup parameters (Robot.motors; not read
    back from the Pinocchio armature)."""
    a, b, c = (setup[SETUP_MOTORS + 9 * k:SETUP_MOTORS + 9 * (k + 1)] for k in range(3))
    return (a * th_ddot + b * th_dot
            + c * ca.tanh(th_dot / setup[SETUP_MOTORS + 27]))


def _build(robot: Robot) -> _Core:
    model = closed_loop_model(robot).model
    setup = ca.SX.sym("p", N_SETUP)
    geom = robot.geometry
    mode: AssemblyMode = robot.mode
    x = ca.SX.sym("x", NX)
    xd = ca.SX.sym("xd", NX)
    xdd = ca.SX.sym("xdd", NX)
    p, r, psi = x[0:3], x[3:6], x[6:9]
    ik = ik_expressions(geom, mode, x)
    R, joint_val, theta = ik["R"], ik["joint_val"], ik["theta"]
    reach, type1, type2, leg_Q, links = (ik[k] for k in ("reach", "type1", "type2", "leg_Q",
                                                         "links"))

    oR, ot, qvec = tree_placements(model, joint_val, p, R, r)

    # Generalized forces by a symbolic recursive Newton-Euler pass over the tree, in the
    # world frame, with joint rates from the IK: qd = Jq xd, qdd = Jq xdd + (dJq/dt) xd.
    rev = revolute_joints(model)
    qv = ca.vertcat(*[joint_val[model.names[j]] for j in rev])
    Jq = ca.jacobian(qv, x)
    qd_all = Jq @ xd
    qdd_all = Jq @ xdd + ca.jtimes(qd_all, x, xd)
    qd = {j: qd_all[k] for k, j in enumerate(rev)}
    qdd = {j: qdd_all[k] for k, j in enumerate(rev)}
    tau_tree, f_ff, n_ff, E = tree_forces(model, oR, ot, qd, qdd, xd, xdd, R, r, setup)
    Q = Jq.T @ tau_tree + ca.vertcat(f_ff, E.T @ n_ff, ca.SX.zeros(3, 1))
    Jth = ca.jacobian(theta, x)
    th_dot = Jth @ xd
    th_ddot = ca.jtimes(th_dot, x, xd) + Jth @ xdd
    motor = motor_torques(setup, th_dot, th_ddot)
    tau = ca.solve(Jth.T, Q) + motor

    # Spherical-joint tilt cosines (kinematics.spherical.spherical_tilts), 3 per leg: E, F, P.
    ref = spherical_reference(robot)
    sph = []
    for i in range(NUM_LEGS):
        body = leg_Q[i]
        jb = model.getJointId(f"leg{i}_Gb")
        jh = model.getJointId(f"leg{i}_Hb")
        jc = model.getJointId(f"platform_crank{i}")
        for k, other in enumerate((oR[jb], oR[jh], oR[jc])):
            sph.append(ca.dot(body @ ca.DM(ref[i, k, 0]), other @ ca.DM(ref[i, k, 1])))

    margins_out = [ca.vertcat(*type1), ca.vertcat(*type2),
                   platform_line_det_normalised(psi, geom)]

    hubs = [(ca.DM(h[0]), ca.DM(h[1])) for h in hub_segments(robot)]
    R_i = [p + R @ ca.DM(geom.crank_axis_position(i)) for i in range(NUM_LEGS)]
    up = robot.collision.plate_offset * R[:, 2]  # the plate above the cranks' plane
    plate = ([(p + up, R_i[i] + up) for i in range(NUM_LEGS)]
             + [(R_i[i] + up, R_i[(i + 1) % NUM_LEGS] + up) for i in range(NUM_LEGS)]
             + [(R_i[i], links[6 * i + 1][1]) for i in range(NUM_LEGS)])
    clear = clearance_rows(links + hubs + plate, robot)
    opts = {"cse": True}
    tau_sym = ca.SX.sym("tau", NX)
    node_p = ca.Function(
        "node_p", [x, xd, xdd, tau_sym, setup],
        [ca.vertcat(Jth.T @ (tau_sym - motor) - Q, th_dot, th_ddot, theta, ca.vertcat(*reach),
                    ca.vertcat(*sph), *margins_out, clear)], opts)
    return _Core(
        theta=ca.Function("theta", [x], [theta], opts),
        theta_dot=ca.Function("theta_dot", [x, xd], [th_dot], opts),
        theta_ddot=ca.Function("theta_ddot", [x, xd, xdd], [th_ddot], opts),
        tau=ca.Function("tau", [x, xd, xdd, setup], [tau], opts),
        q=ca.Function("q", [x], [ca.vertcat(*qvec)], opts),
        reach=ca.Function("reach", [x], [ca.vertcat(*reach)], opts),
        margins=ca.Function("margins", [x], margins_out, opts),
        spherical_cos=ca.Function("spherical_cos", [x], [ca.vertcat(*sph)], opts),
        node_p=node_p,
        sym=(x, xd, xdd, setup, Q, theta, Jth, th_ddot),
    )


def home_x(robot: Robot) -> np.ndarray:
    """Minimal coordinates of the robot's home pose."""
    robot = require_robot(robot)
    return np.r_[robot.home_position, 0.0, 0.0, 0.0, robot.home_psi]
