"""Teach and replay (docs/leadthrough.md, "Teach and replay"): the poses where a person
paused while guiding the platform become a task's waypoints, which the planner then
times as fast as the site's limits for people allow.

From a drive log (a guided motion's, on the prototype or the virtual one): the platform's
pose at each sample by forward kinematics (:func:`~sixplus3.identification.base.
poses_of`), its speed over ``window`` [s]; a **pause** is a stretch of at least
``pause`` [s] with the tool point slower than ``speed`` [m/s] and the platform turning
slower than ``turn_rate`` [rad/s].  The waypoints are the log's first pose, each pause's
middle pose, and the log's last pose, dropping one within ``min_step`` [m] and
``min_turn`` [rad] of the waypoint before it.  The cranks are left free (the planner
chooses them); ``stop`` makes each paused waypoint a stop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sixplus3.control.file.drive_log import DriveLog
from sixplus3.errors import InputError, check_number
from sixplus3.identification.base import poses_of
from sixplus3.interaction.observer.wrench import MIN_RATE
from sixplus3.kinematics import rotations as rot
from sixplus3.robot_description.body_regions import REGIONS
from sixplus3.robot_description.robot import Robot, require_robot


@dataclass(frozen=True)
class Taught:
    """The waypoints found (positions (k, 3) [m], quaternions (k, 4) x, y, z, w), the
    times [s] of the samples they came from, and whether each was a pause."""

    positions: np.ndarray
    quaternions: np.ndarray
    times: np.ndarray
    paused: np.ndarray

    def task(self, name: str = "taught", stop: bool = False, pfl: tuple[str, ...] = (),
             people: str | None = None, source: str = "") -> dict[str, Any]:
        """The task document (planner/task.py's format; positions in metres)."""
        for r in pfl:
            if r not in REGIONS:
                raise InputError(f"--pfl: unknown body region {r!r}", value=r,
                                 valid=", ".join(REGIONS))
        wps: list[dict[str, Any]] = []
        for i, (p, q) in enumerate(zip(self.positions, self.quaternions, strict=True)):
            wp: dict[str, Any] = {"position": [round(float(x), 6) for x in p],
                                  "quaternion": [round(float(x), 7) for x in q]}
            if stop and self.paused[i] and 0 < i < len(self.positions) - 1:
                wp["stop"] = True
            wps.append(wp)
        doc: dict[str, Any] = {
            "name": name,
            "description": (f"taught from {source or 'a guided motion'}: "
                            + (f"{int(self.paused.sum())} pause(s) at t = "
                               + ", ".join(f"{t:.2f}" for t in self.times[self.paused])
                               + " s" if self.paused.any() else "no pause")),
            "frame": "platform", "waypoints": wps}
        if pfl:
            doc["pfl"] = list(pfl)
        if people is not None:
            doc["people"] = people
        return doc


def teach(log: DriveLog, robot: Robot, speed: float = 0.005, turn_rate: float = 0.05,
          pause: float = 0.3, window: float = 0.05, min_step: float = 0.005,
          min_turn: float = math.radians(2.0)) -> Taught:
    """The waypoints of a guided motion's log (module doc)."""
    robot = require_robot(robot)
    check_number("speed [m/s]", speed, 1e-5, 1.0)
    check_number("turn_rate [rad/s]", turn_rate, 1e-5, 10.0)
    check_number("pause [s]", pause, 0.01, 60.0)
    check_number("window [s]", window, 0.0, 1.0)
    check_number("min_step [m]", min_step, 0.0, 1.0)
    check_number("min_turn [rad]", min_turn, 0.0, math.pi)
    t = np.asarray(log.t, dtype=float)
    if len(t) < 3:
        raise InputError(f"{log.name}: too short to teach from", value=len(t),
                         valid=">= 3 samples")
    x, ok = poses_of(robot, log.theta)
    if not ok.all():
        k = int(np.argmin(ok))
        raise InputError(f"{log.name}: no pose of this robot has the logged angles of "
                         f"sample {k}", value=k, valid="angles of an assembly of this robot")
    pos = x[:, 0:3]
    R = rot.matrix_from_rotvec(x[:, 3:6])
    tool = np.asarray(robot.tool.xyz, dtype=float)
    tcp = pos + np.einsum("nij,j->ni", R, tool)
    step = float(np.median(np.diff(t)))
    if not (math.isfinite(step) and 1.0 / 20000.0 <= step <= 1.0 / MIN_RATE):
        raise InputError(f"{log.name}: the log's time step is {step:.3g} s, a drive log "
                         f"steps {1.0 / 20000.0:g} to {1.0 / MIN_RATE:g} s (20 kHz to "
                         f"{MIN_RATE:g} Hz)", value=step,
                         valid=f"[{1.0 / 20000.0:g}, {1.0 / MIN_RATE:g}] s")
    rate = 1.0 / step
    w = max(1, int(round(window * rate)))
    idx = np.arange(len(t))
    lo, hi = np.maximum(idx - w, 0), np.minimum(idx + w, len(t) - 1)
    dt = np.maximum(t[hi] - t[lo], 1e-12)
    v = np.linalg.norm(tcp[hi] - tcp[lo], axis=1) / dt
    rel = np.einsum("nji,njk->nik", R[lo], R[hi])  # R_lo^T R_hi
    ang = np.arccos(np.clip((np.trace(rel, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)) / dt
    still = (v < speed) & (ang < turn_rate)
    picks = [(0, False)]
    k = 0
    n_pause = int(round(pause * rate))
    while k < len(t):
        if still[k]:
            j = k
            while j < len(t) and still[j]:
                j += 1
            if j - k >= n_pause and k > 0 and j < len(t):
                picks.append(((k + j - 1) // 2, True))
            k = j
        else:
            k += 1
    picks.append((len(t) - 1, False))
    keep: list[tuple[int, bool]] = []
    for i, paused in picks:
        if keep:
            j = keep[-1][0]
            step = float(np.linalg.norm(pos[i] - pos[j]))
            turn = float(np.linalg.norm(rot.rotvec_from_matrix((R[j].T @ R[i])[None])[0]))
            if step < min_step and turn < min_turn:
                continue
        keep.append((i, paused))
    if len(keep) < 2:
        raise InputError(f"{log.name}: the platform never moved (no two poses {min_step:g} m "
                         f"or {math.degrees(min_turn):g} deg apart)", value=len(keep),
                         valid="a guided motion")
    ii = np.array([i for i, _ in keep])
    return Taught(positions=pos[ii], quaternions=rot.quat_from_matrix(R[ii]), times=t[ii],
                  paused=np.array([p for _, p in keep], dtype=bool))


__all__ = ["Taught", "teach"]
