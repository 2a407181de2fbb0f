"""A lifted form of the torque balance, for the planner-v2 reformulation (a study).

Today's torque row (:mod:`sixplus3.dynamics.symbolic`) is

    Jth(x)^T (tau - motor) - Jq(x)^T tau_tree(IK(x), Jq xd, Jq xdd + dJq xd) - platform,

so its derivatives go through the closed-form inverse kinematics composed with the
tree's Newton-Euler pass (a point's Hessian: 1.44 million instructions, BENCHMARKS.md).
Here the legs' 27 joint values, rates and accelerations are variables (qv, qd, qdd),
tied to the platform's minimal coordinates by 81 closure rows of their own:

    qv - IK(x) = 0,   qd - Jq(x) xd = 0,   qdd - Jq(x) xdd - dJq(x, xd) xd = 0,

and the torque balance sees the tree only through them:

    Jth(x)^T (tau - motor(qd, qdd)) - Jq(x)^T tau_tree(qv, qd, qdd) - platform = 0.

At a point where the closure rows hold, the balance equals today's row (tests).
``benchmarks/study_lifted_rows.py`` measures what each form's derivatives cost.
"""

from __future__ import annotations

from typing import Any

import casadi as ca

from sixplus3.dynamics.symbolic import N_SETUP, NX, motor_torques
from sixplus3.dynamics.symbolic_ik import ik_expressions, rotvec_matrix
from sixplus3.dynamics.tree import revolute_joints, tree_forces, tree_placements
from sixplus3.robot_description.model import closed_loop_model
from sixplus3.robot_description.robot import Robot, require_robot
from sixplus3.robot_description.robot_geometry import NUM_LEGS

#: the lifted joints of a leg, in this order (legs 0, 1, 2)
LEG_JOINTS = ("A", "Ds2", "Ds3", "B", "Ga", "Gb", "C", "Ha", "Hb")
#: their number
NQ = NUM_LEGS * len(LEG_JOINTS)
#: the actuated joints among them (A, B, C of each leg)
ACTUATED = [len(LEG_JOINTS) * i + LEG_JOINTS.index(j) for i in range(NUM_LEGS)
            for j in ("A", "B", "C")]


def _tree_motion(model: Any, qv: Any, qd: Any, qdd: Any, x: Any, xd: Any, xdd: Any
                 ) -> tuple[dict[str, Any], dict[int, Any], dict[int, Any]]:
    """The tree's joint values (by name), rates and accelerations (by index): the legs'
    joints from the lifted variables, the cranks from the minimal coordinates psi."""
    names = [f"leg{i}_{j}" for i in range(NUM_LEGS) for j in LEG_JOINTS]
    values = {n: qv[k] for k, n in enumerate(names)}
    rates, accels = {}, {}
    for j in revolute_joints(model):
        name = model.names[j]
        if name in names:
            rates[j], accels[j] = qd[names.index(name)], qdd[names.index(name)]
        else:  # platform_crank{i}: the minimal coordinate psi_i
            i = int(name[-1])
            values[name] = x[6 + i]
            rates[j], accels[j] = xd[6 + i], xdd[6 + i]
    return values, rates, accels


def lifted_functions(robot: Robot) -> dict[str, ca.Function]:
    """``closure``: (x, xd, xdd, qv, qd, qdd) -> the 81 closure rows; ``balance``:
    (x, xd, xdd, tau, qv, qd, qdd, p) -> the 9 torque-balance rows [N m] with the setup
    p (``symbolic.setup_parameters``); ``lift``: (x, xd, xdd) -> (qv, qd, qdd) that
    satisfy the closure rows (the closed forms)."""
    robot = require_robot(robot)
    model = closed_loop_model(robot).model
    x, xd, xdd = (ca.SX.sym(n, NX) for n in ("x", "xd", "xdd"))
    tau, setup = ca.SX.sym("tau", NX), ca.SX.sym("p", N_SETUP)
    qv, qd, qdd = (ca.SX.sym(n, NQ) for n in ("qv", "qd", "qdd"))
    ik = ik_expressions(robot.geometry, robot.mode, x)
    names = [f"leg{i}_{j}" for i in range(NUM_LEGS) for j in LEG_JOINTS]
    q_ik = ca.vertcat(*[ik["joint_val"][n] for n in names])
    Jq = ca.jacobian(q_ik, x)
    qd_ik = Jq @ xd
    qdd_ik = Jq @ xdd + ca.jtimes(qd_ik, x, xd)
    closure = ca.vertcat(qv - q_ik, qd - qd_ik, qdd - qdd_ik)
    # the tree sees the lifted legs' joints; the cranks are the minimal coordinates psi
    values, rates, accels = _tree_motion(model, qv, qd, qdd, x, xd, xdd)
    rev = revolute_joints(model)
    R, r = ik["R"], x[3:6]
    oR, ot, _ = tree_placements(model, values, x[0:3], R, r)
    tau_tree, f_ff, n_ff, E = tree_forces(model, oR, ot, rates, accels, xd, xdd, R, r,
                                          setup)
    # tau_tree is in the order of rev; the virtual work of each joint through its rate's
    # dependence on x: legs' joints through Jq, the cranks directly
    J_rev = ca.vertcat(*[Jq[names.index(model.names[j]), :] if model.names[j] in names
                         else ca.DM.eye(NX)[6 + int(model.names[j][-1]), :] for j in rev])
    Q = J_rev.T @ tau_tree + ca.vertcat(f_ff, E.T @ n_ff, ca.SX.zeros(3, 1))
    Jth = Jq[ACTUATED, :]
    th_dot, th_ddot = qd[ACTUATED], qdd[ACTUATED]
    motor = motor_torques(setup, th_dot, th_ddot)
    balance = Jth.T @ (tau - motor) - Q
    opts: dict[str, Any] = {"cse": True}
    return {
        "closure": ca.Function("closure", [x, xd, xdd, qv, qd, qdd], [closure], opts),
        "balance": ca.Function("balance", [x, xd, xdd, tau, qv, qd, qdd, setup],
                               [balance], opts),
        "lift": ca.Function("lift", [x, xd, xdd], [q_ik, qd_ik, qdd_ik], opts),
    }


