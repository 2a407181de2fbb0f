"""The closed-loop regressor: the nine actuated torques, linear in the parameters.

    tau = Y(theta, theta_dot, theta_ddot) pi

with pi = (the 10 inertial parameters of each of the tree's 31 bodies, then per actuated
joint its reflected rotor inertia I_a, viscous b and Coulomb tau_c friction).

- The bodies' columns come from Pinocchio's joint torque regressor of the spanning tree
  (``computeJointTorqueRegressor``, Y_tree: nv x 310, with each body's parameters in
  Pinocchio's order ``Inertia.toDynamicParameters()``: m, m c_x, m c_y, m c_z, I_xx,
  I_xy, I_yy, I_xz, I_yz, I_zz, the inertia about the joint frame's origin, in its axes),
  projected through the closures exactly as the inverse dynamics are
  (:mod:`sixplus3.dynamics.closed_loop`): Y = G^T Y_tree = Y_tree[act] - X^T Y_tree[pas],
  X = J_pas^-1 J_act, at the consistent (v, a) of the actuated rates.
- The motor columns: theta_ddot_j, theta_dot_j, tanh(theta_dot_j / omega_c) on joint
  j's row (the model's smoothed Coulomb law, omega_c = ``Robot.motors.coulomb_velocity``).

A body of the tree is a Pinocchio joint's body: its URDF link with every fixed child
merged (the payload on the platform). :func:`body_links` names each body's link.
``Y pi`` equals :meth:`ClosedLoopDynamics.actuated_inverse_dynamics_batch` to 1e-12 N m
(tests/test_identification.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from sixplus3.dynamics.closed_loop import SINGULAR_RCOND, ClosedLoopDynamics
from sixplus3.robot_description.urdf import actuated_joint_names

#: Pinocchio's order of a body's ten inertial parameters.
BODY_PARAMETERS = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
#: The motor parameters of each actuated joint, in the regressor's order.
MOTOR_PARAMETERS = ("Ia", "fv", "fc")
N_BODY = len(BODY_PARAMETERS)
N_MOTOR = len(MOTOR_PARAMETERS)


@dataclass(frozen=True)
class Layout:
    """The parameter vector's layout for one robot structure."""

    bodies: tuple[str, ...]  #: the link of each tree body (Pinocchio joints 1..)
    joints: tuple[str, ...]  #: the actuated joints (the motor parameters' owners)

    @property
    def n_body_params(self) -> int:
        return N_BODY * len(self.bodies)

    @property
    def size(self) -> int:
        return self.n_body_params + N_MOTOR * len(self.joints)

    @property
    def names(self) -> list[str]:
        out = [f"{b}.{p}" for b in self.bodies for p in BODY_PARAMETERS]
        return out + [f"{j}.{p}" for j in self.joints for p in MOTOR_PARAMETERS]

    def motor_index(self, joint: int, which: str) -> int:
        return self.n_body_params + N_MOTOR * joint + MOTOR_PARAMETERS.index(which)


def body_links(model: pin.Model) -> tuple[str, ...]:
    """The URDF link carried by each of the model's joints 1.. (its first body frame)."""
    out = []
    for j in range(1, model.njoints):
        name = next(f.name for f in model.frames
                    if f.parentJoint == j and f.type == pin.FrameType.BODY)
        out.append(name)
    return tuple(out)


def layout(dyn: ClosedLoopDynamics) -> Layout:

    return Layout(bodies=body_links(dyn.model), joints=tuple(actuated_joint_names()))


def body_parameters(model: pin.Model) -> np.ndarray:
    """(10 n_bodies,) the inertial parameters of the model's bodies, Pinocchio's order."""
    return np.concatenate([model.inertias[j].toDynamicParameters()
                           for j in range(1, model.njoints)])


def parameters(dyn: ClosedLoopDynamics) -> np.ndarray:
    """pi of ``dyn``'s robot: its bodies' parameters and its motors' per joint."""
    assert dyn.robot is not None
    mot = dyn.robot.motors
    motor = np.c_[mot.armature_per_joint, mot.viscous_per_joint, mot.coulomb_per_joint]
    return np.r_[body_parameters(dyn.model), motor.reshape(-1)]


def regressor_batch(dyn: ClosedLoopDynamics, q: np.ndarray, theta_dot: np.ndarray,
                    theta_ddot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(Y (n, 9, P), rcond (n,)) at n closed configurations q with actuated rates and
    accelerations: ``Y[k] @ pi`` is the actuated torque of state k.  States at a parallel
    singularity get NaN rows."""
    m, d = dyn.model, dyn.data
    q = np.asarray(q, dtype=float)
    theta_dot = np.asarray(theta_dot, dtype=float)
    theta_ddot = np.asarray(theta_ddot, dtype=float)
    n, nj = len(q), theta_dot.shape[1]
    v, a, X, rcond = dyn.consistent_states_batch(q, theta_dot, theta_ddot)
    act, pas = dyn.clm.idx_v_act, dyn.clm.idx_v_pas
    nb = N_BODY * (m.njoints - 1)
    Y = np.full((n, nj, nb + N_MOTOR * nj), np.nan)
    reg = pin.computeJointTorqueRegressor
    ok = (np.isfinite(np.c_[v, a]).all(axis=1) & (rcond > SINGULAR_RCOND)).tolist()
    for k in range(n):
        if ok[k]:
            Yt = reg(m, d, q[k], v[k], a[k])
            Y[k, :, :nb] = Yt[act] - X[k].T @ Yt[pas]
    assert dyn.robot is not None
    mot = dyn.robot.motors
    idx = np.arange(nj)
    good = np.asarray(ok)
    Y[:, :, nb:] = 0.0
    Y[:, idx, nb + N_MOTOR * idx] = theta_ddot
    Y[:, idx, nb + N_MOTOR * idx + 1] = theta_dot
    Y[:, idx, nb + N_MOTOR * idx + 2] = np.tanh(theta_dot / mot.coulomb_velocity)
    Y[~good] = np.nan
    return Y, rcond


__all__ = ["BODY_PARAMETERS", "MOTOR_PARAMETERS", "Layout", "body_links", "body_parameters",
           "layout", "parameters", "regressor_batch"]
