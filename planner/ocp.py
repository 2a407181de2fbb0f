"""Time-optimal planning: Problem -> solve() -> Solution (CasADi + IPOPT).

The planner's public face.  The method lives in modules that each show one part:

- :mod:`~sixplus3.planner.options`: :class:`PlannerOptions` and the transcription's
  constants;
- :mod:`~sixplus3.planner.problem`: :class:`Problem` (data only, immutable): the task on
  its robot, the limits, the node grid and the kinematic first guess;
- :mod:`~sixplus3.planner.statics`: crank angles chosen statically at the waypoints;
- :mod:`~sixplus3.planner.transcription`: the NLP (direct multiple shooting), one
  function per constraint family, assembled in ``build_nlp``;
- :mod:`~sixplus3.planner.solvers`: IPOPT's settings and a bounded per-process cache of
  built solvers;
- :mod:`~sixplus3.planner.nlp`: one NLP solve with given bounds;
- :mod:`~sixplus3.planner.strategy`: the baseline, the NLP starts (homotopy), the
  re-solves after the dense check, the re-timing, the fallbacks;
- :mod:`~sixplus3.planner.timing` and :mod:`~sixplus3.planner.retiming`: uniform
  re-timings, and the re-timing along the path under platform limits;
- :mod:`~sixplus3.planner.solution`: the frozen :class:`Solution` and its dense re-check
  with the numeric model;
- :mod:`~sixplus3.planner.baseline`: the stop-at-waypoints plan (TOPP-RA per segment).

The formulation (docs/planner.md): minimal coordinates x = (platform position [m],
rotation vector [rad], crank angles psi [rad]); a chain of segments, one per pair of
consecutive waypoints, each with ``Task.segment_nodes`` intervals of a free duration;
accelerations linear between the nodes, so that the states are exact cubics; every
path constraint at the nodes and at the intervals' midpoints; the objective is the
total duration plus a small regularisation.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from sixplus3.errors import InfeasibleTaskError
from sixplus3.planner.options import PlannerOptions
from sixplus3.planner.problem import Problem
from sixplus3.planner.solution import Solution
from sixplus3.planner.strategy import solve
from sixplus3.planner.task import Task
from sixplus3.robot_description.robot import Robot

if TYPE_CHECKING:
    from sixplus3.progress import PlanProgress


def plan(task: Task, robot: Robot | None = None, options: PlannerOptions | None = None,
         progress: PlanProgress | None = None) -> Solution:
    """Plan a task; raises :class:`InfeasibleTaskError` (never returns an unsafe plan).

    The curated top-level helper (``sixplus3.plan``): without ``robot`` it plans for
    ``Robot.default()``, the one place of the library that chooses a robot for its
    caller (:class:`Problem` and everything below it require one).  ``progress``: a
    :class:`sixplus3.progress.PlanProgress` told each stage and IPOPT iteration."""
    return plan_problem(Problem(task, Robot.default() if robot is None else robot, options,
                                progress))


def plan_problem(problem: Problem) -> Solution:
    """The plan of a built :class:`Problem` (:func:`strategy.solve`), refused with
    :class:`InfeasibleTaskError` unless it passes its dense re-check."""
    sol = solve(problem)
    if not sol.is_feasible():
        raise InfeasibleTaskError(
            "the solved plan fails its dense re-check: "
            + "; ".join(sol.check.violations if sol.check else ["not checked"]),
            None, "dense check",
            value=sol.check.violations if sol.check else None, valid="every limit met")
    return sol


__all__ = ["plan", "plan_problem"]
