"""The offline feed: read a trajectory file once, validate those bytes, send those samples.

:func:`prepare_feed` reads the file's bytes once and validates them
(:func:`~sixplus3.control.gate.validation.validate_bytes`); what is sent is exactly the
validated samples, so a file swapped or edited after the check changes nothing.  A
slower replay (``speed`` < 1) is a real retiming done here: the motion is resampled at
the controller rate on the quintic Hermite interpolant of the validated samples with
time scaled by 1/speed (rates x speed, accelerations x speed^2), its torques are
recomputed and the whole retimed motion is validated again.  A faster replay would
exceed the limits the plan was optimised to: re-plan instead.
"""

from __future__ import annotations

import ipaddress
import json
import math
import socket
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from sixplus3.control.file.file_format import JOINTS, columns, motion_of
from sixplus3.control.file.trajectory_read import read_bytes
from sixplus3.control.gate.interval import check_torque_hold, held_torque, resample
from sixplus3.control.gate.validation import validate_bytes, validate_motion
from sixplus3.control.report import ValidationReport
from sixplus3.errors import InputError, ValidationFailed, check_number
from sixplus3.kinematics.robot import home
from sixplus3.kinematics.robot_fk import robot_fk_batch
from sixplus3.kinematics.rotations import rotvec_from_quat
from sixplus3.motion import HasMotion, Motion, check_samples
from sixplus3.robot_description.robot import Robot

#: Replay speeds accepted (1 = as planned).
SPEED_RANGE = (0.01, 1.0)


@dataclass(frozen=True)
class FeedPlan(HasMotion):
    """What the feed sends: the validated ``motion`` and its feed-forward torques."""

    motion: Motion  # the samples at their rate
    tau: np.ndarray  # (n, 9) feed-forward [N m] sent: the validated torques, held
    #: as ``torque_hold`` says (control/gate/interval.py, held_torque)
    speed: float
    report: ValidationReport  # the validation of exactly these samples
    torque_hold: str = "mean"

    def messages(self) -> Iterator[bytes]:
        """One JSON datagram per sample, made as it is sent (memory does not grow with
        the length of the motion)."""
        for k in range(len(self.t)):
            yield json.dumps({"t": float(self.t[k]), "joints": JOINTS,
                              "pos": self.theta[k].tolist(),
                              "vel": self.theta_dot[k].tolist(),
                              "acc": self.theta_ddot[k].tolist(),
                              "tau_ff": self.tau[k].tolist()}).encode()


def check_speed(speed: float) -> float:
    """The replay speed (1 = as planned; a faster replay needs a new plan)."""
    return check_number("speed (1 = as planned; a faster replay needs a new plan)", speed,
                        *SPEED_RANGE)


def parse_address(text: str) -> tuple[str, int]:
    """HOST:PORT with an IP address (v4) and a port in 1..65535."""
    host, _, port = str(text).rpartition(":")
    try:
        ipaddress.IPv4Address(host)
        ok = port.isdigit() and 0 < int(port) < 65536
    except ValueError:
        ok = False
    if not ok:
        raise InputError(f"address must be IPv4:PORT with PORT in 1..65535, got {text!r}",
                         value=text, valid="e.g. 127.0.0.1:9870")
    return host, int(port)


def retime(report: ValidationReport, robot: Robot, speed: float) -> FeedPlan:
    """The validated file motion replayed at ``speed`` (< 1: slower), resampled at the
    file's rate and validated again with recomputed torques."""
    assert report.data is not None and report.header is not None
    rate = float(report.header["rate_hz"])
    check_samples(float(report.data[-1, 0]) / speed, rate, f"the replay at speed {speed:g}")
    t_new, p, vel, acc, x_seed = resample(report, rate, speed)
    motion = Motion(t_new, p, vel, acc, rate)
    rep = validate_motion(motion, robot, x_seed)
    if not rep.ok:
        raise ValidationFailed(f"the replay at speed {speed:g} fails validation: "
                               + "; ".join(rep.messages()), rep.exit_code, rep)
    assert rep.tau is not None
    return FeedPlan(motion, rep.tau, speed, rep)


#: The robot's actuated angles and the file's first sample must agree to this [rad]
#: (0.057 deg; the drives' encoders resolve 1.4 microrad at the joint).
START_TOL = 1e-3
#: ... and the platform pose the robot is in (forward kinematics continued from home)
#: and the file's first pose to this [m, rad]: else another assembly branch.
START_POSE_TOL = 1e-4
#: Steps of the continuation from home to the robot's angles.
START_STEPS = 64


def robot_pose_from_home(robot: Robot, theta: np.ndarray) -> np.ndarray | None:
    """The minimal coordinates (position, rotation vector, psi) of the robot at actuated
    angles ``theta``, on the assembly branch of its home pose: forward kinematics
    continued along the straight path in joint space from home (the robot was assembled
    at home and moves continuously).  None if the continuation fails."""

    h = home(robot)
    x = np.r_[np.asarray(robot.home_position), np.zeros(3), np.asarray(robot.home_psi)]
    th0 = h.theta[0]
    for s in np.linspace(0.0, 1.0, START_STEPS + 1)[1:]:
        fk = robot_fk_batch((th0 + s * (theta - th0))[None], x[None], robot, margins=False)
        if not bool(fk.converged[0]):
            return None
        x = fk.x[0]
    return x


