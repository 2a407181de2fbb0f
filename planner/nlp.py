"""One NLP solve: a start, the bounds of this solve, IPOPT, and the checked plan.

:class:`Bounds` is what the strategy tightens between solves (the safety fractions of
the limits, the platform margin's proxy, the reserves below the spherical joints' limit
and above contact, the homotopy's margin, the cap on the total duration).
:func:`solve_nlp` makes one solve of :mod:`sixplus3.planner.transcription`'s NLP with
those bounds and returns a :class:`Solution` with its dense re-check, or raises
:class:`InfeasibleTaskError` whose ``limit`` starts with "solver".
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from sixplus3.errors import InfeasibleTaskError
from sixplus3.planner.pfl import pfl_parameters, pfl_points, pfl_ratio_max
from sixplus3.planner.problem import Problem
from sixplus3.planner.solution import Solution, actuated_profile, sample_cubic, stretch_factors
from sixplus3.planner.solvers import ipopt_solver, keyboard_interrupts
from sixplus3.planner.tcp_rows import tcp_rates_at
from sixplus3.planner.transcription import (
    CLEARANCE_ROWS,
    NODE_ROWS,
    node_bounds,
    type2_det_bound,
    variable_bounds,
    variable_scale,
)
from sixplus3.robot_description.limits import Limits

#: limits that a uniform time stretch lowers; the NLP bounds each at a share of its limit
RATE_LIMITS = ("torque", "velocity", "acceleration")
#: the share of the tool centre point's speed and acceleration limits that the NLP's
#: rows allow at its points (the dense check sees between them; :func:`strategy.finish`
#: stretches what little it finds over)
TCP_SAFETY = 0.98


def uniform_safety(value: float) -> dict[str, float]:
    """The same share ``value`` of every limit in :data:`RATE_LIMITS`."""
    return dict.fromkeys(RATE_LIMITS, value)


@dataclass(frozen=True)
class Bounds:
    """The bounds of one NLP solve that the strategy tightens between solves."""

    #: bound of the torque, velocity and acceleration rows, as a share of their limit
    safety: dict[str, float] = field(default_factory=lambda: uniform_safety(0.98))
    #: lower bound of the platform's line determinant (the proxy of its margin)
    platform_proxy: float = 0.5
    #: [rad] below the spherical joints' limit
    spherical_reserve: float = 0.0
    #: [m] of clearance asked between the bodies (None: those rows unbounded)
    clearance: float | None = None
    #: [m] asked at the waypoints' nodes instead (None: ``clearance``): a waypoint's
    #: pose is given, and near contact it may not have the reserve asked elsewhere
    clearance_waypoints: float | None = None
    #: the singularity margin of the rows (None: the task's; a homotopy step)
    margin: float | None = None
    #: upper bound [s] of the total duration (None: 60 s per segment)
    duration_cap: float | None = None
    #: (lo, hi) (3,) [rad] of the crank angles (None: :meth:`Problem.crank_range`)
    cranks: tuple[np.ndarray, np.ndarray] | None = None

    def replace(self, **changes: Any) -> Bounds:
        return replace(self, **changes)


def point_bounds(problem: Problem, x0: np.ndarray, lim: Limits, bounds: Bounds
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(lb, ub) of one point's path rows (:func:`transcription.node_bounds`) for the
    start ``x0`` (N+1, 9) on the nodes: each margin row keeps the side of zero its
    median over the start has (a margin keeps its sign inside a free region)."""
    m1, m2, _ = problem.sr.margins.map(len(x0))(x0.T)
    sign1 = np.sign(np.median(np.array(m1), axis=1))
    sign2 = np.sign(np.median(np.array(m2), axis=1))
    return node_bounds(lim, sign1, sign2, bounds.platform_proxy, bounds.safety["velocity"],
                       bounds.spherical_reserve, bounds.clearance)


