"""Whole-robot kinematics: platform pose + 3 crank angles <-> 9 actuated angles.

Inverse (closed form, batched): the crank tips P_i follow from the platform pose and the
redundant crank angles psi_i; each leg's IK (paper §III-B) gives its five angles at P_i;
the two U joints of each RUS chain follow from the distal link directions.  The result is
the full Pinocchio configuration of the spanning tree, whose 27 closure residuals vanish.

Forward (:mod:`sixplus3.kinematics.robot_fk`): from the 9 actuated angles and a previous
configuration (branch hint), Newton on the 27 closure equations over the 27 passive
velocity coordinates, or Newton on this closed-form inverse, many samples at once.

Singularity measures (all scale-free, 0 = singular): each leg's type I and type II
margins (:mod:`kinematics.leg`) and the platform margin, the inverse condition number of
the 9x9 Jacobian mapping (platform twist, crank rates) to the three P_i velocities, with
angular columns scaled by the platform radius and crank columns by the crank length.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from sixplus3.cache import cached
from sixplus3.errors import InputError, UnreachableError, as_float_array
from sixplus3.kinematics import rotations as rot
from sixplus3.kinematics.leg import LegState, failing_chain, leg_ik, status_reason
from sixplus3.robot_description.model import closed_loop_model
from sixplus3.robot_description.robot import Robot, require_robot
from sixplus3.robot_description.robot_geometry import NUM_LEGS, RobotGeometry

if TYPE_CHECKING:
    pass


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll) (URDF/ROS fixed-axis convention) [rad]."""
    return rot.matrix_from_rpy(roll, pitch, yaw)


@dataclass(frozen=True)
class RobotMargins:
    """Scale-free singularity margins, batched: 0 singular, 1 ideal."""

    leg_type1: np.ndarray  # (n, 3)
    leg_type2: np.ndarray  # (n, 3)
    platform: np.ndarray  # (n,)

    @property
    def minimum(self) -> np.ndarray:
        """(n,) the smallest of all seven margins."""
        return np.minimum(np.minimum(self.leg_type1.min(axis=1), self.leg_type2.min(axis=1)),
                          self.platform)

    def as_dict(self, i: int = 0) -> dict[str, object]:
        return {"leg_type1": self.leg_type1[i].tolist(), "leg_type2": self.leg_type2[i].tolist(),
                "platform": float(self.platform[i]), "minimum": float(self.minimum[i])}


@dataclass(frozen=True)
class RobotConfig:
    """Batched whole-robot configurations (leading axis n)."""

    status: np.ndarray  # (n,) bit i set when leg i failed; 0 = solved
    leg_status: np.ndarray  # (n, 3) each leg's status bitmask (kinematics.leg)
    position: np.ndarray  # (n, 3) platform centre [m]
    rotation: np.ndarray  # (n, 3, 3) platform orientation
    psi: np.ndarray  # (n, 3) crank angles [rad]
    theta: np.ndarray  # (n, 9) actuated angles [rad], legs 0..2 each A, B, C
    P: np.ndarray  # (n, 3, 3) spherical joint centres P_i in the robot frame [m]
    q: np.ndarray  # (n, nq) Pinocchio configuration of the spanning tree
    legs: tuple[LegState, ...]  # per leg, batched
    margins: RobotMargins
    robot: Robot  # the robot these configurations belong to

    def __len__(self) -> int:
        return int(self.status.shape[0])

    @property
    def ok(self) -> np.ndarray:
        return self.status == 0

    def take(self, mask: np.ndarray) -> RobotConfig:
        """The rows ``mask`` ((n,) bool) as a new RobotConfig (for costly checks that
        only the surviving rows need)."""

        def cut(obj: Any) -> Any:
            return replace(obj, **{f.name: getattr(obj, f.name)[mask] for f in fields(obj)
                                   if isinstance(getattr(obj, f.name), np.ndarray)
                                   and getattr(obj, f.name).shape[:1] == mask.shape})

        mg = self.margins
        return replace(cut(self), legs=tuple(cut(s) for s in self.legs),
                       margins=RobotMargins(mg.leg_type1[mask], mg.leg_type2[mask],
                                            mg.platform[mask]))


def q_layout(robot: Robot) -> dict[str, int]:
    """q index of every joint of the robot's tree (from Pinocchio), and the nq."""

    def make() -> dict[str, int]:
        m = closed_loop_model(robot).model
        out = {m.names[j]: int(m.joints[j].idx_q) for j in range(1, m.njoints)}
        out["__nq__"] = int(m.nq)
        return out

    return cached(("layout", robot.hash), make)


