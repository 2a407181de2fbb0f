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

The slacks are computed by a compiled kernel (:mod:`sixplus3.interaction.lead._walls_kernel`:
the same numbers as the gate's checks composed, to 1e-10, tests/test_tick_kernel.py).

The cranks climb the **crank score**: the singularity slack, less how deep the
spherical and range slacks are inside their walls' band (clearance is a wall only: the
cranks barely change it)."""

from __future__ import annotations

import math

import numpy as np

from sixplus3.cache import cached
from sixplus3.interaction.lead import _walls_kernel as wk
from sixplus3.kinematics.checks import actuated_bounds
from sixplus3.kinematics.collision import BASE_BODIES, PAIRS, hub_segments, radii
from sixplus3.kinematics.spherical import spherical_reference
from sixplus3.robot_description.robot import Robot
from sixplus3.robot_description.robot_geometry import NUM_LEGS

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


class Walls:
    """The slacks of one robot's poses (module doc), compiled
    (:mod:`sixplus3.interaction.lead._walls_kernel`): the robot's constants packed once."""

    def __init__(self, robot: Robot) -> None:
        geom, lim, col = robot.geometry, robot.limits, robot.collision
        lo, hi = actuated_bounds(lim)
        k = np.zeros(wk.N_K)
        k[wk.K_CRANK] = geom.platform_crank
        k[wk.K_L] = math.hypot(geom.platform_radius, geom.platform_crank)
        k[wk.K_MARGIN] = lim.margin + MARGIN_GUARD
        k[wk.K_TILT] = lim.spherical - TILT_GUARD
        k[wk.K_LO], k[wk.K_HI], k[wk.K_RANGE] = lo, hi, RANGE_GUARD
        k[wk.K_PLATE], k[wk.K_BASE] = col.plate_offset, col.base_top
        k[wk.K_CLEAR] = CLEARANCE_GUARD
        k[wk.K_L6], k[wk.K_L7] = geom.leg.l6, geom.leg.l7
        self._const = (
            k, geom.leg.packed(), robot.mode.array().astype(float),
            np.array([geom.crank_axis_position(i) for i in range(NUM_LEGS)]),
            np.array([geom.crank_axis_angle(i) for i in range(NUM_LEGS)]),
            np.array([geom.leg_rotation(i) for i in range(NUM_LEGS)]),
            np.array([geom.leg_origin(i) for i in range(NUM_LEGS)]),
            np.ascontiguousarray(spherical_reference(robot)),
            np.ascontiguousarray(hub_segments(robot)), radii(robot), PAIRS, BASE_BODIES)

    def __call__(self, position: np.ndarray, rotation: np.ndarray, psi: np.ndarray,
                 walls: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(the slacks (n, 4), the actuated angles (n, 9), solved (n,)) of the poses
        (position (n, 3), rotation (n, 3, 3), psi (n, 3)); the clearance only on the
        rows ``walls`` ((n,) bool; default all), +inf on the others."""
        p = np.ascontiguousarray(position, dtype=float).reshape(-1, 3)
        n = len(p)
        R = np.ascontiguousarray(rotation, dtype=float).reshape(n, 3, 3)
        ps = np.ascontiguousarray(psi, dtype=float).reshape(n, 3)
        sel = (np.ones(n, dtype=np.bool_) if walls is None
               else np.asarray(walls, dtype=np.bool_).reshape(n))
        out, theta, ok = np.empty((n, 4)), np.empty((n, 9)), np.empty(n, dtype=np.bool_)
        self.into(p, R, ps, sel, out, theta, ok)
        return out, theta, ok

    def into(self, position: np.ndarray, rotation: np.ndarray, psi: np.ndarray,
             walls: np.ndarray, out: np.ndarray, theta: np.ndarray, ok: np.ndarray
             ) -> None:
        """:meth:`__call__` into given arrays (C-contiguous float: position (n, 3),
        rotation (n, 3, 3), psi (n, 3), out (n, 4), theta (n, 9); bool: walls, ok (n,)),
        without a conversion or an allocation (a per-tick caller's)."""
        wk.batch_slacks(position, rotation, psi, walls, self._const, out, theta, ok)


def walls_of(robot: Robot) -> Walls:
    """The robot's :class:`Walls` (built once per robot)."""
    return cached(("walls", robot.hash), lambda: Walls(robot))


def slacks(robot: Robot, position: np.ndarray, rotation: np.ndarray, psi: np.ndarray,
           walls: np.ndarray | None = None) -> np.ndarray:
    """(n, 4) the slacks of the poses (module doc); the clearance (slow) only on the
    rows ``walls`` ((n,) bool; default all), +inf on the others."""
    return walls_of(robot)(position, rotation, psi, walls)[0]


def slacks_and_angles(robot: Robot, position: np.ndarray, rotation: np.ndarray,
                      psi: np.ndarray, walls: np.ndarray | None = None
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(the slacks (n, 4), the actuated angles (n, 9), solved (n,)) of the poses."""
    return walls_of(robot)(position, rotation, psi, walls)


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
    tw = np.ascontiguousarray(twist, dtype=float).reshape(-1, 6)
    pos, rotm = np.empty((len(tw), 3)), np.empty((len(tw), 3, 3))
    wk.moved(np.ascontiguousarray(position, dtype=float),
             np.ascontiguousarray(rotation, dtype=float), tw, pos, rotm)
    return pos, rotm


__all__ = ["ANGLE_SCALE", "CLEARANCE_GUARD", "MARGIN_GUARD", "RANGE_GUARD",
           "TILT_GUARD", "WALL_BAND", "Walls", "crank_score", "moved", "slacks",
           "slacks_and_angles", "walls_of"]
