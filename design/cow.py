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
                 limit (10 N m) at P_i;
5. ``clear``     no interference (:func:`sixplus3.kinematics.collision.clearance`
                 >= 0: the robot's collision model, every link, hub and the platform
                 as capsules).  Not in the paper; it is what makes a COW physical.

With a design :class:`~sixplus3.design.search.Reading`, ``theta`` is the paper's
collision rule in that reading's angle convention (every angle in [0, 270] deg counted
the reading's way); without one, the robot's own actuated range.

:func:`home_in_cow` says where a robot's home pose sits in its COW (all five sets, the
margin at the robot's limit): inside or not, its distance to the boundary, and the
deepest point on the vertical through home.

Projected area = area of the union of the horizontal cross-sections; footprint = area of
the convex hull of the nine actuated-joint positions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy import ndimage
from scipy.spatial import ConvexHull

from sixplus3.design.workspace import theta_within
from sixplus3.errors import InputError
from sixplus3.kinematics.collision import clearance
from sixplus3.kinematics.robot import robot_ik
from sixplus3.robot_description.robot import Robot, require_robot
from sixplus3.robot_description.robot_geometry import RobotGeometry

if TYPE_CHECKING:
    from sixplus3.design.search import Reading

LIMIT_SETS = ("reach", "theta", "singfree", "torque", "clear")
#: Margin used for "singularity-free" (scale-free, see kinematics.robot).
SINGFREE_MARGIN = 0.01
#: Most grid cells of one COW (5 boolean masks: 250 MB at the cap).
MAX_CELLS = 50_000_000
#: The paper's ratio of projected COW area to footprint.
PAPER_RATIO = 5.03


@dataclass(frozen=True)
class COW:
    xs: np.ndarray  # (nx,) [m]
    ys: np.ndarray  # (ny,) [m]
    zs: np.ndarray  # (nz,) [m]
    masks: dict[str, Any]  # limit set -> (nz, nx, ny) bool
    footprint: np.ndarray  # (k, 2) hull polygon [m]
    footprint_area: float  # [m^2]
    step: float
    mode: str = "++++"
    z_step: float = 0.025

    def projected_area(self, limits: str) -> float:
        return float(self.masks[limits].any(axis=0).sum()) * self.step**2

    def ratio(self, limits: str) -> float:
        return self.projected_area(limits) / self.footprint_area

    def volume(self, limits: str) -> float:
        return float(self.masks[limits].sum()) * self.step**2 * self.z_step


def footprint(geom: RobotGeometry) -> tuple[np.ndarray, float]:
    pts = geom.actuated_joint_positions()[:, :2]
    hull = ConvexHull(pts)
    return pts[hull.vertices], float(hull.volume)  # in 2D, 'volume' is the area


def compute_cow(robot: Robot, step: float = 0.01, z_step: float = 0.025,
                extent: float = 0.6, z_max: float = 0.75, reading: Reading | None = None,
                margin: float = SINGFREE_MARGIN, z_min: float | None = None) -> COW:
    """Evaluate the COW of ``robot`` on a grid of
    platform-centre positions [m], platform horizontal with the cranks at the robot's
    home angles; singularity signs are those at the robot's home pose.

    ``reading``: count the actuated angles the reading's way (the paper's [0, 270] deg
    collision rule); ``margin``: the smallest singularity margin of ``singfree``;
    layers from ``z_min`` (default ``z_step``) to ``z_max``."""
    z_min = z_step if z_min is None else z_min
    values = (step, z_step, extent, z_max, margin, z_min)
    if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in values):
        raise InputError(f"COW grid parameters must be finite numbers, got {values}",
                         value=values, valid="finite numbers [m]")
    if not (1e-3 <= step <= 0.1 and 1e-3 <= z_step <= 0.2 and 0 < extent <= 2
            and 0 < z_max <= 2 and 0 <= margin < 1 and -2 <= z_min <= z_max):
        raise InputError(f"step, z_step, extent, z_max, margin, z_min must be in [0.001, 0.1], "
                         f"[0.001, 0.2], (0, 2], (0, 2] m, [0, 1), [-2, z_max] m, got {values}",
                         value=values)
    robot = require_robot(robot)
    geom, mode, lim = robot.geometry, robot.mode.name, robot.limits
    psi = robot.home_psi
    xs = np.arange(-extent + step / 2, extent, step)
    zs = np.arange(z_min, z_max + 1e-9, z_step)
    cells = len(xs) ** 2 * len(zs)
    if cells > MAX_CELLS:
        raise InputError(f"the COW grid would hold {cells:.3g} cells, over the cap of "
                         f"{MAX_CELLS:.3g} (5 masks of a byte each): use a coarser step "
                         "or a smaller extent", value=cells, valid=f"<= {MAX_CELLS:.3g}")
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    ref = robot_ik(np.array(robot.home_position), np.eye(3), psi, robot)
    if not ref.ok[0]:
        raise InputError(f"the home pose {list(robot.home_position)} m of {robot.name} is "
                         "unreachable: the COW's singularity signs are taken there",
                         value=list(robot.home_position), valid="a reachable home pose")
    sign_j = np.array([np.sign(s.det_J[0]) for s in ref.legs])
    sign_k = np.array([np.sign(s.det_K[0]) for s in ref.legs])
    masks = {k: np.zeros((len(zs), len(xs), len(xs)), dtype=bool) for k in LIMIT_SETS}
    for iz, z in enumerate(zs):
        pos = np.c_[X.ravel(), Y.ravel(), np.full(X.size, z)]
        cfg = robot_ik(pos, np.eye(3), psi, robot)
        reach = cfg.ok
        th = cfg.theta
        if reading is None:
            in_range = np.all((th >= lim.theta_min) & (th <= lim.theta_max), axis=1)
        else:
            in_range = theta_within(th, math.radians(270.0), reading.theta_zero,
                                    reading.theta_direction)
        theta_ok = reach & in_range
        sing = theta_ok & (cfg.margins.minimum > margin)
        for i, s in enumerate(cfg.legs):
            sing &= (np.sign(s.det_J) == sign_j[i]) & (np.sign(s.det_K) == sign_k[i])
        torque = sing & np.all(np.stack([s.tau_ext for s in cfg.legs], axis=1) <= lim.torque,
                               axis=1)
        clear = torque.copy()
        if clear.any():
            clear[clear] = clearance(cfg, clear)[clear] >= 0.0
        for key, m in zip(LIMIT_SETS, (reach, theta_ok, sing, torque, clear), strict=True):
            masks[key][iz] = m.reshape(X.shape)
    poly, area = footprint(geom)
    return COW(xs, xs, zs, masks, poly, area, step, mode, z_step)