def start_point(problem: Problem, psi_wp: np.ndarray, bounds: Bounds,
                warm: Solution | None = None, time_scale: float = 1.0,
                duration: float | None = None) -> tuple[Any, ...]:
    """(waypoints' x, x, xd, xdd on the nodes, segment durations, (x, xd, xdd) at the
    nodes then the midpoints, the actuated profile there) of a solve's start: the
    kinematic guess stretched by ``time_scale``, or ``warm``'s motion (slowed inside the
    bounds' safety share when it is a plan without an NLP point, e.g. the baseline)."""
    safety = bounds.safety
    wp_x, x0, xd0, xdd0, T0 = problem.guess(psi_wp)
    if time_scale != 1.0:
        T0, xd0, xdd0 = T0 * time_scale, xd0 / time_scale, xdd0 / time_scale**2
    if warm is not None:
        x0, xd0, xdd0, T0 = problem.on_nodes(warm)
    # the start at the nodes and the midpoints (the NLP's points), with its theta_dot,
    # theta_ddot, torques and gravity torques from the model
    t0 = problem.node_times(T0)
    xm, xdm, um = sample_cubic(t0, x0, xd0, xdd0, (t0[:-1] + t0[1:]) / 2)
    pts = (np.r_[x0, xm], np.r_[xd0, xdm], np.r_[xdd0, um])
    profile = actuated_profile(problem.robot, *pts)
    if warm is not None and warm.nlp_point is None and duration is None:
        # a plan at 99.5% of its limits (the baseline, a stretched plan) exceeds this
        # NLP's bounds (safety x limit): slowed uniformly to just inside them, so the
        # start is not clipped into violating the dynamics rows (the clipped baseline
        # started IPOPT with theta_ddot and torque residuals of 3-13 units and sent some
        # solves astray, BENCHMARKS.md)
        a = float(stretch_factors(*profile, problem.limits,
                                  0.99 * min(safety.values())).max())
        if 1.0 < a < 2.0:
            T0, xd0, xdd0 = T0 * a, xd0 / a, xdd0 / a**2
            pts = (pts[0], pts[1] / a, pts[2] / a**2)  # the same cubics, slower
            profile = actuated_profile(problem.robot, *pts)
    if problem.motion_limits.has_tcp and duration is None and (
            warm is None or warm.nlp_point is None):
        # a start over the platform-space limits (the guess, a plan timed to the joint
        # limits) slowed uniformly to just inside the rows
        a = tcp_stretch(problem, *pts, 0.99 * TCP_SAFETY)
        if a > 1.0:
            T0, xd0, xdd0 = T0 * a, xd0 / a, xdd0 / a**2
            pts = (pts[0], pts[1] / a, pts[2] / a**2)
            profile = actuated_profile(problem.robot, *pts)
    if problem.pfl and duration is None and (warm is None or warm.nlp_point is None):
        # likewise inside the power and force limiting rows (v^T C v goes as 1/a^2)
        worst = pfl_ratio_max(problem.robot, pts[0], pts[1], problem.pfl, problem.pfl_links)
        a = math.sqrt(worst / (0.99 * problem.options.pfl_share))
        if a > 1.0:
            T0, xd0, xdd0 = T0 * a, xd0 / a, xdd0 / a**2
            pts = (pts[0], pts[1] / a, pts[2] / a**2)
            profile = actuated_profile(problem.robot, *pts)
    return wp_x, x0, xd0, xdd0, T0, pts, profile


def tcp_stretch(problem: Problem, x: np.ndarray, xd: np.ndarray, xdd: np.ndarray,
                fraction: float, at_least: float = 1.0) -> float:
    """The uniform time stretch (at least ``at_least``; < 1 compresses) that brings the
    tool centre point's speed and acceleration at the states (n, 9) to ``fraction`` of
    the task's platform-space limits (speed scales 1/a, acceleration 1/a^2)."""
    lim = problem.motion_limits
    v, acc = tcp_rates_at(problem.robot.tool.xyz, x, xd, xdd)
    return max(at_least, float(v.max()) / (fraction * lim.tcp_speed),
               math.sqrt(float(acc.max()) / (fraction * lim.tcp_acceleration)))


