"""The gate's findings: the consistency tolerances, one :class:`Finding` (of
:mod:`sixplus3.control.report`) per failed check, and the findings of the limits on
samples, midpoints and whole intervals, each by the one limit rule
(:mod:`sixplus3.kinematics.checks`).  :mod:`sixplus3.control.validation` runs the checks
and re-exports these names."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sixplus3.control import interval
from sixplus3.control.file_format import JOINTS
from sixplus3.control.report import Finding, ValidationReport
from sixplus3.kinematics.checks import (
    RCOND_MIN,
    cap_excess,
    floor_excess,
    range_excess,
    tilt_excess,
)
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot

#: |t_k - k / rate| allowed [s] (17 significant digits are written).
TIME_TOL = 1e-9
#: At rest at both ends: |theta_dot| [rad/s] and |theta_ddot| [rad/s^2] allowed.
REST_VELOCITY_TOL = 1e-6
REST_ACCELERATION_TOL = 1e-4
#: Platform columns against the forward kinematics of the joints [m, rad, rad].
POSE_TOL = 1e-6
#: Feed-forward torques against Pinocchio's [N m].
FEEDFORWARD_TOL = 1e-6
#: Two forward-kinematics seeds must agree to this [m, rad]: else a branch switch.
BRANCH_TOL = 1e-7
#: Rounding slack of the consistency checks (positions [rad], rates [rad/s]).
ROUND_POS, ROUND_VEL = 1e-10, 1e-9


@dataclass(frozen=True)
class Tolerances:
    """Consistency tolerances of a motion sampled every ``dt`` [s] whose actuated jerk is
    bounded by ``jerk`` [rad/s^3] (the robot's limit).  Exact consequences of |jerk| <= J
    (Taylor's theorem with integral remainder), per joint and interval:

        |theta_{k+1} - theta_k - v_k dt - a_k dt^2/2|        <= J dt^3 / 6   (and backward)
        |v_{k+1} - v_k - (a_k + a_{k+1}) dt / 2|              <= J dt^2 / 4
        |a_{k+1} - a_k| / dt                                   <= J            (jerk limit)
    """

    dt: float
    jerk: float

    @property
    def position(self) -> float:
        return self.jerk * self.dt**3 / 6.0 + ROUND_POS

    @property
    def velocity(self) -> float:
        return self.jerk * self.dt**2 / 4.0 + ROUND_VEL

    def as_dict(self) -> dict[str, float]:
        return {"dt_s": self.dt, "jerk_rad_s3": self.jerk, "position_rad": self.position,
                "velocity_rad_s": self.velocity, "time_s": TIME_TOL,
                "rest_velocity_rad_s": REST_VELOCITY_TOL,
                "rest_acceleration_rad_s2": REST_ACCELERATION_TOL, "pose": POSE_TOL,
                "feedforward_n_m": FEEDFORWARD_TOL, "branch": BRANCH_TOL}


def finding(check: str, kind: str, unit: str, bound: float, excess: np.ndarray,
             value: np.ndarray, times: np.ndarray, names: list[str]) -> Finding | None:
    """A finding from per-(sample, element) ``excess`` (> 0 fails) and ``value``."""
    excess = np.atleast_2d(np.asarray(excess, dtype=float).T).T
    value = np.atleast_2d(np.asarray(value, dtype=float).T).T
    bad = np.nan_to_num(excess, nan=np.inf) > 0.0
    if not bad.any():
        return None
    rows = np.flatnonzero(bad.any(axis=1))
    k0 = int(rows[0])
    j0 = int(np.flatnonzero(bad[k0])[0])
    flat = np.nan_to_num(excess, nan=np.inf).ravel()
    kw, jw = divmod(int(np.argmax(flat)), excess.shape[1])
    return Finding(check=check, kind=kind, unit=unit, bound=float(bound),
                   count=int(len(rows)), first_t=float(times[k0]), first_where=names[j0],
                   first_value=float(value[k0, j0]), worst_t=float(times[kw]),
                   worst_where=names[jw], worst_value=float(value[kw, jw]),
                   excess=float(flat[kw * excess.shape[1] + jw]))


def failed(n: int, robot: Robot, findings: list[Finding], tol: dict) -> ValidationReport:
    """The report of a motion refused before its limits were measured."""
    return ValidationReport(
        ok=False, samples=n, robot_hash=robot.hash, max_torque_ratio=math.inf,
        max_velocity_ratio=math.inf, max_acceleration_ratio=math.inf,
        max_jerk_ratio=math.inf, min_margin_leg_type1=0.0, min_margin_leg_type2=0.0,
        min_margin_platform=0.0, min_clearance=-math.inf, max_spherical_tilt_deg=180.0,
        theta_range_ok=False, findings=findings, tolerances=tol)


@dataclass
class Between:
    """What the whole intervals gave: findings and the largest values [SI]."""

    findings: list[Finding]
    velocity: float
    acceleration: float
    jerk: float
    torque: float


def interval_findings(lim: Limits, dt: float, th: np.ndarray, v: np.ndarray, a: np.ndarray,
                       t_int: np.ndarray, tau_all: np.ndarray, n: int,
                       inertia: np.ndarray | None,
                       ext: dict[str, tuple[np.ndarray, np.ndarray]]) -> Between:
    """The interpolant over every whole interval (control/interval.py): its jerk against
    what a motion within the jerk limit allows (a defect above), its velocity and
    acceleration exactly (``ext``: :func:`interval.rate_extremes`), and the torque bound
    (with the midpoints' dynamics)."""
    out: list[Finding | None] = []
    jerk = ext["jerk"][0]
    cap = interval.C_JERK * lim.jerk
    out.append(finding("interpolant jerk (no motion within the jerk limit has these "
                        "samples)", "defect", "rad/s^3", cap, cap_excess(jerk, cap), jerk,
                        t_int, JOINTS))
    vel, acc = ext["velocity"][0], ext["acceleration"][0]
    out.append(finding("velocity (between samples)", "limit", "rad/s", lim.velocity,
                        cap_excess(vel, lim.velocity), vel, t_int, JOINTS))
    out.append(finding("acceleration (between samples)", "limit", "rad/s^2",
                        lim.acceleration, cap_excess(acc, lim.acceleration), acc, t_int,
                        JOINTS))
    torque = 0.0
    if inertia is not None and len(tau_all) > n:
        bound, _ = interval.torque_bound(dt, th, v, a, tau_all[:n], inertia[:n],
                                         tau_all[n:], inertia[n:])
        torque = float(bound.max())
        out.append(finding("torque (between samples, bound)", "limit", "N m", lim.torque,
                            cap_excess(bound, lim.torque), bound, t_int, JOINTS))
    return Between([f for f in out if f is not None], float(vel.max()), float(acc.max()),
                    float(jerk.max()), torque)


def limit_findings(lim: Limits, cfgs: list, tau: np.ndarray, v: np.ndarray, a: np.ndarray,
                    t: np.ndarray, rcond: np.ndarray, jerk: np.ndarray, t_int: np.ndarray,
                    sph: np.ndarray, clear: np.ndarray) -> list[Finding]:
    """Every limit on samples and midpoints (rows of the stacked arrays, in time order
    of each block), one finding per limit."""
    out: list[Finding | None] = []
    atau = np.nan_to_num(np.abs(tau), nan=np.inf)
    out.append(finding("torque", "limit", "N m", lim.torque, cap_excess(atau, lim.torque),
                        atau, t, JOINTS))
    out.append(finding("velocity", "limit", "rad/s", lim.velocity,
                        cap_excess(np.abs(v), lim.velocity), np.abs(v), t, JOINTS))
    out.append(finding("acceleration", "limit", "rad/s^2", lim.acceleration,
                        cap_excess(np.abs(a), lim.acceleration), np.abs(a), t, JOINTS))
    out.append(finding("jerk (between samples)", "limit", "rad/s^3", lim.jerk,
                        cap_excess(jerk, lim.jerk), jerk, t_int, JOINTS))
    out.append(finding("parallel singularity (closure Jacobian)", "limit", "rcond",
                        RCOND_MIN, floor_excess(rcond, RCOND_MIN), rcond, t, ["closures"]))
    th = np.vstack([c.theta for c in cfgs])
    out.append(finding("actuated range", "limit", "rad", lim.theta_max,
                        range_excess(th, lim), th, t, JOINTS))
    sph_names = [f"leg{i}_{s}" for i in range(3) for s in ("E", "F", "P")]
    out.append(finding("spherical joint tilt", "limit", "rad", lim.spherical,
                        tilt_excess(sph, lim), sph, t, sph_names))
    m = np.vstack([np.c_[c.margins.leg_type1, c.margins.leg_type2, c.margins.platform]
                   for c in cfgs])
    m_names = ([f"leg{i} type I" for i in range(3)] + [f"leg{i} type II" for i in range(3)]
               + ["platform"])
    out.append(finding("singularity margin", "limit", "", lim.margin,
                        floor_excess(m, lim.margin), m, t, m_names))
    out.append(finding("interference (clearance)", "limit", "m", 0.0, floor_excess(clear, 0.0),
                        clear, t, ["collision model"]))
    return [f for f in out if f is not None]