def implicit_functions(robot: Robot) -> dict[str, ca.Function]:
    """The lifted variables tied without the closed forms: the 27 loop-closure rows of the
    tree (each spherical joint's centre from both of its bodies, the closed-loop model's
    constraints) with their velocity and acceleration forms, and the tree's 36 equations
    of motion with the closures' forces ``lam`` (27,):

        tau_tree(qv, qd, qdd) - S^T (tau - motor) - dc/dq^T lam = 0   (30 joints),
        platform wrench - dc/d(p, r)^T lam = 0                         (6).

    ``closure``: (x, xd, xdd, qv, qd, qdd) -> 81 rows; ``dynamics``: (x, xd, xdd, tau,
    qv, qd, qdd, lam, p) -> 36 rows [N m, N].  At a state whose closures hold, the 36 rows
    are linear in (tau, lam) with a unique solution, whose tau is today's
    (tests/test_planner_structure.py)."""
    robot = require_robot(robot)
    clm = closed_loop_model(robot)
    model = clm.model
    x, xd, xdd = (ca.SX.sym(n, NX) for n in ("x", "xd", "xdd"))
    tau, setup = ca.SX.sym("tau", NX), ca.SX.sym("p", N_SETUP)
    qv, qd, qdd = (ca.SX.sym(n, NQ) for n in ("qv", "qd", "qdd"))
    lam = ca.SX.sym("lam", NQ)
    names = [f"leg{i}_{j}" for i in range(NUM_LEGS) for j in LEG_JOINTS]
    values, rates, accels = _tree_motion(model, qv, qd, qdd, x, xd, xdd)
    rev = revolute_joints(model)
    r = x[3:6]
    R = rotvec_matrix(r)
    oR, ot, _ = tree_placements(model, values, x[0:3], R, r)
    def centre(joint: int, placement: Any) -> Any:
        return ot[joint] + oR[joint] @ ca.DM(placement.translation)

    c = ca.vertcat(*[centre(cm.joint1_id, cm.joint1_placement)
                     - centre(cm.joint2_id, cm.joint2_placement)
                     for cm in clm.constraint_models])
    q_all, v_all, a_all = ca.vertcat(qv, x), ca.vertcat(qd, xd), ca.vertcat(qdd, xdd)
    c_dot = ca.jtimes(c, q_all, v_all)
    c_ddot = ca.jtimes(c_dot, q_all, v_all) + ca.jtimes(c, q_all, a_all)
    tau_tree, f_ff, n_ff, E = tree_forces(model, oR, ot, rates, accels, xd, xdd, R, r, setup)
    Cq, Cx = ca.jacobian(c, qv), ca.jacobian(c, x)
    th_dot, th_ddot = qd[ACTUATED], qdd[ACTUATED]
    motor = motor_torques(setup, th_dot, th_ddot)
    act = ca.SX.zeros(NQ, 1)
    act[ACTUATED] = tau - motor
    joint_rows, crank_rows = [], []
    for k, j in enumerate(rev):
        name = model.names[j]
        if name in names:
            m = names.index(name)
            joint_rows.append((m, tau_tree[k] - act[m] - ca.dot(Cq[:, m], lam)))
        else:
            i = int(name[-1])
            crank_rows.append(tau_tree[k] - ca.dot(Cx[:, 6 + i], lam))
    joint_rows.sort(key=lambda kv: kv[0])
    platform = ca.vertcat(f_ff, E.T @ n_ff) - Cx[:, 0:6].T @ lam
    dynamics = ca.vertcat(*[row for _, row in joint_rows], *crank_rows, platform)
    opts: dict[str, Any] = {"cse": True}
    return {
        "closure": ca.Function("closure", [x, xd, xdd, qv, qd, qdd],
                               [ca.vertcat(c, c_dot, c_ddot)], opts),
        "dynamics": ca.Function("dynamics", [x, xd, xdd, tau, qv, qd, qdd, lam, setup],
                                [dynamics], opts),
    }


__all__ = ["ACTUATED", "LEG_JOINTS", "NQ", "implicit_functions", "lifted_functions"]
