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
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from sixplus3.control.file.file_format import columns
from sixplus3.control.file.trajectory_file import (
    check_robot,
    read_bytes,
    samples_fingerprint,
    write_trajectory,
)
from sixplus3.control.file.trajectory_parse import parse
from sixplus3.control.gate import interval
from sixplus3.control.gate.findings import (
    BRANCH_TOL,
    Tolerances,
    consistency_findings,
    failed,
    feedforward_findings,
    finding,
    grid_finding,
    interval_findings,
    limit_findings,
    platform_findings,
    rest_findings,
    tcp_findings,
)
from sixplus3.control.gate.interval import hermite_midpoints
from sixplus3.control.gate.motion_input import (  # noqa: E402
    RATE_RANGE,
    check_motion_arrays,
)
from sixplus3.control.gate.offload import OFFLOAD_SHARE, Offload
from sixplus3.control.gate.pfl import judged_regions, pfl_check
from sixplus3.control.gate.stop import HEADER_KEY as STOP_KEY
from sixplus3.control.gate.stop import header_entry, stop_check, stop_table
from sixplus3.control.report import Finding, ValidationReport
from sixplus3.errors import InputError, LimitError, TrajectoryFileError, ValidationFailed
from sixplus3.kinematics import rotations as rot
from sixplus3.kinematics.checks import (
    range_excess,
)
from sixplus3.kinematics.collision import clearance
from sixplus3.kinematics.robot import robot_fk_batch
from sixplus3.kinematics.spherical import spherical_tilts
from sixplus3.robot_description.body_regions import BodyRegion, names_of
from sixplus3.robot_description.hardware import judged_limits
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot, require_robot

