"""Independent validation of an actuated-joint trajectory with the numeric model.

From the actuated angles, rates and accelerations alone (what the controller executes):
forward kinematics by Newton on the 27 closures (each sample hinted by the previous one),
Pinocchio's constrained inverse dynamics for the torques, the numeric singularity
margins, the actuated range, the spherical joints and the leg clearance.  Nothing from
the optimiser's CasADi model is used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.kinematics.robot import leg_clearance, robot_fk, robot_ik, spherical_tilts
from sixplus3.planner.task import Limits
from sixplus3.robot_description.urdf import SPHERICAL_LIMIT
from sixplus3.errors import ConvergenceError, SingularityError


@dataclass
class ValidationReport:
    ok: bool
    samples: int
    max_torque_ratio: float  # max |tau| / limit
    max_velocity_ratio: float
    max_acceleration_ratio: float
    min_margin_leg_type1: float
    min_margin_leg_type2: float
    min_margin_platform: float
    min_leg_clearance: float  # [m]
    max_spherical_tilt_deg: float
    theta_range_ok: bool
    violations: list[str] = field(default_factory=list)
    tau: np.ndarray | None = None  # (M, 9) [N m]
    position: np.ndarray | None = None  # (M, 3) platform [m]
    quaternion: np.ndarray | None = None  # (M, 4) x, y, z, w
    psi: np.ndarray | None = None  # (M, 3) [rad]

    def summary(self) -> dict:
        keys = ("ok", "samples", "max_torque_ratio", "max_velocity_ratio",
                "max_acceleration_ratio", "min_margin_leg_type1", "min_margin_leg_type2",
                "min_margin_platform", "min_leg_clearance", "max_spherical_tilt_deg",
                "theta_range_ok", "violations")
        return {k: getattr(self, k) for k in keys}


@dataclass(frozen=True)
class LimitMeasures:
    """Extremes of a sampled motion against the limits, and the limits it violates."""

    max_torque_ratio: float  # max |tau| / limit
    max_velocity_ratio: float
    max_acceleration_ratio: float
    min_margin_leg_type1: float
    min_margin_leg_type2: float
    min_margin_platform: float
    min_leg_clearance: float  # [m] between links of different legs (capsules)
    max_spherical_tilt: float  # [rad]
    theta_range_ok: bool
    violations: list[str]


def measure_limits(cfg, tau: np.ndarray, theta: np.ndarray, theta_dot: np.ndarray,
                   theta_ddot: np.ndarray, limits: Limits) -> LimitMeasures:
    """The one rule both independent checks apply (the planner's dense re-check and the
    file validation): torques, actuated rates and accelerations against their limits,
    the numeric singularity margins of ``cfg`` (a batched RobotConfig), leg clearance,
    spherical-joint tilts and the actuated range [0, 270] deg.  Each violation is one
    message starting with the limit's name (the planner tightens by that name)."""
    torque = float(np.abs(tau).max() / limits.torque)
    vel = float(np.abs(theta_dot).max() / limits.velocity)
    acc = float(np.abs(theta_ddot).max() / limits.acceleration)
    m = cfg.margins
    m1, m2, mp = float(m.leg_type1.min()), float(m.leg_type2.min()), float(m.platform.min())
    clearance = float(leg_clearance(cfg).min())
    tilt = float(spherical_tilts(cfg).max())
    theta_ok = bool(np.all((theta >= -1e-9) & (theta <= 1.5 * math.pi + 1e-9)))
    violations = []
    if torque > 1.0:
        violations.append(f"torque {torque * limits.torque:.3f} N m > {limits.torque:g} N m")
    if vel > 1.0 + 1e-9:
        violations.append(f"velocity {vel * limits.velocity:.3f} rad/s > "
                          f"{limits.velocity:g} rad/s")
    if acc > 1.0 + 1e-9:
        violations.append(f"acceleration {acc * limits.acceleration:.1f} rad/s^2 > "
                          f"{limits.acceleration:g} rad/s^2")
    for name, val in (("leg type I margin", m1), ("leg type II margin", m2),
                      ("platform margin", mp)):
        if val < limits.margin:
            violations.append(f"{name} {val:.4f} < {limits.margin:g}")
    if clearance < 0.0:
        violations.append(f"leg interference: links of different legs overlap by "
                          f"{-clearance * 1e3:.1f} mm")
    if tilt > SPHERICAL_LIMIT:
        violations.append(f"spherical joint at {math.degrees(tilt):.1f} deg > 150 deg")
    if not theta_ok:
        violations.append("an actuated angle leaves [0, 270] deg")
    return LimitMeasures(torque, vel, acc, m1, m2, mp, clearance, tilt, theta_ok, violations)


def validate_joint_trajectory(theta: np.ndarray, theta_dot: np.ndarray,
                              theta_ddot: np.ndarray, limits: Limits,
                              q_hint: np.ndarray) -> ValidationReport:
    """Check every sample; ``q_hint`` is the tree configuration near the first sample."""
    dyn = ClosedLoopDynamics()
    n = theta.shape[0]
    tau = np.zeros((n, 9))
    q = np.array(q_hint, dtype=float)
    qs = np.zeros((n, dyn.model.nq))
    pos = np.zeros((n, 3))
    quat = np.zeros((n, 4))
    psi = np.zeros((n, 3))
    violations: list[str] = []
    for k in range(n):
        try:
            fk = robot_fk(theta[k], q_hint=q)
        except ConvergenceError:
            violations.append(f"forward kinematics fails at sample {k}")
            break
        q = fk.q
        qs[k] = q
        pos[k], psi[k] = fk.position, fk.psi
        quat[k] = Rotation.from_matrix(fk.rotation).as_quat()
        try:
            v, a = dyn.consistent_state(q, theta_dot[k], theta_ddot[k])
            tau[k] = dyn.inverse_dynamics(q, v, a)
        except SingularityError as exc:
            violations.append(f"sample {k}: {exc}")
            break
    if violations:
        return ValidationReport(False, n, math.inf, math.inf, math.inf, 0, 0, 0, -math.inf,
                                180.0, False, violations)
    cfg = robot_ik(pos, Rotation.from_quat(quat).as_matrix(), psi)
    if not cfg.ok.all():
        violations.append("a recomputed pose is unreachable")
    lm = measure_limits(cfg, tau, theta, theta_dot, theta_ddot, limits)
    violations += lm.violations
    return ValidationReport(not violations, n, lm.max_torque_ratio, lm.max_velocity_ratio,
                            lm.max_acceleration_ratio, lm.min_margin_leg_type1,
                            lm.min_margin_leg_type2, lm.min_margin_platform,
                            lm.min_leg_clearance, math.degrees(lm.max_spherical_tilt),
                            lm.theta_range_ok, violations, tau, pos, quat, psi)
