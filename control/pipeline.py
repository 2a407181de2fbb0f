"""plan -> smooth -> validate -> write: what ``sixplus3 plan`` and ``sixplus3 demo`` run."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from sixplus3.control.file.trajectory_file import output_path
from sixplus3.control.gate.validation import validate_and_write
from sixplus3.control.report import ValidationReport
from sixplus3.errors import TaskError, TrajectoryFileError, ValidationFailed
from sixplus3.motion import check_rate, check_samples
from sixplus3.planner.ocp import plan_problem
from sixplus3.planner.options import PlannerOptions
from sixplus3.planner.pfl import PFL_SAFETY, task_regions
from sixplus3.planner.problem import Problem
from sixplus3.planner.smoothing import Smoothed, smooth
from sixplus3.planner.solution import Solution
from sixplus3.planner.task import Task
from sixplus3.progress import PlanProgress
from sixplus3.robot_description.robot import Robot, require_robot


def demo_task(robot: Robot) -> dict[str, Any]:
    """The built-in task of ``sixplus3 demo``: tilt 30 deg about x at the robot's home
    and come back."""
    home = list(require_robot(robot).home_position)
    return {
        "name": "demo_tilt30",
        "description": "Built-in demo: tilt the platform 30 deg about x at home and back.",
        "waypoints": [{"position": home}, {"position": home, "rpy": [30, 0, 0]},
                      {"position": home}],
        "nodes_per_segment": 10,
    }


@dataclass
class PlanOutputs:
    solution: Solution
    smoothed: Smoothed
    report: ValidationReport
    csv: Path  # the trajectory file (header + samples, one atomic unit)
    html: Path | None
    plots: list[str]
    seconds: dict[str, float]


def _silent(text: str) -> None:
    pass


#: Plans a task with power and force limiting may take (each lowering the speed bound
#: by what the gate found).
PFL_TRIES = 3
#: A re-plan after a torque finding lowers the node bound by this many times the gate's
#: excess: the smoothed file's peak falls by about a quarter of the bound's change
#: (measured on a held-out task for an identified robot: bounds 0.9727, 0.9669, 0.9622
#: left 1.00398, 1.00285, 1.00169 of the limit; BENCHMARKS.md).
TORQUE_GAIN = 5.0


def _planned(sol: Solution) -> str:
    """The line that says how the plan was found and what it costs."""
    assert sol.check is not None  # plan() returns only checked plans
    how = ("the time-optimal NLP" if sol.source == "ocp" else
           "the stop-at-waypoints baseline (the NLP failed or was slower)")
    base = (f"baseline {sol.baseline_time:.4f} s" if sol.baseline_time is not None
            else "no admissible baseline")
    return (f"  planned: {sol.final_time:.4f} s motion from {how} ({base}), {sol.solves} "
            f"NLP solve(s), IPOPT {sol.total_iterations} iterations ({sol.iterations} in "
            f"the last), {sol.solve_time:.2f} s solving ({sol.function_time:.2f} s of it "
            f"evaluating the NLP's functions), {sol.wall_time:.2f} s in all; dense "
            f"re-check: max|tau| {sol.check.max_torque_ratio:.3f} of the limit, min margin "
            f"{sol.check.min_margin:.3f}")


def _smoothed(sol: Solution, rate: float, task: Task) -> Smoothed:
    """The plan sampled at ``rate`` (planner/smoothing.py), starting exactly at the
    task's start state when it has one."""
    sm = smooth(sol, rate=rate)
    if task.start_theta is not None:
        # the first sample is the robot's state, exactly (FK -> plan -> IK returns it to
        # rounding; anything more would be a bug, not a motion to send)
        gap = float(np.abs(sm.theta[0] - task.start_theta).max())
        if gap > 1e-9:
            raise TrajectoryFileError(f"the plan does not start at the given state: "
                                      f"{gap:.2e} rad away", value=gap, valid="<= 1e-9 rad")
        theta = sm.theta.copy()
        theta[0] = task.start_theta
        sm = replace(sm, motion=sm.motion.with_theta(theta))
    return sm