#: Samples checked at once: a longer motion is checked in windows of this many samples
#: (sharing their end samples), so the checks' memory does not grow with its length.
WINDOW = 8192
#: Longest motion accepted [s].
MAX_DURATION = 3600.0


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
    check_motion_arrays(t, theta, theta_dot, theta_ddot, rate)
    # the hardware is the authority: the robot's limits, tightened by the site's
    # (robot_description.hardware); ``limits`` (a task's or a header's) only tighten them
    lim = judged_limits(robot, limits)
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
            by_check[f.check] = replace(
                old, count=old.count + f.count, worst_t=worst.worst_t,
                worst_where=worst.worst_where, worst_value=worst.worst_value,
                excess=max(old.excess, f.excess))
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
    f: Finding | None
    # ------------------------------------------------------------ grid and rate
    grid = grid_finding(t, th, v, a, rate, rate_range, k0, n_total, MAX_DURATION)
    tol = Tolerances(1.0 / rate if math.isfinite(rate) and rate > 0 else math.nan, lim.jerk)
    tol_d = tol.as_dict() if grid is None or grid.check != "rate" else {}
    if grid is not None:
        return failed(n, robot, [grid], tol_d)
    dt = tol.dt
    # ------------------------------------------------------------ rest, consistency
    findings = rest_findings(t, v, a, rest)
    jumps, jerk = consistency_findings(t, th, v, a, tol)
    findings += jumps
    t_int = t[:-1]
    # ------------------------------------------------------------ forward kinematics
    # a worker for the dynamics, forked now if this process may fork (control/gate/offload.py)
    offload = Offload(robot, n + (n - 1 if midpoints else 0))
    try:
        x_guess = np.asarray(x_guess, dtype=float)
        fk = robot_fk_batch(th, x_guess, robot)
        if not fk.converged.all():
            f = finding("forward kinematics (no pose reproduces the joints)", "defect", "rad",
                         1e-10, fk.residual - 1e-10, fk.residual, t, ["platform"])
            if f:
                findings.append(f)
            return failed(n, robot, findings, tol_d)
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
                mid_finding = finding("forward kinematics between samples", "limit", "rad",
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
        f = finding("forward-kinematics branch continuity", "defect", "", BRANCH_TOL,
                     branch - BRANCH_TOL, branch, t, ["platform"])
        if f:
            findings.append(f)
        quat = rot.quat_from_matrix(fk.rotation)
        findings += platform_findings(t, cfg, quat, platform)
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
        between = interval_findings(lim, dt, th, v, a, t_int, tau_all, n,
                                     offload.inertia[:n_all] if fkm is not None else None,
                                     extremes)
        findings += between.findings
        ff_findings, ff_err = feedforward_findings(t, tau, tau_file)
        findings += ff_findings
        # ------------------------------------------------------------ limits everywhere
        findings += limit_findings(lim, cfg_points, tau_all, v_all, a_all, t_all, rcond_all,
                                    jerk, t_int, sph, clear)
        tcp, tcp_v, tcp_a = tcp_findings(lim, t, cfg, v, t_all,
                                         None if fkm is None else (fkm.cfg, vm))
        findings += tcp
        tilt = float(sph.max())
        min_clear = float(clear.min())
        th_all = np.vstack([c.theta for c in cfg_points])
        theta_ok = bool(np.all(range_excess(th_all, lim) <= 0.0))
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


def validate_joint_trajectory(theta: np.ndarray, theta_dot: np.ndarray,
                              theta_ddot: np.ndarray, robot: Robot, rate: float,
                              x_guess: np.ndarray, limits: Limits | None = None,
                              t: np.ndarray | None = None) -> ValidationReport:
    """:func:`validate_motion` of samples on the grid k / ``rate`` (the pipeline's check
    before it writes anything)."""
    check_motion_arrays(theta if t is None else t, theta, theta_dot, theta_ddot, rate)
    n = len(theta)
    t = np.arange(n) / rate if t is None else t
    return validate_motion(t, theta, theta_dot, theta_ddot, robot, rate, x_guess, limits)


def _header_limits(header: dict[str, Any], robot: Robot, name: str) -> Limits:
    """The limits the file says it was made to, as a tightening of the robot's hardware
    limits (a task's, e.g. a tool centre point speed): the gate judges the file by them
    too.  A header can only make the gate stricter: a limit looser than the hardware's,
    an unknown one or a value of the wrong type is a forged or corrupted file."""

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


def validate_bytes(raw: bytes, robot: Robot, name: str = "trajectory",
                   limits: Limits | None = None) -> ValidationReport:
    """Validate the bytes of a trajectory file for ``robot``.

    Raises :class:`~sixplus3.errors.TrajectoryFileError` for a file that is unreadable,
    corrupted (integrity digest) or made for another robot; returns a report whose
    ``exit_code`` is 2 for a motion defect, 1 for a violated limit, 0 when valid.
    """
    header, data = parse(raw, name)
    check_robot(header, robot, name)
    rate = float(header["rate_hz"])  # a finite number (parse)
    # the header's limits and a task's own (validate --task): each only tightens
    limits = judged_limits(robot, _header_limits(header, robot, name), limits)
    x_guess = np.c_[columns(data, "position"),
                    rot.rotvec_from_quat(columns(data, "quaternion")), columns(data, "psi")]
    try:  # the file's own PFL set (what it was planned for) and the site's
        judged = judged_regions(header.get("pfl"))
    except InputError as exc:
        raise TrajectoryFileError(f"{name}: header pfl: {exc}", value=exc.value,
                                  valid=exc.valid) from None
    rep = validate_motion(data[:, 0], columns(data, "pos"), columns(data, "vel"),
                          columns(data, "acc"), robot, rate, x_guess, limits=limits,
                          platform=columns(data, "platform"), tau_file=columns(data, "tau"))
    _add_pfl(rep, robot, data[:, 0], columns(data, "vel"), judged)
    if rep.ok:  # the stop table the file carries (control/gate/stop.py), if any
        table, found = stop_check(rep, robot, data[:, 0], columns(data, "vel"),
                                  columns(data, "acc"), limits, rate, header.get(STOP_KEY))
        rep.stop_deceleration = table
        if found:
            rep.findings, rep.ok = list(rep.findings) + found, False
    rep.header, rep.data = header, data
    return rep


def _add_pfl(rep: ValidationReport, robot: Robot, t: np.ndarray, theta_dot: np.ndarray,
             judged: tuple[BodyRegion, ...]) -> None:
    """The power and force limiting check (control/gate/pfl.py) into ``rep``."""
    found = pfl_check(rep, robot, t, theta_dot, judged)
    if found:
        rep.findings = list(rep.findings) + found
        rep.ok = False


def validate_and_write(path: str | Path, t: np.ndarray, theta: np.ndarray,
                       theta_dot: np.ndarray, theta_ddot: np.ndarray, robot: Robot,
                       rate: float, x_guess: np.ndarray, limits: Limits | None = None,
                       meta: dict[str, Any] | None = None) -> tuple[Path, ValidationReport]:
    """Validate the motion (:func:`validate_motion`, the gate) and, only if it passes,
    write it as one atomic trajectory file: (path, report).  Raises
    :class:`~sixplus3.errors.ValidationFailed` (exit code 1 or 2, every finding) and
    writes nothing otherwise."""

    meta = dict(meta or {})
    judged = judged_regions(meta.get("pfl"))
    rep = validate_joint_trajectory(theta, theta_dot, theta_ddot, robot, rate, x_guess,
                                    limits, t=t)
    _add_pfl(rep, robot, np.asarray(t, dtype=float), np.asarray(theta_dot, dtype=float),
             judged)
    if judged:
        meta["pfl"] = names_of(judged)  # the header names what the file was judged for
    if not rep.ok:
        raise ValidationFailed("the trajectory fails validation, nothing written: "
                               + "; ".join(rep.messages()), rep.exit_code, rep)
    lim = judged_limits(robot, limits)
    # the stop table a controller looks up (control/gate/stop.py), in the header
    rep.stop_deceleration = stop_table(robot, rep, np.asarray(theta_dot, dtype=float),
                                       np.asarray(theta_ddot, dtype=float), lim, rate)
    meta[STOP_KEY] = header_entry(rep.stop_deceleration)
    out = write_trajectory(path, t, theta, theta_dot, theta_ddot, rep, robot, lim, meta)
    return out, rep


def validate_file(path: str | Path, robot: Robot,
                  limits: Limits | None = None) -> ValidationReport:
    """Validate a trajectory file for ``robot``: the file is read once, and
    ``report.data`` holds exactly the samples validated.  ``limits``: a tightening to
    judge by as well (a task's own, ``validate --task``); the robot's and the site's
    hardware limits apply whatever the file or ``limits`` say."""
    robot = require_robot(robot)
    if limits is not None and not isinstance(limits, Limits):
        raise InputError("limits must be a Limits (or None)", value=type(limits).__name__,
                         valid="Limits or None")
    return validate_bytes(read_bytes(path), robot, Path(path).name, limits)


__all__ = ["MAX_DURATION", "WINDOW", "validate_and_write", "validate_bytes",
           "validate_file", "validate_joint_trajectory", "validate_motion"]
