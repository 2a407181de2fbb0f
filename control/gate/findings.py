"""The gate's findings: the consistency tolerances, one :class:`Finding` (of
:mod:`sixplus3.control.report`) per failed check, and the findings of the limits on
samples, midpoints and whole intervals, each by the one limit rule
(:mod:`sixplus3.kinematics.checks`).  :mod:`sixplus3.control.gate.validation` runs the checks."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sixplus3.control.file.file_format import JOINTS
from sixplus3.control.gate import interval
from sixplus3.control.report import Finding, ValidationReport
from sixplus3.kinematics.checks import (
    RCOND_MIN,
    cap_excess,
    floor_excess,
    range_excess,
    tilt_excess,
)
from sixplus3.kinematics.tcp import tcp_acceleration, tcp_velocity
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



# ----------------------------------------------------------------- families of checks
# One function per family of the gate's checks (control/gate/validation.py runs them in order).


def grid_finding(t: np.ndarray, th: np.ndarray, v: np.ndarray, a: np.ndarray, rate: float,
                 rate_range: tuple[float, float], k0: int, n_total: int | None,
                 max_duration: float) -> Finding | None:
    """The first defect of the time grid, or None: the rate outside ``rate_range``, fewer
    than 2 samples or a non-finite one, a motion longer than ``max_duration`` [s], or a
    sample off t_k = k / rate (samples k0 .. of a motion of ``n_total``)."""
    n = len(t)
    lo, _hi = rate_range
    if not (math.isfinite(rate) and rate_range[0] <= rate <= rate_range[1]):
        return Finding(check="rate", kind="defect", unit="Hz", bound=lo, count=1, first_t=0.0,
                       first_where="header", first_value=float(rate), worst_t=0.0,
                       worst_where="header", worst_value=float(rate))
    if n < 2 or not np.all(np.isfinite(np.c_[t, th, v, a])):
        return Finding(check="samples", kind="defect", unit="", bound=2, count=1, first_t=0.0,
                       first_where="file", first_value=float(n), worst_t=0.0,
                       worst_where="file", worst_value=n)
    grid = (k0 + np.arange(n)) / rate
    if (k0 + (n_total or n) - 1) / rate > max_duration:
        return Finding(check="duration", kind="defect", unit="s", bound=max_duration,
                       count=1, first_t=float(t[-1]), first_where="file",
                       first_value=float(grid[-1]), worst_t=float(t[-1]),
                       worst_where="file", worst_value=float(grid[-1]))
    err = np.abs(t - grid)
    return finding("time grid (t_k = k / rate)", "defect", "s", TIME_TOL,
                   err - TIME_TOL - 1e-12 * grid, err, t, ["time"])


def rest_findings(t: np.ndarray, v: np.ndarray, a: np.ndarray,
                  rest: tuple[bool, bool]) -> list[Finding]:
    """At rest (zero velocity and acceleration) at the start and the end where ``rest``
    says the motion starts or ends in these samples."""
    out = []
    n = len(t)
    for k, end in [e for e, on in zip(((0, "start"), (n - 1, "end")), rest, strict=True)
                   if on]:
        for arr, bound, what, unit in ((v, REST_VELOCITY_TOL, "velocity", "rad/s"),
                                       (a, REST_ACCELERATION_TOL, "acceleration", "rad/s^2")):
            f = finding(f"at rest at the {end} ({what})", "defect", unit, bound,
                        np.abs(arr[k:k + 1]) - bound, arr[k:k + 1], t[k:k + 1], JOINTS)
            if f:
                out.append(f)
    return out


def consistency_findings(t: np.ndarray, th: np.ndarray, v: np.ndarray, a: np.ndarray,
                         tol: Tolerances) -> tuple[list[Finding], np.ndarray]:
    """(the jumps: positions, rates and accelerations that no motion within the jerk
    limit connects (:class:`Tolerances`), |jerk| (n-1, 9) between the samples)."""
    dt = tol.dt
    d_th, d_v, d_a = np.diff(th, axis=0), np.diff(v, axis=0), np.diff(a, axis=0)
    fwd = d_th - v[:-1] * dt - a[:-1] * dt**2 / 2
    bwd = d_th - v[1:] * dt + a[1:] * dt**2 / 2
    pos_err = np.maximum(np.abs(fwd), np.abs(bwd))
    vel_err = np.abs(d_v - (a[:-1] + a[1:]) * dt / 2)
    out = []
    for check, e, bound, unit in (
            ("position/velocity consistency", pos_err, tol.position, "rad"),
            ("velocity/acceleration consistency", vel_err, tol.velocity, "rad/s")):
        f = finding(check, "defect", unit, bound, e - bound, e, t[:-1], JOINTS)
        if f:
            out.append(f)
    return out, np.abs(d_a) / dt


def platform_findings(t: np.ndarray, cfg: Any, quat: np.ndarray,
                      platform: np.ndarray | None) -> list[Finding]:
    """The file's platform columns (position, quaternion, cranks) against the forward
    kinematics of its joints ``cfg`` (quaternions ``quat``); none without columns."""
    if platform is None:
        return []
    platform = np.asarray(platform, dtype=float)
    dq = np.abs(np.einsum("ni,ni->n", platform[:, 3:7], quat))
    ang = 2 * np.arccos(np.clip(dq, -1.0, 1.0))
    errs = np.c_[np.abs(platform[:, 0:3] - cfg.position).max(axis=1), ang,
                 np.abs(platform[:, 7:10] - cfg.psi).max(axis=1),
                 np.abs(np.linalg.norm(platform[:, 3:7], axis=1) - 1.0)]
    f = finding("platform columns vs forward kinematics", "defect", "m or rad", POSE_TOL,
                errs - POSE_TOL, errs, t, ["position", "orientation", "psi",
                                           "quaternion norm"])
    return [f] if f else []


def feedforward_findings(t: np.ndarray, tau: np.ndarray, tau_file: np.ndarray | None
                         ) -> tuple[list[Finding], float | None]:
    """(the file's feed-forward torques against Pinocchio's ``tau``, the largest error
    [N m]); nothing without them."""
    if tau_file is None:
        return [], None
    ff = np.abs(np.asarray(tau_file, dtype=float) - tau)
    f = finding("feed-forward torque vs Pinocchio", "defect", "N m", FEEDFORWARD_TOL,
                ff - FEEDFORWARD_TOL, ff, t, JOINTS)
    return ([f] if f else []), float(np.nan_to_num(ff, nan=np.inf).max())


def tcp_findings(lim: Limits, t: np.ndarray, cfg: Any, v: np.ndarray, t_all: np.ndarray,
                 mid: tuple[Any, np.ndarray] | None
                 ) -> tuple[list[Finding], np.ndarray, np.ndarray]:
    """(the platform-space limits, the tool centre point's speed at every point, its
    acceleration at the samples): the speed from the actuated rates, the acceleration
    the finite difference of its vector (:mod:`sixplus3.kinematics.tcp`); ``mid``: the
    midpoints' configurations and rates."""
    v_tcp = tcp_velocity(cfg, v)
    tcp_a = tcp_acceleration(v_tcp, t)
    tcp_v = np.linalg.norm(v_tcp, axis=1)
    if mid is not None:
        tcp_v = np.r_[tcp_v, np.linalg.norm(tcp_velocity(*mid), axis=1)]
    out = []
    for name, unit, cap, val, tt in (("tcp speed", "m/s", lim.tcp_speed, tcp_v, t_all),
                                      ("tcp acceleration (samples)", "m/s^2",
                                       lim.tcp_acceleration, tcp_a, t)):
        f = finding(name, "limit", unit, cap, cap_excess(val, cap), val, tt, ["tcp"])
        if f:
            out.append(f)
    return out, tcp_v, tcp_a

def failed(n: int, robot: Robot, findings: list[Finding], tol: dict[str, Any]) -> ValidationReport:
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
    """The interpolant over every whole interval (control/gate/interval.py): its jerk against
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


def limit_findings(lim: Limits, cfgs: list[Any], tau: np.ndarray, v: np.ndarray, a: np.ndarray,
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
