"""Exports of a validated trajectory for the controller side.

Only a file that passes the gate is exported: :func:`export_file` validates the bytes it
reads (for the robot of the invocation) and hands exactly those samples, as a
:class:`~sixplus3.motion.Motion`, to the format asked for (the registry
:mod:`sixplus3.control.formats.registry`: ROS 2 JointTrajectory as YAML or JSON,
:mod:`~sixplus3.control.formats.ros2`; the servo drives' table,
:mod:`~sixplus3.control.formats.drive_csv`).  The interpolated forms (ROS 2) may be
decimated to a lower rate first (:func:`decimate`), and that motion is validated again
as the controller will run it.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from sixplus3.control.file.file_format import columns, motion_of
from sixplus3.control.formats.export_format import Export
from sixplus3.control.formats.registry import FORMATS
from sixplus3.control.gate.interval import check_torque_hold, held_torque, hermite, resample
from sixplus3.control.gate.validation import validate_file, validate_motion
from sixplus3.control.report import ValidationReport
from sixplus3.errors import InputError, ValidationFailed
from sixplus3.motion import INTERPOLATED_RATE_RANGE, RATE_RANGE, Motion, check_rate
from sixplus3.robot_description.robot import Robot


def densify(t: np.ndarray, th: np.ndarray, v: np.ndarray, a: np.ndarray,
            x: np.ndarray, rate: float, dense_rate: float
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The quintic Hermite interpolant through the points (t, th, v, a) spaced 1 / ``rate``
    (what a JointTrajectoryController makes of positions, velocities and accelerations),
    sampled at ``dense_rate``, a whole multiple of ``rate``: (t, theta, theta_dot,
    theta_ddot, x_seed), every exported point one of the dense samples."""

    m = int(round(dense_rate / rate))
    n = len(t)
    k = np.repeat(np.arange(n - 1), m)
    s = np.tile(np.arange(m) / m, n - 1)
    dth, dv, da = hermite(1.0 / rate, th, v, a, k, s)
    td = np.arange(len(k) + 1) / dense_rate
    return (td, np.r_[dth, th[-1:]], np.r_[dv, v[-1:]], np.r_[da, a[-1:]],
            np.r_[x[k + (s > 0.5)], x[-1:]])


def dense_rate_for(rate: float) -> float:
    """The rate the interpolated motion between exported points is checked at: the
    lowest whole multiple of ``rate`` of at least 1 kHz (the gate's own contract)."""

    return rate * math.ceil(RATE_RANGE[0] / rate - 1e-9)


def _check_interpolated(rep: ValidationReport, robot: Robot,
                        rate: float) -> tuple[Any, ...]:
    """(t, theta, theta_dot, theta_ddot, tau, report at the points, report of the dense
    motion) of the validated motion of ``rep`` resampled at ``rate``."""

    t, th, v, a, x = resample(rep, rate)
    again = validate_motion(Motion(t, th, v, a, rate), robot, x,
                            rate_range=INTERPOLATED_RATE_RANGE)
    if not again.ok:
        return t, th, v, a, again.tau, again, again
    dense = densify(t, th, v, a, x, rate, dense_rate_for(rate))
    dense_rep = validate_motion(Motion(*dense[:4], dense_rate_for(rate)), robot, dense[4])
    return t, th, v, a, again.tau, again, dense_rep


#: Relative distance within which an export rate is taken as the whole fraction of the
#: file's rate it is next to.
RATE_SNAP = 1e-6


def snap_rate(rate: float, r0: float) -> float:
    """``rate`` checked against the file's rate ``r0`` (at most r0); a rate typed within
    :data:`RATE_SNAP` of a whole fraction of r0 is that fraction (999.9999999 is the
    file's own 1000 Hz, not a rate whose grid cannot hold the motion)."""
    rate = check_rate(rate, (INTERPOLATED_RATE_RANGE[0], r0 * (1 + RATE_SNAP)),
                      name="--rate")
    m = max(1, round(r0 / rate))
    if abs(r0 / m - rate) <= RATE_SNAP * rate:
        return float(r0 / m)
    return float(rate)


