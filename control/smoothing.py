"""Jerk-limited resampling of a plan at the controller rate with Ruckig.

Segment by segment in actuated-joint space: the knots are the exact plan sampled on the
controller's grid (every 1 / rate and at the end); each segment starts at a knot's
(theta, theta_dot, theta_ddot) and targets the next knot's, with ``minimum_duration`` =
the time between them; Ruckig stretches a segment whose velocity, acceleration or jerk
limits cannot be met in that time, which delays everything after it.  Why knots on the
output grid: between the OCP's nodes (3-5 ms apart) Ruckig's own jerk-limited profile
departs from the plan's accelerations by up to ~100 rad/s^2, and the re-check then found
13 to 59 N m instead of the plan's 9.8 N m (measured on the demo task, the platform
margin being 0.08 to 0.25 there): the controller must receive the validated plan, not
a reinterpolation of it.  ``intermediate_positions`` is never set (it calls a cloud
service, LIBRARY-NOTES.md).  The result is sampled on a uniform grid at ``rate`` Hz.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Trajectory

from sixplus3.errors import SmoothingError
from sixplus3.planner.ocp import Solution


@dataclass(frozen=True)
class Smoothed:
    rate: float  # [Hz]
    t: np.ndarray  # (M,) [s]
    theta: np.ndarray  # (M, 9) [rad]
    theta_dot: np.ndarray  # (M, 9) [rad/s]
    theta_ddot: np.ndarray  # (M, 9) [rad/s^2]
    planned_duration: float  # [s]
    duration: float  # [s] after smoothing
    stretched_segments: int
    max_jerk: float  # [rad/s^3] the jerk limit used

    @property
    def added_fraction(self) -> float:
        return self.duration / self.planned_duration - 1.0


def knots(sol: Solution, rate: float):
    """Knots on the controller's grid: times k / rate and the end, with the exact plan's
    (theta, theta_dot, theta_ddot) there (from its piecewise-cubic motion)."""
    sr = sol.robot.symbolic()
    t = np.arange(0.0, sol.t[-1], 1.0 / rate)
    if sol.t[-1] - t[-1] > 1e-12:
        t = np.r_[t, sol.t[-1]]
    x, xd, xdd = sol.sample(t)
    n = len(t)
    th = np.array(sr.theta.map(n)(x.T)).T
    thd = np.array(sr.theta_dot.map(n)(x.T, xd.T)).T
    thdd = np.array(sr.theta_ddot.map(n)(x.T, xd.T, xdd.T)).T
    return t, th, thd, thdd


def plan_jerk(t: np.ndarray, thdd: np.ndarray) -> float:
    """Largest actuated jerk of the plan (finite differences of theta_ddot at the knots)."""
    return float(np.max(np.abs(np.diff(thdd, axis=0)) / np.diff(t)[:, None]))


def smooth(sol: Solution, rate: float = 1000.0, jerk_factor: float = 1.5,
           max_jerk: float | None = None) -> Smoothed:
    """Resample ``sol`` at ``rate`` [Hz], segment by segment between knots on the
    controller's grid; jerk limit = ``jerk_factor`` x the plan's largest jerk."""
    if not (rate > 0 and np.isfinite(rate)):
        raise SmoothingError(f"rate must be a positive number of Hz, got {rate}")
    lim = sol.limits
    kt, th, thd, thdd = knots(sol, rate)
    n = len(kt)
    jerk = max_jerk if max_jerk is not None else jerk_factor * plan_jerk(kt, thdd)
    otg = Ruckig(9)
    segments, durations, stretched = [], [], 0
    for k in range(n - 1):
        inp = InputParameter(9)
        inp.current_position, inp.current_velocity = th[k].tolist(), thd[k].tolist()
        inp.current_acceleration = thdd[k].tolist()
        inp.target_position, inp.target_velocity = th[k + 1].tolist(), thd[k + 1].tolist()
        inp.target_acceleration = thdd[k + 1].tolist()
        inp.max_velocity = [lim.velocity] * 9
        inp.max_acceleration = [lim.acceleration] * 9
        inp.max_jerk = [jerk] * 9
        h = float(kt[k + 1] - kt[k])
        inp.minimum_duration = h
        traj = Trajectory(9)
        res = otg.calculate(inp, traj)
        if res not in (Result.Working, Result.Finished):
            raise SmoothingError(f"Ruckig failed on segment {k} ({res}); the plan's knots "
                                 "violate the velocity/acceleration limits")
        if traj.duration > h * (1 + 1e-9):
            stretched += 1
        segments.append(traj)
        durations.append(traj.duration)
    starts = np.concatenate([[0.0], np.cumsum(durations)])
    total = float(starts[-1])
    t = np.arange(0.0, total + 0.5 / rate, 1.0 / rate)
    t[-1] = min(t[-1], total)
    seg = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(segments) - 1)
    out = np.zeros((3, len(t), 9))
    for i, (tt, s) in enumerate(zip(t, seg, strict=True)):
        p, v, a = segments[s].at_time(float(tt - starts[s]))
        out[:, i] = p, v, a
    if t[-1] < total - 1e-12:  # the last sample lands exactly on the end, at rest
        t = np.r_[t, total]
        out = np.concatenate([out, np.stack([th[-1], thd[-1], thdd[-1]])[:, None]], axis=1)
    return Smoothed(rate, t, out[0], out[1], out[2], float(sol.final_time), total, stretched,
                    jerk)
