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
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from sixplus3.control.trajectory_file import columns, read_trajectory
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.errors import ConvergenceError, SingularityError, TrajectoryFileError
from sixplus3.kinematics.checks import measure_limits
from sixplus3.kinematics.robot import home, robot_fk, robot_ik
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot


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
    feedforward_error: float | None = None  # max |tau_file - tau| [N m] (validate_file)
    duration: float | None = None  # [s] (validate_file)
    header: dict | None = field(default=None, repr=False)  # the header read (validate_file)
    #: the samples validated, exactly as read from the file (validate_file): send these
    data: np.ndarray | None = field(default=None, repr=False)

    def summary(self) -> dict:
        keys = ("ok", "samples", "max_torque_ratio", "max_velocity_ratio",
                "max_acceleration_ratio", "min_margin_leg_type1", "min_margin_leg_type2",
                "min_margin_platform", "min_leg_clearance", "max_spherical_tilt_deg",
                "theta_range_ok", "violations")
        return {k: getattr(self, k) for k in keys}


def validate_joint_trajectory(theta: np.ndarray, theta_dot: np.ndarray,
                              theta_ddot: np.ndarray, robot: Robot | None = None,
                              limits: Limits | None = None,
                              q_hint: np.ndarray | None = None) -> ValidationReport:
    """Check every sample of a motion of ``robot`` against ``limits`` (default: the
    robot's hardware limits; tighter ones may be given, looser ones are refused).

    ``q_hint`` is the tree configuration near the first sample (default: home); it only
    selects the assembly branch of the forward kinematics.
    """
    robot = robot or Robot.default()
    limits = robot.limits if limits is None else robot.limits.tightened(**limits.as_dict())
    dyn = ClosedLoopDynamics(robot)
    n = theta.shape[0]
    tau = np.zeros((n, 9))
    q = home(robot).q[0] if q_hint is None else np.array(q_hint, dtype=float)
    pos = np.zeros((n, 3))
    quat = np.zeros((n, 4))
    psi = np.zeros((n, 3))
    violations: list[str] = []
    for k in range(n):
        try:
            fk = robot_fk(theta[k], q_hint=q, model=dyn.clm)
        except ConvergenceError:
            violations.append(f"forward kinematics fails at sample {k}")
            break
        q = fk.q
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
    cfg = robot_ik(pos, Rotation.from_quat(quat).as_matrix(), psi, robot)
    if not cfg.ok.all():
        violations.append("a recomputed pose is unreachable")
    lm = measure_limits(cfg, tau, theta, theta_dot, theta_ddot, limits)
    violations += lm.violations
    return ValidationReport(not violations, n, lm.max_torque_ratio, lm.max_velocity_ratio,
                            lm.max_acceleration_ratio, lm.min_margin_leg_type1,
                            lm.min_margin_leg_type2, lm.min_margin_platform,
                            lm.min_leg_clearance, math.degrees(lm.max_spherical_tilt),
                            lm.theta_range_ok, violations, tau, pos, quat, psi)


def validate_file(path: str | Path, robot: Robot | None = None) -> ValidationReport:
    """Validate a trajectory file for ``robot`` (default ``Robot.default()``).

    Raises :class:`TrajectoryFileError` for a file that is missing, corrupted or made for
    another robot (bad input); returns a report whose ``ok`` is False when a limit is
    violated.  The limits are the robot's hardware limits, never the file's.
    """
    robot = robot or Robot.default()
    header, data = read_trajectory(Path(path), robot)
    cfg0 = robot_ik(data[0, 37:40], Rotation.from_quat(data[0, 40:44]).as_matrix(),
                    data[0, 44:47], robot)
    if not cfg0.ok[0]:
        raise TrajectoryFileError(f"{Path(path).name}: the first platform pose is unreachable")
    rep = validate_joint_trajectory(columns(data, "pos"), columns(data, "vel"),
                                    columns(data, "acc"), robot, None, cfg0.q[0])
    tau_file = columns(data, "tau")
    ff_err = float(np.abs(rep.tau - tau_file).max()) if rep.tau is not None else math.inf
    rep.feedforward_error = ff_err
    rep.duration = float(data[-1, 0])
    rep.header, rep.data = header, data
    if ff_err > 1e-6 * max(1.0, robot.limits.torque):
        rep.violations.append(f"feed-forward torques differ from the recomputed ones by "
                              f"{ff_err:.2e} N m")
        rep.ok = False
    return rep
