"""Sensorless touch: the wrench a person applies to the platform, from the drives alone
(docs/interaction.md).

The external wrench w = (f, m) on the platform (base frame, m about the platform centre)
enters the actuated dynamics through the inverse kinematics Jacobian J (9 x 9:
theta_dot = J (v, omega, psi_dot), :func:`sixplus3.kinematics.robot.ik_jacobian`).  By
virtual work, J^T tau + (w, 0) = Q(x, xd, xdd), so with the model's torque
tau_model = J^-T Q:

    tau_ext := tau_model - tau_measured = J^-T (w, 0),   (w, c) = J^T tau_ext.

The six first components are the wrench; the last three, ``c``, are the generalized
forces on the three redundant cranks, which carry no platform load: a crank residual is
a model error or a force on a crank (the report shows it).

Two estimates of tau_ext:

- the **momentum observer** (De Luca and Mattone 2003; Haddadin et al. 2017) on the
  closed-loop dynamics in the actuated coordinates: p = M(theta) theta_dot,
  r_k = K (p_k - p_0 - sum_j (tau_j - h_j + Mdot_j theta_dot_j + r_j-1) dt), which needs
  no acceleration; r follows tau_ext through a first-order low-pass of bandwidth K.
  M is the reduced inertia G^T M_tree G (rotors included) and h the model's torque at
  zero acceleration (Coriolis, gravity, friction), both from Pinocchio;
- the **direct residual** with filtered accelerations (the identification's filter).

Uncertainty per sample: the torque's noise (the monitor's and the 0.1 % quantisation)
through the observer's low-pass, the model's error (``model_sigma``), and near zero speed
(|theta_dot| < ``v_band``) the dry friction band: there a joint's friction can take any
value within +-f_c, which a hold cannot tell from a push.  The band is reported apart, as
a bound in newtons at the platform (|A| f_c, A = J^T's wrench rows).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.linalg import lapack

from sixplus3.control.file.drive_log import DriveLog
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.errors import InputError, check_number
from sixplus3.filters import butter_sos, sosfiltfilt
from sixplus3.identification.base import (
    base_parameters,
    configurations,
    poses_of,
    stacked_regressor,
)
from sixplus3.identification.signals import filter_log
from sixplus3.interaction.observer.momentum import momentum_observer
from sixplus3.kinematics.robot_fk import ik_jacobian, robot_fk
from sixplus3.robot_description.robot import Robot, require_robot

#: Default observer gain [1/s]: a step reaches 95 % of its value in 3 / K = 20 ms.
GAIN = 150.0
#: Default standard deviation of the model's torque error [N m] (an identified robot on
#: the virtual prototype: 0.005-0.01, docs/identification.md).
MODEL_SIGMA = 0.01
#: Below this speed a joint's dry friction is a band, not a law [rad/s].
V_BAND = 0.1
#: Contact when a component leaves N_SIGMA standard deviations plus its band.
N_SIGMA = 4.0
#: Samples tracked at a time by the pose search of a log (1 kHz: 0.1 s).
CHUNK_STATES = 100
#: Lowest log rate the observer takes [Hz].
MIN_RATE = 200.0


@dataclass
class WrenchEstimate:
    """Per sample: t (n,), wrench (n, 6) [N, N m], its standard deviation (n, 6), the
    friction band (n, 6), the crank residual (n, 3) [N m], the contact flag (n,), and
    the direct residual's wrench (n, 6) for comparison."""

    t: np.ndarray
    wrench: np.ndarray
    std: np.ndarray
    band: np.ndarray
    crank: np.ndarray
    contact: np.ndarray
    direct: np.ndarray | None = None
    at: str = "centre"
    gain: float = GAIN
    notes: list[str] = field(default_factory=list)

    def summary(self) -> dict[str, Any]:
        return {"samples": len(self.t), "at": self.at, "gain_per_s": self.gain,
                "contact_samples": int(self.contact.sum()),
                "max_force_n": float(np.linalg.norm(self.wrench[:, :3], axis=1).max()),
                "max_moment_n_m": float(np.linalg.norm(self.wrench[:, 3:], axis=1).max()),
                "median_std": np.median(self.std, axis=0).tolist(),
                "max_friction_band": self.band.max(axis=0).tolist(),
                "max_crank_residual_n_m": float(np.abs(self.crank).max()),
                "notes": self.notes}


def torque_sigma(robot: Robot, monitor_noise: float = 0.005) -> float:
    """The standard deviation of a logged torque [N m at the joint]: the monitor's noise
    and the drive's 0.1 %-of-rated quantisation (uniform)."""
    unit = robot.motors.gear_ratio * robot.motors.rated_torque / 1000.0
    return math.sqrt(monitor_noise ** 2 + unit ** 2 / 12.0)


