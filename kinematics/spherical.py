"""The spherical joints: each one's tilt from its axis at home, and the range check.

Every spherical joint (each leg's E, F and P) is measured as the angle between its
joint axis in the current configuration and the same axis at home; the robot's
``limits.spherical`` (150 deg) bounds it.  Used by the planner's static and dense
checks, the gate and the atlas.
"""

from __future__ import annotations

import numpy as np

from sixplus3.cache import cached
from sixplus3.kinematics.robot import RobotConfig, axis_rotations, home, q_layout
from sixplus3.robot_description.robot import Robot
from sixplus3.robot_description.robot_geometry import NUM_LEGS


def spherical_reference(robot: Robot) -> np.ndarray:
    """Mounting axes of the S joints, fixed in their bodies, from the home pose.

    Returns (3 legs, 3 joints E/F/P, 2 sides, 3): for E and F, (axis in the leg body
    frame, axis in the distal link frame); for P, (axis in the leg body frame, axis in the
    platform crank frame).  The joint is mounted centred at home: tilt 0.
    """
    return cached(("spherical_reference", robot.hash), lambda: _spherical_reference(robot))


def _spherical_reference(robot: Robot) -> np.ndarray:
    h = home(robot)
    ref = np.zeros((NUM_LEGS, 3, 2, 3))
    frames = _body_frames(h)
    for i in range(NUM_LEGS):
        body, dist_b, dist_c, crank = (f[0] for f in frames[i])
        for j, other in enumerate((dist_b, dist_c)):
            axis = other[:, 1]  # distal link direction in the world
            ref[i, j] = (body.T @ axis, other.T @ axis)
        axis = body[:, 0]  # D -> P
        ref[i, 2] = (body.T @ axis, crank.T @ axis)
    return ref


def _body_frames(cfg: RobotConfig) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """World rotations (n, 3, 3) of leg body, distal B, distal C, platform crank i."""
    out = []
    geom = cfg.robot.geometry
    lay = q_layout(cfg.robot)
    for i in range(NUM_LEGS):
        Rl = geom.leg_rotation(i)
        s = cfg.legs[i]
        q = cfg.q
        body = Rl @ s.Q
        distal = []
        for crank_joint, ua, ub in (("B", "Ga", "Gb"), ("C", "Ha", "Hb")):
            ang = q[:, lay[f"leg{i}_{crank_joint}"]] + q[:, lay[f"leg{i}_{ua}"]]
            b = q[:, lay[f"leg{i}_{ub}"]]
            distal.append(Rl @ axis_rotations(0, ang) @ axis_rotations(2, b))
        crank = cfg.rotation @ axis_rotations(2, geom.crank_axis_angle(i) + cfg.psi[:, i])
        out.append((body, distal[0], distal[1], crank))
    return out


def spherical_tilts(cfg: RobotConfig) -> np.ndarray:
    """(n, 3, 3) tilt [rad] of every spherical joint (leg, E/F/P) from its home axis.

    The range check: each must stay below the robot's ``limits.spherical`` (150 deg).
    """
    ref = spherical_reference(cfg.robot)
    frames = _body_frames(cfg)
    tilt = np.zeros((len(cfg), NUM_LEGS, 3))
    for i in range(NUM_LEGS):
        body, dist_b, dist_c, crank = frames[i]
        for j, other in enumerate((dist_b, dist_c, crank)):
            a = body @ ref[i, j, 0]
            b = other @ ref[i, j, 1]
            tilt[:, i, j] = np.arccos(np.clip(np.sum(a * b, axis=1), -1.0, 1.0))
    return np.where(cfg.ok[:, None, None], tilt, 0.0)


def spherical_ok(cfg: RobotConfig) -> np.ndarray:
    """(n,) every spherical joint within the robot's spherical limit (150 deg)."""
    return np.all(spherical_tilts(cfg) <= cfg.robot.limits.spherical, axis=(1, 2))


# --------------------------------------------------------------------- forward kinematics


__all__ = ["spherical_ok", "spherical_reference", "spherical_tilts"]
