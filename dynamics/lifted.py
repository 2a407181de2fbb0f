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

from sixplus3.dynamics.symbolic import N_SETUP, NX, ik_expressions
from sixplus3.dynamics.tree import revolute_joints, tree_forces, tree_placements
from sixplus3.robot_description.robot import NUM_LEGS, Robot, require_robot

#: the lifted joints of a leg, in this order (legs 0, 1, 2)
LEG_JOINTS = ("A", "Ds2", "Ds3", "B", "Ga", "Gb", "C", "Ha", "Hb")
#: their number
NQ = NUM_LEGS * len(LEG_JOINTS)
#: the actuated joints among them (A, B, C of each leg)
ACTUATED = [len(LEG_JOINTS) * i + LEG_JOINTS.index(j) for i in range(NUM_LEGS)
            for j in ("A", "B", "C")]


def lifted_functions(robot: Robot) -> dict[str, ca.Function]:
    """``closure``: (x, xd, xdd, qv, qd, qdd) -> the 81 closure rows; ``balance``:
    (x, xd, xdd, tau, qv, qd, qdd, p) -> the 9 torque-balance rows [N m] with the setup
    p (``symbolic.setup_parameters``); ``lift``: (x, xd, xdd) -> (qv, qd, qdd) that
    satisfy the closure rows (the closed forms)."""
    robot = require_robot(robot)
    model = robot.closed_loop_model().model
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
    values = {n: qv[k] for k, n in enumerate(names)}
    rates, accels = {}, {}
    rev = revolute_joints(model)
    for j in rev:
        name = model.names[j]
        if name in values:
            k = names.index(name)
            rates[j], accels[j] = qd[k], qdd[k]
        else:  # platform_crank{i}
            i = int(name[-1])
            values[name] = x[6 + i]
            rates[j], accels[j] = xd[6 + i], xdd[6 + i]
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
    motor = (setup[13] * th_ddot + setup[14] * th_dot
             + setup[15] * ca.tanh(th_dot / setup[16]))
    balance = Jth.T @ (tau - motor) - Q
    opts: dict[str, Any] = {"cse": True}
    return {
        "closure": ca.Function("closure", [x, xd, xdd, qv, qd, qdd], [closure], opts),
        "balance": ca.Function("balance", [x, xd, xdd, tau, qv, qd, qdd, setup],
                               [balance], opts),
        "lift": ca.Function("lift", [x, xd, xdd], [q_ik, qd_ik, qdd_ik], opts),
    }


__all__ = ["ACTUATED", "LEG_JOINTS", "NQ", "lifted_functions"]
