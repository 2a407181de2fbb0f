"""One window of the gate's check (:func:`sixplus3.control.gate.validation.validate_motion`
checks a long motion window by window) and the report of consecutive windows.

A window is checked in this order (docs/validation.md lists every check):

1. the time grid and the rate (a failed grid ends the check: nothing else is defined);
2. rest at the ends and the consistency of the velocities and accelerations with the
   positions;
3. the forward kinematics of the samples (a failure ends the check) and of the
   interpolant's midpoints, a second seed for the branch continuity, the platform
   columns, the spherical joints and the clearance, while a worker process computes the
   dynamics (:mod:`sixplus3.control.gate.offload`);
4. the dynamics (Pinocchio), the whole intervals between the samples, the feed-forward
   torques, every limit on the samples and the midpoints, the tool centre point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

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
from sixplus3.control.gate.offload import OFFLOAD_SHARE, Offload
from sixplus3.control.report import Finding, ValidationReport
from sixplus3.kinematics import rotations as rot
from sixplus3.kinematics.checks import range_excess
from sixplus3.kinematics.collision import clearance
from sixplus3.kinematics.robot import RobotConfig
from sixplus3.kinematics.robot_fk import BatchFK, robot_fk_batch
from sixplus3.kinematics.spherical import spherical_tilts
from sixplus3.motion import RATE_RANGE, Motion
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot

#: Longest motion accepted [s].
MAX_DURATION = 3600.0


def merge_windows(reps: list[ValidationReport], n: int) -> ValidationReport:
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


@dataclass
class _Midpoints:
    """The interpolant's midpoints of a window: their forward kinematics (None when it
    failed, with its finding, or when midpoints are not checked), rates and times."""

    fk: BatchFK | None
    finding: Finding | None
    t: np.ndarray
    v: np.ndarray
    a: np.ndarray


def _midpoints(dt: float, t: np.ndarray, th: np.ndarray, v: np.ndarray, a: np.ndarray,
               fk: BatchFK, robot: Robot, midpoints: bool) -> _Midpoints:
    """The Hermite midpoints of every interval, seeded halfway between the neighbouring
    samples' poses (small steps)."""
    empty = np.zeros((0, 9))
    if not midpoints:
        return _Midpoints(None, None, np.zeros(0), empty, empty)
    pm, vm, am = hermite_midpoints(dt, th, v, a)
    tm = t[:-1] + dt / 2
    fkm = robot_fk_batch(pm, 0.5 * (fk.x[:-1] + fk.x[1:]), robot)
    if fkm.converged.all():
        return _Midpoints(fkm, None, tm, vm, am)
    f = finding("forward kinematics between samples", "limit", "rad", 1e-10,
                fkm.residual - 1e-10, fkm.residual, tm, ["platform"])
    return _Midpoints(None, f, tm, vm, am)


def _branch_finding(th: np.ndarray, fk: BatchFK, robot: Robot, t: np.ndarray
                    ) -> Finding | None:
    """A second seed, each sample from the previous sample's solution: the two agree
    unless the motion switches assembly branch (or the guesses were on another branch)."""
    fk2 = robot_fk_batch(th, np.r_[fk.x[:1], fk.x[:-1]], robot, margins=False)
    branch = np.abs(fk2.x - fk.x).max(axis=1)
    branch = np.where(fk2.converged, branch, np.inf)
    return finding("forward-kinematics branch continuity", "defect", "", BRANCH_TOL,
                   branch - BRANCH_TOL, branch, t, ["platform"])


@dataclass(frozen=True)
class Window:
    """Where a window of samples sits in its motion, and the file's columns over it:
    ``x_guess`` (n, 9) seeding the forward kinematics, the ``platform`` (n, 10) and
    ``tau_file`` (n, 9) columns to compare (or None); the window's first sample ``k0``
    of a motion of ``n_total`` samples (None: this window is the motion); ``rest``:
    whether it holds the motion's start / end."""

    x_guess: np.ndarray
    platform: np.ndarray | None = None
    tau_file: np.ndarray | None = None
    k0: int = 0
    rest: tuple[bool, bool] = (True, True)
    n_total: int | None = None