def _beside(task: Task, sol: Solution, sm: Smoothed, rep: ValidationReport, robot: Robot,
            out: Path, stem: str, plots: bool, html: bool, say: Callable[[str], None]
            ) -> tuple[list[str], Path | None]:
    """The plots and the MeshCat page beside the written file, as asked."""
    files: list[str] = []
    if plots:
        from sixplus3.visualization.plots import (
            plot_trajectory,  # deferred: matplotlib loads only when plots are asked for
        )

        files = plot_trajectory(robot, out, sm.motion, rep.tau,
                                (rep.position, rep.quaternion, rep.psi), stem,
                                limits=sol.limits, planned_torque=sol.limits.torque)
        say(f"  plots: {', '.join(Path(f).name for f in files)}")
    html_path = None
    if html:
        # deferred: meshcat loads only when the page is asked for
        from sixplus3.visualization.meshcat_player import (
            frames_from_samples,
            write_html,
        )

        wps = (sol.task or task).waypoints
        frames = frames_from_samples(robot, sm.t, rep.position, rep.quaternion, rep.psi,
                                     title=f"sixplus3: {task.name}", theta_dot=sm.theta_dot,
                                     waypoints=[w.position for w in wps])
        html_path = write_html(frames, out / f"{stem}.html")
        say(f"  MeshCat page: {html_path} (slowed down {frames.slowdown:.0f}x)")
    return files, html_path


def _replan_options(exc: ValidationFailed, options: PlannerOptions | None, tries: int,
                    say: Callable[[str], None]) -> PlannerOptions | None:
    """The options to plan again with after the gate refused the smoothed file, or None
    (the refusal stands): a file over its PFL limits, or over its torque limit by what
    the NLP's nodes did not see (between them, or after the smoothing), is planned
    again with the rows' share, or the node bound, lowered by what the gate found, at
    most PFL_TRIES times."""
    failed = exc.report if isinstance(exc.report, ValidationReport) else None
    found = failed.findings if failed is not None else []
    if not found or tries >= PFL_TRIES:
        return None
    opts = options or PlannerOptions()
    ratio = failed.max_pfl_ratio if failed is not None else None
    if all(f.check.startswith("pfl ") for f in found) and ratio:
        # between the NLP's points, or after the smoothing, the energy was higher than
        # the rows allowed: lower their share by what the gate found
        share = max(0.01, opts.pfl_share * PFL_SAFETY**2 / float(ratio))
        say(f"  the gate's PFL check found {ratio:.3f} of the limit: planning again "
            f"with the rows at {share:.3f} of it")
        return replace(opts, pfl_share=share)
    if all(f.check in ("torque", "torque (between samples, bound)") for f in found):
        # the smoothing (or the interpolant between samples) asks a hair more torque
        # than the NLP's nodes allowed (session 34: 9.00302 N m of 9 on a robot
        # identified on a perturbed prototype): the node bound lowered the same way
        worst = max(abs(f.worst_value) / f.bound for f in found if f.bound > 0)
        safety = max(0.5, opts.torque_safety * (1.0 - TORQUE_GAIN * (worst - 1.0)))
        say(f"  the gate found {worst:.5f} of the torque limit after smoothing: "
            f"planning again with the node bound at {safety:.4f} of it")
        return replace(opts, torque_safety=safety)
    return None


