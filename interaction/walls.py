"""Where a guided platform may go (docs/leadthrough.md, "Walls and cranks"): the slacks
of platform poses against the robot's walls, and the crank score the redundancy climbs.

A pose's slacks, each > 0 inside its wall (one row per pose):

0. singularity: the smallest of the seven margins (each leg's type I and type II, the
   platform's; :class:`~sixplus3.kinematics.robot.RobotMargins`) minus
   ``limits.margin + MARGIN_GUARD``;
1. spherical joints: ``limits.spherical - TILT_GUARD`` minus the largest tilt [rad];
2. actuated range: the distance of the nearest actuated angle to an end of the range,
   minus ``RANGE_GUARD`` [rad];
3. legs apart: the collision model's clearance minus ``CLEARANCE_GUARD``, in
   centimetres (1 cm of clearance weighs as 1 rad or a margin of 1).

A pose the closed-form inverse kinematics cannot solve has every slack -1.  The walls
stand inside the gate's limits by the guards, so a guided motion that stays inside them
is a motion the gate accepts.

The cranks climb the **crank score**: the singularity slack, less how deep the
spherical and range slacks are inside their walls' band (clearance is a wall only: the
cranks barely change it)."""

from __future__ import annotations

import math

import numpy as np

from sixplus3.kinematics import rotations as rot
from sixplus3.kinematics.checks import actuated_bounds
from sixplus3.kinematics.collision import clearance
from sixplus3.kinematics.robot import robot_ik
from sixplus3.kinematics.spherical import spherical_tilts
from sixplus3.robot_description.robot import Robot

#: The singularity wall stands this far above the limits' smallest margin.
MARGIN_GUARD = 0.05
#: The spherical joints' wall stands this far inside their cone [rad].
TILT_GUARD = math.radians(10.0)
#: The actuated range's wall stands this far inside its ends [rad].
RANGE_GUARD = math.radians(5.0)
#: The legs' wall: this much clearance of the collision model kept [m].
CLEARANCE_GUARD = 0.002
#: A wall is near (its barrier applies) when its slack is below this.
WALL_BAND = 0.1
#: [m per rad] the twist metric: a rotation (or a crank turn) of 1 rad weighs as 0.5 m of
#: translation (a wall is left mostly by translating, not by spinning the platform).
ANGLE_SCALE = 0.5


def slacks(robot: Robot, position: np.ndarray, rotation: np.ndarray, psi: np.ndarray,
           walls: np.ndarray | None = None) -> np.ndarray:
    """(n, 4) the slacks of the poses (module doc); the clearance (slow) only on the
    rows ``walls`` ((n,) bool; default all), +inf on the others."""
    return slacks_and_angles(robot, position, rotation, psi, walls)[0]


def slacks_and_angles(robot: Robot, position: np.ndarray, rotation: np.ndarray,
                      psi: np.ndarray, walls: np.ndarray | None = None
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(the slacks (n, 4), the actuated angles (n, 9), solved (n,)) of the poses."""
    cfg = robot_ik(position, rotation, psi, robot)
    lim = robot.limits
    n = len(cfg)
    out = np.full((n, 4), -1.0)
    ok = cfg.ok
    if not ok.any():
        return out, cfg.theta, ok
    out[ok, 0] = cfg.margins.minimum[ok] - (lim.margin + MARGIN_GUARD)
    tilt = spherical_tilts(cfg).max(axis=(1, 2))
    out[ok, 1] = (lim.spherical - TILT_GUARD) - tilt[ok]
    lo, hi = actuated_bounds(lim)
    th = cfg.theta
    out[ok, 2] = np.minimum(th - lo, hi - th).min(axis=1)[ok] - RANGE_GUARD
    sel = ok if walls is None else ok & np.asarray(walls, dtype=bool)
    out[:, 3] = np.where(ok, np.inf, -1.0)
    if sel.any():
        out[sel, 3] = (clearance(cfg, sel)[sel] - CLEARANCE_GUARD) / 0.01
    return out, cfg.theta, ok


def crank_score(sl: np.ndarray) -> np.ndarray:
    """(n,) what the cranks climb: the singularity slack, less how far the spherical
    and range slacks are inside their walls' band (module doc): far from those walls
    the cranks maximise the singularity margin alone."""
    inside = np.minimum(sl[:, 1:3] - WALL_BAND, 0.0).sum(axis=1)
    return np.asarray(sl[:, 0] + inside)


def moved(position: np.ndarray, rotation: np.ndarray, twist: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray]:
    """The pose (position (3,), rotation (3, 3)) moved by the twists (n, 6) (a
    translation [m] and a rotation vector [rad] in the base frame): (n, 3), (n, 3, 3)."""
    return (position + twist[:, :3],
            np.einsum("nij,jk->nik", rot.matrix_from_rotvec(twist[:, 3:]), rotation))


__all__ = ["ANGLE_SCALE", "CLEARANCE_GUARD", "MARGIN_GUARD", "RANGE_GUARD",
           "TILT_GUARD", "WALL_BAND", "crank_score", "moved", "slacks",
           "slacks_and_angles"]
