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

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from sixplus3.control.file.file_format import columns, motion_of
from sixplus3.control.file.trajectory_file import write_trajectory
from sixplus3.control.file.trajectory_parse import parse
from sixplus3.control.file.trajectory_read import check_robot, read_bytes
from sixplus3.control.gate.pfl import judged, pfl_check
from sixplus3.control.gate.stop import HEADER_KEY as STOP_KEY
from sixplus3.control.gate.stop import header_entry, stop_check, stop_table
from sixplus3.control.gate.window import Window, merge_windows, validate_window
from sixplus3.control.report import ValidationReport
from sixplus3.errors import InputError, LimitError, TrajectoryFileError, ValidationFailed
from sixplus3.kinematics import rotations as rot
from sixplus3.motion import RATE_RANGE, Motion
from sixplus3.robot_description.hardware import envelope_record, judged_limits
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot, require_robot

#: Samples checked at once: a longer motion is checked in windows of this many samples
#: (sharing their end samples), so the checks' memory does not grow with its length.
WINDOW = 8192


def _check_arguments(who: str, motion: object, robot: object, limits: object) -> None:
    """The gate's doors: a Motion, a Robot and Limits (or None), else an InputError."""
    require_robot(robot)
    if not isinstance(motion, Motion):
        raise InputError(f"{who} takes a sixplus3.motion.Motion",
                         value=type(motion).__name__, valid="a Motion")
    if limits is not None and not isinstance(limits, Limits):
        raise InputError("limits must be a Limits (or None)", value=type(limits).__name__,
                         valid="Limits or None")


def validate_motion(motion: Motion, robot: Robot, x_guess: np.ndarray,
                    limits: Limits | None = None, platform: np.ndarray | None = None,
                    tau_file: np.ndarray | None = None, midpoints: bool = True,
                    rate_range: tuple[float, float] = RATE_RANGE) -> ValidationReport:
    """Validate a sampled motion of ``robot``: every check of docs/validation.md.

    ``motion``: the samples and their declared rate (:class:`~sixplus3.motion.Motion`);
    ``x_guess`` (n, 9) minimal coordinates seeding the forward kinematics (e.g. the
    file's platform columns; only a starting guess, and the first one is checked);
    ``limits`` tighter than the robot's (default: the robot's hardware limits);
    ``platform`` (n, 10) position, quaternion, psi to compare with the forward
    kinematics; ``tau_file`` (n, 9) feed-forward torques to compare with Pinocchio's.
    ``rate_range``: the rates accepted (default :data:`RATE_RANGE`, for drives that hold
    each sample; :data:`INTERPOLATED_RATE_RANGE` for consumers that interpolate the
    quintic through the points, such as a decimated ROS 2 JointTrajectory).

    The report is frozen and holds the judged limits, the rate and the motion's
    fingerprint.  A motion of more than :data:`WINDOW` samples is checked window by
    window (each window shares its last sample with the next, so every interval is
    checked once), so that the memory of the checks does not grow with its length.
    """
    _check_arguments("validate_motion", motion, robot, limits)
    # the hardware is the authority: the robot's limits, tightened by the site's
    # (robot_description.hardware); ``limits`` (a task's or a header's) only tighten them
    return _judge(motion, robot, x_guess, judged_limits(robot, limits), platform, tau_file,
                  midpoints, rate_range)


