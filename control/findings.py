"""The gate's findings and report: the consistency tolerances, one :class:`Finding` per
failed check, the :class:`ValidationReport`, and the findings of the limits on samples,
midpoints and whole intervals, each by the one limit rule
(:mod:`sixplus3.kinematics.checks`).  :mod:`sixplus3.control.validation` runs the checks
and re-exports these names."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sixplus3.control import interval
from sixplus3.control.trajectory_file import JOINTS
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


@dataclass(frozen=True)
class Finding:
    """One failed check: where it first failed and where it failed worst."""

    check: str  # e.g. "torque", "velocity consistency"
    kind: str  # "limit" (exit 1) or "defect" (exit 2)
    unit: str
    bound: float  # the limit or tolerance
    count: int  # samples (or intervals) that fail
    first_t: float
    first_where: str  # joint or part
    first_value: float
    worst_t: float
    worst_where: str
    worst_value: float
    excess: float = 0.0  # how far past the bound the worst is (in the check's own terms)

    def message(self) -> str:
        u = f" {self.unit}" if self.unit else ""
        return (f"{self.check}: first at t = {self.first_t:.4f} s on {self.first_where}: "
                f"{self.first_value:.6g}{u} (bound {self.bound:.6g}{u}); worst at t = "
                f"{self.worst_t:.4f} s on {self.worst_where}: {self.worst_value:.6g}{u}; "
                f"{self.count} failing")


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
    return Finding(check, kind, unit, float(bound), int(len(rows)), float(times[k0]),
                   names[j0], float(value[k0, j0]), float(times[kw]), names[jw],
                   float(value[kw, jw]), float(flat[kw * excess.shape[1] + jw]))


@dataclass
class ValidationReport:
    ok: bool
    samples: int
    robot_hash: str
    max_torque_ratio: float  # max |tau| / limit (samples and midpoints)
    max_velocity_ratio: float
    max_acceleration_ratio: float
    max_jerk_ratio: float
    min_margin_leg_type1: float
    min_margin_leg_type2: float
    min_margin_platform: float
    min_clearance: float  # [m]
    max_spherical_tilt_deg: float
    theta_range_ok: bool
    findings: list[Finding] = field(default_factory=list)
    tolerances: dict = field(default_factory=dict)
    checked_points: int = 0  # samples + midpoints evaluated with the full dynamics
    tau: np.ndarray | None = None  # (M, 9) [N m] on the samples
    position: np.ndarray | None = None  # (M, 3) platform [m]
    quaternion: np.ndarray | None = None  # (M, 4) x, y, z, w
    psi: np.ndarray | None = None  # (M, 3) [rad]
    feedforward_error: float | None = None  # max |tau_file - tau| [N m]
    #: max |tau(k+1) - tau(k)| / dt over the samples [N m/s]: reported, not a gate check
    #: (the planner bounds it between its own points, docs/validation.md)
    max_torque_rate: float | None = None
    duration: float | None = None  # [s]
    #: max |jerk| of the interpolant over the intervals / (C_JERK x the jerk limit): above
    #: 1 no motion within the jerk limit has these samples (control/interval.py)
    max_interpolant_jerk_ratio: float = 0.0
    header: dict | None = field(default=None, repr=False)  # validate_file only
    #: the samples validated, exactly as read (validate_file): send these
    data: np.ndarray | None = field(default=None, repr=False)
    rate_hz: float | None = None  # the rate the samples were judged at [Hz]
    #: trajectory_file.samples_fingerprint of (t, theta, theta_dot, theta_ddot, rate)
    fingerprint: str | None = field(default=None, repr=False)
    limits: dict | None = None  # the limits judged by (the robot's, or tighter)
    max_tcp_speed: float = 0.0  # [m/s] the tool centre point (samples and midpoints)
    max_tcp_acceleration: float = 0.0  # [m/s^2] (samples: finite difference)

    @property
    def defects(self) -> list[Finding]:
        return [f for f in self.findings if f.kind == "defect"]

    @property
    def violations(self) -> list[str]:
        """Messages of every finding (defects first)."""
        return self.messages()

    def messages(self) -> list[str]:
        order = sorted(self.findings, key=lambda f: f.kind != "defect")
        return [f.message() for f in order]

    @property
    def exit_code(self) -> int:
        """0 valid; 2 the file is not a consistent motion of this robot; 1 a limit."""
        if self.defects:
            return 2
        return 1 if self.findings else 0

    def summary(self) -> dict:
        keys = ("ok", "samples", "robot_hash", "max_torque_ratio", "max_velocity_ratio",
                "max_acceleration_ratio", "max_jerk_ratio", "min_margin_leg_type1",
                "min_margin_leg_type2", "min_margin_platform", "min_clearance",
                "max_spherical_tilt_deg", "theta_range_ok", "checked_points", "tolerances",
                "max_torque_rate", "max_interpolant_jerk_ratio", "rate_hz", "limits",
                "max_tcp_speed", "max_tcp_acceleration")
        out = {k: getattr(self, k) for k in keys}
        out["exit_code"] = self.exit_code
        out["findings"] = self.messages()
        return out


def failed(n: int, robot: Robot, findings: list[Finding], tol: dict) -> ValidationReport:
    return ValidationReport(False, n, robot.hash, math.inf, math.inf, math.inf, math.inf,
                            0.0, 0.0, 0.0, -math.inf, 180.0, False, findings, tol)


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
