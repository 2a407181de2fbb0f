"""The tool centre point's velocity and acceleration along a motion.

The velocity follows exactly from the actuated rates through the inverse of the IK
Jacobian (:func:`sixplus3.kinematics.robot.ik_jacobian`); the acceleration is a finite
difference over the samples.  The planner's dense check and the gate measure the
platform-space limits (``Limits.tcp_speed``, ``tcp_acceleration``) with these.
"""

from __future__ import annotations

import numpy as np

from sixplus3.kinematics.robot import RobotConfig
from sixplus3.kinematics.robot_fk import ik_jacobian


def tcp_velocity(cfg: RobotConfig, theta_dot: np.ndarray) -> np.ndarray:
    """(n, 3) velocity of the tool centre point [m/s] (``cfg.robot.tool``), from the
    actuated rates theta_dot (n, 9) [rad/s] through the inverse of :func:`ik_jacobian`
    (inf where it is singular)."""
    J = ik_jacobian(cfg)
    out = np.full((len(cfg), 3), np.inf)
    ok = cfg.ok & np.all(np.isfinite(J), axis=(1, 2))
    if ok.any():
        try:
            xd = np.linalg.solve(J[ok], np.asarray(theta_dot, dtype=float)[ok][:, :, None])
        except np.linalg.LinAlgError:
            xd = np.einsum("nij,nj->ni", np.linalg.pinv(J[ok]), theta_dot[ok])[:, :, None]
        xd = xd[:, :, 0]
        r = np.einsum("nij,j->ni", cfg.rotation[ok], np.asarray(cfg.robot.tool.xyz))
        out[ok] = xd[:, 0:3] + np.cross(xd[:, 3:6], r)
    return out


def tcp_acceleration(velocity: np.ndarray, times: np.ndarray) -> np.ndarray:
    """(n,) |acceleration| of the tool centre point [m/s^2]: the second-order finite
    difference over ``times`` (n,) [s], increasing, of its velocity (n, 3) [m/s]
    (``numpy.gradient``; one-sided at the ends; 0 for a single sample)."""
    t = np.asarray(times, dtype=float)
    if len(t) < 2:
        return np.zeros(len(t))
    acc = np.gradient(velocity, t, axis=0, edge_order=2 if len(t) > 2 else 1)
    return np.linalg.norm(np.nan_to_num(acc, nan=np.inf), axis=1)


def tcp_rates(cfg: RobotConfig, theta_dot: np.ndarray, times: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """(speed (n,) [m/s], acceleration (n,) [m/s^2]) of the tool centre point along a
    motion sampled at ``times`` (n,) [s], increasing: the speed exactly from the actuated
    rates (:func:`tcp_velocity`), the acceleration by :func:`tcp_acceleration`."""
    v = tcp_velocity(cfg, theta_dot)
    return np.linalg.norm(v, axis=1), tcp_acceleration(v, times)


__all__ = ["tcp_acceleration", "tcp_rates", "tcp_velocity"]
