"""Constrained dynamics of the closed-loop robot with Pinocchio 4.

Notation: q (nq = 37), v, a (nv = 36) of the spanning tree; S selects the 9 actuated
velocity coordinates; the closures r(q) = 0 have Jacobian Jc = [J_act, J_pas] (27 x 36,
columns split by actuated / passive coordinates).

- Independent coordinates are the actuated angles: v = G theta_dot with
  G = dq/dtheta = [I ; -J_pas^-1 J_act] (rows ordered as v), so S G = I.
- Constrained inverse dynamics (virtual work; G^T Jc^T = 0 removes the closure forces):
      tau = (S G)^-T G^T rnea(q, v, a) = G^T rnea(q, v, a).
  Valid for a consistent motion (Jc v = 0, Jc a + gamma = 0).  A singular J_pas (the
  actuators locked, the mechanism can still move: a parallel singularity) raises
  :class:`SingularityError`.
- Motors (``Robot.motors``): the reflected rotor inertia is the actuated joints'
  ``model.armature`` (included by ``rnea`` and ``crba``); the joint friction
  f(theta_dot) = b theta_dot + tau_c tanh(theta_dot / omega_c) is added to every inverse
  dynamics result and subtracted from the applied torque in the forward dynamics.
- Constrained forward dynamics: Pinocchio ``constraintDynamics`` with the 27 CONTACT_3D
  constraints and Baumgarte stabilisation; a step is RK4 (or semi-implicit Euler)
  followed by a projection onto the closure manifold.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.linalg import lapack

from sixplus3.errors import InputError, SingularityError
from sixplus3.robot_description.model import ClosedLoopModel, closed_loop_model
from sixplus3.robot_description.robot import Robot, require_robot

#: Parallel-singularity threshold on the reciprocal condition number (1-norm) of J_pas.
SINGULAR_RCOND = 1e-10


@dataclass(frozen=True)
class ForwardResult:
    a: np.ndarray  # (nv,) tree acceleration
    forces: np.ndarray  # (27,) constraint forces (Pinocchio's contact forces, LOCAL frames)


@dataclass(frozen=True)
class Trajectory:
    t: np.ndarray  # (n,) [s]
    q: np.ndarray  # (n, nq)
    v: np.ndarray  # (n, nv)
    kinetic: np.ndarray  # (n,) [J]
    potential: np.ndarray  # (n,) [J]
    residual: np.ndarray  # (n,) max closure residual [m]

    @property
    def energy(self) -> np.ndarray:
        return self.kinetic + self.potential


class ClosedLoopDynamics:
    """Closed-loop dynamics of one robot.

    Each instance owns its Pinocchio model copy, data and constraint models (made by
    :meth:`Robot.closed_loop_model`), so instances never affect each other: different
    Baumgarte gains, one instance per thread.  ``model`` instead uses a closed-loop model
    the caller built (e.g. :func:`~sixplus3.robot_description.model.load_model_from`),
    which this instance then owns.
    """

    def __init__(self, robot: Robot | None = None, *, kp: float = 400.0, kd: float = 40.0,
                 mu: float = 1e-10, model: ClosedLoopModel | None = None) -> None:
        for name, val in (("kp", kp), ("kd", kd), ("mu", mu)):
            if not (math.isfinite(val) and val >= 0.0):
                raise InputError(f"{name} must be a finite number >= 0, got {val!r}",
                                 value=val, valid=">= 0")
        if model is not None:
            if robot is not None and model.robot is not None and model.robot.hash != robot.hash:
                raise InputError("ClosedLoopDynamics: the model given is of another robot",
                                 value=model.robot.hash, valid=robot.hash)
            self.clm = model
        else:
            self.clm = closed_loop_model(require_robot(robot))
        self.robot = self.clm.robot
        self.model = self.clm.model
        self.data = self.model.createData()
        self.cmodels = self.clm.constraint_models
        for cm in self.cmodels:
            cm.setBaumgarteCorrectorParameters(pin.BaumgarteCorrectorParameters(kp, kd))
        self.cdatas = pin.StdVec_RigidConstraintData()
        for cm in self.cmodels:
            self.cdatas.append(cm.createData())
        pin.initConstraintDynamics(self.model, self.data, self.cmodels, self.cdatas)
        self.prox = pin.ProximalSettings(1e-12, mu, 10)
        self._act = self.clm.idx_v_act
        self._pas = self.clm.idx_v_pas
        motors = self.robot.motors if self.robot is not None else None
        self._friction = (motors.friction if motors is not None
                          else (lambda w: np.zeros_like(np.asarray(w, dtype=float))))

    # ------------------------------------------------------------------ kinematics
    def _check_state(self, q: np.ndarray, *vs: np.ndarray) -> None:
        m = self.model
        if q.shape != (m.nq,) or not np.all(np.isfinite(q)):
            raise InputError(f"q must be {m.nq} finite numbers, got shape {q.shape}",
                             value=q.shape, valid=f"({m.nq},) finite")
        if not pin.isNormalized(m, q, 1e-6):
            raise InputError("q's quaternions (the platform's free joint) must have norm 1 "
                             "(to 1e-6)", value="norm != 1",
                             valid="a configuration on the tree's Lie group")
        for v in vs:
            if v.shape != (m.nv,) or not np.all(np.isfinite(v)):
                raise InputError(f"v and a must be {m.nv} finite numbers, got {v.shape}",
                                 value=v.shape, valid=f"({m.nv},) finite")

    def G(self, q: np.ndarray) -> np.ndarray:
        """(nv, 9) dv/dtheta_dot; raises SingularityError at a parallel singularity."""
        return self._G_from(self.clm.constraint_jacobian(q))

    def _lu(self, Jc: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """(lu, piv, rcond) of J_pas: LU, then LAPACK's 1-norm reciprocal condition
        estimate, O(n^2) on top of the factorisation (an SVD would cost ~4x the solve);
        rcond 0 when singular."""
        Jp = np.asfortranarray(Jc[:, self._pas])
        lu, piv, info = lapack.dgetrf(Jp)
        rcond = 0.0
        if info == 0:
            rcond, _ = lapack.dgecon(lu, np.abs(Jp).sum(axis=0).max(), norm="1")
        return lu, piv, float(rcond)

    def _G_from(self, Jc: np.ndarray) -> np.ndarray:
        lu, piv, rcond = self._lu(Jc)
        if rcond <= SINGULAR_RCOND:
            raise SingularityError(
                f"parallel singularity: the closure Jacobian of the passive joints has "
                f"reciprocal condition number {rcond:.2e} <= {SINGULAR_RCOND:g}; the "
                "actuators cannot determine the motion, no torque is defined",
                value=rcond, valid=f"> {SINGULAR_RCOND:g}")
        X, _ = lapack.dgetrs(lu, piv, Jc[:, self._act])
        G = np.zeros((self.model.nv, len(self._act)))
        G[self._act] = np.eye(len(self._act))
        G[self._pas] = -X
        return G

    def consistent_state(self, q: np.ndarray, theta_dot: np.ndarray,
                         theta_ddot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(v, a) of the tree for actuated rates [rad/s] and accelerations [rad/s^2] at q.

        v = G theta_dot;  a = G theta_ddot + a_0, with a_0 the passive-only correction
        that cancels the drift: J_pas a_0,pas = -gamma(q, v).
        """
        q = np.asarray(q, dtype=float)
        self._check_state(q)
        theta_dot, theta_ddot = (np.asarray(x, dtype=float) for x in (theta_dot, theta_ddot))
        for name, x in (("theta_dot", theta_dot), ("theta_ddot", theta_ddot)):
            if x.shape != (len(self._act),) or not np.all(np.isfinite(x)):
                raise InputError(f"{name} must be {len(self._act)} finite numbers, got "
                                 f"shape {x.shape}", value=x.shape,
                                 valid=f"({len(self._act)},) finite")
        G = self.G(q)
        v = G @ theta_dot
        gamma = self.clm.drift(q, v)
        Jp = self.clm.constraint_jacobian(q)[:, self._pas]
        a = G @ theta_ddot
        a[self._pas] -= np.linalg.solve(Jp, gamma)
        return v, a

    # ------------------------------------------------------------------ inverse dynamics
    def inverse_dynamics(self, q: np.ndarray, v: np.ndarray, a: np.ndarray,
                         f_ext: dict[str, np.ndarray] | None = None) -> np.ndarray:
        """The 9 actuator torques [N m] producing the consistent motion (q, v, a).

        ``f_ext`` maps frame names to world-frame forces [N] applied at those frame
        origins (e.g. ``{"leg0_P": f}``); tau balances them too.
        """
        q, v, a = (np.asarray(x, dtype=float) for x in (q, v, a))
        self._check_state(q, v, a)
        G = self.G(q)
        h = pin.rnea(self.model, self.data, q, v, a)
        if f_ext:
            h = h - self._external_generalized_force(q, f_ext)
        return G.T @ h + self._friction(v[self._act])

    def _external_generalized_force(self, q: np.ndarray,
                                    f_ext: dict[str, np.ndarray]) -> np.ndarray:
        m, d = self.model, self.data
        pin.computeJointJacobians(m, d, q)
        pin.updateFramePlacements(m, d)
        out = np.zeros(m.nv)
        for name, f in f_ext.items():
            if not m.existFrame(name):
                raise InputError(f"unknown frame {name!r} for an external force",
                                 value=name, valid="a frame of the model")
            J = pin.getFrameJacobian(m, d, m.getFrameId(name), pin.LOCAL_WORLD_ALIGNED)[:3]
            out += J.T @ np.asarray(f, dtype=float)
        return out

    def actuated_inverse_dynamics(self, q: np.ndarray, theta_dot: np.ndarray,
                                  theta_ddot: np.ndarray) -> tuple[np.ndarray, float]:
        """(tau [N m], rcond) of the consistent motion through the closed configuration q
        with actuated rates theta_dot [rad/s] and accelerations theta_ddot [rad/s^2].

        The same equations as :meth:`consistent_state` + :meth:`inverse_dynamics`, with
        one constraint Jacobian, one LU and one RNEA per call.
        ``rcond`` is the 1-norm reciprocal condition estimate of J_pas; at or below
        :data:`SINGULAR_RCOND` tau is NaN (a parallel singularity: no torque is defined).
        """
        m, d = self.model, self.data
        Jc = self.clm.constraint_jacobian(q)
        lu, piv, rcond = self._lu(Jc)
        if rcond <= SINGULAR_RCOND:
            return np.full(len(self._act), np.nan), rcond
        X, _ = lapack.dgetrs(lu, piv, Jc[:, self._act])  # J_pas^-1 J_act
        v = np.zeros(m.nv)
        v[self._act] = theta_dot
        v[self._pas] = -X @ theta_dot
        gamma = self.clm.drift(q, v)  # world-aligned, like Jc
        a = np.zeros(m.nv)
        a[self._act] = theta_ddot
        corr, _ = lapack.dgetrs(lu, piv, gamma)
        a[self._pas] = -X @ theta_ddot - corr
        h = pin.rnea(m, d, q, v, a)
        return h[self._act] - X.T @ h[self._pas] + self._friction(theta_dot), rcond

    def actuated_inverse_dynamics_batch(self, q: np.ndarray, theta_dot: np.ndarray,
                                        theta_ddot: np.ndarray,
                                        inertia: np.ndarray | None = None,
                                        ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`actuated_inverse_dynamics` of n states at once: (tau (n, 9), rcond (n,)).

        Three passes over the states with Pinocchio (the closure Jacobian, the joints'
        world Jacobians and the closure points; their time variation for the drift;
        RNEA), everything else batched in numpy
        (:meth:`ClosedLoopModel.constraint_jacobian_batch`, :meth:`~ClosedLoopModel.drift_batch`).
        ``rcond`` is the exact 1-norm reciprocal condition number of J_pas; states at or
        below :data:`SINGULAR_RCOND` get NaN torques.

        With ``inertia`` (an (n, 9, 9) array), it is filled with the reduced inertia
        M_red = S^T M S of each state (S = [I; -J_pas^-1 J_act], M from ``crba``, rotors
        included): tau is affine in theta_ddot with this slope at fixed (q, theta_dot).
        """
        m, d = self.model, self.data
        q = np.asarray(q, dtype=float)
        n = len(q)
        theta_dot = np.asarray(theta_dot, dtype=float)
        v, a, X, rcond = self.consistent_states_batch(q, theta_dot, theta_ddot)
        H = np.empty((n, m.nv))
        rnea = pin.rnea
        ok: list[bool] = np.isfinite(np.c_[a, v]).all(axis=1).tolist()  # type: ignore[union-attr]
        for k in range(n):
            H[k] = rnea(m, d, q[k], v[k], a[k]) if ok[k] else np.nan
        if inertia is not None:
            self._reduced_inertia(q, X, inertia)
        tau = H[:, self._act] - np.einsum("nij,ni->nj", X, H[:, self._pas])
        tau += self._friction(theta_dot)
        tau[rcond <= SINGULAR_RCOND] = np.nan
        return tau, rcond

    def consistent_states_batch(self, q: np.ndarray, theta_dot: np.ndarray,
                                theta_ddot: np.ndarray
                                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(v (n, nv), a (n, nv), X (n, 27, 9) = J_pas^-1 J_act, rcond (n,)) of n closed
        configurations q with actuated rates and accelerations: :meth:`consistent_state`
        batched (v = G theta_dot, a = G theta_ddot + the drift's correction).  States at a
        parallel singularity have NaN rows."""
        m = self.model
        q = np.asarray(q, dtype=float)
        n = len(q)
        theta_dot = np.asarray(theta_dot, dtype=float)
        Jc, kin = self.clm.constraint_jacobian_batch(q)  # world-aligned, like the drift
        Jp = Jc[:, :, self._pas]
        with np.errstate(all="ignore"):
            try:
                inv = np.linalg.inv(Jp)
            except np.linalg.LinAlgError:  # some state exactly singular: one by one
                inv = np.stack([_safe_inv(J) for J in Jp])
            rcond = 1.0 / (np.abs(Jp).sum(axis=1).max(axis=1)
                           * np.abs(inv).sum(axis=1).max(axis=1))
        rcond = np.nan_to_num(rcond, nan=0.0)
        X = inv @ Jc[:, :, self._act]  # (n, 27, 9) J_pas^-1 J_act
        v = np.zeros((n, m.nv))
        v[:, self._act] = theta_dot
        v[:, self._pas] = -np.einsum("nij,nj->ni", X, theta_dot)
        moving = np.any(theta_dot != 0.0, axis=1)  # at rest the drift is exactly 0
        with np.errstate(all="ignore"):  # singular states: NaN, masked by the callers
            gamma = self.clm.drift_batch(q, v, kin, rows=moving)
            a = np.zeros((n, m.nv))
            a[:, self._act] = theta_ddot
            a[:, self._pas] = -np.einsum("nij,nj->ni", X, theta_ddot) \
                - np.einsum("nij,nj->ni", inv, gamma)
        return v, a, X, rcond

    def _reduced_inertia(self, q: np.ndarray, X: np.ndarray, out: np.ndarray) -> None:
        """out[k] = S^T M(q_k) S with S = [I on the actuated; -X_k on the passive]: one
        ``crba`` per state, which fills the upper triangle U of M = U + U^T - diag(M),
        so S^T M S = A + A^T - S^T diag(M) S with A = S^T U S (batched)."""
        m, d = self.model, self.data
        n = len(q)
        M = np.empty((n, m.nv, m.nv))
        crba = pin.crba
        ok = np.isfinite(X).all(axis=(1, 2))
        for k in range(n):
            M[k] = crba(m, d, q[k]) if ok[k] else np.nan
        U = np.triu(M)
        diag = np.diagonal(M, axis1=1, axis2=2)
        S = np.zeros((n, m.nv, len(self._act)))
        S[:, self._act, np.arange(len(self._act))] = 1.0
        S[:, self._pas, :] = -X
        St = np.swapaxes(S, 1, 2)
        A = St @ (U @ S)
        out[:] = A + np.swapaxes(A, 1, 2) - St @ (diag[:, :, None] * S)

    def holding_torques_batch(self, q: np.ndarray) -> np.ndarray:
        """(n, 9) static actuator torques holding the robot still at n configurations
        [N m]: tau = g_act - J_act^T y with J_pas^T y = g_pas (the closed-loop balance of
        :meth:`actuated_inverse_dynamics_batch` at v = a = 0, one solve instead of an
        inverse).  Singular states give NaN or inf; callers compare with a limit."""
        m, d = self.model, self.data
        n = len(q)
        Jc, _ = self.clm.constraint_jacobian_batch(q, drift=False)
        g = np.empty((n, m.nv))
        grav = pin.computeGeneralizedGravity
        for k in range(n):
            g[k] = grav(m, d, q[k])
        Jp = Jc[:, :, self._pas]
        with np.errstate(all="ignore"):
            try:
                y = np.linalg.solve(np.swapaxes(Jp, 1, 2), g[:, self._pas, None])[..., 0]
            except np.linalg.LinAlgError:
                y = np.full((n, len(self._pas)), np.nan)
            tau = g[:, self._act] - np.einsum("nij,ni->nj", Jc[:, :, self._act], y)
        return tau

    def gravity_torques(self, q: np.ndarray) -> np.ndarray:
        """Static actuator torques holding the robot still at q [N m]."""
        q = np.asarray(q, dtype=float)
        self._check_state(q)
        z = np.zeros(self.model.nv)
        return self.inverse_dynamics(q, z, z)

    # ------------------------------------------------------------------ forward dynamics
    def forward_dynamics(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> ForwardResult:
        """Tree acceleration under actuator torques tau (9,) [N m] and the 27 closures."""
        q, v = np.asarray(q, dtype=float), np.asarray(v, dtype=float)
        self._check_state(q, v)
        tau_full = np.zeros(self.model.nv)
        tau_full[self._act] = np.asarray(tau, dtype=float) - self._friction(v[self._act])
        a = pin.constraintDynamics(self.model, self.data, q, v, tau_full, self.cmodels,
                                   self.cdatas, self.prox)
        return ForwardResult(a=a.copy(), forces=self.data.lambda_c.copy())

    def step(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, dt: float,
             method: str = "rk4", project: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """One step of length dt [s] under constant tau: (q+, v+).

        ``method``: "rk4" (classical Runge-Kutta on the configuration Lie group, default)
        or "euler" (semi-implicit: v+ = v + a dt, q+ = q (+) v+ dt).  Baumgarte keeps the
        closures attracting inside a step; ``project`` then removes what drift is left
        (q by Gauss-Newton on r(q) = 0, v onto Jc v = 0, both minimum-norm).
        """
        m = self.model

        def acc(qq: np.ndarray, vv: np.ndarray) -> np.ndarray:
            return self.forward_dynamics(qq, vv, tau).a

        if method == "euler":
            v_next = v + acc(q, v) * dt
            q_next = pin.integrate(m, q, v_next * dt)
        elif method == "rk4":
            a1 = acc(q, v)
            v2 = v + 0.5 * dt * a1
            a2 = acc(pin.integrate(m, q, 0.5 * dt * v), v2)
            v3 = v + 0.5 * dt * a2
            a3 = acc(pin.integrate(m, q, 0.5 * dt * v2), v3)
            v4 = v + dt * a3
            a4 = acc(pin.integrate(m, q, dt * v3), v4)
            q_next = pin.integrate(m, q, dt / 6.0 * (v + 2 * v2 + 2 * v3 + v4))
            v_next = v + dt / 6.0 * (a1 + 2 * a2 + 2 * a3 + a4)
        else:
            raise InputError(f"unknown integration method {method!r}: use 'rk4' or 'euler'",
                             value=method, valid="rk4 or euler")
        if project:
            q_next, v_next = self.project(q_next, v_next)
        return q_next, v_next

    def project(self, q: np.ndarray, v: np.ndarray, tol: float = 1e-12,
                max_iter: int = 5) -> tuple[np.ndarray, np.ndarray]:
        """Closest consistent state: r(q) = 0 by Gauss-Newton, then Jc v = 0 [m, m/s]."""
        m = self.model
        for _ in range(max_iter):
            r = self.clm.residual(q)
            if np.abs(r).max() < tol:
                break
            Jc = self.clm.constraint_jacobian(q)
            q = pin.integrate(m, q, -np.linalg.lstsq(Jc, r, rcond=None)[0])
        Jc = self.clm.constraint_jacobian(q)
        v = v - np.linalg.lstsq(Jc, Jc @ v, rcond=None)[0]
        return q, v

    def energy(self, q: np.ndarray, v: np.ndarray) -> tuple[float, float]:
        """(kinetic, potential) energy [J]; potential is zero at z = 0.  The kinetic
        energy is v^T M v / 2 with the mass matrix of ``crba``, so it includes the
        rotors (armature)."""
        k = 0.5 * v @ pin.crba(self.model, self.data, q) @ v
        u = pin.computePotentialEnergy(self.model, self.data, q)
        return float(k), float(u)

    def simulate(self, q0: np.ndarray, v0: np.ndarray, duration: float, dt: float,
                 tau: np.ndarray | Callable[[float, np.ndarray, np.ndarray], np.ndarray] | None
                 = None, method: str = "rk4", project: bool = True) -> Trajectory:
        """Integrate from (q0, v0) for ``duration`` [s] at step ``dt`` [s].

        ``tau`` is None (unactuated), a (9,) constant or a callable (t, q, v) -> (9,).
        """
        if not (math.isfinite(dt) and dt > 0 and math.isfinite(duration) and duration > 0):
            raise InputError(f"dt and duration must be positive, got {dt}, {duration}",
                             value=(dt, duration), valid="finite, > 0 [s]")
        n = int(round(duration / dt)) + 1
        q, v = np.array(q0, dtype=float), np.array(v0, dtype=float)
        qs, vs = np.zeros((n, self.model.nq)), np.zeros((n, self.model.nv))
        ke, pe, res = np.zeros(n), np.zeros(n), np.zeros(n)
        for k in range(n):
            qs[k], vs[k] = q, v
            ke[k], pe[k] = self.energy(q, v)
            res[k] = np.abs(self.clm.residual(q)).max()
            if k == n - 1:
                break
            t = k * dt
            if tau is None:
                u = np.zeros(len(self._act))
            elif callable(tau):
                u = np.asarray(tau(t, q, v), dtype=float)
            else:
                u = np.asarray(tau, dtype=float)
            q, v = self.step(q, v, u, dt, method, project)
        return Trajectory(np.arange(n) * dt, qs, vs, ke, pe, res)


def _safe_inv(J: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.inv(J)
    except np.linalg.LinAlgError:
        return np.full_like(J, np.inf)