def decimate(rep: ValidationReport, robot: Robot, rate: float) -> tuple[Any, ...]:
    """The validated motion of ``rep`` (a report of :func:`validate_file`) resampled at the
    lower ``rate`` [Hz] on the gate's quintic Hermite interpolant of its samples (at a
    whole fraction of the file's rate these are exactly every m-th sample), the resting
    end held until the next point of the new grid, and validated again **as the
    controller will run it**: the quintic through the new points (a ROS 2
    JointTrajectoryController given positions, velocities and accelerations), sampled at
    a whole multiple of ``rate`` of at least 1 kHz (:func:`dense_rate_for`), through the
    whole gate (Pinocchio's torques, margins, spherical joints, clearance, every rate over
    whole intervals).  A rate whose motion fails is refused with one line naming the
    failed check and the lowest safe rate among the file rate's whole fractions.
    Returns (t, theta, theta_dot, theta_ddot, tau, report); raises ValidationFailed or
    InputError."""

    assert rep.header is not None  # a report of validate_file
    r0 = float(rep.header["rate_hz"])
    # at most the file's rate
    rate = snap_rate(rate, r0)
    t, th, v, a, tau, again, dense = _check_interpolated(rep, robot, rate)
    if not dense.ok:
        first = dense.messages()[0] if dense.messages() else "not a valid motion"
        safe = lowest_safe_rate(rep, robot, rate)
        m = r0 / rate
        whole = abs(m - round(m)) <= 1e-9
        raise ValidationFailed(
            f"the motion a controller interpolates through the points at {rate:.12g} Hz"
            + ("" if whole else f" (not a whole fraction of the file's {r0:.12g} Hz)")
            + f" fails the gate: {first}; the lowest safe rate is "
            + (f"{safe:.12g} Hz" if safe else f"the file's own, {r0:.12g} Hz"),
            dense.exit_code, dense)
    return t, th, v, a, tau, again


#: The rates tried for the lowest safe export rate (those that are whole fractions of
#: the file's rate): passing is not monotonic in the rate, so each is checked in turn.
SAFE_RATE_LADDER = (10.0, 20.0, 25.0, 40.0, 50.0, 80.0, 100.0, 125.0, 200.0, 250.0, 400.0,
                    500.0, 1000.0, 2000.0, 2500.0, 5000.0, 10000.0)


def lowest_safe_rate(rep: ValidationReport, robot: Robot,
                     failed_rate: float) -> float | None:
    """The lowest rate of :data:`SAFE_RATE_LADDER` above ``failed_rate`` that is a whole
    fraction of the file's rate r0 and whose interpolated motion passes the gate, or
    None if only r0 itself does."""
    assert rep.header is not None  # a report of validate_file
    r0 = float(rep.header["rate_hz"])
    for r in SAFE_RATE_LADDER:
        m = r0 / r
        if not failed_rate < r < r0 or abs(m - round(m)) > 1e-9:
            continue
        if _check_interpolated(rep, robot, r)[6].ok:
            return r
    return None


def export_file(path: str | Path, robot: Robot, fmt: str,
                torque_hold: str | None = None, rate: float | None = None,
                goal: bool = False) -> str:
    """Validate the trajectory file at ``path`` for ``robot`` and return its export in
    ``fmt`` (a name of :data:`~sixplus3.control.formats.registry.FORMATS`); raises
    :class:`ValidationFailed` (nothing is exported) when the file is not a valid motion
    within the limits.  The torque (effort, drive torque) is as ``torque_hold`` says
    (default: the format's): ``mean``, each sample carries the mean of its own and the
    next sample's torque, for a drive that holds it over the tick (``drive-csv``);
    ``sample``, the sample's own (the ROS 2 forms, whose controllers interpolate
    between points).  ``rate`` (ROS 2 forms):
    decimate to this rate first (:func:`decimate`, validated again); ``goal``: the ROS 2
    forms as a FollowJointTrajectory goal
    (:func:`~sixplus3.control.formats.ros2.follow_joint_trajectory_goal`)."""

    form = FORMATS.get(fmt)
    texts = [f.name for f in FORMATS.values() if f.render is not None]
    if form is None or form.render is None:
        raise InputError(f"unknown text export format {fmt!r}" + (
            f" ({fmt} writes a directory: its format's directory())" if form else ""),
            value=fmt, valid=", ".join(texts))
    if torque_hold is None:
        torque_hold = form.torque_hold
    check_torque_hold(torque_hold)  # a bad mode is refused before the work
    rep = validate_file(path, robot)
    if rep.exit_code != 0 or rep.data is None:
        raise ValidationFailed("not exported: " + "; ".join(rep.messages()),
                               exit_code=rep.exit_code, report=rep)
    data = rep.data
    if (rate is not None or goal) and not form.interpolated:
        names = [f.name for f in FORMATS.values() if f.interpolated]
        raise InputError(f"--rate and --goal go with the ROS 2 forms ({', '.join(names)})",
                         value=fmt, valid=" or ".join(names))
    tau = columns(data, "tau")
    r0 = float((rep.header or {}).get("rate_hz", 0.0))
    motion = motion_of(data, r0)
    if rate is not None and snap_rate(rate, r0) != r0:
        t, th, thd, thdd, tau, _ = decimate(rep, robot, rate)
        motion = Motion(t, th, thd, thdd, snap_rate(rate, r0))
    return form.render(Export(Path(path).name, robot, motion, held_torque(tau, torque_hold),
                              torque_hold, goal))


__all__ = ["RATE_SNAP", "SAFE_RATE_LADDER", "decimate", "dense_rate_for", "densify",
           "export_file", "lowest_safe_rate", "snap_rate"]