def run_plan(task: Task, out_dir: str | Path, robot: Robot,
             rate: float = 1000.0, html: bool = True, plots: bool = True,
             options: PlannerOptions | None = None,
             progress: Callable[[str], None] | PlanProgress | None = None,
             _pfl_try: int = 0) -> PlanOutputs:
    """Plan ``task`` for ``robot`` and write the validated
    trajectory file ``out_dir/<name>.csv`` (and the page and plots beside it).

    ``progress``: a :class:`sixplus3.progress.PlanProgress` (every stage, the planner's
    too, and each IPOPT iteration), or a callable given this function's own stage lines.

    The output name and the rate are checked before anything is solved.  Raises
    :class:`InfeasibleTaskError` for an infeasible task and :class:`TrajectoryFileError`
    if the smoothed trajectory fails its validation; in both cases nothing is written.
    """
    listener = progress if isinstance(progress, PlanProgress) else None
    say: Callable[[str], None] = (progress.stage if isinstance(progress, PlanProgress)
                                  else progress if progress is not None else _silent)
    # power and force limiting (docs/safety.md): the task's and the site's body regions,
    # as rows of the NLP (planner/pfl.py)
    if not isinstance(task, Task):
        raise TaskError(f"task must be a Task (sixplus3.planner.task), got "
                        f"{type(task).__name__}", value=type(task).__name__, valid="a Task")
    regions = task_regions(task)
    if regions and _pfl_try == 0:
        share = (options or PlannerOptions()).pfl_share
        say(f"power and force limiting for {', '.join(r.name for r in regions)}: every "
            f"contact's energy within {share:.3f} of its limit, in any direction")
    # the task checked once, here: the arguments, its setup robot and its limits (a
    # looser limit than the hardware's is refused before anything is solved), all held
    # by the Problem
    problem = Problem(task, robot, options, listener)
    robot = problem.robot  # with the task's payload, tool and mounting
    out = Path(out_dir)
    csv_path = output_path(out, task.name)  # a safe name, inside out_dir: before the solve
    check_rate(rate)
    # a fixed duration and the dwells are known before the solve: refuse a task that
    # would make more samples than the cap now, not after planning it
    check_samples((task.duration or 0.0) + sum(w.dwell for w in task.waypoints), rate,
                  f"task '{task.name}'")
    secs: dict[str, float] = {}
    t0 = time.perf_counter()
    say(f"planning '{task.name}' ({len(task.waypoints)} waypoints, "
        f"{task.n_segments * task.segment_nodes} intervals) ...")
    sol = plan_problem(problem)
    secs["plan"] = time.perf_counter() - t0
    say(_planned(sol))
    t1 = time.perf_counter()
    sm = _smoothed(sol, rate, task)
    secs["smooth"] = time.perf_counter() - t1
    say(f"  sampled at {rate:g} Hz, {sm.smoothed_segments} transitions certified by "
        f"Ruckig (jerk limit {sm.jerk_limit:.3g} rad/s^3): {len(sm.t)} samples, duration "
        f"{sm.duration:.4f} s (+{100 * sm.added_fraction:.2f}%, time stretch "
        f"{sm.time_stretch:.4f}), max jerk {sm.max_jerk:.3g} rad/s^3")
    t2 = time.perf_counter()
    meta: dict[str, Any] = {"rate_hz": rate, "task": task.source, "planner": sol.header(),
            "smoothing": sm.header()}
    if regions:
        meta["pfl"] = [r.name for r in regions]
        meta["pfl_links"] = list(problem.pfl_links)
    out.mkdir(parents=True, exist_ok=True)
    try:
        _, rep = validate_and_write(csv_path, sm.motion, robot, sm.x_guess, sol.limits, meta)
    except ValidationFailed as exc:
        again = _replan_options(exc, options, _pfl_try, say)
        if again is not None:
            return run_plan(task, out_dir, robot, rate, html, plots, again, progress,
                            _pfl_try=_pfl_try + 1)
        raise TrajectoryFileError("the smoothed trajectory fails validation, nothing "
                                  "written: " + str(exc).split(": ", 1)[-1],
                                  value=str(exc)[:2000],
                                  valid="a valid trajectory") from None
    secs["validate"] = time.perf_counter() - t2
    say(f"  validated {rep.samples} samples and {rep.checked_points - rep.samples} "
        f"midpoints with Pinocchio: max|tau| {rep.max_torque_ratio * sol.limits.torque:.3f} "
        f"N m, min margins {rep.min_margin_leg_type1:.3f}/{rep.min_margin_leg_type2:.3f}/"
        f"{rep.min_margin_platform:.3f}")
    say(f"  wrote {csv_path}")
    files, html_path = _beside(task, sol, sm, rep, robot, out, csv_path.stem, plots, html,
                               say)
    secs["total"] = time.perf_counter() - t0
    return PlanOutputs(sol, sm, rep, csv_path, html_path, files, secs)
