"""Jerk-limited resampling of a plan at the controller rate with Ruckig.

1. The plan is stretched uniformly in time by the smallest factor that makes its
   duration a whole number of controller periods (at most one period longer; a uniform
   stretch keeps the path and scales rates by 1/a and accelerations by 1/a^2).
2. Knots: the stretched plan sampled at every period, (theta, theta_dot, theta_ddot) in
   actuated-joint space.
3. Ruckig joins consecutive knots, segment by segment, with the limits planned to
   (velocity, acceleration, and the robot's **jerk** limit), ``minimum_duration`` = one
   period.  A segment whose jerk (or other) limit cannot be met in one period is
   stretched by Ruckig, which delays everything after it; the output is then resampled
   on the uniform grid and, once the motion has come to rest, held until the next
   grid point.  ``intermediate_positions`` is never set (it calls a cloud service,
   LIBRARY-NOTES).

Why knots on the output grid: between the OCP's nodes (3-5 ms apart) Ruckig's own
jerk-limited profile departs from the plan's accelerations by up to ~100 rad/s^2, and
the re-check then found 13 to 59 N m instead of the plan's 9.8 N m (measured on the
demo task): the controller must receive the validated plan, not a reinterpolation of
it.  The result is always re-validated with the full dynamics before anything is
written (:mod:`sixplus3.control.validation`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Trajectory

from sixplus3.control.validation import RATE_RANGE, hermite
from sixplus3.errors import SmoothingError
from sixplus3.planner.ocp import Solution


@dataclass(frozen=True)
class Smoothed:
    rate: float  # [Hz]
    t: np.ndarray  # (M,) [s], exactly k / rate
    theta: np.ndarray  # (M, 9) [rad]
    theta_dot: np.ndarray  # (M, 9) [rad/s]
    theta_ddot: np.ndarray  # (M, 9) [rad/s^2]
    x_guess: np.ndarray  # (M, 9) the plan's minimal coordinates near each sample
    planned_duration: float  # [s] the plan's, plus its dwells
    duration: float  # [s] of the output (a whole number of periods)
    stretched_segments: int  # Ruckig segments longer than one period
    smoothed_segments: int  # segments Ruckig recomputed (the plan's jerk above the limit)
    jerk_limit: float  # [rad/s^3] the limit Ruckig enforced (the robot's)
    max_jerk: float  # [rad/s^3] the largest jerk of the output (differences of theta_ddot)
    max_deviation: float  # [rad] largest |theta_out - theta_plan| at the output samples

    @property
    def added_fraction(self) -> float:
        return self.duration / self.planned_duration - 1.0


def check_rate(rate: float) -> float:
    lo, hi = RATE_RANGE
    if not (isinstance(rate, (int, float)) and math.isfinite(rate) and lo <= rate <= hi):
        raise SmoothingError(f"controller rate must be in [{lo:g}, {hi:g}] Hz, got {rate!r}",
                             value=rate, valid=f"[{lo:g}, {hi:g}] Hz")
    return float(rate)


def _joint_samples(sol: Solution, times: np.ndarray, a: float, t0: float = 0.0):
    """Actuated (theta, theta_dot, theta_ddot) and x of the plan's piece starting at plan
    time ``t0``, stretched by ``a``, at piece-local output times ``times`` [s]."""
    sr = sol.robot.symbolic()
    x, xd, xdd = sol.sample(t0 + times / a)
    xd, xdd = xd / a, xdd / a**2
    n = len(times)
    th = np.array(sr.theta.map(n)(x.T)).T
    thd = np.array(sr.theta_dot.map(n)(x.T, xd.T)).T
    thdd = np.array(sr.theta_ddot.map(n)(x.T, xd.T, xdd.T)).T
    return th, thd, thdd, x


def rest_pieces(sol: Solution) -> list[tuple[float, float, float]]:
    """(start, end, dwell after it) [s] of the plan's rest-to-rest pieces: the motion is
    split at every waypoint where it stops (``stop`` or ``dwell``)."""
    times = np.concatenate([[0.0], np.cumsum(sol.segment_times)])
    wps = sol.task.waypoints if sol.task is not None else ()
    cuts = [0] + [w for w in range(1, len(times) - 1) if wps and wps[w].stop] + [
        len(times) - 1]
    return [(float(times[a]), float(times[b]), float(wps[b].dwell) if wps else 0.0)
            for a, b in zip(cuts[:-1], cuts[1:], strict=True)]


def smooth(sol: Solution, rate: float = 1000.0) -> Smoothed:
    """Resample ``sol`` at ``rate`` [Hz] on a uniform grid, jerk-limited by the robot's
    jerk limit (``sol.limits.jerk``), with velocity and acceleration limits planned to.

    A plan that stops at waypoints is smoothed piece by piece (each rest to rest, each a
    whole number of periods, so every stop lands on a sample), with each waypoint's
    dwell held at rest in between.
    """
    rate = check_rate(rate)
    dt = 1.0 / rate
    parts = []
    pieces = rest_pieces(sol)
    for k, (t0, t1, dwell) in enumerate(pieces):
        p = _smooth_piece(sol, t0, t1, rate)
        if k > 0:  # the previous piece's last sample is this one's first (both at rest)
            p = {key: (v[1:] if isinstance(v, np.ndarray) else v) for key, v in p.items()}
        parts.append(p)
        hold = round(dwell * rate)
        if hold > 0:
            last_th, last_x = p["theta"][-1], p["x_guess"][-1]
            z = np.zeros((hold, 9))
            parts.append({"theta": np.tile(last_th, (hold, 1)), "theta_dot": z,
                          "theta_ddot": z, "x_guess": np.tile(last_x, (hold, 1)),
                          "stretched": 0, "smoothed": 0, "deviation": 0.0})
    cat = {key: np.concatenate([p[key] for p in parts])
           for key in ("theta", "theta_dot", "theta_ddot", "x_guess")}
    t = np.arange(len(cat["theta"])) / rate
    jerk = np.abs(np.diff(cat["theta_ddot"], axis=0)).max() / dt if len(t) > 1 else 0.0
    return Smoothed(rate, t, cat["theta"], cat["theta_dot"], cat["theta_ddot"],
                    cat["x_guess"], float(sol.final_time) + sum(d for *_, d in pieces),
                    float(t[-1]),
                    sum(p["stretched"] for p in parts), sum(p["smoothed"] for p in parts),
                    sol.limits.jerk, float(jerk), max(p["deviation"] for p in parts))


def _smooth_piece(sol: Solution, t0: float, t1: float, rate: float) -> dict:
    """One rest-to-rest piece [t0, t1] of the plan at ``rate`` (see the module doc)."""
    lim = sol.limits
    dt = 1.0 / rate
    T = float(t1 - t0)
    periods = max(1, math.ceil(T * rate - 1e-9))
    a = periods * dt / T  # >= 1: a whole number of periods
    kt = np.arange(periods + 1) / rate
    th, thd, thdd, xk = _joint_samples(sol, kt, a, t0)
    thd[[0, -1]] = 0.0  # at rest, exactly (the NLP's bounds hold them at 0 to rounding)
    thdd[[0, -1]] = 0.0
    otg = Ruckig(9)
    # Ruckig only if the plan needs it: some segment whose jerk (the change of the knots'
    # accelerations over one period) is above the robot's jerk limit.  Otherwise the plan
    # is already a jerk-limited motion through its knots, and a synchronised Ruckig
    # profile near the acceleration limit would only stretch it (measured: 35 of 5590
    # segments of a slow task stretched, and the output then left the limits).  If one
    # segment needs it, every segment goes through Ruckig, so that the whole output is
    # one jerk-limited profile.
    need = np.abs(np.diff(thdd, axis=0)).max(axis=1) > lim.jerk * dt
    need[:] = need.any()
    segments: list[Trajectory | None] = []
    durations, stretched, smoothed = [], 0, int(need.sum())  # 0 or all
    for k in range(periods):
        if not need[k]:
            segments.append(None)
            durations.append(dt)
            continue
        inp = InputParameter(9)
        inp.current_position, inp.current_velocity = th[k].tolist(), thd[k].tolist()
        inp.current_acceleration = thdd[k].tolist()
        inp.target_position, inp.target_velocity = th[k + 1].tolist(), thd[k + 1].tolist()
        inp.target_acceleration = thdd[k + 1].tolist()
        inp.max_velocity = [lim.velocity] * 9
        inp.max_acceleration = [lim.acceleration] * 9
        inp.max_jerk = [lim.jerk] * 9
        inp.minimum_duration = dt
        traj = Trajectory(9)
        res = otg.calculate(inp, traj)
        if res not in (Result.Working, Result.Finished):
            raise SmoothingError(f"Ruckig failed on segment {k} ({res}): the plan's knots "
                                 "violate the velocity or acceleration limits",
                                 value=str(res), valid="Result.Working or Result.Finished")
        if traj.duration > dt * (1 + 1e-9):
            stretched += 1
        segments.append(traj)
        durations.append(traj.duration)
    if stretched == 0:
        # every segment took exactly one period: the output is the knots themselves
        t, out_th, out_thd, out_thdd, x_guess = kt, th, thd, thdd, xk
        deviation = 0.0
    else:
        starts = np.concatenate([[0.0], np.cumsum(durations)])
        total = float(starts[-1])
        m = math.ceil(total * rate - 1e-9)
        t = np.arange(m + 1) / rate
        seg = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, periods - 1)
        out = np.zeros((3, len(t), 9))
        for i, (tt, s) in enumerate(zip(t, seg, strict=True)):
            if tt >= total:  # at rest after the end: hold the final state
                out[0, i], out[1, i], out[2, i] = th[-1], 0.0, 0.0
                continue
            seg_k = segments[s]
            if seg_k is None:  # the plan's own segment: its knot, or the cubic between
                p, v, acc = _plan_between(th, thd, thdd, s, float(tt - starts[s]), dt)
            else:
                p, v, acc = seg_k.at_time(float(tt - starts[s]))
            out[:, i] = p, v, acc
        out_th, out_thd, out_thdd = out
        # plan time of each output sample: its knot index plus the fraction of its segment
        frac = np.clip((t - starts[seg]) / np.asarray(durations)[seg], 0.0, 1.0)
        plan_t = np.minimum((seg + frac) * dt, kt[-1])
        ref, _, _, x_guess = _joint_samples(sol, plan_t, a, t0)
        deviation = float(np.abs(out_th - ref).max())
    return {"theta": out_th, "theta_dot": out_thd, "theta_ddot": out_thdd,
            "x_guess": x_guess, "stretched": stretched, "smoothed": smoothed,
            "deviation": deviation}


def _plan_between(th, thd, thdd, k: int, s: float, dt: float):
    """The plan between knots k and k+1, s [s] after knot k: the quintic Hermite
    interpolant of both knots' (theta, theta_dot, theta_ddot), the same interpolant the
    validator checks between samples."""
    p, v, a = hermite(dt, th, thd, thdd, np.array([k]), np.array([s / dt]))
    return p[0], v[0], a[0]