def check_start(rep: ValidationReport, robot: Robot, current_theta: np.ndarray) -> None:
    """Refuse to send a validated file that does not start where the robot is: its first
    sample's actuated angles against ``current_theta`` (9, rad; naming the joint), and
    the platform pose of those angles on the robot's own assembly branch against the
    file's first pose.  Raises :class:`ValidationFailed` (exit code 2)."""
    cur = np.asarray(current_theta, dtype=float).reshape(-1)
    if cur.shape != (9,) or not np.all(np.isfinite(cur)):
        raise InputError(f"the robot's current angles must be 9 finite numbers [rad], got "
                         f"{cur.shape[0]} values", value=cur.tolist()[:12],
                         valid="9 finite angles, legs 0..2 each A, B, C")
    assert rep.data is not None and rep.position is not None
    first = columns(rep.data[:1], "pos")[0]
    gap = np.abs(first - cur)
    j = int(np.argmax(gap))
    if gap[j] > START_TOL:
        raise ValidationFailed(
            f"the robot is not at the file's start: {JOINTS[j]} is at "
            f"{math.degrees(cur[j]):.3f} deg, the file starts at {math.degrees(first[j]):.3f}"
            f" deg ({math.degrees(gap[j]):.3f} deg apart, tolerance "
            f"{math.degrees(START_TOL):.3f} deg): move it there first (sixplus3 "
            "move-to-start)", 2, rep)
    x = robot_pose_from_home(robot, cur)
    assert rep.quaternion is not None and rep.psi is not None
    file_x = np.r_[rep.position[0], rotvec_from_quat(rep.quaternion[:1])[0],
                   rep.psi[0]]
    if x is None or float(np.abs(x - file_x).max()) > START_POSE_TOL:
        what = ("cannot be followed from home to the robot's angles" if x is None else
                f"differs by {float(np.abs(x - file_x).max()):.3g} m or rad")
        raise ValidationFailed(
            "the file starts on another assembly branch than the robot's: the platform "
            f"pose of the robot's angles on its home branch {what} from the file's first "
            "pose; re-plan from the robot's state (sixplus3 move-to-start)", 2, rep)


def prepare_feed(path: str | Path, robot: Robot, speed: float = 1.0,
                 current_theta: np.ndarray | Callable[[], np.ndarray] | None = None,
                 torque_hold: str = "mean") -> FeedPlan:
    """Read ``path`` once, validate its bytes for ``robot`` and return what to send.

    ``current_theta``: the robot's actuated angles now (9, rad), or a callable that reads
    them from the controller; the file must start there, on the robot's assembly branch
    (:func:`check_start`).  None skips that check (the caller confirms the start).
    ``torque_hold``: ``mean`` (default) sends each tick the mean of the torques at both
    ends of the interval the drive holds it over, ``sample`` the tick's own
    (docs/validation.md, "Torque for sampled drives").

    Raises :class:`TrajectoryFileError` for a bad or mismatched file and
    :class:`ValidationFailed` (with the report and its exit code) for a motion that fails
    validation or does not start at the robot's state; nothing is sent then.
    """
    speed = check_speed(speed)
    check_torque_hold(torque_hold)  # a bad mode is refused before the work
    rep = validate_bytes(read_bytes(path), robot, Path(path).name)
    if not rep.ok:
        raise ValidationFailed(f"{Path(path).name} fails validation: "
                               + "; ".join(rep.messages()), rep.exit_code, rep)
    if current_theta is not None:
        check_start(rep, robot, current_theta() if callable(current_theta)
                    else current_theta)
    assert rep.data is not None and rep.tau is not None
    data = rep.data
    rate = float(rep.header["rate_hz"]) if rep.header else float("nan")
    if speed == 1.0:
        plan = FeedPlan(motion_of(data, rate), rep.tau, 1.0, rep)
    else:
        plan = retime(rep, robot, speed)
    return replace(plan, tau=held_torque(plan.tau, torque_hold), torque_hold=torque_hold)


def send(feed: FeedPlan, emit: Callable[[bytes], object],
         clock: Callable[[], float] = time.perf_counter,
         sleep: Callable[[float], object] = time.sleep) -> int:
    """Emit every datagram at its time on ``clock``; returns how many were sent."""
    t0 = clock()
    sent = 0
    for k, msg in enumerate(feed.messages()):
        delay = float(feed.t[k]) - (clock() - t0)
        if delay > 0:
            sleep(delay)
        emit(msg)
        sent += 1
    return sent


def udp_sender(address: tuple[str, int]) -> Callable[[bytes], object]:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    return lambda msg: sock.sendto(msg, address)


__all__ = ["SPEED_RANGE", "FeedPlan", "check_speed", "check_start", "robot_pose_from_home",
           "parse_address", "prepare_feed", "retime", "send", "udp_sender"]
