"""The robot's spanning tree, symbolically (CasADi SX), read from its Pinocchio model:
the joints' world placements for given joint values, and the generalized forces of a
recursive Newton-Euler pass for given joint rates and accelerations.

:mod:`sixplus3.dynamics.symbolic` gives them the closed-form inverse kinematics' joint
values and rates (the planner's model in minimal coordinates); they take any
expressions, e.g. NLP variables (a lifted formulation).
"""

from __future__ import annotations

from typing import Any

import casadi as ca

#: Where the bodies' inertial parameters start in the setup vector (after gravity), and
#: how many each body has (Pinocchio's ``Inertia.toDynamicParameters`` order).
SETUP_BODIES = 3
N_BODY_PARAMETERS = 10


def _rx(q: Any) -> Any:
    c, s = ca.cos(q), ca.sin(q)
    return ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, c, -s), ca.horzcat(0, s, c))


def _rz(q: Any) -> Any:
    c, s = ca.cos(q), ca.sin(q)
    return ca.vertcat(ca.horzcat(c, -s, 0), ca.horzcat(s, c, 0), ca.horzcat(0, 0, 1))


def revolute_joints(model: Any) -> list[int]:
    """The indices of the tree's revolute joints (every joint but the platform's
    free-flyer), in the model's order."""
    return [j for j in range(1, model.njoints)
            if model.joints[j].shortname() != "JointModelFreeFlyer"]


def tree_placements(model: Any, joint_val: dict[str, Any], p: Any, R: Any, r: Any
                    ) -> tuple[list[Any], list[Any], list[Any]]:
    """(oR, ot, q): each joint's world rotation and position, and Pinocchio's
    configuration vector, for the revolute joints' values ``joint_val`` (by name) and
    the platform's pose (position ``p``, rotation ``R`` = exp([r]x))."""
    oR = [ca.SX.eye(3)] * model.njoints
    ot = [ca.SX.zeros(3, 1)] * model.njoints
    qvec = [ca.SX(0)] * model.nq
    for j in range(1, model.njoints):
        name = model.names[j]
        jm = model.joints[j]
        par = model.parents[j]
        M = model.jointPlacements[j]
        Rp = oR[par] @ ca.DM(M.rotation)
        tp = ot[par] + oR[par] @ ca.DM(M.translation)
        kind = jm.shortname()
        if kind == "JointModelFreeFlyer":
            oR[j], ot[j] = R, p
            # q of the free-flyer: position and quaternion (x, y, z, w) of R
            qvec[jm.idx_q:jm.idx_q + 3] = [p[0], p[1], p[2]]
            th_r = ca.sqrt(ca.dot(r, r) + 1e-30)
            sinc = ca.if_else(ca.dot(r, r) < 1e-8, 0.5 - ca.dot(r, r) / 48,
                              ca.sin(th_r / 2) / th_r)
            qvec[jm.idx_q + 3:jm.idx_q + 7] = [r[0] * sinc, r[1] * sinc, r[2] * sinc,
                                               ca.cos(th_r / 2)]
            continue
        val = joint_val[name]
        qvec[jm.idx_q] = val
        if kind == "JointModelRX":
            oR[j] = Rp @ _rx(val)
        elif kind == "JointModelRZ":
            oR[j] = Rp @ _rz(val)
        else:  # pragma: no cover - the generator only makes RX / RZ / free-flyer
            raise NotImplementedError(kind)
        ot[j] = tp

    return oR, ot, qvec


def tree_forces(model: Any, oR: list[Any], ot: list[Any], qd: dict[int, Any],
                qdd: dict[int, Any], xd: Any, xdd: Any, R: Any, r: Any, setup: Any
                ) -> tuple[Any, Any, Any, Any]:
    """(tau_tree, f, n, E): the generalized forces of the revolute joints (a recursive
    Newton-Euler pass in the world frame with joint rates ``qd`` and accelerations
    ``qdd`` by joint index), and the force ``f`` and moment ``n`` the platform's joint
    transmits, with omega = E(r) r_dot.  Gravity and every body's inertial parameters
    (the payload merged into the platform's) come from ``setup``
    (:func:`sixplus3.dynamics.symbolic.setup_parameters`)."""
    rev = revolute_joints(model)
    rd, rdd = xd[3:6], xdd[3:6]
    Rdot = ca.reshape(ca.jtimes(ca.reshape(R, 9, 1), r, rd), 3, 3)
    W = Rdot @ R.T
    w_plat = ca.vertcat(W[2, 1], W[0, 2], W[1, 0])
    E = ca.jacobian(w_plat, rd)  # omega = E(r) r_dot
    a_plat = ca.jtimes(w_plat, r, rd) + E @ rdd
    grav = setup[0:3]
    zero = ca.SX.zeros(3, 1)
    om, al, acc = [zero] * model.njoints, [zero] * model.njoints, [zero] * model.njoints
    axes = {}
    F, N = {}, {}
    for j in range(1, model.njoints):
        par = model.parents[j]
        kind = model.joints[j].shortname()
        if kind == "JointModelFreeFlyer":
            om[j], al[j], acc[j] = w_plat, a_plat, xdd[0:3]
        else:
            ax = oR[j][:, 0] if kind == "JointModelRX" else oR[j][:, 2]
            axes[j] = ax
            d = ot[j] - ot[par]
            om[j] = om[par] + ax * qd[j]
            al[j] = al[par] + ax * qdd[j] + ca.cross(om[par], ax * qd[j])
            acc[j] = acc[par] + ca.cross(al[par], d) + ca.cross(om[par], ca.cross(om[par], d))
        # the body's ten inertial parameters (Pinocchio's order, about the joint origin,
        # joint axes) from the setup: identified and payload-carrying robots share one
        # compiled model; the forces are linear in them
        k = SETUP_BODIES + N_BODY_PARAMETERS * (j - 1)
        m = setup[k]
        h = oR[j] @ setup[k + 1:k + 4]
        ixx, ixy, iyy, ixz, iyz, izz = (setup[k + 4 + i] for i in range(6))
        I_o = ca.vertcat(ca.horzcat(ixx, ixy, ixz), ca.horzcat(ixy, iyy, iyz),
                         ca.horzcat(ixz, iyz, izz))
        Iw = oR[j] @ I_o @ oR[j].T
        a_g = acc[j] - grav
        F[j] = m * a_g + ca.cross(al[j], h) + ca.cross(om[j], ca.cross(om[j], h))
        N[j] = Iw @ al[j] + ca.cross(om[j], Iw @ om[j]) + ca.cross(h, a_g)
    f = {j: F[j] for j in range(1, model.njoints)}
    n = {j: N[j] for j in range(1, model.njoints)}  # about t_j
    ff = next(j for j in range(1, model.njoints)
              if model.joints[j].shortname() == "JointModelFreeFlyer")
    for j in range(model.njoints - 1, 0, -1):
        par = model.parents[j]
        if par > 0:
            f[par] = f[par] + f[j]
            n[par] = n[par] + n[j] + ca.cross(ot[j] - ot[par], f[j])
    tau_tree = ca.vertcat(*[ca.dot(axes[j], n[j]) for j in rev])
    return tau_tree, f[ff], n[ff], E
