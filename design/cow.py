"""Constant-orientation workspace (COW) of the whole robot (paper §V-B, Fig. cow_9dof).

Setup of the paper: legs placed symmetrically with |a_j - a_i| = 0.143 m, platform
horizontal with its spherical joints on an equilateral triangle of side 0.173 m (our
platform at psi = 90 deg).  A platform-centre position belongs to the COW when every leg
reaches its P_i (in the default assembly mode) and the chosen limits hold.  Limits are
cumulative, so the report says which one bounds the workspace:

1. ``reach``     every leg solved (the kinematic COW, intersection of the leg tori);
2. ``theta``     every actuated angle in the robot's actuated range ([0, 270] deg: no
                 base collision, paper §V-A);
3. ``singfree``  no singularity crossed from home: every leg's det J and det K keep their
                 sign at home, and every margin (leg type I/II, platform) > 0.01;
4. ``torque``    every leg meets the paper's 2 g criterion: tau_ext <= the robot's torque
                 limit (10 N m) at P_i.

Projected area = area of the union of the horizontal cross-sections; footprint = area of
the convex hull of the nine actuated-joint positions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull

from sixplus3.errors import InputError
from sixplus3.kinematics.robot import robot_ik
from sixplus3.robot_description.robot import Robot, RobotGeometry

LIMIT_SETS = ("reach", "theta", "singfree", "torque")
#: Margin used for "singularity-free" (scale-free, see kinematics.robot).
SINGFREE_MARGIN = 0.01
#: The paper's ratio of projected COW area to footprint.
PAPER_RATIO = 5.03


@dataclass(frozen=True)
class COW:
    xs: np.ndarray  # (nx,) [m]
    ys: np.ndarray  # (ny,) [m]
    zs: np.ndarray  # (nz,) [m]
    masks: dict  # limit set -> (nz, nx, ny) bool
    footprint: np.ndarray  # (k, 2) hull polygon [m]
    footprint_area: float  # [m^2]
    step: float
    mode: str = "++++"

    def projected_area(self, limits: str) -> float:
        return float(self.masks[limits].any(axis=0).sum()) * self.step**2

    def ratio(self, limits: str) -> float:
        return self.projected_area(limits) / self.footprint_area

    def volume(self, limits: str) -> float:
        dz = self.zs[1] - self.zs[0] if len(self.zs) > 1 else 0.0
        return float(self.masks[limits].sum()) * self.step**2 * dz


def footprint(geom: RobotGeometry) -> tuple[np.ndarray, float]:
    pts = geom.actuated_joint_positions()[:, :2]
    hull = ConvexHull(pts)
    return pts[hull.vertices], float(hull.volume)  # in 2D, 'volume' is the area


def compute_cow(robot: Robot | None = None, step: float = 0.01, z_step: float = 0.025,
                extent: float = 0.6, z_max: float = 0.75) -> COW:
    """Evaluate the COW of ``robot`` (default ``Robot.default()``) on a grid of
    platform-centre positions [m], platform horizontal with the cranks at the robot's
    home angles; singularity signs are those at the robot's home pose."""
    values = (step, z_step, extent, z_max)
    if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in values):
        raise InputError(f"COW grid parameters must be finite numbers, got {values}",
                         value=values, valid="finite numbers [m]")
    if not (1e-3 <= step <= 0.1 and 1e-3 <= z_step <= 0.2 and 0 < extent <= 2
            and 0 < z_max <= 2):
        raise InputError(f"step, z_step, extent, z_max must be in [0.001, 0.1], "
                         f"[0.001, 0.2], (0, 2], (0, 2] m, got {values}", value=values)
    robot = robot or Robot.default()
    geom, mode, lim = robot.geometry, robot.mode.name, robot.limits
    psi = robot.home_psi
    xs = np.arange(-extent + step / 2, extent, step)
    zs = np.arange(z_step, z_max + 1e-9, z_step)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    ref = robot_ik(np.array(robot.home_position), np.eye(3), psi, robot)
    sign_j = np.array([np.sign(s.det_J[0]) for s in ref.legs])
    sign_k = np.array([np.sign(s.det_K[0]) for s in ref.legs])
    masks = {k: np.zeros((len(zs), len(xs), len(xs)), dtype=bool) for k in LIMIT_SETS}
    for iz, z in enumerate(zs):
        pos = np.c_[X.ravel(), Y.ravel(), np.full(X.size, z)]
        cfg = robot_ik(pos, np.eye(3), psi, robot)
        reach = cfg.ok
        th = cfg.theta
        theta_ok = reach & np.all((th >= lim.theta_min) & (th <= lim.theta_max), axis=1)
        sing = theta_ok & (cfg.margins.minimum > SINGFREE_MARGIN)
        for i, s in enumerate(cfg.legs):
            sing &= (np.sign(s.det_J) == sign_j[i]) & (np.sign(s.det_K) == sign_k[i])
        torque = sing & np.all(np.stack([s.tau_ext for s in cfg.legs], axis=1) <= lim.torque,
                               axis=1)
        for key, m in zip(LIMIT_SETS, (reach, theta_ok, sing, torque), strict=True):
            masks[key][iz] = m.reshape(X.shape)
    poly, area = footprint(geom)
    return COW(xs, xs, zs, masks, poly, area, step, mode)


def encoder_resolution(theta_res_joint: float, dtheta_dp: np.ndarray) -> np.ndarray:
    """Worst-case position resolution of P [m] at each point.

    With every joint uncertain by +-theta_res_joint, dp = (K^-1 J)^-1 dtheta; the worst
    case over the box of dtheta is at one of its 8 vertices.
    """
    dp_dth = np.linalg.inv(dtheta_dp)  # (n, 3, 3)
    signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1], indexing="ij")).reshape(3, -1).T
    disp = np.einsum("nij,kj->nki", dp_dth, signs * theta_res_joint)
    return np.linalg.norm(disp, axis=2).max(axis=1)


#: Joint resolution of a 20-bit encoder on the motor through the 72/34 belt [rad].
JOINT_RESOLUTION = 2.0 * math.pi / 2**20 * 34.0 / 72.0
