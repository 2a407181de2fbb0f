"""Static capability analyses used to build and judge planning tasks.

``largest_tilt``: the largest tilt of the platform about a horizontal axis, at a given
position, for which some choice of the crank angles (or the locked nominal 90 deg) keeps
the robot reachable, every actuated angle in [0, 270] deg, every spherical joint within
150 deg, no interference in the collision model (kinematics.collision.clearance), every
singularity margin >= the threshold and the static gravity torques
within the limit.  This is the paper's argument for kinematic redundancy (a Gough-Stewart
platform stops near 45 deg).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.errors import InputError, SingularityError
from sixplus3.kinematics.checks import PSI_MAX, PSI_MIN
from sixplus3.planner.statics import static_checks
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot, require_robot


@dataclass(frozen=True)
class TiltResult:
    axis: str  # "x" or "y"
    locked: bool
    tilt_deg: float  # largest feasible tilt found (bisection resolution below)
    psi_deg: tuple[float, float, float]  # crank angles at that tilt
    min_margin: float
    max_gravity_torque: float  # [N m]
    binding: str  # what fails just beyond it


def _psi_grid(robot: Robot, locked: bool, step_deg: float = 7.5) -> np.ndarray:
    if locked:
        return np.asarray(robot.home_psi)[None, :]
    ax = np.radians(np.arange(math.degrees(PSI_MIN), math.degrees(PSI_MAX) + 1e-9, step_deg))
    return np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), -1).reshape(-1, 3)


def static_feasible(robot: Robot, position: Any, rotation: Any, limits: Limits, locked: bool,
                    dyn: ClosedLoopDynamics | None = None) -> Any:
    """(feasible, psi, min margin, max |tau_g|, binding limit) at one pose."""
    dyn = dyn or ClosedLoopDynamics(robot)
    psis = _psi_grid(robot, locked)
    cfg, theta_ok, sph_ok, clear_ok, margin = static_checks(robot, limits, position,
                                                            rotation, psis)
    if not cfg.ok.any():
        return False, None, 0.0, math.inf, "reach"
    if not theta_ok.any():
        return False, None, 0.0, math.inf, "theta range"
    if not sph_ok.any():
        return False, None, 0.0, math.inf, "spherical joints"
    if not clear_ok.any():
        return False, None, 0.0, math.inf, "interference"
    if margin.max() < limits.margin:
        return False, None, float(margin.max()), math.inf, "singularity margin"
    best_tau = math.inf
    for idx in np.argsort(-margin)[:60]:
        if margin[idx] < limits.margin:
            break
        try:
            tau = float(np.abs(dyn.gravity_torques(cfg.q[idx])).max())
        except SingularityError:
            continue
        if tau <= limits.torque:
            return True, psis[idx], float(margin[idx]), tau, ""
        best_tau = min(best_tau, tau)
    return False, None, float(margin.max()), best_tau, "torque"


def largest_tilt(robot: Robot, axis: str = "x", locked: bool = False,
                 limits: Limits | None = None, position: Any = None,
                 resolution_deg: float = 0.5,
                 max_deg: float = 120.0) -> TiltResult:
    """Bisection on the tilt angle about ``axis`` ("x" or "y") at ``position`` [m]
    (default: the robot's home), within ``limits`` (default: the robot's)."""
    require_robot(robot)
    if axis not in ("x", "y"):
        raise InputError(f"axis must be 'x' or 'y', got {axis!r}", value=axis,
                         valid="x or y")
    limits = limits or robot.limits
    dyn = ClosedLoopDynamics(robot)
    pos = np.asarray(robot.home_position if position is None else position, dtype=float)
    vec = {"x": np.array([1.0, 0, 0]), "y": np.array([0, 1.0, 0])}[axis]

    def test(deg: float) -> Any:
        R = Rotation.from_rotvec(np.radians(deg) * vec).as_matrix()
        return static_feasible(robot, pos, R, limits, locked, dyn)

    ok0 = test(0.0)
    if not ok0[0]:
        return TiltResult(axis, locked, float("nan"), (math.nan,) * 3, ok0[2], ok0[3],
                          ok0[4])
    # the feasible set of tilts need not be an interval; scan coarsely, then bisect
    lo, best, binding = 0.0, ok0, ""
    for deg in np.arange(5.0, max_deg + 1e-9, 5.0):
        r = test(deg)
        if not r[0]:
            binding = r[4]
            hi = deg
            break
        lo, best = deg, r
    else:
        hi = lo
    while hi - lo > resolution_deg:
        mid = 0.5 * (lo + hi)
        r = test(mid)
        if r[0]:
            lo, best = mid, r
        else:
            hi, binding = mid, r[4]
    return TiltResult(axis, locked, lo, tuple(np.round(np.degrees(best[1]), 2).tolist()),
                      best[2], best[3], binding)
