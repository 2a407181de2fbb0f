"""The offline feed: read a trajectory file once, validate those bytes, send those samples.

:func:`prepare_feed` reads the file's bytes once and validates them
(:func:`~sixplus3.control.validation.validate_bytes`); what is sent is exactly the
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
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sixplus3.control.trajectory_file import JOINTS, columns, read_bytes
from sixplus3.control.validation import (
    RATE_RANGE,
    ValidationReport,
    hermite,
    validate_bytes,
    validate_motion,
)
from sixplus3.errors import InputError, ValidationFailed
from sixplus3.kinematics import rotations as rot
from sixplus3.robot_description.robot import Robot

#: Replay speeds accepted (1 = as planned).
SPEED_RANGE = (0.01, 1.0)


@dataclass(frozen=True)
class FeedPlan:
    """What the feed sends: validated samples at ``rate`` [Hz]."""

    t: np.ndarray  # (n,) [s]
    theta: np.ndarray  # (n, 9) [rad]
    theta_dot: np.ndarray  # (n, 9) [rad/s]
    theta_ddot: np.ndarray  # (n, 9) [rad/s^2]
    tau: np.ndarray  # (n, 9) feed-forward [N m], recomputed by the validation
    rate: float
    speed: float
    report: ValidationReport  # the validation of exactly these samples

    def messages(self) -> list[bytes]:
        """One JSON datagram per sample."""
        return [json.dumps({"t": float(self.t[k]), "joints": JOINTS,
                            "pos": self.theta[k].tolist(), "vel": self.theta_dot[k].tolist(),
                            "acc": self.theta_ddot[k].tolist(),
                            "tau_ff": self.tau[k].tolist()}).encode()
                for k in range(len(self.t))]


def check_speed(speed: float) -> float:
    lo, hi = SPEED_RANGE
    if not (isinstance(speed, (int, float)) and math.isfinite(speed) and lo <= speed <= hi):
        raise InputError(f"speed must be in [{lo:g}, {hi:g}] (1 = as planned; a faster "
                         f"replay needs a new plan), got {speed!r}", value=speed,
                         valid=f"[{lo:g}, {hi:g}]")
    return float(speed)


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
    data, header = report.data, report.header
    assert data is not None and header is not None
    rate = float(header["rate_hz"])
    dt = 1.0 / rate
    th, v, a = columns(data, "pos"), columns(data, "vel"), columns(data, "acc")
    T = float(data[-1, 0])
    m = math.ceil(T / speed * rate - 1e-9)
    tau_new = np.arange(m + 1) * dt
    u = np.minimum(tau_new * speed, T)  # time in the original motion
    k = np.minimum((u / dt).astype(int), len(data) - 2)
    s = np.clip((u - k * dt) / dt, 0.0, 1.0)
    p, vel, acc = hermite(dt, th, v, a, k, s)
    vel, acc = vel * speed, acc * speed**2
    vel[[0, -1]] = 0.0
    acc[[0, -1]] = 0.0
    assert report.position is not None and report.quaternion is not None
    assert report.psi is not None
    # platform seeds for the forward kinematics: the validated poses, nearest sample
    near = np.minimum(np.rint(u / dt).astype(int), len(data) - 1)
    x_seed = np.c_[report.position[near], _rotvec(report.quaternion[near]),
                   report.psi[near]]
    rep = validate_motion(tau_new, p, vel, acc, robot, rate, x_seed)
    if not rep.ok:
        raise ValidationFailed(f"the replay at speed {speed:g} fails validation: "
                               + "; ".join(rep.messages()), rep.exit_code, rep)
    assert rep.tau is not None
    return FeedPlan(tau_new, p, vel, acc, rep.tau, rate, speed, rep)


def _rotvec(quat: np.ndarray) -> np.ndarray:
    return rot.rotvec_from_quat(quat)


def prepare_feed(path: str | Path, robot: Robot, speed: float = 1.0) -> FeedPlan:
    """Read ``path`` once, validate its bytes for ``robot`` and return what to send.

    Raises :class:`TrajectoryFileError` for a bad or mismatched file and
    :class:`ValidationFailed` (with the report and its exit code) for a motion that fails
    validation; nothing is sent then.
    """
    speed = check_speed(speed)
    rep = validate_bytes(read_bytes(path), robot, Path(path).name)
    if not rep.ok:
        raise ValidationFailed(f"{Path(path).name} fails validation: "
                               + "; ".join(rep.messages()), rep.exit_code, rep)
    assert rep.data is not None and rep.tau is not None
    data = rep.data
    rate = float(rep.header["rate_hz"]) if rep.header else float("nan")
    if speed == 1.0:
        return FeedPlan(data[:, 0], columns(data, "pos"), columns(data, "vel"),
                        columns(data, "acc"), rep.tau, rate, 1.0, rep)
    return retime(rep, robot, speed)


def send(feed: FeedPlan, emit: Callable[[bytes], object],
         clock: Callable[[], float] = time.perf_counter,
         sleep: Callable[[float], object] = time.sleep) -> int:
    """Emit every datagram at its time on ``clock``; returns how many were sent."""
    msgs = feed.messages()
    t0 = clock()
    for k, msg in enumerate(msgs):
        delay = float(feed.t[k]) - (clock() - t0)
        if delay > 0:
            sleep(delay)
        emit(msg)
    return len(msgs)


def udp_sender(address: tuple[str, int]) -> Callable[[bytes], object]:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    return lambda msg: sock.sendto(msg, address)


__all__ = ["RATE_RANGE", "SPEED_RANGE", "FeedPlan", "check_speed",
           "parse_address", "prepare_feed", "retime", "send", "udp_sender"]