def _judge(motion: Motion, robot: Robot, x_guess: np.ndarray, lim: Limits,
           platform: np.ndarray | None = None, tau_file: np.ndarray | None = None,
           midpoints: bool = True,
           rate_range: tuple[float, float] = RATE_RANGE) -> ValidationReport:
    """:func:`validate_motion` by the judged limits ``lim`` (checked arguments)."""
    n = len(motion)
    extra: dict[str, np.ndarray | None] = {}
    for name, arr, width in (("x_guess", x_guess, 9), ("platform", platform, 10),
                             ("tau_file", tau_file, 9)):
        try:
            extra[name] = None if arr is None else np.asarray(arr, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InputError(f"{name} must be numeric: {exc}"[:200], value=None,
                             valid=f"({n}, {width}) numbers") from None
        got = extra[name]
        if got is not None and got.shape != (n, width):
            raise InputError(f"{name} must be ({n}, {width}), got {got.shape}",
                             value=got.shape, valid=f"({n}, {width})")
    xg, pf, tf_ = extra["x_guess"], extra["platform"], extra["tau_file"]
    if xg is None:
        raise InputError("x_guess (n, 9) is needed to seed the forward kinematics",
                         value=None, valid=f"({n}, 9)")
    rate = motion.rate
    if n <= WINDOW:
        rep = validate_window(motion, robot, lim, Window(xg, pf, tf_), midpoints,
                              rate_range)
    else:
        reps = []
        for i0 in range(0, n - 1, WINDOW - 1):
            sl = slice(i0, min(n, i0 + WINDOW))
            win = Window(xg[sl], None if pf is None else pf[sl],
                         None if tf_ is None else tf_[sl], k0=i0,
                         rest=(i0 == 0, sl.stop == n), n_total=n)
            reps.append(validate_window(motion.window(sl.start, sl.stop), robot, lim, win,
                                        midpoints, rate_range))
            if reps[-1].tau is None:  # a window that could not be checked through
                break
        rep = merge_windows(reps, n)
    return replace(rep, rate_hz=rate, fingerprint=motion.fingerprint, limits=lim.as_dict())


def validate_joint_trajectory(motion: Motion, robot: Robot, x_guess: np.ndarray,
                              limits: Limits | None = None) -> ValidationReport:
    """:func:`validate_motion` with the drives' rates (the pipeline's check before it
    writes anything)."""
    return validate_motion(motion, robot, x_guess, limits)


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
        what = judged(header.get("pfl"), header.get("pfl_links"))
    except InputError as exc:
        raise TrajectoryFileError(f"{name}: header pfl or pfl_links: {exc}", value=exc.value,
                                  valid=exc.valid) from None
    motion = motion_of(data, rate)
    rep = validate_motion(motion, robot, x_guess, limits=limits,
                          platform=columns(data, "platform"), tau_file=columns(data, "tau"))
    rep = pfl_check(rep, robot, motion, what)
    if rep.ok:  # the stop table the file carries (control/gate/stop.py), if any
        table, found = stop_check(rep, robot, motion, limits, header.get(STOP_KEY))
        rep = replace(rep, stop_deceleration=table, ok=not found,
                      findings=list(rep.findings) + found)
    return replace(rep, header=header, data=data)


def validation_record(file: str, rep: ValidationReport) -> dict[str, Any]:
    """The gate's record of a file (``sixplus3 validate --json`` prints it; the safety
    report keeps it whole): the report's summary, the duration, the feed-forward's
    largest error and the hardware envelope in force."""
    return {"file": file, "duration_s": rep.duration, **rep.summary(),
            "feedforward_max_error": rep.feedforward_error, "envelope": envelope_record()}


def validate_and_write(path: str | Path, motion: Motion, robot: Robot, x_guess: np.ndarray,
                       limits: Limits | None = None,
                       meta: dict[str, Any] | None = None) -> tuple[Path, ValidationReport]:
    """Validate the motion (:func:`validate_motion`, the gate) and, only if it passes,
    write it as one atomic trajectory file: (path, report).  Raises
    :class:`~sixplus3.errors.ValidationFailed` (exit code 1 or 2, every finding) and
    writes nothing otherwise."""

    meta = dict(meta or {})
    what = judged(meta.get("pfl"), meta.get("pfl_links"))
    _check_arguments("validate_and_write", motion, robot, limits)
    lim = judged_limits(robot, limits)  # once: the gate and the header judge by them
    rep = pfl_check(_judge(motion, robot, x_guess, lim), robot, motion, what)
    meta.update(what.header())  # the header names what the file was judged for
    if not rep.ok:
        raise ValidationFailed("the trajectory fails validation, nothing written: "
                               + "; ".join(rep.messages()), rep.exit_code, rep)
    # the stop table a controller looks up (control/gate/stop.py), in the header
    table = stop_table(robot, rep, motion, lim)
    rep = replace(rep, stop_deceleration=table)
    meta[STOP_KEY] = header_entry(table)
    out = write_trajectory(path, motion, rep, robot, lim, meta)
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


__all__ = ["WINDOW", "validate_and_write", "validate_bytes",
           "validate_file", "validate_joint_trajectory", "validate_motion"]