@dataclass(frozen=True)
class HomeInCOW:
    """Where a robot's home pose sits in its constant-orientation workspace."""

    home: tuple[float, float, float]  # [m]
    inside: bool  # home satisfies every limit set (reach .. clear)
    failing: str | None  # the first limit set home fails, None when inside
    depth: float  # distance from home to the COW boundary [m] (0 outside)
    #: deepest COW point on the grid's column nearest the vertical through home (the
    #: grid is cell-centred: its columns sit half a pitch off the axis)
    deepest: tuple[float, float, float]
    deepest_depth: float  # [m]
    z_range: tuple[float, float]  # lowest, highest COW layer on that vertical [m] (NaN: none)
    volume_l: float  # COW volume (all five sets) [L]
    step: float  # grid pitch [m]

    def line(self) -> str:
        where = (f"inside, {self.depth * 100:.1f} cm from its boundary" if self.inside
                 else f"OUTSIDE (fails '{self.failing}')")
        head = (f"home {[round(float(v), 3) for v in self.home]} m is {where}; the COW "
                "(horizontal platform, 2 g within the torque limit, margins >= the robot's, "
                f"no interference) is {self.volume_l:.1f} L")
        if not math.isfinite(self.z_range[0]):
            return head + " and does not cross the vertical through home"
        return (head + f"; the grid's column nearest home (x = {self.deepest[0] * 1e3:.0f}, "
                f"y = {self.deepest[1] * 1e3:.0f} mm; {self.step * 100:g} cm grid) spans "
                f"z = {self.z_range[0]:.2f}..{self.z_range[1]:.2f} m, deepest at z = "
                f"{self.deepest[2]:.2f} m ({self.deepest_depth * 100:.1f} cm deep)")


def home_in_cow(robot: Robot, step: float = 0.01,
                extent: float = 0.4, z_max: float = 0.8) -> HomeInCOW:
    """Where ``robot``'s home pose sits in its COW with every limit (``clear``): the
    margin at the robot's own limit, the 2 g criterion at its torque limit.

    Depth is the Euclidean distance transform of the COW mask on a cubic grid of pitch
    ``step`` (scipy.ndimage), i.e. the distance to the nearest position outside it.
    """

    robot = require_robot(robot)
    cow = compute_cow(robot, step=step, z_step=step, extent=extent, z_max=z_max,
                      margin=robot.limits.margin, z_min=0.0)
    full = cow.masks["clear"]
    depth = ndimage.distance_transform_edt(full) * step
    hx, hy, hz = robot.home_position
    ix = int(np.argmin(np.abs(cow.xs - hx)))
    iy = int(np.argmin(np.abs(cow.ys - hy)))
    iz = int(np.argmin(np.abs(cow.zs - hz)))
    at = (iz, ix, iy)
    failing = next((k for k in LIMIT_SETS if not cow.masks[k][at]), None)
    column = depth[:, ix, iy]
    k = int(np.argmax(column))
    layers = np.flatnonzero(full[:, ix, iy])
    zr = ((float(cow.zs[layers[0]]), float(cow.zs[layers[-1]])) if len(layers)
          else (math.nan, math.nan))
    return HomeInCOW(
        home=robot.home_position, inside=failing is None, failing=failing,
        depth=float(depth[at]),
        deepest=(float(cow.xs[ix]), float(cow.ys[iy]), float(cow.zs[k])),
        deepest_depth=float(column[k]), z_range=zr,
        volume_l=cow.volume("clear") * 1e3, step=step)


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


def deepest_point(robot: Robot, step: float = 0.01, extent: float = 0.4,
                  z_max: float = 0.8) -> tuple[tuple[float, float, float], float, float]:
    """The deepest point of ``robot``'s interference-free, torque-limited 2 g COW (every
    limit set, at the robot's margin) on a cubic grid of pitch ``step`` [m]: (point,
    its distance to the COW's boundary [m], the COW's volume [L]).  Ties go to the point
    nearest the central axis, then the lowest."""

    cow = compute_cow(robot, step=step, z_step=step, extent=extent, z_max=z_max,
                      margin=robot.limits.margin, z_min=0.0)
    full = cow.masks["clear"]
    if not full.any():
        raise InputError(f"{robot.name} has no interference-free 2 g COW on the grid",
                         value=robot.name, valid="a robot with a COW")
    depth = ndimage.distance_transform_edt(full) * step
    Z, X, Y = np.meshgrid(cow.zs, cow.xs, cow.ys, indexing="ij")
    key = np.lexsort((Z.ravel(), np.hypot(X, Y).ravel(), -np.round(depth.ravel(), 9)))
    k = key[0]
    return ((float(X.ravel()[k]), float(Y.ravel()[k]), float(Z.ravel()[k])),
            float(depth.ravel()[k]), cow.volume("clear") * 1e3)
