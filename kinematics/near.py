"""The body pairs that come near contact around a robot's home: the pairs the planner's
smooth clearance rows measure (:mod:`sixplus3.dynamics.clearance`).

It samples poses (the whole robot's IK, the actuated-range and spherical-joint masks of
:mod:`.checks`) and measures every capsule pair of :mod:`.collision` on them.
"""

from __future__ import annotations

import numpy as np

from sixplus3.cache import cached
from sixplus3.kinematics import _geometry_kernel
from sixplus3.kinematics import rotations as rot
from sixplus3.kinematics.checks import pose_masks
from sixplus3.kinematics.collision import BASE_BODIES, PAIRS, capsules, radii
from sixplus3.kinematics.robot import robot_ik
from sixplus3.robot_description.robot import Robot

#: The region :func:`near_pairs` samples, around the robot's home: |x|, |y| <= 0.15 m,
#: z from -0.20 to +0.15 m, tilts up to 100 deg about any axis, cranks in [35, 145] deg.
NEAR_SAMPLES = 40000


def near_pairs(robot: Robot, margin: float = 0.02) -> tuple[np.ndarray, np.ndarray]:
    """The pairs (indices into :data:`PAIRS`) and base bodies (into
    :data:`BASE_BODIES`) that come within ``margin`` [m] of contact somewhere in a seeded
    sample of the workspace around home (``NEAR_SAMPLES`` random poses, the solved ones
    with every actuated angle and spherical joint in range).  The planner's smooth rows
    measure only these; the dense check and the gate measure every pair.  Cached per
    robot."""
    return cached(("near-pairs", f"{robot.hash}:{margin!r}"),
                  lambda: _near_pairs(robot, margin))


def _near_pairs(robot: Robot, margin: float) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(0)
    n = NEAR_SAMPLES
    pos = np.asarray(robot.home_position) + np.c_[rng.uniform(-0.15, 0.15, (n, 2)),
                                                  rng.uniform(-0.20, 0.15, n)]
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    R = rot.matrix_from_rotvec(axis * rng.uniform(0.0, np.radians(100.0), (n, 1)))
    psi = rng.uniform(np.radians(35.0), np.radians(145.0), (n, 3))
    cfg = robot_ik(pos, R, psi, robot, platform_margins=False)
    _, sph = pose_masks(cfg, robot.limits)
    cfg = cfg.take(sph)
    caps = np.ascontiguousarray(capsules(cfg))
    r = radii(robot)
    d = _geometry_kernel.pair_distances(caps, r, PAIRS).min(axis=0)
    low = (caps[:, BASE_BODIES][..., 2].min(axis=(0, 2)) - r[BASE_BODIES]
           - robot.collision.base_top)
    return np.flatnonzero(d < margin), np.flatnonzero(low < margin)


__all__ = ["NEAR_SAMPLES", "near_pairs"]
