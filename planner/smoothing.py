"""Jerk-limited resampling of a plan at the controller rate, certified with Ruckig.

Per rest-to-rest piece of the plan (the whole plan, or the pieces between its stops):

1. The piece is stretched uniformly in time by the smallest factor that makes it a whole
   number of controller periods **and** keeps its jerk, acceleration and speed (sampled
   4x finer than the output) within the limits (a uniform stretch by a keeps the path and scales
   rates by 1/a, accelerations by 1/a^2 and jerk by 1/a^3: every limit only gets
   easier, the torques move towards the holding torque).
2. Knots: the stretched plan sampled at every period, (theta, theta_dot, theta_ddot) in
   actuated-joint space.  They are the output.
3. Ruckig checks every knot-to-knot transition: a profile within the velocity,
   acceleration and jerk limits that takes exactly one period (``minimum_duration``),
   or, where Ruckig refuses a tiny move numerically, the constant-jerk cubic through
   both knots.  The count of transitions it cannot certify in one period is reported
   (``Smoothed.stretched_segments``, in the file's header); it does not change the
   output: time-synchronising nine joints, Ruckig sometimes needs 1.1 periods where
   the plan itself (jerk-checked on a 4x grid) takes one.  The gate re-checks the jerk.
   ``intermediate_positions`` is never set (it calls a cloud service, docs/libraries.md).

Why not let Ruckig reshape segments: joining the knots with Ruckig's own profiles,
segment by segment, departs from the plan (accelerations up to ~100 rad/s^2 off between
the OCP's nodes; 13 to 59 N m instead of 9.8 N m on the demo task), and stretching single
segments with exact knot targets gave motions 5-60x longer that failed validation
(torque 31-94 N m, measured on a small task with the jerk limit at 0.5-0.9x the plan's).
The planner bounds the jerk itself (docs/planner.md), so the stretch is 1 unless the
limits were tightened after planning.  The result is always re-validated with the full
dynamics before anything is written (:mod:`sixplus3.control.gate.validation`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from ruckig import InputParameter, Result, Ruckig, RuckigError, Trajectory

from sixplus3.dynamics.symbolic import symbolic_robot
from sixplus3.errors import InputError, SmoothingError
from sixplus3.motion import HasMotion, Motion, check_rate, check_samples
from sixplus3.planner.solution import Solution, actuated_profile


@dataclass(frozen=True)
class Smoothed(HasMotion):
    #: the samples at t = k / rate (read-only; :class:`~sixplus3.motion.Motion`)
    motion: Motion
    x_guess: np.ndarray  # (M, 9) the plan's minimal coordinates near each sample
    planned_duration: float  # [s] the plan's, plus its dwells
    duration: float  # [s] of the output (a whole number of periods)
    stretched_segments: int  # transitions Ruckig could not certify in one period
    smoothed_segments: int  # knot-to-knot transitions certified by Ruckig
    jerk_limit: float  # [rad/s^3] the limit Ruckig enforced (the robot's)
    max_jerk: float  # [rad/s^3] the largest jerk of the output (differences of theta_ddot)
    max_deviation: float  # [rad] largest |theta_out - theta_plan| at the output samples
    #: largest uniform time stretch of a piece (>= 1; whole-period rounding included)
    time_stretch: float = 1.0

    @property
    def added_fraction(self) -> float:
        return self.duration / self.planned_duration - 1.0

    def header(self) -> dict[str, Any]:
        """The trajectory file's ``smoothing`` header field."""
        return {"rate_hz": self.rate, "planned_duration_s": self.planned_duration,
                "duration_s": self.duration, "added_fraction": self.added_fraction,
                "time_stretch": self.time_stretch,
                "certified_transitions": self.smoothed_segments,
                "jerk_limit_rad_s3": self.jerk_limit, "max_jerk_rad_s3": self.max_jerk,
                "max_deviation_rad": self.max_deviation}


