"""Uniform re-timing of a plan: slower or faster along the same path.

Stretching time by a keeps the path (and every margin) and scales theta_dot by 1/a,
theta_ddot and the inertial torques by 1/a^2 exactly (:func:`stretched`).  The strategy
uses it to compress a checked plan up to its binding limit (:func:`retime`), to fix a
small overshoot between the NLP's points, and to meet what the dense check still finds
of the platform-space limits and of power and force limiting (:func:`tcp_limited`,
:func:`pfl_stretch`).  For those the planner also tries a re-timing along the path
(:func:`platform_limited`, :mod:`sixplus3.planner.retiming`) and keeps the shorter.
"""

from __future__ import annotations

import math

import numpy as np

from sixplus3.planner.nlp import Bounds, active_limits, tcp_stretch, uniform_safety
from sixplus3.planner.pfl import pfl_ratio_max
from sixplus3.planner.problem import Problem
from sixplus3.planner.retiming import retimed
from sixplus3.planner.solution import Solution, actuated_profile
from sixplus3.planner.tcp_rows import tcp_rates_at


def tcp_limited(problem: Problem, sol: Solution, target: float = 0.995) -> Solution:
    """``sol`` within the platform-space limits (the tool centre point's speed and
    acceleration): stretched uniformly in time by the smallest factor that brings both
    within ``target`` of their limits (the speed scales 1/a, the acceleration 1/a^2,
    every joint rate and inertial torque with them), checked (once) against every limit.
    Power and force limiting (``problem.pfl``) likewise: its ratio at the dense samples
    within ``target`` of the rows' share (:func:`pfl_stretch`).  Without such limits:
    ``sol`` as it is.  The NLP bounds them at its points
    (:mod:`sixplus3.planner.tcp_rows`); this stretch covers what the dense check finds
    between those points (a few percent near a corner of the path)."""
    lim = problem.motion_limits
    if not lim.has_tcp and not problem.pfl:
        return sol
    if sol.check is None:
        sol = sol.checked()
    assert sol.check is not None
    # the dense check measured the tool centre point on the same samples (the
    # acceleration by finite differences, as the gate does); its exact rates there
    # can be higher between the samples of a sharp peak
    speed, acc = exact_tcp_peaks(problem, sol)
    speed = max(speed, sol.check.max_tcp_speed)
    acc = max(acc, sol.check.max_tcp_acceleration)
    a_pfl = pfl_stretch(problem, sol, target)
    if not lim.has_tcp:
        if a_pfl > 1.0:
            problem.stage(f"stretching time by {a_pfl:.3f} for power and force limiting")
            return stretched(problem, sol.replace(limits=lim), a_pfl).replace(
                active_limits=(f"pfl (uniform stretch {a_pfl:.3f})",))
        return sol.replace(limits=lim).checked()
    a = max(1.0, speed / (target * lim.tcp_speed),
            math.sqrt(acc / (target * lim.tcp_acceleration)), a_pfl)
    if a > 1.0:
        problem.stage(f"stretching time by {a:.3f} for the tool centre point's limits "
                      f"({lim.tcp_speed:g} m/s, {lim.tcp_acceleration:g} m/s^2)")
        by_speed = speed / lim.tcp_speed >= math.sqrt(acc / lim.tcp_acceleration)
        return stretched(problem, sol.replace(limits=lim), a).replace(active_limits=(
            f"tcp {'speed' if by_speed else 'acceleration'} (uniform stretch {a:.3f})",))
    return sol.replace(limits=lim).checked()


def exact_tcp_peaks(problem: Problem, sol: Solution, samples: int = 10) -> tuple[float, float]:
    """The tool centre point's largest speed [m/s] and acceleration [m/s^2] of ``sol``,
    exact (:func:`tcp_rates_at`), at ``samples`` points per interval and every node."""
    t = np.unique(np.concatenate([np.linspace(a, b, samples + 1)
                                  for a, b in zip(sol.t[:-1], sol.t[1:], strict=True)]))
    speed, acc = tcp_rates_at(problem.robot.tool.xyz, *sol.sample(t))
    return float(speed.max()), float(acc.max())


