"""How a plan is found: static choices, the baseline, NLP starts, re-solves, re-timing.

:func:`solve` is the planner's method, in order:

1. the crank angles at the waypoints (:func:`statics.choose_static_psi`);
2. the stop-at-waypoints baseline (:func:`baseline.baseline_plan`): the NLP's first warm
   start, its trust region (the NLP's total duration is capped at 1.5x the baseline's)
   and the plan returned when the NLP fails or is slower;
3. NLP starts in a measured order (:func:`first_solve`): a homotopy in the margin from
   the baseline, the task's margin from the baseline, the kinematic guess twice as slow;
4. the dense re-check sees between the NLP's points: an overshoot that a uniform time
   stretch fixes is stretched (:func:`retime`), any other violated limit is tightened
   and re-solved from the previous primal-dual point (at most 5 times);
5. the checked plan is compressed uniformly up to 99.5% of its binding limit;
6. :func:`finish`: the baseline if it is faster, the task's duration or speed (minimum
   effort), the platform-space limits (a uniform stretch).

Every solve's state is local here; the :class:`Problem` is never changed.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from sixplus3.errors import InfeasibleTaskError
from sixplus3.planner import baseline
from sixplus3.planner.nlp import (
    RATE_LIMITS,
    Bounds,
    solve_nlp,
    uniform_safety,
)
from sixplus3.planner.problem import Problem
from sixplus3.planner.solution import NO_WORK, Solution
from sixplus3.planner.statics import check_crank_sides, choose_static_psi, clearance_needed
from sixplus3.planner.timing import platform_limited, retime, stretched, tcp_limited

#: [m] of clearance a re-solve asks beyond the overlap the dense check found.  Plans
#: that slide along contact dip between their points by some hundredths of a mm
#: (broad_11 of `--broad --seed 2`: 0.05 mm); 0.5 mm made that re-solve hit the iteration
#: cap and the baseline come back after 52 s, 0.1 mm re-solves it in 19 iterations
#: (BENCHMARKS.md, "Planner v2").
CLEARANCE_RESERVE = 1e-4


def solve(problem: Problem) -> Solution:
    """The plan of ``problem`` (see the module's docstring); raises
    :class:`InfeasibleTaskError` when neither the NLP nor the baseline plans it."""
    t_wall = time.perf_counter()
    task, opt = problem.task, problem.options
    at_rest = problem.rest_waypoints()
    if not opt.lock_redundancy:
        check_crank_sides(task)
    psi_wp = choose_static_psi(task, problem.robot, problem.limits, opt.lock_redundancy,
                               at_rest)
    if opt.lock_redundancy:
        fixed = [wp.psi for wp in task.waypoints if wp.psi is not None]
        lock = fixed[0] if fixed else np.asarray(problem.robot.home_psi)
        psi_wp = np.tile(lock, (len(task.waypoints), 1))
    problem.stage("crank angles at the waypoints chosen; building the stop-at-waypoints "
                  "baseline (TOPP-RA per segment)")
    base, note = baseline.baseline_plan(problem, psi_wp)
    if base is not None and (problem.motion_limits.has_tcp or problem.pfl):
        base = tcp_limited(problem, base)  # the baseline knows the joints' limits only
    bounds = initial_bounds(problem, psi_wp, base)
    problem.stage(f"baseline: {base.final_time:.4f} s" if base is not None else
                  f"no admissible baseline ({note})")
    sol, bounds, first, failed = first_solve(problem, psi_wp, bounds, base)
    if sol is None:
        if base is not None:
            base = base.plus_work(*failed)
            return finish(problem, base, base, t_wall, psi_wp, bounds)
        assert first is not None
        raise first
    sol, bounds = resolve(problem, psi_wp, bounds, sol)
    if sol.is_feasible():
        problem.stage("re-timing the checked plan up to 99.5% of its binding limit")
        sol = retime(problem, sol, bounds.platform_proxy)
    return finish(problem, sol, base, t_wall, psi_wp, bounds)


def initial_bounds(problem: Problem, psi_wp: np.ndarray, base: Solution | None) -> Bounds:
    """The bounds of the first NLP solve: the options' safety share of the rate limits,
    the platform proxy max(0.5, 6 m), the clearance rows bounded only when a waypoint
    comes near contact (:func:`statics.clearance_needed`), and with a baseline the
    rows widened to admit it (:func:`admitting`) and the total duration capped at 1.5x
    its: a plan slower than the baseline is never returned, and the cap is a trust
    region that stops IPOPT's early quasi-Newton steps from running the durations up to
    the 60 s bound, which is how most failed starts failed (BENCHMARKS.md)."""
    bounds = Bounds(safety=uniform_safety(problem.options.torque_safety),
                    platform_proxy=max(0.5, 6 * problem.limits.margin),
                    clearance=(0.0 if clearance_needed(problem.robot, problem.task, psi_wp)
                               else None))
    if base is None:
        return bounds
    return admitting(problem, bounds, base).replace(duration_cap=1.5 * base.final_time)


def admitting(problem: Problem, bounds: Bounds, base: Solution) -> Bounds:
    """``bounds`` widened so that the NLP's proxy rows admit the baseline, a plan that
    meets every official limit: the crank bounds ([45, 135] deg by default) widened to
    the baseline's crank angles, and the platform's line-determinant bound lowered to
    0.9 of the baseline's smallest.

    Those two rows are proxies of the platform's margin (a 9x9 singular-value ratio with
    no cheap smooth form), sufficient on the range where they were sampled but not
    necessary: a static crank choice outside [45, 135] deg (when nothing inside passes)
    made a baseline that met the official margin but not the rows, and every NLP start
    failed (broad_10: the line determinant fell to 0.22 < 0.5).  The dense check still
    measures the official margin on every plan, and raises the proxy for a re-solve when
    it is violated (:func:`tightened`).
    """
    if problem.options.lock_redundancy:
        return bounds
    lo, hi = problem.crank_range()
    cranks = (np.minimum(lo, base.x[:, 6:9].min(axis=0)),
              np.maximum(hi, base.x[:, 6:9].max(axis=0)))
    line = float(np.array(problem.sr.margins.map(len(base.x))(base.x.T)[2]).min())
    return bounds.replace(cranks=cranks,
                          platform_proxy=min(bounds.platform_proxy, max(0.9 * line, 1e-3)))


def first_solve(problem: Problem, psi_wp: np.ndarray, bounds: Bounds,
                base: Solution | None) -> tuple[Solution | None, Bounds,
                                                InfeasibleTaskError | None,
                                                tuple[float, int, float]]:
    """(Solution or None, the bounds its re-solves keep, the first solver error, the
    work of the failed starts (seconds, iterations, function seconds:
    :meth:`Solution.plus_work`)), trying in turn: a homotopy step in the margin from the
    baseline (the margin rows at 0.6 x the margin; its plan is kept if the dense check,
    against the task's own margin, passes: the OCP's margin rows are conservative
    proxies, det J-hat >= m (3 - m^2) / 2 and the platform's line determinant >=
    max(0.5, 6 m), so a
    plan can meet the official margin although the NLP at the full margin was declared
    infeasible; otherwise it is re-solved from there at the task's margin); the NLP at
    the task's margin from the baseline; the kinematic guess twice as slow.  With no
    baseline: the kinematic guess, twice as slow, then the homotopy from the guess.
    Failed starts count in the solve time.

    The order is measured (BENCHMARKS.md, held-out set): the homotopy first planned
    every task in one solve, its plans met the task's margin in the dense check, and it
    removed the 4-7 s that a start at the full margin spent before declaring a feasible
    task infeasible (p95 wall time 4.0 -> 3.1 s); the plain guess never planned where
    these failed.
    """
    opt = problem.options
    homotopy = {"warm": base, "margin": 0.6 * problem.limits.margin}
    starts: list[dict[str, Any]] = (
        [homotopy, {"warm": base}, {"time_scale": 2.0}] if base is not None
        else [{}, {"time_scale": 2.0}, homotopy])
    first = None
    failed = NO_WORK
    for i, start in enumerate(starts):
        t0 = time.perf_counter()
        start = dict(start)
        margin = start.pop("margin", None)
        # a start that a fallback follows stops at start_max_iter (held-out set: no
        # start that planned needed more, BENCHMARKS.md); the last runs to max_iter
        if i < len(starts) - 1 and opt.start_max_iter < opt.max_iter:
            start["max_iter"] = opt.start_max_iter
        problem.stage("NLP " + ("from the baseline" if start.get("warm") is not None
                                else "from the kinematic guess")
                      + (" at 0.6 x the margin (homotopy)" if margin is not None else "")
                      + (", twice as slow" if "time_scale" in start else ""))
        step = NO_WORK  # the work of the homotopy's first step, once it succeeded
        try:
            sol = solve_nlp(problem, psi_wp, bounds.replace(margin=margin), **start)
            if margin is not None:
                assert sol.check is not None
                if any("margin" in v for v in sol.check.violations):
                    step = sol.work()
                    sol = solve_nlp(problem, psi_wp, bounds, warm=sol).plus_work(*step)
                else:  # the homotopy's plan meets the task's margin: re-solves keep its rows
                    bounds = bounds.replace(margin=margin)
        except InfeasibleTaskError as exc:
            if exc.limit is None or not exc.limit.startswith("solver"):
                raise
            first = first or exc
            spent = time.perf_counter() - t0
            _, its, fn = exc.nlp_work or NO_WORK
            # the start's wall time, and the iterations of its failed and earlier steps
            failed = (failed[0] + spent, failed[1] + its + step[1], failed[2] + fn + step[2])
            problem.stage(f"  failed ({exc.value}) after {spent:.1f} s")
            continue
        return sol.plus_work(*failed), bounds, None, failed
    return None, bounds, first, failed


def resolve(problem: Problem, psi_wp: np.ndarray, bounds: Bounds,
            sol: Solution) -> tuple[Solution, Bounds]:
    """The dense re-check sees between the NLP's points: tighten what it found violated
    and re-solve from the previous solution (at most 5 times).  Only limits that a
    uniform time stretch fixes: the plan is stretched (up to 5% slower) instead, which
    saves a whole NLP solve and does not tighten the bounds everywhere."""
    solves = 1
    for _ in range(5):
        chk = sol.check
        assert chk is not None  # solve_nlp always re-checks its solution
        bad = chk.violations
        if not bad:
            break
        if all(v.startswith(RATE_LIMITS) for v in bad):
            slow = retime(problem, sol, bounds.platform_proxy, max_stretch=1.05)
            if slow is not sol:
                problem.stage(f"the dense check found {'; '.join(bad)}: time stretched by "
                              f"{slow.time_scale / sol.time_scale:.4f} instead of a "
                              "re-solve")
                sol = slow
                break
        bounds, fixable = tightened(bounds, chk, problem.limits.spherical)
        if not fixable:
            break
        problem.stage(f"re-solve {solves}: the dense check found {'; '.join(bad)}; "
                      "tightening those limits")
        try:
            nxt = solve_nlp(problem, psi_wp, bounds, warm=sol)
        except InfeasibleTaskError as exc:
            if exc.limit is None or not exc.limit.startswith("solver"):
                raise
            problem.stage(f"  re-solve failed ({exc.value}): keeping the last plan")
            break  # keep the last iterate; the baseline may replace it (finish)
        solves += 1
        sol = nxt.plus_work(*sol.work())
    return sol.replace(solves=solves), bounds


def tightened(bounds: Bounds, chk: Any, spherical_limit: float) -> tuple[Bounds, bool]:
    """(the bounds with every limit the dense check ``chk`` found violated tightened,
    whether a re-solve can fix them)."""
    bad = chk.violations
    ratios = {"torque": chk.max_torque_ratio, "velocity": chk.max_velocity_ratio,
              "acceleration": chk.max_acceleration_ratio}
    safety = dict(bounds.safety)
    fixable = False
    for name in RATE_LIMITS:
        if any(v.startswith(name) for v in bad):
            safety[name] *= 0.985 / ratios[name]
            fixable = True
    new = bounds.replace(safety=safety)
    if any(v.startswith("platform") for v in bad):
        new = new.replace(platform_proxy=min(0.9, bounds.platform_proxy + 0.2))
        fixable = True
    if any(v.startswith("spherical") for v in bad):
        # bound the tilts below the limit by the overshoot found, plus 0.25 deg
        over = chk.max_spherical_tilt - (spherical_limit - bounds.spherical_reserve)
        reserve = bounds.spherical_reserve + over + math.radians(0.25)
        new = new.replace(spherical_reserve=reserve)
        fixable = fixable or reserve < math.radians(10.0)
    if any(v.startswith("interference") for v in bad):
        # ask the NLP for the overlap found plus CLEARANCE_RESERVE at its points, except
        # at the waypoints' nodes, which keep the bound they had (a given pose near
        # contact may have less than the reserve: heldout_20's has 0.1 mm at most);
        # rows that were unbounded are bounded first
        if bounds.clearance is None:
            new = new.replace(clearance=0.0)
        else:
            at_wp = (bounds.clearance if bounds.clearance_waypoints is None
                     else bounds.clearance_waypoints)
            new = new.replace(clearance=bounds.clearance - chk.min_clearance
                              + CLEARANCE_RESERVE, clearance_waypoints=at_wp)
        fixable = fixable or (new.clearance or 0.0) < 0.01
    return new, fixable


def finish(problem: Problem, sol: Solution, base: Solution | None, t_wall: float,
           psi_wp: np.ndarray, bounds: Bounds) -> Solution:
    """The returned plan: the NLP's, or the baseline when the NLP's failed its check or
    is slower; then the task's duration or speed, if it asks for one; then the
    platform-space limits."""
    if base is not None and sol is not base and (
            not sol.is_feasible() or sol.final_time > base.final_time):
        sol = base.plus_work(*sol.work()).replace(solves=sol.solves)
        problem.stage("returning the baseline (the NLP's plan failed its check or is "
                      "slower)")
    target = target_duration(problem, sol)
    if target is not None:
        problem.stage(f"stretching to the task's duration, {target:.4f} s (minimum effort "
                      "at that duration)")
        sol = fixed_duration(problem, sol, target, psi_wp, bounds)
    if sol.check is not None:  # limits that bind between the nodes
        extra = [f"{name} ({ratio:.3f} of the limit in the dense check)"
                 for name, ratio in (("torque", sol.check.max_torque_ratio),
                                     ("velocity", sol.check.max_velocity_ratio),
                                     ("acceleration", sol.check.max_acceleration_ratio))
                 if ratio > 0.99 and not any(a.startswith(name) for a in sol.active_limits)]
        sol = sol.replace(active_limits=(*sol.active_limits, *extra))
    sol = platform_limited(problem, sol)
    return sol.replace(baseline_time=base.final_time if base is not None else None,
                       wall_time=time.perf_counter() - t_wall)


def target_duration(problem: Problem, sol: Solution) -> float | None:
    """The duration the task asks for (None: minimum time); raises if it is shorter than
    the minimum-time plan."""
    task = problem.task
    if task.duration is None and task.speed is None:
        return None
    if not sol.is_feasible():
        return None  # the minimum-time plan failed its check: reported as is
    t_min = sol.final_time
    if task.duration is not None:
        target = task.duration
    else:
        assert task.speed is not None
        target = t_min / task.speed
    if target < t_min * (1.0 - 1e-9):
        raise InfeasibleTaskError(
            f"a duration of {target:.4f} s is shorter than the minimum-time plan "
            f"({t_min:.4f} s) within the limits", None, "duration", value=target,
            valid=f">= {t_min:.4f} s")
    return float(target)


def fixed_duration(problem: Problem, sol: Solution, target: float, psi_wp: np.ndarray,
                   bounds: Bounds) -> Solution:
    """A plan of exactly ``target`` seconds that minimises the mean squared torque,
    warm-started from the minimum-time plan stretched uniformly to that duration (which
    is the fallback when the effort solve fails its dense check)."""
    slow = stretched(problem, sol, target / sol.final_time)
    eff: Solution | None = None
    try:
        eff = solve_nlp(problem, psi_wp, bounds.replace(margin=None), warm=slow,
                        duration=target)
        eff_work = eff.work()
    except InfeasibleTaskError as exc:
        eff_work = exc.nlp_work or NO_WORK
    if eff is not None and eff.is_feasible():
        best = eff.plus_work(*sol.work())  # its own work plus the minimum-time plan's
    else:
        best = slow.plus_work(*eff_work)  # slow carries the minimum-time plan's work
    best = best.replace(solves=sol.solves + 1)
    if not best.is_feasible():
        return sol  # neither passed: the minimum-time plan and its diagnosis
    return best


__all__ = ["admitting", "finish", "first_solve", "fixed_duration", "initial_bounds",
           "resolve", "solve", "target_duration", "tightened"]
