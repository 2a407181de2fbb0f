"""The stop-at-waypoints baseline: straight lines, static crank angles, TOPP-RA per segment.

What a user would build without the OCP, and the plan the planner must never be slower
than (it is also its warm start and its fallback, :func:`planner.strategy.solve`):

1. every segment is the straight line x(s) = x_a + s (x_b - x_a), s in [0, 1], in the
   minimal coordinates (position, rotation vector, crank angles), between the waypoint
   states with the statically best crank angles (:func:`planner.statics.choose_static_psi`),
   at rest at both ends;
2. the line is checked geometrically at 101 points (reach, actuated range, spherical
   joints, leg clearance, singularity margins); a line that fails has no baseline;
3. TOPP-RA (:func:`planner.toppra_baseline.toppra_trajectory`) gives the time-optimal
   s(t) on it under the torque, velocity and acceleration limits;
4. TOPP-RA's acceleration jumps (bang-bang) break the jerk and torque-rate limits, so
   s(t) is averaged over a sliding window of width w (exactly: s_w(t) = (1/w)
   int_{t-w}^t s(r) dr, with s = 0 before and 1 after the motion).  Then
   s_w'' = (s'(t) - s'(t - w)) / w is continuous and its rate is at most
   2 max|s''| / w; w = 1.1 x (the largest torque swing) / (torque-rate limit), so a
   full bang-bang torque swing takes about w.  The motion gets w longer;
5. s_w is put on a node grid (2.5 ms) as the planner's own representation: accelerations
   at the nodes, linear in between, positions and rates integrated exactly (so that
   :meth:`Solution.sample` reproduces the motion without jumps); a smooth correction
   (zero at both ends) makes it end exactly at rest at s = 1;
6. each segment is scaled uniformly in time to within ``target`` of every limit
   (velocity, acceleration, torque, jerk and torque rate on a 4x grid, with the CasADi
   model): under t -> a t the rates scale 1/a, the accelerations and the inertial
   torques 1/a^2, the jerks 1/a^3, exactly;
7. the result is dense-checked with Pinocchio like every plan
   (:func:`planner.solution.dense_check`).

A baseline that fails the check is not returned.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.spatial.transform import Rotation

from sixplus3.errors import InfeasibleTaskError
from sixplus3.kinematics.checks import pose_masks
from sixplus3.kinematics.collision import clearance
from sixplus3.kinematics.robot import robot_ik
from sixplus3.planner.solution import Solution, actuated_profile, sample_cubic, stretch_factors
from sixplus3.planner.toppra_baseline import toppra_trajectory
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot

if TYPE_CHECKING:
    from sixplus3.planner.problem import Problem

#: node spacing of the baseline plan [s]
NODE_STEP = 2.5e-3
#: the baseline is retimed to this share of every limit
TARGET = 0.99


def line_check(robot: Robot, limits: Limits, xa: np.ndarray, xb: np.ndarray,
               points: int = 101) -> str | None:
    """None if the straight line xa -> xb (minimal coordinates) is admissible at
    ``points`` points, else the first reason it is not."""
    s = np.linspace(0.0, 1.0, points)[:, None]
    x = xa + s * (xb - xa)
    cfg = robot_ik(x[:, 0:3], Rotation.from_rotvec(x[:, 3:6]).as_matrix(), x[:, 6:9], robot)
    if not cfg.ok.all():
        return "the straight line leaves the workspace"
    theta_ok, sph_ok = pose_masks(cfg, limits)
    if not theta_ok.all():
        return "the straight line leaves the actuated range"
    if not sph_ok.all():
        return "the straight line exceeds a spherical joint's tilt"
    if clearance(cfg).min() < 0.0:
        return "the legs' links interfere on the straight line"
    worst = float(cfg.margins.minimum.min())
    if worst < limits.margin:
        return f"a singularity margin drops to {worst:.4f} < {limits.margin:g} on the straight line"
    return None


def _smoothed_profile(traj: Any, d: np.ndarray, duration: float, width: float,
                      step: float) -> tuple[np.ndarray, ...]:
    """Node times and (s, s', s'') of the window-averaged TOPP-RA profile, integrated
    exactly from the node accelerations and corrected to end at rest at s = 1."""
    total = duration + width
    n = max(8, int(math.ceil(total / step)))
    t = np.linspace(0.0, total, n + 1)
    h = t[1] - t[0]

    def rate(times: np.ndarray) -> np.ndarray:  # s'(t) of TOPP-RA, 0 outside [0, duration]
        inside = (times >= 0.0) & (times <= duration)
        out = np.zeros_like(times)
        if inside.any():
            xdot = np.asarray(traj(times[inside], 1)).reshape(inside.sum(), -1)
            out[inside] = xdot @ d / (d @ d)  # the line's parameter rate
        return out

    u = (rate(t) - rate(t - width)) / width
    u[0] = u[-1] = 0.0

    def integrate(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        v = np.r_[0.0, np.cumsum(h * (u[:-1] + u[1:]) / 2)]
        s = np.r_[0.0, np.cumsum(h * v[:-1] + h**2 * (2 * u[:-1] + u[1:]) / 6)]
        return s, v

    _, v = integrate(u)
    bump = np.sin(np.pi * t / total) ** 2
    _, vb = integrate(bump)
    u = u - v[-1] / vb[-1] * bump  # end at rest
    s, v = integrate(u)
    return t, s / s[-1], v / s[-1], u / s[-1]


def _stretch_needed(robot: Robot, limits: Limits, xa: np.ndarray, d: np.ndarray,
                    t: np.ndarray, s: np.ndarray, v: np.ndarray, u: np.ndarray,
                    target: float) -> float:
    """Smallest uniform time stretch a bringing the segment within ``target`` of the
    velocity, acceleration, torque, jerk and torque-rate limits (4x grid)."""
    tt = np.linspace(0.0, t[-1], 4 * (len(t) - 1) + 1)
    ss, vv, uu = sample_cubic(t, s[:, None], v[:, None], u[:, None], tt)
    thd, thdd, tau, grav = actuated_profile(robot, xa + ss * d, vv * d, uu * d)
    if (np.abs(grav) >= target * limits.torque).any():
        return math.inf  # gravity alone exceeds the limit somewhere on the line
    dt = tt[1] - tt[0]
    jerk = np.abs(np.diff(thdd, axis=1)).max() / dt
    a = max(float(stretch_factors(thd, thdd, tau, grav, limits, target).max()),
            (jerk / (target * limits.jerk)) ** (1.0 / 3.0))
    # torque rate: the gravity part scales 1/a, the rest 1/a^3; solve by bisection
    rg = np.abs(np.diff(grav, axis=1)) / dt
    ri = np.abs(np.diff(tau - grav, axis=1)) / dt

    def rate_ok(a: float) -> bool:
        return bool((rg / a + ri / a**3).max() <= target * limits.torque_rate)

    if not rate_ok(a):
        lo, hi = a, a
        while not rate_ok(hi):
            hi *= 1.5
            if hi > 1e3:
                return math.inf
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if rate_ok(mid) else (mid, hi)
        a = hi
    return a


def baseline_plan(problem: Problem, psi_wp: np.ndarray, step: float = NODE_STEP,
                  target: float = TARGET) -> tuple[Solution | None, str]:
    """(Solution or None, reason): the baseline plan of ``problem`` (a
    :class:`planner.problem.Problem`) with the crank angles ``psi_wp`` at its waypoints."""

    t_start = time.perf_counter()
    robot, lim, sr = problem.robot, problem.limits, problem.sr
    wp_x = problem.waypoint_states(psi_wp)
    width = 1.1 * 2.0 * lim.torque / lim.torque_rate
    ts, xs, xds, xdds, seg_T = [], [], [], [], []
    t0 = 0.0
    for k in range(len(wp_x) - 1):
        xa, xb = wp_x[k], wp_x[k + 1]
        d = xb - xa
        if np.abs(d).max() < 1e-9:  # the same state twice: hold it
            t = np.linspace(0.0, 0.02, 9)
            s = v = u = np.zeros_like(t)
        else:
            why = line_check(robot, lim, xa, xb)
            if why is not None:
                return None, f"segment {k}: {why}"
            line = xa + np.linspace(0.0, 1.0, 11)[:, None] * d
            try:
                traj = toppra_trajectory(robot, line, lim.tightened(
                    torque=0.97 * lim.torque, velocity=0.97 * lim.velocity,
                    acceleration=0.97 * lim.acceleration), gridpoints=100)
            except InfeasibleTaskError as exc:  # TOPP-RA found no parametrisation
                return None, f"segment {k}: {exc}"
            t, s, v, u = _smoothed_profile(traj, d, float(traj.duration), width, step)
            a = _stretch_needed(robot, lim, xa, d, t, s, v, u, target)
            if not math.isfinite(a):
                return None, f"segment {k}: no time scaling meets the limits on the line"
            a = max(a, 0.5)
            t, v, u = t * a, v / a, u / a**2
        ts.append(t0 + t[:-1] if k < len(wp_x) - 2 else t0 + t)
        xs.append((xa + s[:, None] * d)[: len(ts[-1])])
        xds.append((v[:, None] * d)[: len(ts[-1])])
        xdds.append((u[:, None] * d)[: len(ts[-1])])
        seg_T.append(float(t[-1]))
        t0 += float(t[-1])
    t, x, xd, xdd = np.concatenate(ts), np.vstack(xs), np.vstack(xds), np.vstack(xdds)
    n = len(t)
    tau = actuated_profile(robot, x, xd, xdd)[2].T
    theta = np.array(sr.theta.map(n)(x.T)).T
    sol = Solution(status="baseline (stop at every waypoint, TOPP-RA per segment)",
                   final_time=float(t[-1]), solve_time=0.0, iterations=0,
                   segment_times=np.array(seg_T), t=t, x=x, xd=xd, xdd=xdd, tau=tau,
                   theta=theta, residuals={}, active_limits=(), robot=robot, limits=lim,
                   options=problem.options, task=problem.task, solves=0, source="baseline")
    sol = sol.checked(factor=4)
    sol = sol.replace(solve_time=time.perf_counter() - t_start)
    assert sol.check is not None
    if not sol.check.ok:
        return None, "the baseline fails its dense check: " + "; ".join(sol.check.violations)
    return sol, ""
