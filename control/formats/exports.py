"""Exports of a validated trajectory for the controller side.

Only a file that passes the gate is exported: :func:`export_file` validates the bytes it
reads (for the robot of the invocation) and converts exactly those samples.

- **ROS 2** (:func:`ros2_joint_trajectory`): a ``trajectory_msgs/msg/JointTrajectory``
  as a plain mapping (YAML or JSON): ``joint_names`` (the nine actuated joints, legs
  0..2 each A, B, C, as in the URDF), one point per sample with ``positions`` [rad],
  ``velocities`` [rad/s], ``accelerations`` [rad/s^2], ``effort`` [N m] at the joint and
  ``time_from_start`` {sec, nanosec}.  ``rclpy``'s ``set_message_fields`` takes it as
  is; ``ros2 topic pub`` takes it on its command line only while it is under Linux's
  128 KiB limit for one argument (a 0.14 s motion at 1 kHz is already ~135 KB): for
  longer motions use ``--rate`` (fewer points, validated again), the FollowJointTrajectory
  goal (:func:`follow_joint_trajectory_goal`) from a node, or the rosbag2 export
  (:mod:`sixplus3.control.formats.rosbag`).
- **Drive** (:func:`drive_table`): the same samples in the units of servo drives in
  cyclic synchronous position or torque mode (e.g. Yaskawa SGD7S in CSP/CST), per axis:
  position in encoder counts of the motor, velocity in counts/s, torque in 0.1 % of the
  motor's rated torque.  With N the belt ratio, 2^b the counts per motor turn, d the
  axis direction and theta_0 the zero offset (``Robot.motors``)::

      counts   = round(d (theta - theta_0) N 2^b / (2 pi))
      counts/s = round(d theta_dot N 2^b / (2 pi))    [the drive's velocity objects
                                                     are integers]
      torque   = round(1000 d tau / (N tau_rated))       [0.1 % of rated]

  The header carries every parameter used.  Rounding the position to a count changes
  the angle by at most half a count: 2 pi / (2 N 2^b) = 1.4 microrad at the joint.
"""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from sixplus3.control.drive.drive_log import to_drive_units
from sixplus3.control.file.file_format import columns, motion_of
from sixplus3.control.gate.interval import check_torque_hold, held_torque, hermite, resample
from sixplus3.control.gate.motion_input import INTERPOLATED_RATE_RANGE, RATE_RANGE, check_rate
from sixplus3.control.gate.validation import validate_file, validate_motion
from sixplus3.control.report import ValidationReport
from sixplus3.errors import InputError, ValidationFailed
from sixplus3.motion import Motion
from sixplus3.robot_description.robot import Robot
from sixplus3.robot_description.urdf import actuated_joint_names

FORMATS = ("ros2-yaml", "ros2-json", "drive-csv")


def ros2_joint_trajectory(motion: Motion, tau: np.ndarray,
                          frame_id: str = "base_link") -> dict[str, Any]:
    """A ``trajectory_msgs/msg/JointTrajectory`` of ``motion`` with the efforts ``tau``
    (n, 9) [N m] as a mapping (header stamp zero: start on reception)."""
    t, theta, theta_dot, theta_ddot = (motion.t, motion.theta, motion.theta_dot,
                                       motion.theta_ddot)
    points = []
    for k in range(len(t)):
        ns_total = int(round(float(t[k]) * 1e9))
        points.append({
            "positions": [float(v) for v in theta[k]],
            "velocities": [float(v) for v in theta_dot[k]],
            "accelerations": [float(v) for v in theta_ddot[k]],
            "effort": [float(v) for v in tau[k]],
            "time_from_start": {"sec": ns_total // 1_000_000_000,
                                "nanosec": ns_total % 1_000_000_000},
        })
    return {"header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": frame_id},
            "joint_names": actuated_joint_names(), "points": points}


def _yaml_float(x: float) -> str:
    """A float as YAML 1.1 reads it back exactly (PyYAML wants a '.' before an exponent:
    '1e-05' would be text)."""
    r = repr(float(x))
    if r in ("inf", "-inf", "nan"):
        return {"inf": ".inf", "-inf": "-.inf", "nan": ".nan"}[r]
    if "e" in r and "." not in r:
        r = r.replace("e", ".0e")
    return r


def ros2_yaml(msg: dict[str, Any]) -> str:
    """The JointTrajectory mapping of :func:`ros2_joint_trajectory` as block YAML, the
    points' arrays in flow style, written line by line (``yaml.safe_dump`` of a long
    motion held ~2.8 GB; this holds the text only).  ``yaml.safe_load`` returns ``msg``."""
    h = msg["header"]
    lines = ["header:", "  stamp:", f"    sec: {int(h['stamp']['sec'])}",
             f"    nanosec: {int(h['stamp']['nanosec'])}",
             f"  frame_id: {json.dumps(h['frame_id'])}", "joint_names:"]
    lines += [f"- {json.dumps(n)}" for n in msg["joint_names"]]
    lines.append("points:" if msg["points"] else "points: []")
    for p in msg["points"]:
        for k, key in enumerate(("positions", "velocities", "accelerations", "effort")):
            lead = "- " if k == 0 else "  "
            lines.append(f"{lead}{key}: [" + ", ".join(_yaml_float(v) for v in p[key]) + "]")
        tf = p["time_from_start"]
        lines += ["  time_from_start:", f"    sec: {int(tf['sec'])}",
                  f"    nanosec: {int(tf['nanosec'])}"]
    return "\n".join(lines) + "\n"