def platform_limited(problem: Problem, sol: Solution, target: float = 0.995) -> Solution:
    """``sol`` within the platform-space limits (and power and force limiting with
    them): the shorter of the uniform stretch (:func:`tcp_limited`) and the re-timing
    along the path
    (:func:`sixplus3.planner.retiming.retimed`, then :func:`tcp_limited` for what its
    dense check still finds) that passes its dense check.  The uniform stretch runs a
    whole cruise below the limit for the worst point of its ripple; the re-timing runs
    it at the limit (BENCHMARKS.md)."""
    uniform = tcp_limited(problem, sol, target)
    if not problem.motion_limits.has_tcp:
        # power and force limiting alone keeps the uniform stretch: its re-timed plans
        # meet their contacts faster (a free hand at 1.5 m/s instead of 1.2), and the
        # guard then reads the impact as a clamp (BENCHMARKS.md, session 32)
        return uniform
    problem.stage("re-timing the plan along its path for the platform's limits")
    local = retimed(problem, sol, target)
    if local is None:
        return uniform
    local = tcp_limited(problem, local, target)
    if not local.is_feasible() or local.final_time >= uniform.final_time:
        return uniform
    return local.replace(active_limits=(*sol.active_limits, (
        f"re-timed along the path ({local.final_time:.4f} s; the uniform stretch: "
        f"{uniform.final_time:.4f} s)")))


def pfl_stretch(problem: Problem, sol: Solution, target: float = 0.995,
                samples: int = 10) -> float:
    """The uniform time stretch (< 1: a compression is possible) that brings the power
    and force limiting ratio v^T C v at ``samples`` points per interval of ``sol`` to
    ``target`` of the rows' share (it goes as 1/a^2); 0 without PFL."""
    if not problem.pfl:
        return 0.0
    times = np.linspace(0.0, sol.t[-1], (len(sol.t) - 1) * samples + 1)
    x, xd, _ = sol.sample(times)
    worst = pfl_ratio_max(problem.robot, x, xd, problem.pfl, problem.pfl_links)
    return math.sqrt(max(worst, 0.0) / (target * problem.options.pfl_share))


def stretched(problem: Problem, sol: Solution, a: float) -> Solution:
    """``sol`` with time scaled uniformly by ``a`` (slower for a > 1; the path kept,
    rates / a, accelerations / a^2, torques recomputed with the whole model),
    dense-checked."""
    tau = actuated_profile(problem.robot, sol.x, sol.xd / a, sol.xdd / a**2)[2].T
    return sol.replace(final_time=sol.final_time * a, segment_times=sol.segment_times * a,
                       t=sol.t * a, xd=sol.xd / a, xdd=sol.xdd / a**2, tau=tau,
                       active_limits=(), nlp_point=None,
                       time_scale=sol.time_scale * a).checked()


def retime(problem: Problem, sol: Solution, platform_proxy: float, target: float = 0.995,
           max_stretch: float = 1.0) -> Solution:
    """Compress the verified plan uniformly in time up to ``target`` of its limits (or,
    with ``max_stretch`` > 1, slow down a plan whose torques, rates or accelerations
    exceed ``target`` by a stretch 1 < a <= ``max_stretch``).

    The NLP bounds the torques at the nodes and midpoints at a safety fraction of the
    limit, so the verified plan usually keeps 1-2% in reserve everywhere.  Stretching
    time by a keeps the path (and every margin) and scales theta_dot by 1/a and
    theta_ddot and the inertial torques by 1/a^2 exactly, so the smallest a that keeps
    every dense sample within ``target`` of the limits follows in closed form.  The
    result is re-checked with Pinocchio; if that check fails, ``sol`` itself is returned.
    """
    times = np.linspace(0.0, sol.t[-1], (len(sol.t) - 1) * 10 + 1)
    x, xd, xdd = sol.sample(times)
    a = float(problem.time_stretch(x, xd, xdd, target).max())
    if problem.motion_limits.has_tcp:  # the platform-space limits bind as well
        a = max(a, tcp_stretch(problem, x, xd, xdd, target, at_least=0.0))
    a = max(a, pfl_stretch(problem, sol, target))  # and power and force limiting
    wanted = 1.0 < a <= max_stretch if max_stretch > 1.0 else 0.5 < a < 1.0
    if not wanted:
        return sol
    new = stretched(problem, sol, a)
    if not new.is_feasible():
        return sol
    full = Bounds(safety=uniform_safety(1.0), platform_proxy=platform_proxy)
    return new.replace(active_limits=active_limits(problem, new.x, new.xd, new.xdd, new.tau,
                                                   new.t, full))


__all__ = ["exact_tcp_peaks", "pfl_stretch", "platform_limited", "retime", "stretched",
           "tcp_limited"]
