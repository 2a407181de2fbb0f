"""The wrench observer's per-tick state in compiled form (docs/leadthrough.md, "Cost per
tick"): the same (J, M, h, tcp offset) as :class:`~sixplus3.interaction.wrench.
SingleState`, from the CasADi model in minimal coordinates
(:func:`~sixplus3.dynamics.symbolic.observer_function`, generated as C and compiled like
the planner's functions) instead of Pinocchio.

Each sample: forward kinematics by Newton's method in the minimal coordinates x =
(position, rotation vector, crank angles), from the previous sample's x moved by
J_x^-1 (theta - theta_prev) (one correction is then enough; at most ``NEWTON`` are
taken); then one call of the observer function at (x, xd = J_x^-1 theta_dot) and two
9 x 9 solves:

    M = J_x^-T Q_a J_x^-1 + diag(I_a),   h = J_x^-T (Q_0 - Q_a J_x^-1 c) + friction,
    J = J_x blockdiag(I, J_l(r)^-1, I),

with J_l the left Jacobian of SO(3) (omega = J_l(r) r_dot).  The functions are called
through CasADi's buffer interface on preallocated arrays
(:class:`~sixplus3.dynamics.compiled_kinematics.Buffered`).  tests/test_leadthrough.py
checks every output against SingleState (Pinocchio)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.linalg import lapack

from sixplus3.dynamics.codegen import compiled_small
from sixplus3.dynamics.compiled_kinematics import Buffered, kinematics_buffer, wrapped
from sixplus3.dynamics.symbolic import (
    observer_function,
    setup_parameters,
    structure,
)
from sixplus3.errors import InputError
from sixplus3.kinematics import rotations as rot
from sixplus3.kinematics.robot import robot_fk
from sixplus3.robot_description.robot import Robot, require_robot

#: Newton steps of forward kinematics at most per sample.
NEWTON = 4
#: Converged when every actuated angle is within this of the reading [rad].
TOL = 1e-10


def left_jacobian(r: np.ndarray) -> np.ndarray:
    """J_l(r) (3, 3): omega = J_l(r) r_dot for R = exp([r]x) (base-frame angular
    velocity)."""
    t2 = float(r @ r)
    K = rot.skew(r[None])[0]
    if t2 < 1e-8:
        return np.eye(3) + K / 2.0 + K @ K / 6.0
    t = math.sqrt(t2)
    return np.eye(3) + (1.0 - math.cos(t)) / t2 * K + (t - math.sin(t)) / (t2 * t) * (K @ K)


class CompiledState:
    """One sample at a time from the compiled CasADi model (module doc): the interface of
    :class:`~sixplus3.interaction.wrench.SingleState`."""

    def __init__(self, robot: Robot) -> None:
        self.robot = require_robot(robot)
        key = structure(self.robot).hash
        r = self.robot
        self._kin = kinematics_buffer(r)
        obs = compiled_small(lambda: observer_function(r), key, "observer_p")
        self._obs = Buffered(obs, ((9,), (9, 9), (9,), (9, 9), (9,)))
        self._obs.args[2][:] = setup_parameters(self.robot)  # the robot's setup, fixed
        mot = self.robot.motors
        self._armature = np.asarray(mot.armature_per_joint, dtype=float)
        self._friction = mot.friction
        self._tool = np.asarray(self.robot.tool.xyz, dtype=float)
        self._armature_diag = np.diag(self._armature)
        self._x: np.ndarray | None = None
        self._lu: Any = None
        self._piv: Any = None
        self._theta: np.ndarray | None = None

    def reset(self) -> None:
        """Forget the previous sample (the next one starts from the full forward
        kinematics)."""
        self._x = None

    def _fk(self, theta: np.ndarray) -> tuple[np.ndarray, Any, Any, np.ndarray]:
        """(x, the LU factors of J_x, J_x) of the angles theta by Newton's method from
        the previous sample."""
        if self._x is None or self._lu is None or self._theta is None:
            x = robot_fk(theta, self.robot, tol=1e-9).x
        else:
            x = self._x + lapack.dgetrs(self._lu, self._piv, theta - self._theta)[0]
        for _ in range(NEWTON + 1):
            th, Jx = self._kin(x)
            lu, piv, info = lapack.dgetrf(Jx)
            err = wrapped(theta - th)
            if float(np.abs(err).max()) < TOL or info != 0:
                break
            x = x + lapack.dgetrs(lu, piv, err)[0]
        if info != 0 or float(np.abs(err).max()) >= 1e-8:
            self._x = None  # start again from the full forward kinematics next time
            raise InputError("forward kinematics did not converge for these angles",
                             value=float(np.abs(err).max()), valid="angles of an assembly")
        return x, lu, piv, Jx.copy()

    def state(self, theta: np.ndarray, theta_dot: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(J (9, 9), M (9, 9), h (9,), tcp offset (3,)) of one sample."""
        theta = np.asarray(theta, dtype=float)
        theta_dot = np.asarray(theta_dot, dtype=float)
        x, lu, piv, Jx = self._fk(theta)
        xd = lapack.dgetrs(lu, piv, theta_dot)[0]
        _, _, Q0, Qa, c = self._obs(x, xd)
        B = lapack.dgetrs(lu, piv, Qa, trans=1)[0]  # J_x^-T Q_a
        M = lapack.dgetrs(lu, piv, np.ascontiguousarray(B.T), trans=1)[0].T  # B J_x^-1
        M = 0.5 * (M + M.T) + self._armature_diag
        h = (lapack.dgetrs(lu, piv, Q0, trans=1)[0] - B @ lapack.dgetrs(lu, piv, c)[0]
             + self._friction(theta_dot))
        R, Jl_inv = _rotation_and_inverse_left_jacobian(x[3:6])
        J = Jx
        J[:, 3:6] = Jx[:, 3:6] @ Jl_inv
        self._x, self._lu, self._piv, self._theta = x, lu, piv, theta.copy()
        #: the platform's pose and the crank angles of the last sample
        self.position, self.rotation, self.psi = x[0:3].copy(), R, x[6:9].copy()
        return J, M, h, R @ self._tool


def _rotation_and_inverse_left_jacobian(r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(exp([r]x), J_l(r)^-1) in closed form (series near r = 0)."""
    t2 = float(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
    K = np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
    K2 = K @ K
    if t2 < 1e-8:
        return (np.eye(3) + K + 0.5 * K2, np.eye(3) - 0.5 * K + K2 / 12.0)
    t = math.sqrt(t2)
    s, c = math.sin(t), math.cos(t)
    if abs(s) < 1e-6:  # near a half turn: J_l by its series, inverted
        return rot.matrix_from_rotvec(r[None])[0], np.linalg.inv(left_jacobian(r))
    R = np.eye(3) + (s / t) * K + ((1.0 - c) / t2) * K2
    Jl_inv = np.eye(3) - 0.5 * K + (1.0 / t2 - (1.0 + c) / (2.0 * t * s)) * K2
    return R, Jl_inv


__all__ = ["CompiledState", "left_jacobian"]