def solve_nlp(problem: Problem, psi_wp: np.ndarray, bounds: Bounds,
              warm: Solution | None = None, time_scale: float = 1.0,
              duration: float | None = None, max_iter: int | None = None) -> Solution:
    """One NLP solve from the kinematic guess (stretched by ``time_scale``) or from
    ``warm`` (a plan of this task: its primal-dual point if it has one, else its motion
    on this NLP's nodes); ``duration`` fixes the total duration (minimum effort);
    ``max_iter`` stops the solve earlier than ``options.max_iter`` (a failed start)."""
    task, opt, sr = problem.task, problem.options, problem.sr
    lim = problem.limits if bounds.margin is None else replace(problem.limits,
                                                               margin=bounds.margin)
    safety = bounds.safety
    S, N = task.n_segments, problem.n_intervals
    wp_x, x0, xd0, xdd0, T0, pts, profile = start_point(problem, psi_wp, bounds, warm,
                                                         time_scale, duration)
    tmax = safety["torque"] * lim.torque
    lb, ub = point_bounds(problem, x0, lim, bounds)
    cap = bounds.duration_cap
    T_lo, T_hi = ((0.0, np.inf if cap is None else cap) if duration is None
                  else (duration, duration))
    lbx, ubx = variable_bounds(problem, wp_x, tmax, safety["acceleration"] * lim.acceleration,
                               T_hi, bounds.cranks)
    lbg, ubg, tcp_p, pfl_p = _row_bounds(problem, bounds, lb, ub, T_lo, T_hi, pts[0])
    _, acc0, tau0, _ = profile  # (9, 2N+1): the nodes, then the midpoints
    z0 = np.vstack([x0.T, xd0.T, xdd0.T, tau0[:, :N + 1]])
    w0 = np.clip(np.r_[z0.ravel(order="F"), tau0[:, N + 1:].ravel(order="F"),
                       acc0.ravel(order="F"), T0], lbx, ubx)
    if warm is not None and warm.nlp_point is not None:
        # a re-solve with tightened bounds: start IPOPT from the previous primal-dual
        # point (same variable scaling) with a small barrier parameter
        entry = ipopt_solver(problem, warm_start=True)
        ws, lam_x, lam_g, D = warm.nlp_point
        args: dict[str, Any] = {"x0": ws, "lam_x0": lam_x, "lam_g0": lam_g}
    else:
        entry = ipopt_solver(problem)
        D = variable_scale(N, S, tmax)
        args = {"x0": w0 / D}
    weights = (1.0, 0.0) if duration is None else (0.0, 1.0)
    args.update(p=np.r_[D, lim.jerk, lim.torque_rate, weights,
                        problem.interval_fractions(), tcp_p, pfl_p], lbx=lbx / D,
                ubx=ubx / D, lbg=lbg, ubg=ubg)
    res, status, iterations, solve_time, function_time = _run(problem, entry, args, D,
                                                               lbg, ubg, max_iter)
    w = np.array(res["x"]).ravel() * D
    Z = w[:36 * (N + 1)].reshape(N + 1, 36)
    x, xd, u, tau = Z[:, 0:9], Z[:, 9:18], Z[:, 18:27], Z[:, 27:36]
    Tv = w[-S:]
    if status not in ("Solve_Succeeded", "Solved_To_Acceptable_Level"):
        exc = InfeasibleTaskError(diagnose(problem, x, xd, u, status), None,
                                  "solver: " + status, value=status, valid="Solve_Succeeded")
        exc.nlp_work = (solve_time, iterations, function_time)  # counted by the strategy
        raise exc
    t = problem.node_times(Tv)
    nodes = problem.waypoint_nodes()
    residuals = {
        "dynamics": float(np.abs(
            np.array(sr.node.map(N + 1)(x.T, xd.T, u.T, tau.T))[0:9]).max()),
        "integration": float(np.abs(np.array(res["g"]).ravel()[:18 * N]).max()),
        "waypoints": float(max(np.abs(x[k, 0:6] - wp_x[w_, 0:6]).max()
                               for w_, k in enumerate(nodes))),
    }
    sol = Solution(status=status, final_time=float(Tv.sum()), solve_time=solve_time,
                   iterations=iterations, total_iterations=iterations,
                   function_time=function_time, segment_times=Tv, t=t, x=x,
                   xd=xd, xdd=u, tau=tau,
                   theta=np.array(sr.theta.map(N + 1)(x.T)).T, residuals=residuals,
                   active_limits=active_limits(problem, x, xd, u, tau, t, bounds),
                   robot=problem.robot, limits=problem.limits, options=opt, task=task,
                   nlp_point=(w / D, np.array(res["lam_x"]).ravel(),
                              np.array(res["lam_g"]).ravel(), D)).checked()
    assert sol.check is not None
    problem.stage(f"  {status}: {sol.iterations} iterations, {solve_time:.2f} s; motion "
                  f"{sol.final_time:.4f} s; dense re-check "
                  + ("ok" if sol.check.ok else "; ".join(sol.check.violations)))
    return sol