def drive_units(robot: Robot) -> dict[str, Any]:
    """The conversion parameters of :func:`drive_table` (recorded in its header)."""
    m = robot.motors
    return {"gear_ratio": m.gear_ratio, "encoder_bits": m.encoder_bits,
            "counts_per_motor_turn": 2 ** m.encoder_bits,
            "counts_per_joint_rad": m.gear_ratio * 2 ** m.encoder_bits / (2 * math.pi),
            "rated_torque_motor_n_m": m.rated_torque,
            "torque_unit": "0.1 % of the motor's rated torque",
            "zero_offsets_rad": list(m.zero_offsets), "directions": list(m.directions),
            "axes": actuated_joint_names()}


def drive_table(robot: Robot, motion: Motion,
                tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(position counts, velocity counts/s, torque in 0.1 % of rated), each (n, 9) int64,
    of ``motion`` and its torques ``tau`` (:func:`sixplus3.control.drive.drive_log.to_drive_units`:
    the one conversion, also the logs')."""
    counts, vel, torque = to_drive_units(robot, motion.theta, motion.theta_dot, tau)
    assert vel is not None
    return counts, vel, torque


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


def follow_joint_trajectory_goal(msg: dict[str, Any],
                                 goal_time_tolerance_s: float = 0.0) -> dict[str, Any]:
    """A ``control_msgs/action/FollowJointTrajectory`` goal around a JointTrajectory
    mapping: empty path and goal tolerances (the controller's own) and the goal time
    tolerance, in the form ``ros2 action send_goal`` takes."""
    ns = int(round(goal_time_tolerance_s * 1e9))
    return {"trajectory": msg, "path_tolerance": [], "goal_tolerance": [],
            "goal_time_tolerance": {"sec": ns // 1_000_000_000,
                                    "nanosec": ns % 1_000_000_000}}


def export_file(path: str | Path, robot: Robot, fmt: str,
                torque_hold: str | None = None, rate: float | None = None,
                goal: bool = False) -> str:
    """Validate the trajectory file at ``path`` for ``robot`` and return its export in
    ``fmt`` (one of :data:`FORMATS`); raises :class:`ValidationFailed` (nothing is
    exported) when the file is not a valid motion within the limits.  The torque
    (effort, drive torque) is as ``torque_hold`` says: ``mean``, each sample carries the
    mean of its own and the next sample's torque, for a drive that holds it over the
    tick (the default of ``drive-csv``); ``sample``, the sample's own (the default of the
    ROS 2 forms, whose controllers interpolate between points).  ``rate`` (ROS 2 forms):
    decimate to this rate first (:func:`decimate`, validated again); ``goal``: the ROS 2
    forms as a FollowJointTrajectory goal (:func:`follow_joint_trajectory_goal`)."""

    if fmt not in FORMATS:
        raise InputError(f"unknown export format {fmt!r}", value=fmt,
                         valid=", ".join(FORMATS))
    if torque_hold is None:
        torque_hold = "mean" if fmt == "drive-csv" else "sample"
    check_torque_hold(torque_hold)  # a bad mode is refused before the work
    rep = validate_file(path, robot)
    if rep.exit_code != 0 or rep.data is None:
        raise ValidationFailed("not exported: " + "; ".join(rep.messages()),
                               exit_code=rep.exit_code, report=rep)
    data = rep.data
    if (rate is not None or goal) and not fmt.startswith("ros2"):
        raise InputError("--rate and --goal go with the ROS 2 forms (ros2-yaml, ros2-json)",
                         value=fmt, valid="ros2-yaml or ros2-json")
    tau = columns(data, "tau")
    r0 = float((rep.header or {}).get("rate_hz", 0.0))
    motion = motion_of(data, r0)
    if rate is not None and snap_rate(rate, r0) != r0:
        t, th, thd, thdd, tau, _ = decimate(rep, robot, rate)
        motion = Motion(t, th, thd, thdd, snap_rate(rate, r0))
    tau = held_torque(tau, torque_hold)
    if fmt.startswith("ros2"):
        msg = ros2_joint_trajectory(motion, tau)
        if goal:
            msg = follow_joint_trajectory_goal(msg)
        if fmt == "ros2-json":
            return json.dumps(msg) + "\n"
        if goal:
            tolerances = {k: v for k, v in msg.items() if k != "trajectory"}
            body = ros2_yaml(msg["trajectory"])
            return ("trajectory:\n" + "".join(f"  {line}\n" for line in body.splitlines())
                    + yaml.safe_dump(tolerances, sort_keys=False,
                                     default_flow_style=False))
        return ros2_yaml(msg)
    counts, vel, torque = drive_table(robot, motion, tau)
    t = motion.t
    out = io.StringIO()
    out.write("# sixplus3 drive table " + json.dumps({
        "source": Path(path).name, "robot_hash": robot.hash,
        "rate_hz": (rep.header or {}).get("rate_hz"), "torque_hold": torque_hold,
        **drive_units(robot)}) + "\n")
    w = csv.writer(out, lineterminator="\n")
    names = actuated_joint_names()
    w.writerow(["t_s"] + [f"{n}_{q}" for n in names for q in ("counts", "counts_per_s",
                                                                "torque_0p1pct")])
    for i in range(len(t)):
        row: list[Any] = [f"{t[i]:.9f}"]
        for j in range(len(names)):
            row += [int(counts[i, j]), int(vel[i, j]), int(torque[i, j])]
        w.writerow(row)
    return out.getvalue()
