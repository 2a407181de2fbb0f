"""The drive table (:func:`drive_table`): a validated motion's samples in the units of
servo drives in cyclic synchronous position or torque mode (e.g. Yaskawa SGD7S in
CSP/CST), per axis: position in encoder counts of the motor, velocity in counts/s,
torque in 0.1 % of the motor's rated torque.  With N the belt ratio, 2^b the counts per
motor turn, d the axis direction and theta_0 the zero offset (``Robot.motors``)::

    counts   = round(d (theta - theta_0) N 2^b / (2 pi))
    counts/s = round(d theta_dot N 2^b / (2 pi))    [the drive's velocity objects
                                                   are integers]
    torque   = round(1000 d tau / (N tau_rated))       [0.1 % of rated]

The header carries every parameter used.  Rounding the position to a count changes
the angle by at most half a count: 2 pi / (2 N 2^b) = 1.4 microrad at the joint.

The header also carries the drive's own torque limit (``drive_torque_limit``): the
envelope's torque (the site's, else the catalogue's: robot_description/hardware.py) in
the drive's units, rounded down, so that the drive clamps whatever its PD adds to the
file's torques (docs/safety.md, "The command on any drive"): CiA 402's max torque
(6072h, 0.1 % of the motor's rated torque) and a percentage of rated torque (e.g. the
SGD7S's forward and reverse torque limits, Pn402 and Pn403, in 1 %).
"""

from __future__ import annotations

import csv
import io
import json
import math
from typing import Any

import numpy as np

from sixplus3.control.file.drive_log import to_drive_units
from sixplus3.control.formats.export_format import Export, ExportFormat
from sixplus3.motion import Motion
from sixplus3.robot_description.hardware import effective_limits
from sixplus3.robot_description.robot import Robot
from sixplus3.robot_description.urdf import actuated_joint_names


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


def drive_torque_limit(robot: Robot) -> dict[str, Any]:
    """The drive's own torque limit (module doc) for ``robot`` under the envelope in
    force: at the joint [N m], and in the drive's units, each rounded down."""
    lim = effective_limits(robot).torque
    per_rated = lim / (robot.motors.gear_ratio * robot.motors.rated_torque)
    return {"joint_n_m": lim,
            "max_torque_0p1pct": int(math.floor(1000.0 * per_rated + 1e-9)),
            "torque_limit_pct": int(math.floor(100.0 * per_rated + 1e-9)),
            "note": "set the drives' own torque limit to this (CiA 402 6072h; e.g. "
                    "SGD7S Pn402 and Pn403): the drive clamps what its PD adds"}


def drive_table(robot: Robot, motion: Motion,
                tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(position counts, velocity counts/s, torque in 0.1 % of rated), each (n, 9) int64,
    of ``motion`` and its torques ``tau`` (:func:`sixplus3.control.file.drive_log.to_drive_units`:
    the one conversion, also the logs')."""
    counts, vel, torque = to_drive_units(robot, motion.theta, motion.theta_dot, tau)
    assert vel is not None
    return counts, vel, torque


def render(ex: Export) -> str:
    """The drive table as CSV: a header line of JSON (the source, the robot, the rate,
    the torque hold and every conversion parameter), the column names, one row per
    sample."""
    robot = ex.robot
    counts, vel, torque = drive_table(robot, ex.motion, ex.tau)
    t = ex.motion.t
    out = io.StringIO()
    out.write("# sixplus3 drive table " + json.dumps({
        "source": ex.source, "robot_hash": robot.hash, "rate_hz": ex.motion.rate,
        "torque_hold": ex.torque_hold, **drive_units(robot),
        "drive_torque_limit": drive_torque_limit(robot)}) + "\n")
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


FORMAT = ExportFormat("drive-csv", "a servo-drive table (encoder counts, counts/s, torque in "
                      "0.1 % of rated)", "mean", False, render)

__all__ = ["FORMAT", "drive_table", "drive_units", "render"]