def _row_bounds(problem: Problem, bounds: Bounds, lb: np.ndarray, ub: np.ndarray,
                T_lo: float, T_hi: float, pose0: Any
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(lbg, ubg) of the NLP's rows in their order (the integration, the points' rows,
    the smoothness rows, the duration, the tcp rows, the PFL rows), and the tcp and PFL
    rows' parameters."""
    N = problem.n_intervals
    # smoothness rows (transcription.smoothness_rows): per limit, 2 x 9N rows in [-1, 1]
    smooth_lo, smooth_hi = np.full(36 * N, -1.0), np.full(36 * N, 1.0)
    lbg = np.r_[np.zeros(18 * N), np.tile(lb, 2 * N + 1), smooth_lo, T_lo]
    if bounds.clearance is not None and bounds.clearance_waypoints is not None:
        for k in problem.waypoint_nodes():  # the nodes' rows come first, point by point
            first = 18 * N + NODE_ROWS * k
            lbg[first + CLEARANCE_ROWS.start:first + CLEARANCE_ROWS.stop] = \
                bounds.clearance_waypoints
    ubg = np.r_[np.zeros(18 * N), np.tile(ub, 2 * N + 1), smooth_hi, T_hi]
    tcp_p = np.zeros(0)
    if problem.motion_limits.has_tcp:  # the rows of tcp_rows, last
        lbg = np.r_[lbg, np.full(2 * (2 * N + 1), -np.inf)]
        ubg = np.r_[ubg, np.full(2 * (2 * N + 1), TCP_SAFETY**2)]
        tcp_p = np.array([problem.motion_limits.tcp_speed**-2,
                          problem.motion_limits.tcp_acceleration**-2])
    pfl_p = np.zeros(0)
    if problem.pfl:  # the power and force limiting rows, after the tcp rows: each
        # point's C at the start's pose (the poses move little between solves; the gate
        # judges the smoothed file exactly, and the pipeline re-plans with a lower share)
        for point in pfl_points(problem.robot, problem.pfl_links):  # tcp, centre, legs
            c = pfl_parameters(problem.robot, pose0, problem.pfl, point)
            lbg = np.r_[lbg, np.full((2 * N + 1) * point.size, -np.inf)]
            ubg = np.r_[ubg, np.full((2 * N + 1) * point.size, problem.options.pfl_share)]
            pfl_p = np.r_[pfl_p, c.ravel()]
    return lbg, ubg, tcp_p, pfl_p


def _run(problem: Problem, entry: Any, args: dict[str, Any], D: np.ndarray,
         lbg: np.ndarray, ubg: np.ndarray, max_iter: int | None
         ) -> tuple[Any, str, int, float, float]:
    """IPOPT on ``args`` (the progress relayed, ``max_iter`` its cap): (the result, its
    status, iterations, the solve's wall time, the time in the NLP's functions)."""
    S = problem.task.n_segments
    with entry.lock:
        relay = entry.relay
        if problem.progress is not None:
            relay.listener = iteration_listener(problem, D[-S:], lbg, ubg)
        relay.count, relay.limit = 0, max_iter
        t_start = time.perf_counter()
        try:
            with keyboard_interrupts():
                res = entry.solver(**args)
        finally:
            relay.listener, relay.limit = None, None
        solve_time = time.perf_counter() - t_start
        stats = entry.solver.stats()
    status = str(stats.get("return_status", "unknown"))
    iterations = int(stats.get("iter_count", 0))
    function_time = float(sum(v for k, v in stats.items() if k.startswith("t_wall_nlp_")))
    if status == "User_Requested_Stop" and max_iter is not None:
        status = "Maximum_Iterations_Exceeded"  # the relay's cap (a start's)
    return res, status, iterations, solve_time, function_time