class StateModel:
    """The robot's configuration, Jacobian, reduced inertia and bias torque along a
    sequence of actuated angles (forward kinematics seeded sample after sample)."""

    def __init__(self, robot: Robot) -> None:
        self.robot = require_robot(robot)
        self.dyn = ClosedLoopDynamics(self.robot)
        self._x: np.ndarray | None = None

    def seed(self, theta: np.ndarray) -> None:
        fk = robot_fk(theta, self.robot)
        self._x = fk.x

    def states(self, theta: np.ndarray, theta_dot: np.ndarray, chunk: int = CHUNK_STATES
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(J (n, 9, 9), M (n, 9, 9), h (n, 9), tcp offset (n, 3)) of the samples; the
        configurations are kept in ``self.q`` (n, nq).  The poses are tracked ``chunk``
        samples at a time (:func:`~sixplus3.identification.base.poses_of`), then the
        Jacobians and the dynamics are evaluated in large batches."""
        theta = np.asarray(theta, dtype=float)
        theta_dot = np.asarray(theta_dot, dtype=float)
        n = len(theta)
        x, ok = poses_of(self.robot, theta, chunk)
        if not ok.all():
            k = int(np.argmin(ok))
            raise InputError(f"no pose of this robot has the logged angles of sample {k}",
                             value=k, valid="angles of an assembly of this robot")
        J = np.empty((n, 9, 9))
        M = np.empty((n, 9, 9))
        h = np.empty((n, 9))
        off = np.empty((n, 3))
        tool = np.asarray(self.robot.tool.xyz)
        qs = []
        for sl, cfg, _ in configurations(self.robot, theta, x):
            J[sl] = ik_jacobian(cfg)
            h[sl], _ = self.dyn.actuated_inverse_dynamics_batch(
                cfg.q, theta_dot[sl], np.zeros((sl.stop - sl.start, 9)), inertia=M[sl])
            off[sl] = np.einsum("nij,j->ni", cfg.rotation, tool)
            qs.append(cfg.q)
        self.q = np.concatenate(qs)
        self._x = x[-1]
        return J, M, h, off


class SingleState:
    """One sample at a time with Pinocchio only (no batched kernels: their thread pools
    cost more than a sample): forward kinematics by Newton on the closures from the
    previous configuration, G = dv/dtheta_dot, and from G's platform and crank rows the
    inverse kinematics Jacobian J = (S G)^-1; the reduced inertia G^T M G and the model's
    torque at zero acceleration."""

    def __init__(self, robot: Robot) -> None:
        # deferred: Pinocchio loads only when this runs
        import pinocchio as pin

        self.robot = require_robot(robot)
        self.dyn = ClosedLoopDynamics(self.robot)
        m = self.dyn.model
        self._pin = pin
        self._q: np.ndarray | None = None
        self._G: np.ndarray | None = None
        self._theta: np.ndarray | None = None
        ff = next(j for j in range(1, m.njoints) if m.joints[j].nq == 7)
        self._ffq, self._ffv = m.joints[ff].idx_q, m.joints[ff].idx_v
        self._crank_v = [m.joints[m.getJointId(f"platform_crank{i}")].idx_v
                         for i in range(3)]
        self._crank_q = [m.joints[m.getJointId(f"platform_crank{i}")].idx_q
                         for i in range(3)]
        self._tool = np.asarray(self.robot.tool.xyz)

    def reset(self) -> None:
        """Forget the previous sample (the next one is solved from home)."""
        self._q = self._G = self._theta = None

    def state(self, theta: np.ndarray, theta_dot: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(J (9, 9), M (9, 9), h (9,), tcp offset (3,)) of one sample."""

        pin, dyn = self._pin, self.dyn
        hint = self._q
        if hint is not None and self._G is not None and self._theta is not None:
            # first-order prediction along the closures: one Newton step is then enough
            hint = pin.integrate(dyn.model, hint, self._G @ (theta - self._theta))
        fk = robot_fk(theta, self.robot, q_hint=hint, model=dyn.clm, tol=1e-9)
        q = self._q = fk.q
        m, d, act, pas = dyn.model, dyn.data, dyn.clm.idx_v_act, dyn.clm.idx_v_pas
        Jc = dyn.clm.constraint_jacobian(q)  # one Jacobian for G, the drift and h
        lu, piv, _ = dyn._lu(Jc)
        X, _ = lapack.dgetrs(lu, piv, Jc[:, act])
        G = np.zeros((m.nv, len(act)))
        G[act] = np.eye(len(act))
        G[pas] = -X
        v = G @ theta_dot
        a = np.zeros(m.nv)
        corr, _ = lapack.dgetrs(lu, piv, dyn.clm.drift(q, v))
        a[pas] = -corr
        rn = pin.rnea(m, d, q, v, a)
        h = rn[act] - X.T @ rn[pas] + dyn._friction(theta_dot)
        Mt = pin.crba(m, d, q)
        Mt = np.triu(Mt) + np.triu(Mt, 1).T
        M = G.T @ Mt @ G
        quat = q[self._ffq + 3:self._ffq + 7]
        R = pin.Quaternion(quat[3], quat[0], quat[1], quat[2]).toRotationMatrix()
        vf = self._ffv
        B = np.vstack([R @ G[vf:vf + 3], R @ G[vf + 3:vf + 6], G[self._crank_v]])
        J = np.linalg.inv(B)
        self._G, self._theta = G, np.array(theta, dtype=float)
        #: the platform's pose and the crank angles of the last sample
        self.position, self.rotation = q[self._ffq:self._ffq + 3].copy(), R
        self.psi = q[self._crank_q].copy()
        return J, M, h, R @ self._tool


def wrench_map(J: np.ndarray) -> np.ndarray:
    """(n, 9, 9) J^T: tau_ext -> (f, m about the centre, crank torques)."""
    return np.swapaxes(J, 1, 2)


def to_tcp(w: np.ndarray, off: np.ndarray) -> np.ndarray:
    """The wrench about the platform centre as the wrench about the tool centre point
    (``off``: the TCP minus the centre, base frame): m_tcp = m_c - off x f."""
    out = w.copy()
    out[:, 3:] = w[:, 3:] - np.cross(off, w[:, :3])
    return out


def estimate(log: DriveLog, robot: Robot, gain: float = GAIN, at: str = "centre",
             monitor_noise: float = 0.005, model_sigma: float = MODEL_SIGMA,
             v_band: float = V_BAND, n_sigma: float = N_SIGMA,
             direct: bool = True,
             parameter_cov: tuple[np.ndarray, np.ndarray] | None = None) -> WrenchEstimate:
    """The wrench on the platform over ``log`` (module doc).  ``parameter_cov``: (the
    base columns, the covariance of the base parameters) of an identification
    (``--report DIR``'s ``parameters.npz``): each sample's torque variance then adds
    Y_b Sigma Y_b^T, the parameters' confidence at that state."""

    robot = require_robot(robot)
    for name, v, lo, hi in (("gain", gain, 1.0, 2000.0), ("model_sigma", model_sigma, 0.0,
                                                          10.0),
                            ("monitor_noise", monitor_noise, 0.0, 10.0),
                            ("v_band", v_band, 0.0, 10.0), ("n_sigma", n_sigma, 0.0, 100.0)):
        check_number(name, v, lo, hi)
    if at not in ("centre", "tcp"):
        raise InputError(f"--at must be centre or tcp, got {at!r}", value=at,
                         valid="centre or tcp")
    rate = log.rate
    if rate < MIN_RATE or rate < 4 * gain / (2 * math.pi):
        need = max(MIN_RATE, 4 * gain / (2 * math.pi))
        raise InputError(f"{log.name}: its rate {rate:.6g} Hz is too low for the observer "
                         f"(gain {gain:g}/s)", value=rate, valid=f">= {need:g} Hz")
    dt = 1.0 / rate
    # velocity: the encoder's differences, zero-phase filtered at rate / 8 (no lag; the
    # streaming form uses a causal filter instead)
    sos = butter_sos(4, rate / 8.0, rate)
    pad = min(len(log.t) - 1, 24)
    th_f = sosfiltfilt(sos, log.theta, pad)
    thd = np.gradient(th_f, dt, axis=0)
    tau = np.vstack([log.tau[:1], 0.5 * (log.tau[1:] + log.tau[:-1])])  # held over a tick
    sm = StateModel(robot)
    J, M, h, off = sm.states(log.theta, thd)
    tau_ext = momentum_observer(log.t, tau, thd, M, h, gain)
    A = wrench_map(J)
    full = np.einsum("nij,nj->ni", A, tau_ext)
    w, crank = full[:, :6], full[:, 6:]
    sig = torque_sigma(robot, monitor_noise)
    s_obs = sig * math.sqrt(gain * dt / 2.0)  # white noise through the first-order filter
    var = np.broadcast_to(np.full(9, s_obs ** 2 + model_sigma ** 2), (len(log.t), 9))
    if parameter_cov is not None:
        var = var + parameter_variance(robot, log.theta, thd, parameter_cov)
    # the encoder's quantisation (uniform over a count) through the bias's sensitivity is
    # below 1e-6 N m at the joint: not added
    std = np.sqrt(np.einsum("nij,nj->ni", A[:, :6, :] ** 2, var))
    fc = robot.motors.coulomb_per_joint
    slow = np.abs(thd) < v_band
    band = np.einsum("nij,nj->ni", np.abs(A[:, :6, :]), slow * fc)
    if at == "tcp":
        w = to_tcp(w, off)
        # the bound moves with the lever: |m_tcp| <= |m_c| + |off| |f| componentwise
        band = band.copy()
        band[:, 3:] += np.abs(off) @ np.ones((3, 3)) * band[:, :3].max(axis=1)[:, None]
    contact = np.any(np.abs(w) > n_sigma * std + band, axis=1)
    out_direct = None
    if direct:
        f = filter_log(log, decimate=False, coulomb_velocity=None)
        sm2 = StateModel(robot)
        J2, _, _, off2 = sm2.states(f.theta, f.theta_dot)
        tau_m, _ = sm2.dyn.actuated_inverse_dynamics_batch(sm2.q, f.theta_dot, f.theta_ddot)
        wd = np.einsum("nij,nj->ni", wrench_map(J2), tau_m - f.tau)[:, :6]
        if at == "tcp":
            wd = to_tcp(wd, off2)
        out_direct = np.full_like(w, np.nan)
        idx = np.searchsorted(log.t, f.t)
        out_direct[idx] = wd
    notes = [f"observer gain {gain:g}/s (95 % of a step in {3000 / gain:.0f} ms); torque "
             f"noise {sig:.4f} N m per joint, {s_obs:.4f} N m after the observer; model "
             f"error {model_sigma:g} N m per joint",
             f"below {v_band:g} rad/s a joint's dry friction (f_c up to "
             f"{fc.max():.3g} N m) is a band: the 'band' columns bound what a hold cannot "
             "tell from a push"]
    return WrenchEstimate(t=log.t.copy(), wrench=w, std=std, band=band, crank=crank,
                          contact=contact, direct=out_direct, at=at, gain=gain, notes=notes)


def checked_covariance(robot: Robot, parameter_cov: tuple[np.ndarray, np.ndarray]
                       ) -> tuple[Any, np.ndarray]:
    """(the robot's base parameters, the covariance) of an identification's
    (base columns, covariance), refused with an InputError when it is of another base
    or shape, or not a covariance (symmetric, positive semi-definite, finite)."""
    try:
        index, cov = (np.asarray(x, dtype=float) for x in parameter_cov)
    except (TypeError, ValueError):
        raise InputError("parameter_cov must be (the base columns, the covariance): two "
                         "arrays of numbers (identify estimate --report's parameters.npz)",
                         value=repr(parameter_cov)[:80],
                         valid="(index (rank,), covariance (rank, rank))") from None
    base = base_parameters(robot)
    if index.shape != base.index.shape or np.any(index != base.index):
        raise InputError("the parameters' covariance is of another base (another robot "
                         "structure)", value=index.shape, valid=f"({base.rank},) base columns")
    if cov.shape != (base.rank, base.rank) or not np.all(np.isfinite(cov)):
        raise InputError("the parameters' covariance has the wrong shape", value=cov.shape,
                         valid=f"({base.rank}, {base.rank}) finite")
    scale = max(float(np.abs(cov).max()), 1e-300)
    if (float(np.abs(cov - cov.T).max()) > 1e-9 * scale
            or float(np.linalg.eigvalsh(0.5 * (cov + cov.T)).min()) < -1e-9 * scale):
        raise InputError("the parameters' covariance is not symmetric positive "
                         "semi-definite", value="asymmetric or a negative eigenvalue",
                         valid="a covariance matrix")
    return base, cov


def parameter_variance(robot: Robot, theta: np.ndarray, theta_dot: np.ndarray,
                       parameter_cov: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """(n, 9) the variance of each joint's model torque from the base parameters'
    covariance: diag(Y_b Sigma Y_b^T) at each sample (its acceleration taken as zero: a
    hold's or a slow motion's dominant terms, gravity and friction)."""

    base, cov = checked_covariance(robot, parameter_cov)
    out = np.empty((len(theta), 9))
    step = 2000
    for i in range(0, len(theta), step):
        sl = slice(i, i + step)
        Wb = base.reduce(stacked_regressor(ClosedLoopDynamics(robot), theta[sl],
                                           theta_dot[sl], np.zeros_like(theta_dot[sl])))
        out[sl] = np.einsum("nja,ab,njb->nj", Wb, cov, Wb)
    return np.maximum(out, 0.0)


__all__ = ["GAIN", "MODEL_SIGMA", "N_SIGMA", "StateModel", "V_BAND", "WrenchEstimate",
           "checked_covariance", "parameter_variance",
           "estimate", "to_tcp", "torque_sigma", "wrench_map"]