def validate_window(motion: Motion, robot: Robot, lim: Limits, win: Window,
                    midpoints: bool = True,
                    rate_range: tuple[float, float] = RATE_RANGE) -> ValidationReport:
    """:func:`~sixplus3.control.gate.validation.validate_motion` of the samples
    ``motion`` (a :meth:`~sixplus3.motion.Motion.window` of the whole), placed by
    ``win`` (module doc: the order of the checks)."""
    t, th, v, a, rate = (motion.t, motion.theta, motion.theta_dot, motion.theta_ddot,
                         motion.rate)
    x_guess, platform, tau_file = win.x_guess, win.platform, win.tau_file
    k0, rest, n_total = win.k0, win.rest, win.n_total
    n = len(t)
    grid = grid_finding(t, th, v, a, rate, rate_range, k0, n_total, MAX_DURATION)
    tol = Tolerances(1.0 / rate if math.isfinite(rate) and rate > 0 else math.nan, lim.jerk)
    tol_d = tol.as_dict() if grid is None or grid.check != "rate" else {}
    if grid is not None:
        return failed(n, robot, [grid], tol_d)
    dt = tol.dt
    findings = rest_findings(t, v, a, rest)
    jumps, jerk = consistency_findings(t, th, v, a, tol)
    findings += jumps
    # a worker for the dynamics, forked now if this process may fork (control/gate/offload.py)
    offload = Offload(robot, n + (n - 1 if midpoints else 0))
    try:
        fk = robot_fk_batch(th, np.asarray(x_guess, dtype=float), robot)
        if not fk.converged.all():
            f = finding("forward kinematics (no pose reproduces the joints)", "defect", "rad",
                        1e-10, fk.residual - 1e-10, fk.residual, t, ["platform"])
            if f:
                findings.append(f)
            return failed(n, robot, findings, tol_d)
        cfg = fk.cfg
        offload.q[:n], offload.v[:n], offload.a[:n] = cfg.q, v, a
        offload.submit(0, n)  # the samples' dynamics: in the worker if there is one
        mid = _midpoints(dt, t, th, v, a, fk, robot, midpoints)
        cfg_points = [cfg] + ([mid.fk.cfg] if mid.fk is not None else [])
        n_all = n + (len(mid.t) if mid.fk is not None else 0)
        v_all, a_all, t_all = v, a, t
        if mid.fk is not None:
            v_all, a_all, t_all = np.r_[v, mid.v], np.r_[a, mid.a], np.r_[t, mid.t]
            offload.q[n:n_all] = mid.fk.cfg.q
        offload.v[n:n_all], offload.a[n:n_all] = v_all[n:], a_all[n:]
        # every point's dynamics: the samples' (sent after the first forward kinematics,
        # above) and the next midpoints up to OFFLOAD_SHARE of all points in the worker,
        # the rest here after the branch check, the spherical joints and the clearance
        split = max(n, int(round(OFFLOAD_SHARE * n_all))) if offload.pid else n
        offload.submit(n, split)
        f = _branch_finding(th, fk, robot, t)
        if f:
            findings.append(f)
        quat = rot.quat_from_matrix(fk.rotation)
        findings += platform_findings(t, cfg, quat, platform)
        if mid.finding is not None:
            findings.append(mid.finding)
        sph = np.vstack([spherical_tilts(c).reshape(len(c), 9) for c in cfg_points])
        clear = np.concatenate([clearance(c) for c in cfg_points])
        # the interpolant's rates over whole intervals need no dynamics: done while the
        # worker computes
        extremes = interval.rate_extremes(dt, th, v, a)
        offload.compute(split, n_all)
        offload.wait()
        tau_all, rcond_all = offload.tau[:n_all].copy(), offload.rcond[:n_all].copy()
        tau = tau_all[:n]
        between = interval_findings(lim, dt, th, v, a, t[:-1], tau_all, n,
                                    offload.inertia[:n_all] if mid.fk is not None else None,
                                    extremes)
        findings += between.findings
        ff_findings, ff_err = feedforward_findings(t, tau, tau_file)
        findings += ff_findings
        findings += limit_findings(lim, cfg_points, tau_all, v_all, a_all, t_all, rcond_all,
                                   jerk, t[:-1], sph, clear)
        tcp, tcp_v, tcp_a = tcp_findings(lim, t, cfg, v, t_all,
                                         None if mid.fk is None else (mid.fk.cfg, mid.v))
        findings += tcp
        m1, m2, mp, theta_ok = _margins(cfg_points, lim)
        return ValidationReport(
            ok=not findings, samples=n, robot_hash=robot.hash,
            max_torque_ratio=max(float(np.nan_to_num(np.abs(tau_all), nan=np.inf).max()),
                                 between.torque) / lim.torque,
            max_velocity_ratio=max(float(np.abs(v_all).max()), between.velocity) / lim.velocity,
            max_acceleration_ratio=max(float(np.abs(a_all).max()),
                                       between.acceleration) / lim.acceleration,
            max_jerk_ratio=float(jerk.max() / lim.jerk),
            min_margin_leg_type1=m1, min_margin_leg_type2=m2, min_margin_platform=mp,
            theta_range_ok=theta_ok, min_clearance=float(clear.min()),
            max_spherical_tilt_deg=math.degrees(float(sph.max())),
            findings=findings, tolerances=tol_d, checked_points=n_all,
            tau=tau, position=cfg.position.copy(), quaternion=quat, psi=cfg.psi.copy(),
            feedforward_error=ff_err, duration=float(t[-1]),
            max_interpolant_jerk_ratio=between.jerk / (interval.C_JERK * lim.jerk),
            max_tcp_speed=float(np.nan_to_num(tcp_v, nan=np.inf).max()),
            max_tcp_acceleration=float(np.nan_to_num(tcp_a, nan=np.inf).max()),
            max_torque_rate=(float(np.nan_to_num(np.abs(np.diff(tau, axis=0)), nan=np.inf).max()
                                   / np.diff(t).min()) if n > 1 else 0.0))
    finally:
        offload.close()


def _margins(cfg_points: list[RobotConfig], lim: Limits
             ) -> tuple[float, float, float, bool]:
    """The smallest leg type I, leg type II and platform margins of the samples and
    midpoints, and whether every actuated angle is in its range."""
    th_all = np.vstack([c.theta for c in cfg_points])
    return (min(float(c.margins.leg_type1.min()) for c in cfg_points),
            min(float(c.margins.leg_type2.min()) for c in cfg_points),
            min(float(c.margins.platform.min()) for c in cfg_points),
            bool(np.all(range_excess(th_all, lim) <= 0.0)))


__all__ = ["MAX_DURATION", "Window", "merge_windows", "validate_window"]
