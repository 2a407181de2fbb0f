"""Whole-robot forward kinematics: from the 9 actuated angles to the platform pose and the
crank angles (:mod:`sixplus3.kinematics.robot` holds the inverse kinematics and the
singularity measures).

- :func:`robot_fk`: one sample, Newton on the 27 closure equations over the 27 passive
  velocity coordinates, from a previous configuration (the branch hint);
- :func:`robot_fk_batch`: many samples at once, Newton on the closed-form IK (the
  analytic :func:`ik_jacobian`), each from a guess of its minimal coordinates."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from sixplus3.errors import ConvergenceError, InputError, as_float_array
from sixplus3.kinematics import rotations as rot
from sixplus3.kinematics.robot import RobotConfig, home, robot_ik
from sixplus3.robot_description.model import closed_loop_model
from sixplus3.robot_description.robot import Robot, require_robot
from sixplus3.robot_description.robot_geometry import NUM_LEGS

if TYPE_CHECKING:
    from sixplus3.robot_description.model import ClosedLoopModel


@dataclass(frozen=True)
class RobotFK:
    q: np.ndarray  # (nq,) full tree configuration
    position: np.ndarray  # (3,) platform centre [m]
    rotation: np.ndarray  # (3, 3)
    psi: np.ndarray  # (3,) crank angles [rad]
    residual: float  # max closure residual [m]
    iterations: int

    @property
    def x(self) -> np.ndarray:
        """(9,) minimal coordinates: position, rotation vector, crank angles."""
        return np.r_[self.position, np.reshape(rot.rotvec_from_matrix(self.rotation), -1),
                     self.psi]


def robot_fk(theta: ArrayLike, robot: Robot | None, q_hint: ArrayLike | None = None,
             tol: float = 1e-12,
             max_iter: int = 50, model: ClosedLoopModel | None = None) -> RobotFK:
    """9 actuated angles [rad] -> full configuration, by Newton on the 27 closures.

    ``q_hint`` (a previous configuration, default: the robot's home) selects the assembly
    branch; the actuated coordinates are overwritten by ``theta`` and only the 27 passive
    velocity coordinates move.  ``model`` is a caller-owned closed-loop model of the same
    robot to reuse (one is made otherwise).  Raises :class:`ConvergenceError` when the
    closure residual does not drop below ``tol`` [m] within ``max_iter`` Gauss-Newton
    steps.
    """
    # deferred: Pinocchio loads only when this runs
    import pinocchio as pin

    if model is not None and model.robot is not None:
        if robot is not None and robot.hash != model.robot.hash:
            raise InputError("robot_fk: the model given is of another robot",
                             value=model.robot.hash, valid=robot.hash)
        robot = model.robot
    robot = require_robot(robot)
    clm = model or closed_loop_model(robot)
    theta = as_float_array(theta, "theta", "9 actuated angles [rad]")
    if theta.shape != (9,) or not np.all(np.isfinite(theta)):
        raise InputError(f"theta must be 9 finite angles [rad], got shape {theta.shape}",
                         value=theta.shape, valid="(9,) finite [rad]")
    q = (home(robot).q[0] if q_hint is None else np.array(q_hint, dtype=float)).copy()
    if q.shape != (clm.model.nq,):
        raise InputError(f"q_hint must have {clm.model.nq} entries, got {q.shape}",
                         value=q.shape, valid=f"({clm.model.nq},)")
    q[clm.idx_q_act] = theta
    pas = clm.idx_v_pas
    res = math.inf
    for it in range(max_iter + 1):
        r = clm.residual(q)
        res = float(np.abs(r).max())
        if res < tol:
            break
        if it == max_iter or not math.isfinite(res):
            raise ConvergenceError(
                f"robot forward kinematics did not converge: closure residual {res:.3e} m "
                f"after {it} iterations (tolerance {tol:g} m); theta may be unreachable or "
                "the hint is on another assembly branch",
                value=res, valid=f"closure residual < {tol:g} m")
        Jp = clm.constraint_jacobian(q)[:, pas]
        dv = np.zeros(clm.model.nv)
        dv[pas] = -np.linalg.lstsq(Jp, r, rcond=None)[0]
        step = np.abs(dv).max()
        if step > 0.3:  # damp steps beyond ~17 deg / 0.3 m
            dv *= 0.3 / step
        q = pin.integrate(clm.model, q, dv)
    iq = clm.q_index("platform_free")
    quat = q[iq + 3:iq + 7]
    psi = np.array([q[clm.q_index(f"platform_crank{i}")] for i in range(NUM_LEGS)])
    return RobotFK(q=q, position=q[iq:iq + 3].copy(),
                   rotation=rot.matrix_from_quat(quat)[0], psi=psi, residual=res,
                   iterations=it)


@dataclass(frozen=True)
class BatchFK:
    """Forward kinematics of many samples at once (:func:`robot_fk_batch`)."""

    x: np.ndarray  # (n, 9) platform position [m], rotation vector [rad], psi [rad]
    rotation: np.ndarray  # (n, 3, 3)
    residual: np.ndarray  # (n,) max |theta(x) - theta| [rad]; inf where unsolved
    iterations: int
    cfg: RobotConfig  # the closed-form IK at x: q, margins, legs, ...

    @property
    def converged(self) -> np.ndarray:
        return self.residual < 1e-10


def ik_jacobian(cfg: RobotConfig) -> np.ndarray:
    """(n, 9, 9) d theta / d (platform velocity [m/s], angular velocity [rad/s] in the
    robot frame, crank rates [rad/s]), analytic, from each leg's K^-1 J (paper §III-C):

        v_Pi = v + omega x (P_i - O) + psi_dot_i z_p x (P_i - R_i),
        theta_dot_leg_i = (K^-1 J)_i R_leg_i^T v_Pi.
    """
    robot = cfg.robot
    geom = robot.geometry
    n = len(cfg)
    out = np.zeros((n, 9, 9))
    z = cfg.rotation[:, :, 2]
    for i in range(NUM_LEGS):
        D = cfg.legs[i].dtheta_dp() @ geom.leg_rotation(i).T  # (n, 3, 3) world -> theta
        r = cfg.P[:, i] - cfg.position
        R_i = cfg.position + np.einsum("nij,j->ni", cfg.rotation, geom.crank_axis_position(i))
        rows = slice(3 * i, 3 * i + 3)
        out[:, rows, 0:3] = D
        out[:, rows, 3:6] = -D @ rot.skew(r)
        out[:, rows, 6 + i] = np.einsum("nij,nj->ni", D, np.cross(z, cfg.P[:, i] - R_i))
    return out


def robot_fk_batch(theta: np.ndarray, x_guess: np.ndarray, robot: Robot,
                   tol: float = 1e-12, max_iter: int = 12, margins: bool = True) -> BatchFK:
    """Forward kinematics of n samples at once: Newton on the closed-form IK.

    theta (n, 9) [rad]; x_guess (n, 9) minimal coordinates near the answer (they only
    seed Newton; the answer is whatever pose reproduces theta in the robot's assembly
    mode, reported with its residual).  Each step: theta(x) by the batched closed-form
    IK, then x += (d theta / d x)^-1 (theta - theta(x)) with the analytic Jacobian of
    :func:`ik_jacobian`; rotations are updated on SO(3).  Samples whose IK fails or
    whose Jacobian is singular keep residual inf.  ``margins=False``: the result's
    platform margins are NaN (not needed, e.g. for a second seed).
    """
    robot = require_robot(robot)
    theta = np.asarray(theta, dtype=float)
    x = np.array(x_guess, dtype=float)
    if theta.ndim != 2 or theta.shape[1] != 9 or x.shape != theta.shape:
        raise InputError(f"theta and x_guess must be (n, 9), got {theta.shape}, {x.shape}",
                         value=(theta.shape, x.shape), valid="(n, 9) each")
    pos, R, psi = x[:, 0:3].copy(), rot.matrix_from_rotvec(x[:, 3:6]), x[:, 6:9].copy()
    residual = np.full(len(x), np.inf)
    it = 0
    cfg = robot_ik(pos, R, psi, robot, platform_margins=False)
    for it in range(max_iter + 1):
        err = theta - cfg.theta
        err = np.where(cfg.ok[:, None], err, np.inf)
        residual = np.abs(err).max(axis=1)
        todo = cfg.ok & (residual > tol)
        if not todo.any() or it == max_iter:
            break
        Jm = ik_jacobian(cfg)
        step = np.zeros((len(x), 9))
        ok = todo & np.all(np.isfinite(Jm), axis=(1, 2))
        if ok.any():
            try:
                step[ok] = np.linalg.solve(Jm[ok], err[ok][:, :, None])[:, :, 0]
            except np.linalg.LinAlgError:
                step[ok] = np.einsum("nij,nj->ni", np.linalg.pinv(Jm[ok]), err[ok])
        big = np.abs(step).max(axis=1, keepdims=True)
        step *= np.minimum(1.0, 0.2 / np.maximum(big, 1e-300))  # damp steps > 0.2
        pos = pos + step[:, 0:3]
        R = rot.matrix_from_rotvec(step[:, 3:6]) @ R
        psi = psi + step[:, 6:9]
        cfg = robot_ik(pos, R, psi, robot, platform_margins=False)
    if margins:
        cfg = robot_ik(pos, R, psi, robot)
    xs = np.c_[pos, rot.rotvec_from_matrix(R), psi]
    return BatchFK(xs, R, residual, it, cfg)