def _joint_samples(sol: Solution, times: np.ndarray, a: float, t0: float = 0.0
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Actuated (theta, theta_dot, theta_ddot) and x of the plan's piece starting at plan
    time ``t0``, stretched by ``a``, at piece-local output times ``times`` [s]."""
    sr = symbolic_robot(sol.robot)
    x, xd, xdd = sol.sample(t0 + times / a)
    xd, xdd = xd / a, xdd / a**2
    n = len(times)
    th = np.array(sr.theta.map(n)(x.T)).T
    thd, thdd, _, _ = (v.T for v in actuated_profile(sol.robot, x, xd, xdd))
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
    if not isinstance(sol, Solution):
        raise InputError("smooth needs a planner Solution (sixplus3.plan)",
                         value=type(sol).__name__, valid="a Solution")
    rate = check_rate(rate)
    dt = 1.0 / rate
    parts = []
    pieces = rest_pieces(sol)
    # every sample the plan will make, estimated before any is (a 1 % stretch included)
    check_samples(sum(1.01 * (t1 - t0) + dwell for t0, t1, dwell in pieces), rate,
                  "the plan" if sol.task is None else f"the plan '{sol.task.name}'")
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
                          "stretched": 0, "smoothed": 0, "deviation": 0.0,
                          "time_stretch": 1.0})
    cat = {key: np.concatenate([p[key] for p in parts])
           for key in ("theta", "theta_dot", "theta_ddot", "x_guess")}
    t = np.arange(len(cat["theta"])) / rate
    jerk = np.abs(np.diff(cat["theta_ddot"], axis=0)).max() / dt if len(t) > 1 else 0.0
    return Smoothed(Motion(t, cat["theta"], cat["theta_dot"], cat["theta_ddot"], rate),
                    cat["x_guess"], float(sol.final_time) + sum(d for *_, d in pieces),
                    float(t[-1]),
                    sum(p["stretched"] for p in parts), sum(p["smoothed"] for p in parts),
                    sol.limits.jerk, float(jerk), max(p["deviation"] for p in parts),
                    max(p["time_stretch"] for p in parts))


def _smooth_piece(sol: Solution, t0: float, t1: float, rate: float) -> dict[str, Any]:
    """One rest-to-rest piece [t0, t1] of the plan at ``rate`` (see the module doc).

    The piece is stretched uniformly (jerk scales as 1/a^3, acceleration 1/a^2, speed
    1/a, so every limit only gets easier) by the smallest factor that makes it a whole
    number of periods with its jerk, acceleration and speed (on a 4x grid) within the
    limits; then Ruckig checks every knot-to-knot transition as a jerk-, acceleration-
    and velocity-limited profile of one period, and the transitions it cannot certify are counted.
    """
    lim = sol.limits
    dt = 1.0 / rate
    T = float(t1 - t0)
    stretch = 1.0  # requested uniform stretch beyond the whole-period rounding
    otg = Ruckig(9)
    for _ in range(6):  # the cube-root step converges in one or two rounds
        periods = max(1, math.ceil(T * stretch * rate - 1e-9))
        a = periods * dt / T  # >= stretch: a whole number of periods
        # the plan on a 4x grid: the jerk inside the periods, not only between knots;
        # the knots (the output) are every 4th point
        fine = np.arange(4 * periods + 1) / (4 * rate)
        th_f, thd_f, thdd_f, x_f = _joint_samples(sol, fine, a, t0)
        jerk = np.abs(np.diff(thdd_f, axis=0)).max() * 4 * rate
        th, thd, thdd, xk = th_f[::4], thd_f[::4].copy(), thdd_f[::4].copy(), x_f[::4]
        thd[[0, -1]] = 0.0  # at rest, exactly (the NLP's bounds hold them at 0)
        thdd[[0, -1]] = 0.0
        # between its nodes the plan's interpolation can overshoot the node bounds
        # slightly: the stretch covers speed (1/a) and acceleration (1/a^2) too
        need = max(jerk / lim.jerk, 0.0) ** (1.0 / 3.0)
        need = max(need, np.abs(thd_f).max() / lim.velocity,
                   math.sqrt(np.abs(thdd_f).max() / lim.acceleration))
        if need > 1.0:
            stretch = a * need * (1.0 + 1e-3)
            continue
        late = 0
        for k in range(periods):
            inp = InputParameter(9)
            inp.current_position, inp.current_velocity = th[k].tolist(), thd[k].tolist()
            inp.current_acceleration = thdd[k].tolist()
            inp.target_position = th[k + 1].tolist()
            inp.target_velocity = thd[k + 1].tolist()
            inp.target_acceleration = thdd[k + 1].tolist()
            inp.max_velocity = [lim.velocity] * 9
            inp.max_acceleration = [lim.acceleration] * 9
            inp.max_jerk = [lim.jerk] * 9
            inp.minimum_duration = dt
            traj = Trajectory(9)
            try:
                res = otg.calculate(inp, traj)
            except RuckigError:
                # Ruckig refuses some tiny moves (~1e-8 rad) in its first step; such a
                # transition is certified by the constant-jerk cubic through both knots
                if not _constant_jerk_fits(th[k:k + 2], thd[k:k + 2], thdd[k:k + 2], dt,
                                           lim.jerk):
                    late += 1
                continue
            if res not in (Result.Working, Result.Finished) or traj.duration > dt * (
                    1 + 1e-9):
                late += 1
        return {"theta": th, "theta_dot": thd, "theta_ddot": thdd, "x_guess": xk,
                "stretched": late, "smoothed": periods - late, "deviation": 0.0,
                "time_stretch": a}
    raise SmoothingError(
        f"no uniform stretch up to {stretch:.2f}x makes the piece [{t0:.4f}, {t1:.4f}] s "
        "a jerk-limited motion at the controller rate", value=stretch,
        valid=f"jerk <= {lim.jerk:g} rad/s^3 between samples")


def _constant_jerk_fits(th: np.ndarray, thd: np.ndarray, thdd: np.ndarray, dt: float,
                        jerk: float) -> bool:
    """Whether one constant jerk within ``jerk`` joins the two knots (rows 0 and 1) in
    one period: theta_ddot linear, theta_dot quadratic and theta cubic, matched to 1e-9
    (relative) at the second knot."""
    j = (thdd[1] - thdd[0]) / dt
    v = thd[0] + thdd[0] * dt + j * dt**2 / 2
    p = th[0] + thd[0] * dt + thdd[0] * dt**2 / 2 + j * dt**3 / 6
    return bool(np.all(np.abs(j) <= jerk)
                and np.all(np.abs(v - thd[1]) <= 1e-9 * (1 + np.abs(thd[1]))
                           + 1e-3 * jerk * dt**2)
                and np.all(np.abs(p - th[1]) <= 1e-12 + 1e-3 * jerk * dt**3))

