"""The wrench observer's per-tick state in compiled form (docs/leadthrough.md, "Cost per
tick"): the same (J, M, h, tcp offset) as :class:`~sixplus3.interaction.observer.wrench.
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

import numpy as np

from sixplus3.dynamics.codegen import compiled_small
from sixplus3.dynamics.compiled_kinematics import Buffered, kinematics_buffer
from sixplus3.dynamics.native import native
from sixplus3.dynamics.symbolic import (
    observer_function,
    setup_parameters,
    structure,
)
from sixplus3.errors import InputError
from sixplus3.interaction.observer._tick_kernel import (
    lu_solve,
    native_state,
    newton,
    observer_state,
    predict,
)
from sixplus3.kinematics.robot_fk import robot_fk
from sixplus3.robot_description.robot import Robot, require_robot

#: Newton steps of forward kinematics at most per sample.
NEWTON = 4
#: Converged when every actuated angle is within this of the reading [rad].
TOL = 1e-10


class CompiledState:
    """One sample at a time from the compiled CasADi model (module doc): the interface of
    :class:`~sixplus3.interaction.observer.wrench.SingleState`.  The small linear algebra between
    the two C calls is compiled too (:mod:`sixplus3.interaction.observer._tick_kernel`)."""

    def __init__(self, robot: Robot) -> None:
        self.robot = require_robot(robot)
        key = structure(self.robot).hash
        r = self.robot
        self._kin = kinematics_buffer(r)
        obs = compiled_small(lambda: observer_function(r), key, "observer_p")
        self._obs = Buffered(obs, ((9,), (9, 9), (9,), (9, 9), (9,)))
        self._obs.args[2][:] = setup_parameters(self.robot)  # the robot's setup, fixed
        mot = self.robot.motors
        #: the drive train's (armature, viscous, coulomb, the Coulomb law's speed)
        self._drive = (np.asarray(mot.armature_per_joint, dtype=float),
                       np.asarray(mot.viscous_per_joint, dtype=float),
                       np.asarray(mot.coulomb_per_joint, dtype=float),
                       float(mot.coulomb_velocity))
        self._tool = np.asarray(self.robot.tool.xyz, dtype=float)
        self._x = np.zeros(9)
        self._have = False  # a previous sample to start from
        self._lu = np.zeros((9, 9))
        self._piv = np.zeros(9, dtype=np.int64)
        self._theta = np.zeros(9)
        self._step = np.zeros(9)
        #: the native path's outputs (J, M, h, R), valid until the next sample
        self._out = (np.zeros((9, 9)), np.zeros((9, 9)), np.zeros(9), np.zeros((3, 3)))
        # the generated C called from the kernel itself (dynamics/native.py), where the
        # libraries are on disk; else through CasADi's buffers (the same numbers)
        nkin = native("kin_x", key, self._kin)
        nobs = native("observer_p", key, self._obs)
        self._native = None if nkin is None or nobs is None else (nkin, nobs)

    def reset(self) -> None:
        """Forget the previous sample (the next one starts from the full forward
        kinematics)."""
        self._have = False

    def _fk(self, theta: np.ndarray) -> None:
        """x (into ``_x``) of the angles theta by Newton's method from the previous
        sample, and the LU factors of J_x there (``_lu``, ``_piv``)."""
        x = self._x
        if not self._have:
            x[:] = robot_fk(theta, self.robot, tol=1e-9).x
        else:
            predict(x, self._lu, self._piv, theta, self._theta, self._step)
        kin = self._kin
        err, info = math.inf, 0
        for _ in range(NEWTON + 1):
            kin.args[0][:] = x
            kin.evaluate()
            err, info = newton(x, kin.res[0], kin.res[1], theta, self._lu, self._piv,
                               self._step, TOL)
            if err < TOL or info != 0:
                break
        if info != 0 or err >= 1e-8:
            self._have = False  # start again from the full forward kinematics next time
            raise InputError("forward kinematics did not converge for these angles",
                             value=float(err), valid="angles of an assembly")

    def state(self, theta: np.ndarray, theta_dot: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(J (9, 9), M (9, 9), h (9,), tcp offset (3,)) of one sample."""
        theta = np.asarray(theta, dtype=float)
        theta_dot = np.asarray(theta_dot, dtype=float)
        if self._native is not None and self._have:
            return self._native_state(theta, theta_dot)
        self._fk(theta)
        obs, x = self._obs, self._x
        obs.args[0][:] = x
        lu_solve(self._lu, self._piv, theta_dot, obs.args[1])  # xd = J_x^-1 theta_dot
        obs.evaluate()
        _, jx, q0, qa, c = obs.res
        J, M, h, R = np.empty((9, 9)), np.empty((9, 9)), np.empty(9), np.empty((3, 3))
        observer_state(self._lu, self._piv, (jx, q0, qa, c), x[3:6], theta_dot,
                       self._drive,
                       (J, M, h, R))
        self._theta[:] = theta
        self._have = True
        #: the platform's pose and the crank angles of the last sample
        self.position, self.rotation, self.psi = x[0:3].copy(), R, x[6:9].copy()
        return J, M, h, R @ self._tool


    def native_args(self) -> tuple[object, ...] | None:
        """The ``model`` of :func:`~sixplus3.interaction.observer._tick_kernel.native_state` and
        :func:`~sixplus3.interaction.observer._tick_kernel.stream_tick` (this state's buffers and
        settings, one tuple), or None without the native path."""
        if self._native is None:
            return None
        kin, obs = self._native
        kb, ob = kin.buf, obs.buf
        return (kin.ptrs, kb.args[0], kb.res[0], kb.res[1], obs.ptrs,
                ob.args[0], ob.args[1], ob.res[1], ob.res[2], ob.res[3], ob.res[4], self._x,
                self._lu, self._piv, self._step, self._theta, NEWTON, TOL, *self._drive,
                *self._out)

    def native_done(self) -> None:
        """After a sample taken by stream_tick: the pose of :meth:`state`."""
        x = self._x
        self.position, self.rotation, self.psi = x[0:3].copy(), self._out[3].copy(), x[6:9].copy()

    def _native_state(self, theta: np.ndarray, theta_dot: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`state` in one compiled call (_tick_kernel.native_state), on the
        previous sample's x and factors."""
        model = self.native_args()
        assert model is not None
        J, M, h, R = self._out
        err, info = native_state(model, theta, True, theta_dot)
        if info != 0 or err >= 1e-8:
            self._have = False  # start again from the full forward kinematics next time
            raise InputError("forward kinematics did not converge for these angles",
                             value=float(err), valid="angles of an assembly")
        x = self._x
        self.position, self.rotation, self.psi = x[0:3].copy(), R.copy(), x[6:9].copy()
        return J.copy(), M.copy(), h.copy(), R @ self._tool


__all__ = ["CompiledState"]
