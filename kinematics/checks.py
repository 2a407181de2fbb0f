"""The one limit rule: when a sampled value violates a robot's limit, with one set of
tolerances.

- a cap (torque, actuated velocity, acceleration and jerk, the tool centre point's speed
  and acceleration) is violated above ``cap * (1 + CAP_RTOL)``: :func:`cap_excess`;
- the actuated range, outside ``[theta_min - RANGE_ATOL, theta_max + RANGE_ATOL]``:
  :func:`range_excess` (and :func:`actuated_bounds` for compiled kernels);
- a floor (a singularity margin, the collision model's clearance of 0 m, the closure
  Jacobian's rcond) and the spherical joints' tilt are exact: :func:`floor_excess`,
  :func:`tilt_excess`.

An excess > 0 is a violation.  Every check applies these functions: the planner's
dense re-check (:func:`measure_limits`, called by
:func:`sixplus3.planner.solution.dense_check`), the file gate
(:mod:`sixplus3.control.gate.validation`), the static checks (:func:`pose_masks`) and the
atlas's compiled kernel (its actuated range from :func:`actuated_bounds`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from sixplus3.kinematics.collision import clearance
from sixplus3.kinematics.robot import RobotConfig
from sixplus3.kinematics.spherical import spherical_tilts
from sixplus3.kinematics.tcp import tcp_rates
from sixplus3.robot_description.limits import Limits

#: The crank (redundant joint) range the planner and the static analyses search [rad].
PSI_MIN, PSI_MAX = math.radians(45.0), math.radians(135.0)
#: Relative tolerance of every cap: rounding of a value planned exactly to its cap.
CAP_RTOL = 1e-9
#: Absolute tolerance of the actuated range [rad].
RANGE_ATOL = 1e-9
#: Smallest reciprocal condition number of the closure Jacobian: below it the pose is
#: (numerically) a parallel singularity.
RCOND_MIN = 1e-10


def cap_excess(values: ArrayLike, cap: float) -> np.ndarray:
    """How far ``values`` (magnitudes) are above ``cap`` (> 0: violated)."""
    return np.asarray(values) - cap * (1.0 + CAP_RTOL)


def actuated_bounds(limits: Limits) -> tuple[float, float]:
    """The actuated range as the rule applies it [rad]."""
    return limits.theta_min - RANGE_ATOL, limits.theta_max + RANGE_ATOL


def range_excess(theta: np.ndarray, limits: Limits) -> np.ndarray:
    """How far actuated angles [rad] are outside the actuated range (> 0: violated)."""
    lo, hi = actuated_bounds(limits)
    return np.maximum(lo - theta, theta - hi)


def floor_excess(values: ArrayLike, floor: float) -> np.ndarray:
    """How far ``values`` are below ``floor`` (> 0: violated; exact)."""
    return floor - np.asarray(values)


def tilt_excess(tilt: ArrayLike, limits: Limits) -> np.ndarray:
    """How far spherical-joint tilts [rad] are above their limit (> 0: violated)."""
    return np.asarray(tilt) - limits.spherical


def pose_masks(cfg: RobotConfig, limits: Limits) -> tuple[np.ndarray, np.ndarray]:
    """(theta_ok, spherical_ok) of batched configurations: solved with every actuated
    angle in the actuated range, and additionally every spherical joint within range
    (evaluated on the rows in range only)."""
    theta_ok = cfg.ok & np.all(range_excess(cfg.theta, limits) <= 0.0, axis=1)
    sph_ok = theta_ok.copy()
    if theta_ok.any():
        sph_ok[theta_ok] = np.all(tilt_excess(spherical_tilts(cfg.take(theta_ok)), limits)
                                  <= 0.0, axis=(1, 2))
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
    tau_max, v_max = float(np.abs(tau).max()), float(np.abs(theta_dot).max())
    a_max = float(np.abs(theta_ddot).max())
    m = cfg.margins
    m1, m2, mp = float(m.leg_type1.min()), float(m.leg_type2.min()), float(m.platform.min())
    clear = float(clearance(cfg).min())
    tilt = float(spherical_tilts(cfg).max())
    theta_ok = bool(np.all(range_excess(theta, limits) <= 0.0))
    violations = []
    if cap_excess(tau_max, limits.torque) > 0:
        violations.append(f"torque {tau_max:.3f} N m > {limits.torque:g} N m")
    if cap_excess(v_max, limits.velocity) > 0:
        violations.append(f"velocity {v_max:.3f} rad/s > {limits.velocity:g} rad/s")
    if cap_excess(a_max, limits.acceleration) > 0:
        violations.append(f"acceleration {a_max:.1f} rad/s^2 > "
                          f"{limits.acceleration:g} rad/s^2")
    for name, val in (("leg type I margin", m1), ("leg type II margin", m2),
                      ("platform margin", mp)):
        if floor_excess(val, limits.margin) > 0:
            violations.append(f"{name} {val:.4f} < {limits.margin:g}")
    if floor_excess(clear, 0.0) > 0:
        violations.append(f"interference: bodies of the collision model overlap by "
                          f"{-clear * 1e3:.1f} mm")
    if tilt_excess(tilt, limits) > 0:
        violations.append(f"spherical joint at {math.degrees(tilt):.1f} deg > "
                          f"{math.degrees(limits.spherical):g} deg")
    if not theta_ok:
        violations.append(f"an actuated angle leaves [{math.degrees(limits.theta_min):g}, "
                          f"{math.degrees(limits.theta_max):g}] deg")
    tcp_v = tcp_a = float("nan")
    if times is not None:
        sp, ac = tcp_rates(cfg, theta_dot, times)
        tcp_v, tcp_a = float(sp.max()), float(ac.max())
        if cap_excess(tcp_v, limits.tcp_speed) > 0:
            violations.append(f"tcp speed {tcp_v:.4f} m/s > {limits.tcp_speed:g} m/s")
        if cap_excess(tcp_a, limits.tcp_acceleration) > 0:
            violations.append(f"tcp acceleration {tcp_a:.3f} m/s^2 > "
                              f"{limits.tcp_acceleration:g} m/s^2")
    return LimitMeasures(tau_max / limits.torque, v_max / limits.velocity,
                         a_max / limits.acceleration, m1, m2, mp, clear, tilt, theta_ok, violations,
                         tcp_v, tcp_a)