def _u_joint_angles(theta_crank: np.ndarray, link_dir: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """U joint (about x, then z) angles so that R_x(theta + a) R_z(b) y = link_dir.

    R_x(a) R_z(b) y = (-sin b, cos b cos a, cos b sin a) in the crank frame; the branch
    cos b > 0 is taken (the distal link never points along x_f in practice).
    """
    c, s = np.cos(theta_crank), np.sin(theta_crank)
    ux = link_dir[:, 0]
    uy = c * link_dir[:, 1] + s * link_dir[:, 2]  # R_x(theta)^T u
    uz = -s * link_dir[:, 1] + c * link_dir[:, 2]
    a = np.arctan2(uz, uy)
    b = np.arctan2(-ux, np.hypot(uy, uz))
    return a, b


def platform_margin(rotation: np.ndarray, P: np.ndarray, position: np.ndarray,
                    geom: RobotGeometry) -> np.ndarray:
    """(n,) sigma_min / sigma_max of the column-scaled 9x9 platform Jacobian.

    v_Pi = v_O + omega x (P_i - O) + psi_dot_i z_p x (P_i - R_i); angular columns are
    multiplied by L = sqrt(rho^2 + c^2) and crank columns by c to make them [m/s].
    Zero when a crank is parallel to its radius (the platform can spin while the cranks
    counter-rotate).
    """
    n = rotation.shape[0]
    L = math.hypot(geom.platform_radius, geom.platform_crank)
    c = geom.platform_crank
    z = rotation[:, :, 2]  # (n, 3)
    J = np.zeros((n, 9, 9))
    for i in range(NUM_LEGS):
        r = P[:, i] - position  # (n, 3)
        R_i = position + np.einsum("nij,j->ni", rotation, geom.crank_axis_position(i))
        s = P[:, i] - R_i
        rows = slice(3 * i, 3 * i + 3)
        J[:, rows, 0:3] = np.eye(3)
        # omega x r = -[r]x omega
        J[:, rows, 3:6] = -rot.skew(r) / L
        J[:, rows, 6 + i] = np.cross(z, s) / c
    sv = np.linalg.svd(J, compute_uv=False)
    return sv[:, -1] / sv[:, 0]


def axis_rotations(axis: int, a: np.ndarray) -> np.ndarray:
    """(n, 3, 3) rotations about coordinate axis ``axis`` (0 = x, 2 = z) by angles a [rad]."""
    c, s = np.cos(a), np.sin(a)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R = np.zeros((a.shape[0], 3, 3))
    R[:, axis, axis] = 1.0
    R[:, i, i], R[:, i, j], R[:, j, i], R[:, j, j] = c, -s, s, c
    return R


def _as_batch(position: ArrayLike, rotation: ArrayLike, psi: ArrayLike
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    position = np.atleast_2d(as_float_array(position, "position", "(n, 3) [m]"))
    rotation = as_float_array(rotation, "rotation", "(n, 3, 3)")
    if rotation.ndim == 2:
        rotation = rotation[None]
    psi = as_float_array(psi, "psi", "(n, 3) [rad]")
    shapes_ok = (position.ndim == 2 and position.shape[-1] == 3 and rotation.ndim == 3
                 and rotation.shape[-2:] == (3, 3) and psi.ndim in (1, 2)
                 and psi.shape[-1] == NUM_LEGS)
    if not shapes_ok:
        raise InputError("position must be (n, 3) [m], rotation (n, 3, 3) and psi (n, 3)",
                         value=(position.shape, rotation.shape, psi.shape),
                         valid="(n, 3), (n, 3, 3) and (n, 3)")
    n = max(position.shape[0], rotation.shape[0], psi.shape[0] if psi.ndim == 2 else 1)
    try:
        psi = np.broadcast_to(psi, (n, NUM_LEGS))
        position = np.broadcast_to(position, (n, 3))
        rotation = np.broadcast_to(rotation, (n, 3, 3))
    except ValueError:
        raise InputError("position, rotation and psi must have one length n (or 1)",
                         value=(position.shape, rotation.shape, psi.shape),
                         valid="(n, 3), (n, 3, 3), (n, 3)") from None
    for name, arr in (("position", position), ("rotation", rotation), ("psi", psi)):
        if not np.all(np.isfinite(arr)):
            raise InputError(f"{name} must be finite (got NaN or inf)",
                             value=name, valid="finite numbers")
    err = np.abs(np.einsum("nji,njk->nik", rotation, rotation) - np.eye(3)).max()
    if err > 1e-6:
        raise InputError(f"rotation is not orthonormal (|R^T R - I| = {err:.2e})",
                         value=err, valid="|R^T R - I| <= 1e-6")
    return np.ascontiguousarray(position), np.ascontiguousarray(rotation), np.array(psi)


def crank_tips(position: np.ndarray, rotation: np.ndarray, psi: np.ndarray,
               robot: Robot) -> np.ndarray:
    """(n, 3, 3) P_i in the robot frame for platform poses and crank angles [m]."""
    geom = robot.geometry
    n = position.shape[0]
    P = np.empty((n, NUM_LEGS, 3))
    for i in range(NUM_LEGS):
        b = geom.crank_axis_angle(i) + psi[:, i]
        local = geom.crank_axis_position(i) + geom.platform_crank * np.c_[
            np.cos(b), np.sin(b), np.zeros(n)]
        P[:, i] = position + np.einsum("nij,nj->ni", rotation, local)
    return P


def robot_ik(position: ArrayLike, rotation: ArrayLike, psi: ArrayLike | None, robot: Robot,
             platform_margins: bool = True) -> RobotConfig:
    """Batched closed-form IK: platform pose (n, 3) [m], (n, 3, 3) and psi (n, 3) [rad]
    (default: the robot's home crank angles), in the robot's assembly mode.

    Failed samples have ``status != 0`` (bit i: leg i), zeros in q and theta, margins 0.
    ``platform_margins=False`` skips the platform margin (an SVD per sample; NaN then):
    for inner loops that need only the angles.
    """
    robot = require_robot(robot)
    position, rotation, psi = _as_batch(position, rotation,
                                        robot.home_psi if psi is None else psi)
    geom, mode = robot.geometry, robot.mode
    n = position.shape[0]
    lay = q_layout(robot)
    leg = geom.leg
    P = crank_tips(position, rotation, psi, robot)
    q = np.zeros((n, lay["__nq__"]))
    theta = np.zeros((n, 3 * NUM_LEGS))
    status = np.zeros(n, dtype=np.int64)
    leg_status = np.zeros((n, NUM_LEGS), dtype=np.int64)
    legs = []
    for i in range(NUM_LEGS):
        s = leg_ik(geom.to_leg(i, P[:, i]), leg, mode)
        legs.append(s)
        leg_status[:, i] = s.status
        status |= np.where(s.ok, 0, 1 << i)
        theta[:, 3 * i:3 * i + 3] = s.theta
        a_g, b_g = _u_joint_angles(s.theta[:, 1], (s.e - s.g) / leg.l4)
        a_h, b_h = _u_joint_angles(s.theta[:, 2], (s.f - s.h) / leg.l5)
        for name, val in (("A", s.theta[:, 0]), ("Ds2", s.theta_s[:, 0]),
                          ("Ds3", s.theta_s[:, 1]), ("B", s.theta[:, 1]), ("Ga", a_g),
                          ("Gb", b_g), ("C", s.theta[:, 2]), ("Ha", a_h), ("Hb", b_h)):
            q[:, lay[f"leg{i}_{name}"]] = val
    iq = lay["platform_free"]
    q[:, iq:iq + 3] = position
    q[:, iq + 3:iq + 7] = rot.quat_from_matrix(rotation)  # (x, y, z, w)
    for i in range(NUM_LEGS):
        q[:, lay[f"platform_crank{i}"]] = psi[:, i]
    bad = status != 0
    q[bad] = 0.0
    q[bad, iq + 6] = 1.0  # keep a valid unit quaternion
    theta[bad] = 0.0
    margins = RobotMargins(
        leg_type1=np.stack([s.margin_I for s in legs], axis=1),
        leg_type2=np.stack([s.margin_II for s in legs], axis=1),
        platform=(np.where(bad, 0.0, platform_margin(rotation, P, position, geom))
                  if platform_margins else np.full(n, np.nan)),
    )
    return RobotConfig(status=status, leg_status=leg_status, position=position,
                       rotation=rotation, psi=psi, theta=theta, P=P, q=q, legs=tuple(legs),
                       margins=margins, robot=robot)


def robot_ik_pose(position: ArrayLike, rpy: ArrayLike = (0.0, 0.0, 0.0),
                  psi: ArrayLike | None = None, *, robot: Robot) -> RobotConfig:
    """IK of one pose (position [m], roll/pitch/yaw [rad], crank angles [rad], default
    the robot's home ones); raises :class:`UnreachableError` naming the failing leg."""
    robot = require_robot(robot)
    psi = robot.home_psi if psi is None else psi
    pos = as_float_array(position, "position", "3 numbers [m]")
    if pos.shape != (3,) or as_float_array(rpy, "rpy", "3 angles [rad]").shape != (3,) \
            or as_float_array(psi, "psi", "3 angles [rad]").shape != (3,):
        raise InputError("position, rpy and psi must each be 3 numbers",
                         value=(pos.shape, np.shape(rpy), np.shape(psi)), valid="(3,) each")
    roll, pitch, yaw = as_float_array(rpy, "rpy", "3 angles [rad]")
    cfg = robot_ik(pos, rpy_matrix(roll, pitch, yaw), psi, robot)
    if cfg.status[0]:
        for i in range(NUM_LEGS):
            st = int(cfg.leg_status[0, i])
            if st:
                raise UnreachableError(
                    f"leg {i} {failing_chain(st)}", tuple(cfg.P[0, i].round(6).tolist()),
                    f"{status_reason(st)} (P_{i} in the robot frame [m])")
    return cfg


def home(robot: Robot) -> RobotConfig:
    """The robot's home pose: platform horizontal at ``robot.home_position``, cranks at
    ``robot.home_psi``."""
    robot = require_robot(robot)
    return robot_ik_pose(robot.home_position, (0.0, 0.0, 0.0), robot.home_psi, robot=robot)


