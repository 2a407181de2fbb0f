"""The one limit rule: the extremes of a sampled motion against a robot's limits.

Both independent checks apply it: the planner's dense re-check
(:func:`sixplus3.planner.solution.dense_check`) and the file validation
(:mod:`sixplus3.control.validation`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sixplus3.kinematics.collision import clearance
from sixplus3.kinematics.robot import RobotConfig
from sixplus3.kinematics.spherical import spherical_tilts
from sixplus3.robot_description.limits import Limits

#: The crank (redundant joint) range the planner and the static analyses search [rad].
PSI_MIN, PSI_MAX = math.radians(45.0), math.radians(135.0)


def pose_masks(cfg: RobotConfig, limits: Limits) -> tuple[np.ndarray, np.ndarray]:
    """(theta_ok, spherical_ok) of batched configurations: solved with every actuated
    angle in the actuated range, and additionally every spherical joint within range
    (evaluated on the rows in range only)."""
    theta_ok = cfg.ok & np.all((cfg.theta >= limits.theta_min)
                               & (cfg.theta <= limits.theta_max), axis=1)
    sph_ok = theta_ok.copy()
    if theta_ok.any():
        sph_ok[theta_ok] = np.all(spherical_tilts(cfg.take(theta_ok)) <= limits.spherical,
                                  axis=(1, 2))
    return theta_ok, sph_ok


@dataclass(frozen=True)
class LimitMeasures:
    """Extremes of a sampled motion against the limits, and the limits it violates."""

    max_torque_ratio: float  # max |tau| / limit
    max_velocity_ratio: float
    max_acceleration_ratio: float
    min_margin_leg_type1: float
    min_margin_leg_type2: float
    min_margin_platform: float
    min_clearance: float  # [m] of the collision model (kinematics.collision)
    max_spherical_tilt: float  # [rad]
    theta_range_ok: bool
    violations: list[str]
    max_tcp_speed: float = float("nan")  # [m/s] (NaN: not measured, no times given)
    max_tcp_acceleration: float = float("nan")  # [m/s^2]


def measure_limits(cfg: RobotConfig, tau: np.ndarray, theta: np.ndarray, theta_dot: np.ndarray,
                   theta_ddot: np.ndarray, limits: Limits,
                   times: np.ndarray | None = None) -> LimitMeasures:
    """The one rule both independent checks apply (the planner's dense re-check and the
    file validation): torques, actuated rates and accelerations against their limits,
    the numeric singularity margins of ``cfg`` (a batched RobotConfig), the collision
    model's clearance, spherical-joint tilts and the actuated range.  Each violation is one
    message starting with the limit's name (the planner tightens by that name)."""
    torque = float(np.abs(tau).max() / limits.torque)
    vel = float(np.abs(theta_dot).max() / limits.velocity)
    acc = float(np.abs(theta_ddot).max() / limits.acceleration)
    m = cfg.margins
    m1, m2, mp = float(m.leg_type1.min()), float(m.leg_type2.min()), float(m.platform.min())
    clear = float(clearance(cfg).min())
    tilt = float(spherical_tilts(cfg).max())
    theta_ok = bool(np.all((theta >= limits.theta_min - 1e-9)
                           & (theta <= limits.theta_max + 1e-9)))
    violations = []
    if torque > 1.0:
        violations.append(f"torque {torque * limits.torque:.3f} N m > {limits.torque:g} N m")
    if vel > 1.0 + 1e-9:
        violations.append(f"velocity {vel * limits.velocity:.3f} rad/s > "
                          f"{limits.velocity:g} rad/s")
    if acc > 1.0 + 1e-9:
        violations.append(f"acceleration {acc * limits.acceleration:.1f} rad/s^2 > "
                          f"{limits.acceleration:g} rad/s^2")
    for name, val in (("leg type I margin", m1), ("leg type II margin", m2),
                      ("platform margin", mp)):
        if val < limits.margin:
            violations.append(f"{name} {val:.4f} < {limits.margin:g}")
    if clear < 0.0:
        violations.append(f"interference: bodies of the collision model overlap by "
                          f"{-clear * 1e3:.1f} mm")
    if tilt > limits.spherical:
        violations.append(f"spherical joint at {math.degrees(tilt):.1f} deg > "
                          f"{math.degrees(limits.spherical):g} deg")
    if not theta_ok:
        violations.append(f"an actuated angle leaves [{math.degrees(limits.theta_min):g}, "
                          f"{math.degrees(limits.theta_max):g}] deg")
    tcp_v = tcp_a = float("nan")
    if times is not None:
        from sixplus3.kinematics.tcp import tcp_rates

        sp, ac = tcp_rates(cfg, theta_dot, times)
        tcp_v, tcp_a = float(sp.max()), float(ac.max())
        if tcp_v > limits.tcp_speed * (1.0 + 1e-9):
            violations.append(f"tcp speed {tcp_v:.4f} m/s > {limits.tcp_speed:g} m/s")
        if tcp_a > limits.tcp_acceleration * (1.0 + 1e-9):
            violations.append(f"tcp acceleration {tcp_a:.3f} m/s^2 > "
                              f"{limits.tcp_acceleration:g} m/s^2")
    return LimitMeasures(torque, vel, acc, m1, m2, mp, clear, tilt, theta_ok, violations,
                         tcp_v, tcp_a)
