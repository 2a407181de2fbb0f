"""The gate: independent validation of a motion of the robot, sample by sample and between.

Nothing in the file is trusted: the limits are the robot's hardware limits
(:attr:`Robot.limits`, never the file's); the platform pose is recomputed from the
actuated angles; the torques are recomputed with Pinocchio (nothing from the planner's
CasADi model); the file's platform columns and feed-forward torques are only compared.
docs/validation.md lists every check and its tolerance: it is the contract the
controller side relies on.

Two kinds of finding:

- a **defect** (exit code 2): the file is not a consistent, sampled motion of this robot
  (time grid, rate, not at rest at an end, velocities or accelerations inconsistent with
  the positions, a forward-kinematics branch switch, platform columns or feed-forward
  torques that differ from the recomputed ones);
- a **limit** (exit code 1): a consistent motion that violates a hardware limit (torque,
  velocity, acceleration, jerk, actuated range, spherical joints, singularity margins,
  leg interference), on a sample or between samples.

Every finding names the check, the joint (or the part), the time and the value of the
first and of the worst violation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sixplus3.control import interval
from sixplus3.control.interval import hermite, hermite_midpoints
from sixplus3.control.offload import OFFLOAD_SHARE, Offload
from sixplus3.control.trajectory_file import (
    COLUMNS,
    JOINTS,
    check_robot,
    columns,
    parse,
    read_bytes,
    samples_fingerprint,
)
from sixplus3.errors import InputError, TrajectoryFileError, ValidationFailed
from sixplus3.kinematics import rotations as rot
from sixplus3.kinematics.collision import clearance
from sixplus3.kinematics.robot import robot_fk_batch
from sixplus3.kinematics.spherical import spherical_tilts
from sixplus3.kinematics.tcp import tcp_acceleration, tcp_velocity
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot, require_robot

#: Controller rates accepted [Hz].  Below 1 kHz the gate and a sampled drive part: in a
#: MuJoCo replay of feed-forward held for a tick + PD (300 / 6), plans that pass the
#: gate peak at 133 N m at 100 Hz (tilt30_x: the PD loop near its discrete stability
#: bound) and at 11.0 N m at 500 Hz (translate); at 1 kHz every example stays within
#: 10 N m (docs/validation.md, "The lowest rate").  Above 10 kHz no drive listens.
RATE_RANGE = (1000.0, 10000.0)
#: Rates accepted for consumers that interpolate the quintic through the points instead
#: of holding each (a ROS 2 JointTrajectory controller with positions, velocities and
#: accelerations): the whole-interval checks prove that interpolated motion, at any rate.
INTERPOLATED_RATE_RANGE = (10.0, 10000.0)
#: Samples checked at once: a longer motion is checked in windows of this many samples
#: (sharing their end samples), so the checks' memory does not grow with its length.
WINDOW = 8192
#: Longest motion accepted [s].
MAX_DURATION = 3600.0
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


def _finding(check: str, kind: str, unit: str, bound: float, excess: np.ndarray,
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


def _failed(n: int, robot: Robot, findings: list[Finding], tol: dict) -> ValidationReport:
    return ValidationReport(False, n, robot.hash, math.inf, math.inf, math.inf, math.inf,
                            0.0, 0.0, 0.0, -math.inf, 180.0, False, findings, tol)


def validate_motion(t: np.ndarray, theta: np.ndarray, theta_dot: np.ndarray,
                    theta_ddot: np.ndarray, robot: Robot, rate: float,
                    x_guess: np.ndarray, limits: Limits | None = None,
                    platform: np.ndarray | None = None,
                    tau_file: np.ndarray | None = None,
                    midpoints: bool = True,
                    rate_range: tuple[float, float] = RATE_RANGE) -> ValidationReport:
    """Validate a sampled motion of ``robot``: every check of docs/validation.md.

    t (n,) [s]; theta, theta_dot, theta_ddot (n, 9); ``rate`` [Hz] the declared rate;
    ``x_guess`` (n, 9) minimal coordinates seeding the forward kinematics (e.g. the
    file's platform columns; only a starting guess, and the first one is checked);
    ``limits`` tighter than the robot's (default: the robot's hardware limits);
    ``platform`` (n, 10) position, quaternion, psi to compare with the forward
    kinematics; ``tau_file`` (n, 9) feed-forward torques to compare with Pinocchio's.
    ``rate_range``: the rates accepted (default :data:`RATE_RANGE`, for drives that hold
    each sample; :data:`INTERPOLATED_RATE_RANGE` for consumers that interpolate the
    quintic through the points, such as a decimated ROS 2 JointTrajectory).

    A motion of more than :data:`WINDOW` samples is checked window by window (each
    window shares its last sample with the next, so every interval is checked once), so
    that the memory of the checks does not grow with the length of the motion.
    """
    require_robot(robot)
    if limits is not None and not isinstance(limits, Limits):
        raise InputError("limits must be a Limits (or None)", value=type(limits).__name__,
                         valid="Limits or None")
    lim = robot.limits if limits is None else robot.limits.tightened(**limits.as_dict())
    try:
        t = np.asarray(t, dtype=float).reshape(-1)
        arrays = [np.asarray(a, dtype=float) for a in (theta, theta_dot, theta_ddot)]
        extra = {k: (None if a is None else np.asarray(a, dtype=float))
                 for k, a in (("x_guess", x_guess), ("platform", platform),
                              ("tau_file", tau_file))}
        rate = float(rate)
    except (TypeError, ValueError) as exc:
        raise InputError(f"the motion must be numeric arrays and a rate: {exc}"[:200],
                         value=None, valid="(n,) times, (n, 9) arrays, a rate [Hz]") from None
    n = len(t)
    for name, arr, width in (("theta", arrays[0], 9), ("theta_dot", arrays[1], 9),
                             ("theta_ddot", arrays[2], 9), ("x_guess", extra["x_guess"], 9),
                             ("platform", extra["platform"], 10),
                             ("tau_file", extra["tau_file"], 9)):
        if arr is not None and arr.shape != (n, width):
            raise InputError(f"{name} must be ({n}, {width}), got {arr.shape}",
                             value=arr.shape, valid=f"({n}, {width})")
    th, v, a = arrays
    xg, pf, tf_ = extra["x_guess"], extra["platform"], extra["tau_file"]
    if xg is None:
        raise InputError("x_guess (n, 9) is needed to seed the forward kinematics",
                         value=None, valid=f"({n}, 9)")
    if n <= WINDOW:
        rep = _validate_window(t, th, v, a, robot, rate, xg, lim, pf, tf_, midpoints,
                               rate_range=rate_range)
    else:
        reps = []
        for i0 in range(0, n - 1, WINDOW - 1):
            sl = slice(i0, min(n, i0 + WINDOW))
            reps.append(_validate_window(
                t[sl], th[sl], v[sl], a[sl], robot, rate, xg[sl], lim,
                None if pf is None else pf[sl], None if tf_ is None else tf_[sl],
                midpoints, k0=i0, rest=(i0 == 0, sl.stop == n), n_total=n,
                rate_range=rate_range))
            if reps[-1].tau is None:  # a window that could not be checked through
                break
        rep = _merge(reps, n)
    rep.rate_hz = rate
    rep.fingerprint = samples_fingerprint(t, th, v, a, rate)
    rep.limits = lim.as_dict()
    return rep


def _merge(reps: list[ValidationReport], n: int) -> ValidationReport:
    """One report of consecutive windows that share their end samples."""
    first = reps[0]
    by_check: dict[str, Finding] = {}
    for r in reps:
        for f in r.findings:
            old = by_check.get(f.check)
            if old is None:
                by_check[f.check] = f
                continue
            worst = f if f.excess > old.excess else old
            by_check[f.check] = Finding(
                f.check, f.kind, f.unit, f.bound, old.count + f.count, old.first_t,
                old.first_where, old.first_value, worst.worst_t, worst.worst_where,
                worst.worst_value, max(old.excess, f.excess))
    complete = all(r.tau is not None for r in reps) and len(reps) > 0

    def cat(name: str) -> np.ndarray | None:
        if not complete:
            return None
        parts = [getattr(r, name) for r in reps]
        return np.concatenate([parts[0]] + [p[1:] for p in parts[1:]])

    ffs = [r.feedforward_error for r in reps if r.feedforward_error is not None]
    rates = [r.max_torque_rate for r in reps if r.max_torque_rate is not None]
    findings = list(by_check.values())
    return ValidationReport(
        ok=not findings and complete, samples=n, robot_hash=first.robot_hash,
        max_torque_ratio=max(r.max_torque_ratio for r in reps),
        max_velocity_ratio=max(r.max_velocity_ratio for r in reps),
        max_acceleration_ratio=max(r.max_acceleration_ratio for r in reps),
        max_jerk_ratio=max(r.max_jerk_ratio for r in reps),
        min_margin_leg_type1=min(r.min_margin_leg_type1 for r in reps),
        min_margin_leg_type2=min(r.min_margin_leg_type2 for r in reps),
        min_margin_platform=min(r.min_margin_platform for r in reps),
        min_clearance=min(r.min_clearance for r in reps),
        max_spherical_tilt_deg=max(r.max_spherical_tilt_deg for r in reps),
        theta_range_ok=all(r.theta_range_ok for r in reps), findings=findings,
        tolerances=first.tolerances,
        checked_points=sum(r.checked_points for r in reps) - (len(reps) - 1),
        tau=cat("tau"), position=cat("position"), quaternion=cat("quaternion"),
        psi=cat("psi"), feedforward_error=max(ffs) if ffs else None,
        max_torque_rate=max(rates) if rates else None,
        max_tcp_speed=max(r.max_tcp_speed for r in reps),
        max_tcp_acceleration=max(r.max_tcp_acceleration for r in reps),
        duration=reps[-1].duration,
        max_interpolant_jerk_ratio=max(r.max_interpolant_jerk_ratio for r in reps))


def _validate_window(t: np.ndarray, th: np.ndarray, v: np.ndarray, a: np.ndarray,
                     robot: Robot, rate: float, x_guess: np.ndarray, lim: Limits,
                     platform: np.ndarray | None, tau_file: np.ndarray | None,
                     midpoints: bool, k0: int = 0, rest: tuple[bool, bool] = (True, True),
                     n_total: int | None = None,
                     rate_range: tuple[float, float] = RATE_RANGE) -> ValidationReport:
    """:func:`validate_motion` of samples k0 .. k0 + len(t) - 1 of a motion of
    ``n_total`` samples; ``rest``: whether this window holds the start / the end."""
    n = len(t)
    findings: list[Finding] = []
    f: Finding | None
    # ------------------------------------------------------------ grid and rate
    lo, hi = rate_range
    if not (math.isfinite(rate) and lo <= rate <= hi):
        f = Finding("rate", "defect", "Hz", lo, 1, 0.0, "header", float(rate), 0.0, "header",
                    float(rate))
        return _failed(n, robot, [f], {})
    dt = 1.0 / rate
    tol = Tolerances(dt, lim.jerk)
    tol_d = tol.as_dict()
    if n < 2 or not np.all(np.isfinite(np.c_[t, th, v, a])):
        f = Finding("samples", "defect", "", 2, 1, 0.0, "file", float(n), 0.0, "file", n)
        return _failed(n, robot, [f], tol_d)
    grid = (k0 + np.arange(n)) / rate
    if (k0 + (n_total or n) - 1) / rate > MAX_DURATION:
        f = Finding("duration", "defect", "s", MAX_DURATION, 1, float(t[-1]), "file",
                    float(grid[-1]), float(t[-1]), "file", float(grid[-1]))
        return _failed(n, robot, [f], tol_d)
    err = np.abs(t - grid)
    g = _finding("time grid (t_k = k / rate)", "defect", "s", TIME_TOL,
                 err - TIME_TOL - 1e-12 * grid, err, t, ["time"])
    if g is not None:
        return _failed(n, robot, [g], tol_d)
    # ------------------------------------------------------------ rest at both ends
    for k, end in [e for e, on in zip(((0, "start"), (n - 1, "end")), rest, strict=True)
                   if on]:
        for arr, bound, what, unit in ((v, REST_VELOCITY_TOL, "velocity", "rad/s"),
                                       (a, REST_ACCELERATION_TOL, "acceleration", "rad/s^2")):
            f = _finding(f"at rest at the {end} ({what})", "defect", unit, bound,
                         np.abs(arr[k:k + 1]) - bound, arr[k:k + 1], t[k:k + 1], JOINTS)
            if f:
                findings.append(f)
    # ------------------------------------------------------------ consistency (no jumps)
    d_th, d_v, d_a = np.diff(th, axis=0), np.diff(v, axis=0), np.diff(a, axis=0)
    fwd = d_th - v[:-1] * dt - a[:-1] * dt**2 / 2
    bwd = d_th - v[1:] * dt + a[1:] * dt**2 / 2
    pos_err = np.maximum(np.abs(fwd), np.abs(bwd))
    vel_err = np.abs(d_v - (a[:-1] + a[1:]) * dt / 2)
    t_int = t[:-1]
    for check, e, bound, unit in (
            ("position/velocity consistency", pos_err, tol.position, "rad"),
            ("velocity/acceleration consistency", vel_err, tol.velocity, "rad/s")):
        f = _finding(check, "defect", unit, bound, e - bound, e, t_int, JOINTS)
        if f:
            findings.append(f)
    jerk = np.abs(d_a) / dt
    # ------------------------------------------------------------ forward kinematics
    # a worker for the dynamics, forked now if this process may fork (control/offload.py)
    offload = Offload(robot, n + (n - 1 if midpoints else 0))
    try:
        x_guess = np.asarray(x_guess, dtype=float)
        fk = robot_fk_batch(th, x_guess, robot)
        if not fk.converged.all():
            f = _finding("forward kinematics (no pose reproduces the joints)", "defect", "rad",
                         1e-10, fk.residual - 1e-10, fk.residual, t, ["platform"])
            if f:
                findings.append(f)
            return _failed(n, robot, findings, tol_d)
        cfg = fk.cfg
        offload.q[:n], offload.v[:n], offload.a[:n] = cfg.q, v, a
        offload.submit(0, n)  # the samples' dynamics: in the worker if there is one
        # ------------------------------------------------------------ between the samples
        fkm = None
        mid_finding = None
        if midpoints:
            pm, vm, am = hermite_midpoints(dt, th, v, a)
            tm = t[:-1] + dt / 2
            # seed: halfway between the neighbouring samples' poses (small steps)
            fkm = robot_fk_batch(pm, 0.5 * (fk.x[:-1] + fk.x[1:]), robot)
            if not fkm.converged.all():
                mid_finding = _finding("forward kinematics between samples", "limit", "rad",
                                       1e-10, fkm.residual - 1e-10, fkm.residual, tm,
                                       ["platform"])
                fkm = None
        cfg_points = [cfg] + ([fkm.cfg] if fkm is not None else [])
        n_all = n + (len(tm) if fkm is not None else 0)
        v_all, a_all, t_all = v, a, t
        if fkm is not None:
            v_all, a_all, t_all = np.r_[v, vm], np.r_[a, am], np.r_[t, tm]
            offload.q[n:n_all] = fkm.cfg.q
        offload.v[n:n_all], offload.a[n:n_all] = v_all[n:], a_all[n:]
        # every point's dynamics: the samples' (sent after the first forward kinematics,
        # above) and the next midpoints up to OFFLOAD_SHARE of all points in the worker,
        # the rest here after the branch check, the spherical joints and the clearance
        split = max(n, int(round(OFFLOAD_SHARE * n_all))) if offload.pid else n
        offload.submit(n, split)
        # a second seed, each sample from the previous sample's solution: the two agree
        # unless the motion switches assembly branch (or the guesses were on another branch)
        fk2 = robot_fk_batch(th, np.r_[fk.x[:1], fk.x[:-1]], robot, margins=False)
        branch = np.abs(fk2.x - fk.x).max(axis=1)
        branch = np.where(fk2.converged, branch, np.inf)
        f = _finding("forward-kinematics branch continuity", "defect", "", BRANCH_TOL,
                     branch - BRANCH_TOL, branch, t, ["platform"])
        if f:
            findings.append(f)
        quat = rot.quat_from_matrix(fk.rotation)
        if platform is not None:
            platform = np.asarray(platform, dtype=float)
            dq = np.abs(np.einsum("ni,ni->n", platform[:, 3:7], quat))
            ang = 2 * np.arccos(np.clip(dq, -1.0, 1.0))
            errs = np.c_[np.abs(platform[:, 0:3] - cfg.position).max(axis=1), ang,
                         np.abs(platform[:, 7:10] - cfg.psi).max(axis=1),
                         np.abs(np.linalg.norm(platform[:, 3:7], axis=1) - 1.0)]
            f = _finding("platform columns vs forward kinematics", "defect", "m or rad",
                         POSE_TOL, errs - POSE_TOL, errs, t,
                         ["position", "orientation", "psi", "quaternion norm"])
            if f:
                findings.append(f)
        if mid_finding is not None:
            findings.append(mid_finding)
        sph = np.vstack([spherical_tilts(c).reshape(len(c), 9) for c in cfg_points])
        clear = np.concatenate([clearance(c) for c in cfg_points])
        # the interpolant's rates over whole intervals need no dynamics: done while the
        # worker computes
        extremes = interval.rate_extremes(dt, th, v, a)
        # ------------------------------------------------------------ dynamics (Pinocchio)
        offload.compute(split, n_all)
        offload.wait()
        tau_all, rcond_all = offload.tau[:n_all].copy(), offload.rcond[:n_all].copy()
        tau = tau_all[:n]
        checked = n_all
        # ------------------------------------------------------------ whole intervals
        between = _interval_findings(lim, dt, th, v, a, t_int, tau_all, n,
                                     offload.inertia[:n_all] if fkm is not None else None,
                                     extremes)
        findings += between.findings
        if tau_file is not None:
            ff = np.abs(np.asarray(tau_file, dtype=float) - tau)
            ff_err = float(np.nan_to_num(ff, nan=np.inf).max())
            f = _finding("feed-forward torque vs Pinocchio", "defect", "N m", FEEDFORWARD_TOL,
                         ff - FEEDFORWARD_TOL, ff, t, JOINTS)
            if f:
                findings.append(f)
        else:
            ff_err = None
        # ------------------------------------------------------------ limits everywhere
        findings += _limit_findings(lim, cfg_points, tau_all, v_all, a_all, t_all, rcond_all,
                                    jerk, t_int, sph, clear)
        # the tool centre point: its speed at every point, its acceleration at the
        # samples (the finite difference of the speed's vector, kinematics.tcp.tcp_rates)
        v_tcp = tcp_velocity(cfg, v)
        tcp_a = tcp_acceleration(v_tcp, t)
        tcp_v = np.linalg.norm(v_tcp, axis=1)
        if fkm is not None:
            tcp_v = np.r_[tcp_v, np.linalg.norm(tcp_velocity(fkm.cfg, vm), axis=1)]
        for name, unit, cap, val, tt in (("tcp speed", "m/s", lim.tcp_speed, tcp_v, t_all),
                                          ("tcp acceleration (samples)", "m/s^2",
                                           lim.tcp_acceleration, tcp_a, t)):
            f = _finding(name, "limit", unit, cap, val - cap * (1 + 1e-9), val, tt, ["tcp"])
            if f:
                findings.append(f)
        tilt = float(sph.max())
        min_clear = float(clear.min())
        th_all = np.vstack([c.theta for c in cfg_points])
        theta_ok = bool(np.all((th_all >= lim.theta_min - 1e-9)
                               & (th_all <= lim.theta_max + 1e-9)))
        m1 = min(float(c.margins.leg_type1.min()) for c in cfg_points)
        m2 = min(float(c.margins.leg_type2.min()) for c in cfg_points)
        mp = min(float(c.margins.platform.min()) for c in cfg_points)
        rep = ValidationReport(
            ok=not findings, samples=n, robot_hash=robot.hash,
            max_torque_ratio=max(float(np.nan_to_num(np.abs(tau_all), nan=np.inf).max()),
                                 between.torque) / lim.torque,
            max_velocity_ratio=max(float(np.abs(v_all).max()), between.velocity) / lim.velocity,
            max_acceleration_ratio=max(float(np.abs(a_all).max()),
                                       between.acceleration) / lim.acceleration,
            max_jerk_ratio=float(jerk.max() / lim.jerk),
            min_margin_leg_type1=m1, min_margin_leg_type2=m2, min_margin_platform=mp,
            min_clearance=min_clear, max_spherical_tilt_deg=math.degrees(tilt),
            theta_range_ok=theta_ok, findings=findings, tolerances=tol_d, checked_points=checked,
            tau=tau, position=cfg.position.copy(), quaternion=quat, psi=cfg.psi.copy(),
            feedforward_error=ff_err, duration=float(t[-1]),
            max_interpolant_jerk_ratio=between.jerk / (interval.C_JERK * lim.jerk),
            max_tcp_speed=float(np.nan_to_num(tcp_v, nan=np.inf).max()),
            max_tcp_acceleration=float(np.nan_to_num(tcp_a, nan=np.inf).max()),
            max_torque_rate=(float(np.nan_to_num(np.abs(np.diff(tau, axis=0)), nan=np.inf).max()
                                   / np.diff(t).min()) if n > 1 else 0.0))
        return rep
    finally:
        offload.close()


@dataclass
class _Between:
    """What the whole intervals gave: findings and the largest values [SI]."""

    findings: list[Finding]
    velocity: float
    acceleration: float
    jerk: float
    torque: float


def _interval_findings(lim: Limits, dt: float, th: np.ndarray, v: np.ndarray, a: np.ndarray,
                       t_int: np.ndarray, tau_all: np.ndarray, n: int,
                       inertia: np.ndarray | None,
                       ext: dict[str, tuple[np.ndarray, np.ndarray]]) -> _Between:
    """The interpolant over every whole interval (control/interval.py): its jerk against
    what a motion within the jerk limit allows (a defect above), its velocity and
    acceleration exactly (``ext``: :func:`interval.rate_extremes`), and the torque bound
    (with the midpoints' dynamics)."""
    out: list[Finding | None] = []
    jerk = ext["jerk"][0]
    cap = interval.C_JERK * lim.jerk
    out.append(_finding("interpolant jerk (no motion within the jerk limit has these "
                        "samples)", "defect", "rad/s^3", cap, jerk - cap * (1 + 1e-9), jerk,
                        t_int, JOINTS))
    vel, acc = ext["velocity"][0], ext["acceleration"][0]
    out.append(_finding("velocity (between samples)", "limit", "rad/s", lim.velocity,
                        vel - lim.velocity * (1 + 1e-9), vel, t_int, JOINTS))
    out.append(_finding("acceleration (between samples)", "limit", "rad/s^2",
                        lim.acceleration, acc - lim.acceleration * (1 + 1e-9), acc, t_int,
                        JOINTS))
    torque = 0.0
    if inertia is not None and len(tau_all) > n:
        bound, _ = interval.torque_bound(dt, th, v, a, tau_all[:n], inertia[:n],
                                         tau_all[n:], inertia[n:])
        torque = float(bound.max())
        out.append(_finding("torque (between samples, bound)", "limit", "N m", lim.torque,
                            bound - lim.torque * (1 + 1e-9), bound, t_int, JOINTS))
    return _Between([f for f in out if f is not None], float(vel.max()), float(acc.max()),
                    float(jerk.max()), torque)


def _limit_findings(lim: Limits, cfgs: list, tau: np.ndarray, v: np.ndarray, a: np.ndarray,
                    t: np.ndarray, rcond: np.ndarray, jerk: np.ndarray, t_int: np.ndarray,
                    sph: np.ndarray, clear: np.ndarray) -> list[Finding]:
    """Every limit on samples and midpoints (rows of the stacked arrays, in time order
    of each block), one finding per limit."""
    out: list[Finding | None] = []
    atau = np.nan_to_num(np.abs(tau), nan=np.inf)
    out.append(_finding("torque", "limit", "N m", lim.torque, atau - lim.torque * (1 + 1e-9),
                        atau, t, JOINTS))
    out.append(_finding("velocity", "limit", "rad/s", lim.velocity,
                        np.abs(v) - lim.velocity * (1 + 1e-9), np.abs(v), t, JOINTS))
    out.append(_finding("acceleration", "limit", "rad/s^2", lim.acceleration,
                        np.abs(a) - lim.acceleration * (1 + 1e-9), np.abs(a), t, JOINTS))
    out.append(_finding("jerk (between samples)", "limit", "rad/s^3", lim.jerk,
                        jerk - lim.jerk * (1 + 1e-9), jerk, t_int, JOINTS))
    out.append(_finding("parallel singularity (closure Jacobian)", "limit", "rcond", 1e-10,
                        1e-10 - rcond, rcond, t, ["closures"]))
    th = np.vstack([c.theta for c in cfgs])
    below, above = lim.theta_min - th, th - lim.theta_max
    out.append(_finding("actuated range", "limit", "rad", lim.theta_max,
                        np.maximum(below, above) - 1e-9, th, t, JOINTS))
    sph_names = [f"leg{i}_{s}" for i in range(3) for s in ("E", "F", "P")]
    out.append(_finding("spherical joint tilt", "limit", "rad", lim.spherical,
                        sph - lim.spherical, sph, t, sph_names))
    m = np.vstack([np.c_[c.margins.leg_type1, c.margins.leg_type2, c.margins.platform]
                   for c in cfgs])
    m_names = ([f"leg{i} type I" for i in range(3)] + [f"leg{i} type II" for i in range(3)]
               + ["platform"])
    out.append(_finding("singularity margin", "limit", "", lim.margin, lim.margin - m, m, t,
                        m_names))
    out.append(_finding("interference (clearance)", "limit", "m", 0.0, -clear, clear, t,
                        ["collision model"]))
    return [f for f in out if f is not None]


def validate_joint_trajectory(theta: np.ndarray, theta_dot: np.ndarray,
                              theta_ddot: np.ndarray, robot: Robot, rate: float,
                              x_guess: np.ndarray, limits: Limits | None = None,
                              t: np.ndarray | None = None) -> ValidationReport:
    """:func:`validate_motion` of samples on the grid k / ``rate`` (the pipeline's check
    before it writes anything)."""
    n = len(theta)
    t = np.arange(n) / rate if t is None else t
    return validate_motion(t, theta, theta_dot, theta_ddot, robot, rate, x_guess, limits)


def _header_limits(header: dict, robot: Robot, name: str) -> Limits:
    """The limits the file says it was made to, as a tightening of the robot's hardware
    limits (a task's, e.g. a tool centre point speed): the gate judges the file by them
    too.  A header can only make the gate stricter: a limit looser than the hardware's,
    an unknown one or a value of the wrong type is a forged or corrupted file."""
    from sixplus3.errors import LimitError

    doc = header.get("limits", {})
    if not isinstance(doc, dict):
        raise TrajectoryFileError(f"{name}: header limits must be a mapping of numbers",
                                  value=type(doc).__name__, valid="a mapping")
    try:
        return robot.limits.tightened(**doc)
    except LimitError as exc:
        raise TrajectoryFileError(f"{name}: header limits: {exc} (a file may only record "
                                  "limits within the robot's hardware limits)",
                                  value=exc.value, valid=exc.valid) from None


def validate_bytes(raw: bytes, robot: Robot, name: str = "trajectory") -> ValidationReport:
    """Validate the bytes of a trajectory file for ``robot``.

    Raises :class:`~sixplus3.errors.TrajectoryFileError` for a file that is unreadable,
    corrupted (integrity digest) or made for another robot; returns a report whose
    ``exit_code`` is 2 for a motion defect, 1 for a violated limit, 0 when valid.
    """
    header, data = parse(raw, name)
    check_robot(header, robot, name)
    rate = float(header["rate_hz"])  # a finite number (parse)
    limits = _header_limits(header, robot, name)
    x_guess = np.c_[data[:, 37:40], rotvec_of_quaternions(data[:, 40:44]), data[:, 44:47]]
    rep = validate_motion(data[:, 0], columns(data, "pos"), columns(data, "vel"),
                          columns(data, "acc"), robot, rate, x_guess, limits=limits,
                          platform=data[:, 37:47], tau_file=columns(data, "tau"))
    rep.header, rep.data = header, data
    return rep


def validate_and_write(path: str | Path, t: np.ndarray, theta: np.ndarray,
                       theta_dot: np.ndarray, theta_ddot: np.ndarray, robot: Robot,
                       rate: float, x_guess: np.ndarray, limits: Limits | None = None,
                       meta: dict | None = None) -> tuple[Path, ValidationReport]:
    """Validate the motion (:func:`validate_motion`, the gate) and, only if it passes,
    write it as one atomic trajectory file: (path, report).  Raises
    :class:`~sixplus3.errors.ValidationFailed` (exit code 1 or 2, every finding) and
    writes nothing otherwise."""
    from sixplus3.control.trajectory_file import write_trajectory

    rep = validate_joint_trajectory(theta, theta_dot, theta_ddot, robot, rate, x_guess,
                                    limits, t=t)
    if not rep.ok:
        raise ValidationFailed("the trajectory fails validation, nothing written: "
                               + "; ".join(rep.messages()), rep.exit_code, rep)
    lim = robot.limits if limits is None else robot.limits.tightened(**limits.as_dict())
    out = write_trajectory(path, t, theta, theta_dot, theta_ddot, rep, robot, lim,
                           meta or {})
    return out, rep


def resample(rep: ValidationReport, rate: float, speed: float = 1.0
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The validated motion of ``rep`` (a report of :func:`validate_file`) at ``rate``
    [Hz], replayed at ``speed`` (time x 1/speed, rates x speed, accelerations x speed^2),
    on the quintic Hermite interpolant of its samples; the resting end is held until the
    next point of the new grid.  Returns (t, theta, theta_dot, theta_ddot, x_seed), the
    last the validated platform poses at the nearest samples (to seed the forward
    kinematics).  The caller validates the result again."""
    data, header = rep.data, rep.header
    assert data is not None and header is not None and rep.position is not None
    assert rep.quaternion is not None and rep.psi is not None
    r0 = float(header["rate_hz"])
    n = len(data)
    T = float(data[-1, 0])
    m = math.ceil(T / speed * rate - 1e-9)
    t = np.arange(m + 1) / rate
    u = np.minimum(t * speed, T) * r0  # in sample periods of the file
    k = np.minimum(np.floor(u + 1e-9).astype(int), n - 2)
    frac = np.clip(u - k, 0.0, 1.0)
    th, v, a = hermite(1.0 / r0, columns(data, "pos"), columns(data, "vel"),
                       columns(data, "acc"), k, frac)
    v, a = v * speed, a * speed**2
    v[[0, -1]] = 0.0  # the file starts and ends at rest (checked)
    a[[0, -1]] = 0.0
    near = np.minimum(np.rint(u).astype(int), n - 1)
    x = np.c_[rep.position[near], rotvec_of_quaternions(rep.quaternion[near]),
              rep.psi[near]]
    return t, th, v, a, x


def rotvec_of_quaternions(quat: np.ndarray) -> np.ndarray:
    """Rotation vectors of (possibly non-unit) quaternions; garbage in, a guess out."""
    q = np.array(quat, dtype=float)
    norm = np.linalg.norm(q, axis=1, keepdims=True)
    q = np.where(norm > 1e-9, q / np.maximum(norm, 1e-300), [0.0, 0.0, 0.0, 1.0])
    return rot.rotvec_from_quat(q)


def validate_file(path: str | Path, robot: Robot) -> ValidationReport:
    """Validate a trajectory file for ``robot``: the file
    is read once, and ``report.data`` holds exactly the samples validated."""
    robot = require_robot(robot)
    return validate_bytes(read_bytes(path), robot, Path(path).name)


__all__ = ["COLUMNS", "Finding", "Tolerances", "ValidationReport", "hermite",
           "hermite_midpoints", "resample", "validate_and_write", "validate_bytes",
           "validate_file", "validate_joint_trajectory", "validate_motion"]
