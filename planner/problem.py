"""A planning problem: one task on one robot, with its limits and its node grid.

:class:`Problem` holds data only and never changes after it is made: the free function
:func:`sixplus3.planner.strategy.solve` plans it and keeps the state of a solve (tightened
bounds, the duration cap, the homotopy's margin) to itself.  The node grid (which nodes
sit at the waypoints, how long each interval is), the kinematic first guess and the
mapping of any plan onto the grid are here, because every part of the planner reads them.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from sixplus3.dynamics.symbolic import SymbolicRobot, symbolic_robot
from sixplus3.errors import InputError, TaskError
from sixplus3.kinematics.checks import PSI_MAX, PSI_MIN
from sixplus3.kinematics.rotations import rotvec_from_matrix
from sixplus3.planner import options as planner_options
from sixplus3.planner.options import PlannerOptions
from sixplus3.planner.pfl import task_links, task_regions
from sixplus3.planner.solution import Solution, actuated_profile, stretch_factors
from sixplus3.planner.task import Task
from sixplus3.robot_description.body_regions import BodyRegion
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot, require_robot

if TYPE_CHECKING:
    from sixplus3.progress import PlanProgress


class Problem:
    """A planning problem for one task on one robot (``strategy.solve(problem)`` ->
    :class:`Solution`).

    The limits are the robot's hardware limits tightened by the task's
    (:meth:`Task.limits_for`: a looser one raises :class:`LimitError`).  Immutable: its
    attributes are set once here.
    """

    robot: Robot
    task: Task
    #: every limit the plan must meet; the NLP plans to ``limits``, the same without the
    #: platform-space ones, which a uniform time stretch meets afterwards
    motion_limits: Limits
    limits: Limits
    options: PlannerOptions
    #: the body regions of power and force limiting (the task's and the site's): the
    #: NLP's PFL rows (:func:`sixplus3.planner.pfl.pfl_matrices`); empty: none
    pfl: tuple[BodyRegion, ...]
    #: the leg links whose vertices get rows too (:func:`sixplus3.planner.pfl.task_links`)
    pfl_links: tuple[str, ...]
    sr: SymbolicRobot
    #: a :class:`sixplus3.progress.PlanProgress` (stages and IPOPT iterations) or None
    progress: PlanProgress | None

    def __init__(self, task: Task, robot: Robot, options: PlannerOptions | None = None,
                 progress: PlanProgress | None = None) -> None:
        check_plan_arguments(task, robot, options)
        # the task's setup (payload, tool, mounting) on the robot; TCP waypoints become
        # platform poses through that robot's tool
        setup = task.robot_for(robot)
        motion = task.limits_for(setup)
        for name, value in (("robot", setup), ("task", task.resolved(setup)),
                            ("motion_limits", motion), ("limits", motion.without_tcp()),
                            ("options", options or PlannerOptions()),
                            ("pfl", task_regions(task)), ("pfl_links", task_links(task)),
                            ("sr", symbolic_robot(setup)), ("progress", progress)):
            object.__setattr__(self, name, value)

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"Problem is immutable (tried to set {name!r})")

    def stage(self, text: str) -> None:
        """Tell the progress reporter about a sub-step of the caller's "planning ..."."""
        if self.progress is not None:
            self.progress.stage("  " + text)

    # -- the node grid
    def segment_intervals(self) -> np.ndarray:
        """(S,) node intervals of each segment: ``Task.segment_nodes``, plus
        ``len(REST_GRADING) - 1`` at each end of the segment where the motion is at rest
        (the graded intervals there replace one regular interval)."""
        ns, S = self.task.segment_nodes, self.task.n_segments
        extra = len(planner_options.REST_GRADING) - 1
        rest = self.rest_waypoints()
        return np.array([ns + extra * ((s in rest) + (s + 1 in rest)) for s in range(S)])

    @property
    def n_intervals(self) -> int:
        return int(self.segment_intervals().sum())

    def interval_segments(self) -> np.ndarray:
        """(N,) the segment of every node interval."""
        n = self.segment_intervals()
        return np.repeat(np.arange(len(n)), n)

    def waypoint_nodes(self) -> np.ndarray:
        """(W,) the node index of every waypoint."""
        return np.r_[0, np.cumsum(self.segment_intervals())]

    def rest_waypoints(self) -> set[int]:
        """Indices of the waypoints where the motion is at rest: the first, the last and
        every ``stop`` waypoint (zero velocity and acceleration there)."""
        wps = self.task.waypoints
        return {0, len(wps) - 1} | {w for w, wp in enumerate(wps) if wp.stop}

    def interval_fractions(self) -> np.ndarray:
        """(N,) each node interval's share of its segment's duration (a segment's sum to 1).

        Uniform, except next to a rest (the start, the end, a ``stop`` waypoint), where
        the intervals are graded by ``REST_GRADING`` (shares of a regular interval, from
        the rest outward): the acceleration is zero at rest and linear over each
        interval, so a long first interval makes the ramp up to the limits slow.  A
        single interval of 0.4 (before) left plans of two waypoints 1-2% slower than the
        fastest re-timing of their own path (the certificate, planner.certificate);
        graded 0.15, 0.5 they are within 1% (BENCHMARKS.md, "Rest ends")."""
        grading = np.asarray(planner_options.REST_GRADING, dtype=float)
        rest = self.rest_waypoints()
        out = []
        for s, n in enumerate(self.segment_intervals()):
            w = np.ones(n)
            if s in rest:
                w[:len(grading)] = grading
            if s + 1 in rest:
                w[n - len(grading):] = np.minimum(w[n - len(grading):], grading[::-1])
            out.append(w / w.sum())
        return np.concatenate(out)

    def node_times(self, T: np.ndarray) -> np.ndarray:
        """(N+1,) node times [s] for the segment durations T (S,)."""
        steps = np.asarray(T, dtype=float)[self.interval_segments()] * self.interval_fractions()
        return np.r_[0.0, np.cumsum(steps)]

    def crank_range(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi), (3,) [rad]: the NLP's bounds on the crank angles.

        [PSI_MIN, PSI_MAX] = [45, 135] deg, the range the static crank choice searches
        first, widened per crank to the crank angles a waypoint gives explicitly in
        (0, 180) deg (the task allows 3-177 deg).  With the bounds not widened, such a
        waypoint could only be reached by a jump of the crank, so every NLP start ran to
        its iteration cap before the baseline was returned (40 s, BENCHMARKS.md).
        """
        lo, hi = np.full(3, PSI_MIN), np.full(3, PSI_MAX)
        for wp in self.task.waypoints:
            if wp.psi is not None and np.all((wp.psi > 0.0) & (wp.psi < math.pi)):
                lo, hi = np.minimum(lo, wp.psi), np.maximum(hi, wp.psi)
        return lo, hi

    def waypoint_states(self, psi_wp: np.ndarray) -> np.ndarray:
        """(W, 9) minimal coordinates of the waypoints with the crank angles ``psi_wp``,
        the rotation vectors kept continuous (|r| near pi has two forms)."""
        rv_prev = None
        rows = []
        for k, wp in enumerate(self.task.waypoints):
            rv = rotvec_from_matrix(wp.rotation[None])[0]
            if rv_prev is not None and np.linalg.norm(rv - rv_prev) > math.pi:
                ang = np.linalg.norm(rv)
                rv = rv - 2 * math.pi * rv / ang
            rv_prev = rv
            rows.append(np.r_[wp.position, rv, psi_wp[k]])
        return np.array(rows)

    # -- motions on the grid
    def time_stretch(self, x: np.ndarray, xd: np.ndarray, xdd: np.ndarray,
                     fraction: float) -> np.ndarray:
        """(n,) smallest a > 0 per sample such that stretching time by a brings it within
        ``fraction`` of the velocity, acceleration and torque limits.

        Under t -> a t on a fixed path theta_dot scales by 1/a, theta_ddot and the
        inertial torques (tau - tau_gravity) by 1/a^2, exactly for the links and the
        rotors; the joint friction scales less (its viscous part by 1/a), which the
        dense check of the result covers (:func:`timing.retime` keeps the original
        plan if it fails).  Samples whose gravity torque alone exceeds the fraction get
        the largest stretch the formula allows (1e3-fold headroom floor), i.e. they are
        reported as needing a very slow motion.
        """
        return stretch_factors(*actuated_profile(self.robot, x, xd, xdd), self.limits,
                               fraction)

    def guess(self, psi_wp: np.ndarray) -> tuple[np.ndarray, ...]:
        """(waypoint states, x, xd, xdd, T): the kinematic first guess on the node grid.

        A rest-to-rest smooth blend between the waypoints (positions and crank angles
        linear in the blend, rotations by slerp), each segment time-scaled so that it
        just meets 90% of the velocity, acceleration and torque limits: with time
        stretched by a, theta_dot scales 1/a and theta_ddot and the inertial torques
        1/a^2, exactly.
        """
        S = self.task.n_segments
        wp_x = self.waypoint_states(psi_wp)
        frac, segs = self.interval_fractions(), self.interval_segments()
        xs, seg_T = [], []
        for s in range(S):
            a, b = wp_x[s], wp_x[s + 1]
            rots = Rotation.from_rotvec([a[3:6], b[3:6]])
            c = np.r_[0.0, np.cumsum(frac[segs == s])]  # the nodes' share of the segment
            share = c[:-1] if s < S - 1 else c
            sm = 3 * share**2 - 2 * share**3  # rest-to-rest smooth blend for the guess
            rv = Slerp([0, 1], rots)(sm).as_rotvec()
            seg = np.c_[a[:3] + sm[:, None] * (b[:3] - a[:3]), rv,
                        a[6:] + sm[:, None] * (b[6:] - a[6:])]
            xs.append(seg)
            # a first timing: it fixes the finite differences at the segment joints
            th = np.array(self.sr.theta(a)).ravel()
            th_b = np.array(self.sr.theta(b)).ravel()
            dth = np.abs(th_b - th).max()
            seg_T.append(max(0.15, 2.0 * math.sqrt(2.0 * dth / 40.0), 1.5 * dth / 4.0))
        x = np.vstack(xs)
        T = np.array(seg_T)
        t = self.node_times(T)
        xd = np.gradient(x, t, axis=0)
        xd[0] = xd[-1] = 0.0
        xdd = np.gradient(xd, t, axis=0)
        stretch = self.time_stretch(x, xd, xdd, 0.9)
        seg = np.r_[segs, S - 1]  # the segment of every node (the last: the last's)
        scale = np.clip([stretch[seg == s].max() for s in range(S)], 0.05, 50.0)
        a_ = scale[seg][:, None]
        return wp_x, x, xd / a_, xdd / a_**2, T * scale

    def on_nodes(self, sol: Solution) -> tuple[np.ndarray, ...]:
        """(x, xd, xdd, T) of a plan of this task on this NLP's node grid (its own arrays
        if it has that grid; else sampled at :meth:`node_times`)."""
        if sol.source == "ocp" and len(sol.t) == self.n_intervals + 1:
            return sol.x, sol.xd, sol.xdd, sol.segment_times
        T = np.asarray(sol.segment_times, dtype=float)
        x, xd, xdd = sol.sample(self.node_times(T))
        return x, xd, xdd, T


def check_plan_arguments(task: object, robot: object, options: object) -> None:
    """Named errors for arguments of the wrong kind (a :class:`Task` checks its own
    fields, :meth:`Task.__post_init__`)."""
    if not isinstance(task, Task):
        raise TaskError("task must be a Task (load_task, task_from_dict)",
                        value=type(task).__name__, valid="a Task")
    require_robot(robot)
    if options is not None and not isinstance(options, PlannerOptions):
        raise InputError("options must be PlannerOptions or None",
                         value=type(options).__name__, valid="PlannerOptions or None")


__all__ = ["Problem", "check_plan_arguments"]