def iteration_listener(problem: Problem, d_time: np.ndarray, lbg: np.ndarray,
                       ubg: np.ndarray) -> Any:
    """The relay's listener for one solve: the iterate's duration (its last S scaled
    variables times their scale) and constraint violation, to ``problem.progress``."""
    progress = problem.progress
    assert progress is not None

    def listener(k: int, ws: np.ndarray, g: np.ndarray) -> None:
        duration = float(ws[-len(d_time):] @ d_time)
        violation = float(max(0.0, np.max(lbg - g), np.max(g - ubg)))
        progress.iteration(k, duration, violation)

    return listener


def active_limits(problem: Problem, x: np.ndarray, xd: np.ndarray, u: np.ndarray,
                  tau: np.ndarray, t: np.ndarray, bounds: Bounds) -> tuple[str, ...]:
    """Limits within 0.5% of their bound at some node, with the bounds of this solve."""
    sr, lim, safety = problem.sr, problem.limits, bounds.safety
    tmax = safety["torque"] * lim.torque
    vmax = safety["velocity"] * lim.velocity
    amax = safety["acceleration"] * lim.acceleration
    names = []
    n = len(t)
    thd, thdd, _, _ = (v.T for v in actuated_profile(problem.robot, x, xd, u))
    m1, m2, mp = (np.array(a) for a in sr.margins.map(n)(x.T))
    crank_lo, crank_hi = problem.crank_range() if bounds.cranks is None else bounds.cranks
    checks = [
        ("torque", np.abs(tau).max(axis=1) / tmax),
        ("velocity", np.abs(thd).max(axis=1) / vmax),
        ("acceleration", np.abs(thdd).max(axis=1) / amax),
        ("leg type I margin", lim.margin / np.abs(m1).min(axis=0)),
        ("leg type II margin", type2_det_bound(lim.margin) / np.abs(m2).min(axis=0)),
        ("platform margin", bounds.platform_proxy / mp.ravel()),
        ("crank angle range", np.maximum(crank_lo / x[:, 6:9], x[:, 6:9] / crank_hi)
         .max(axis=1)),
    ]
    if problem.motion_limits.has_tcp:
        v, acc = tcp_rates_at(problem.robot.tool.xyz, x, xd, u)
        checks += [("tcp speed", v / (TCP_SAFETY * problem.motion_limits.tcp_speed)),
                   ("tcp acceleration",
                    acc / (TCP_SAFETY * problem.motion_limits.tcp_acceleration))]
    for name, ratio in checks:
        hit = np.flatnonzero(ratio > 0.995)
        if len(hit):
            names.append(f"{name} ({len(hit)} of {n} nodes, first at t = "
                         f"{t[hit[0]]:.3f} s)")
    return tuple(names)


def diagnose(problem: Problem, x: np.ndarray, xd: np.ndarray, u: np.ndarray,
             status: str) -> str:
    """Name the limits most violated by the solver's last iterate."""
    sr, lim = problem.sr, problem.limits
    n = x.shape[0]
    tmax = problem.options.torque_safety * lim.torque
    thd, _, dyn_tau, _ = actuated_profile(problem.robot, x, xd, u)
    items = [
        ("torque", np.abs(dyn_tau).max(axis=0) / tmax - 1.0, f"{lim.torque:g} N m"),
        ("velocity", np.abs(thd).max(axis=0) / lim.velocity - 1.0,
         f"{lim.velocity:g} rad/s"),
    ]
    m1, m2, mp = (np.array(a) for a in sr.margins.map(n)(x.T))
    items.append(("singularity margin", lim.margin - np.minimum(np.abs(m1).min(axis=0),
                                                                 2 * np.abs(m2).min(axis=0) / 3),
                  f"{lim.margin:g}"))
    worst = sorted(((float(v.max()), name, int(np.argmax(v)), rng)
                    for name, v, rng in items), reverse=True)
    v, name, k, rng = worst[0]
    seg = int(problem.interval_segments()[min(k, n - 2)])
    how = (f"violated by {max(v, 0) * 100:.1f}% at the solver's last iterate"
           if v < 10 else "the solver's last iterate diverged there")
    return (f"planning failed ({status}): the {name} limit ({rng}) binds between "
            f"waypoints {seg} and {seg + 1} ({how}); lower the demand or move the "
            "waypoints")


__all__ = ["RATE_LIMITS", "TCP_SAFETY", "Bounds", "active_limits", "diagnose", "iteration_listener",
           "point_bounds", "solve_nlp", "start_point", "tcp_stretch", "uniform_safety"]
