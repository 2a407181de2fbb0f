"""Time-optimal planning: Problem -> solve() -> Solution (CasADi + IPOPT).

Minimal coordinates x = (platform position [m], rotation vector [rad], crank angles psi
[rad]).  Direct multiple shooting on a chain of segments, one per pair of consecutive
waypoints, each with ``Task.segment_nodes`` intervals of a free duration T_s (uniform,
but shorter next to a rest: ``Problem.node_fractions``):

- variables: x, xd (nodes), acceleration u = xdd (nodes, linear in between: the states
  integrate exactly as cubics), actuator torques tau and actuated accelerations
  theta_ddot (nodes and interval midpoints; theta_ddot tied to the model by equality
  rows, so that its limit is a bound and the jerk rows are sparse), durations T_s;
- dynamics: x+ = x + h xd + h^2 (2 u + u+) / 6,  xd+ = xd + h (u + u+) / 2;
- path constraints, at every node and at every interval's midpoint (the exact cubic
  state there): (d theta / dx)^T tau = Q(x, xd, u) (dynamics.symbolic) with
  |tau| <= safety * limit, |theta_dot| <= velocity, |theta_ddot| <= acceleration,
  theta in [0, 270] deg, every spherical joint within 150 deg, every chain inside its
  reach, each leg's type I margin and type II margin (through det J-hat >= 3 m, which
  implies sigma_min >= m) and the platform (line determinant >= max(0.5, 6 m) with psi
  in [45, 135] deg), all >= the task's margin; the clearance between the links of
  different legs (bounded when a waypoint comes within 2 cm or the dense check finds
  interference);
- waypoints, rest at both ends and given or locked crank angles: equal variable bounds;
- objective: sum T_s + a small regularisation of u.

The NLP of a given size is built once per process (:meth:`Problem._template`); every
task-specific value is a bound or a parameter.  The constraint functions are compiled C
(:mod:`dynamics.codegen`) when a compiler is available.

Warm start: kinematic interpolation between the waypoints, the free crank angles chosen
statically at each waypoint to maximise the smallest singularity margin, each segment
time-scaled to 90% of the velocity, acceleration and torque limits.  The solution is
re-checked with the numeric model (Pinocchio, official margins) at 10x the node density;
a torque, velocity or acceleration overshoot between the constrained points is fixed by
a uniform time stretch (at most 5%, the path kept); any other violated limit tightens that
limit and re-solves from the previous primal-dual point (at most 5 times).
"""

from __future__ import annotations

import contextlib
import math
import signal
import threading
import time
from dataclasses import dataclass, field, replace
from typing import Any

import casadi as ca
import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from sixplus3.dynamics.symbolic import symbolic_robot
from sixplus3.errors import InfeasibleTaskError, InputError, TaskError
from sixplus3.kinematics.checks import PSI_MAX, PSI_MIN, measure_limits, pose_masks
from sixplus3.kinematics.collision import clearance
from sixplus3.kinematics.robot import robot_ik
from sixplus3.planner.task import Task, Waypoint, rotvec
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot

#: Built NLPs by structure (see Problem._template); one per process.
_TEMPLATES: dict[tuple, dict] = {}
#: a node interval next to a rest, as a share of a regular one (Problem.node_fractions)
REST_INTERVAL = 0.4
#: the scale [(m or rad)/s^2] of the NLP's acceleration variables (u, theta_ddot)
ACC_SCALE = 100.0
#: the NLP's torque-balance rows [N, N m] and theta_ddot ties [rad/s^2] are divided by
#: these (the nominal joint torque and the acceleration variables' scale)
ROW_SCALE = {"torque": 10.0, "acceleration": ACC_SCALE}


class _IterationRelay(ca.Callback):
    """IPOPT's per-iteration hook (CasADi's ``iteration_callback``): passes the iteration
    number and the iterate's scaled variables and constraint values to ``listener`` (set
    per solve, None: off), and stops the solve after ``limit`` iterations.

    Only x, f and g are taken (the multipliers are declared empty, so CasADi does not
    copy them); a failing listener is switched off rather than stopping the solve.
    """

    def __init__(self, nx: int, ng: int) -> None:
        ca.Callback.__init__(self)
        self.nx, self.ng = nx, ng
        self.listener: Any = None
        #: stop the solve (IPOPT's User_Requested_Stop) after this many iterations
        self.limit: int | None = None
        self.count = 0
        self.construct("iteration_relay", {})

    def get_n_in(self) -> int:
        return ca.nlpsol_n_out()

    def get_n_out(self) -> int:
        return 1

    def get_name_in(self, i: int) -> str:
        return ca.nlpsol_out(i)

    def get_name_out(self, i: int) -> str:
        return "ret"

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        name = ca.nlpsol_out(i)
        if name == "f":
            return ca.Sparsity.scalar()
        if name == "x":
            return ca.Sparsity.dense(self.nx)
        if name == "g":
            return ca.Sparsity.dense(self.ng)
        return ca.Sparsity(0, 0)

    def eval(self, arg):
        k = self.count  # the first call is IPOPT's iteration 0 (the starting point)
        self.count += 1
        if self.listener is not None:
            try:
                self.listener(k, np.array(arg[0]).ravel(), np.array(arg[2]).ravel())
            except Exception:  # a reporter's bug must not change the plan
                self.listener = None
        return [1 if self.limit is not None and k >= self.limit else 0]


@contextlib.contextmanager
def _keyboard_interrupts():
    """Let a Ctrl-C during an IPOPT solve stop the planner.

    CasADi turns a KeyboardInterrupt raised inside IPOPT into a failed solve
    (``NonIpopt_Exception_Thrown``); the planner's fallbacks would take that for a failed
    start and go on to plan and write files.  The interrupt is noted here and raised once
    the solver has returned.  Only where Python's default SIGINT handler is in place (the
    main thread; not where SIGINT is ignored, e.g. a Dask worker).
    """
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        yield
        return
    seen: list[int] = []

    def note(signum, frame):
        seen.append(signum)
        raise KeyboardInterrupt

    signal.signal(signal.SIGINT, note)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if seen:
        raise KeyboardInterrupt


@dataclass(frozen=True)
class PlannerOptions:
    lock_redundancy: bool = False  # psi fixed at 90 deg (or the waypoints' psi) throughout
    torque_safety: float = 0.98  # initial node bound = safety * limit (then tightened only
    #                              where the dense re-check finds an overshoot between nodes)
    max_iter: int = 600  # the held-out set was measured at 250 (BENCHMARKS.md); the fixed-
    #                      duration effort solve needs more (tests/test_motion.py)
    start_max_iter: int = 250  # the cap of an NLP start that a fallback follows
    tol: float = 1e-4  # IPOPT's tol (acceptable: 10x for 5 iterations); 4-35% fewer
    #                    iterations than 1e-6, the same durations to 4 digits (BENCHMARKS.md)
    # IPOPT's constr_viol_tol, also for an acceptable stop (IPOPT's default there is
    # 1e-2): the largest residual of a row left in a returned solution: [rad] or [m] in
    # the integration rows, [10 N m] in the dynamics rows (ROW_SCALE).  The written
    # torques are Pinocchio's, not these variables (control/validation.py)
    constr_viol_tol: float = 1e-4
    regularisation: float = 1e-4
    verbose: bool = False
    #: extra IPOPT options as (name, value) pairs, applied over the planner's own (expert
    #: use: the planner's settings are the fastest measured, BENCHMARKS.md; e.g.
    #: ``(("print_timing_statistics", "yes"), ("print_level", 5))`` shows where a solve's
    #: time goes).  A name or value IPOPT rejects raises ValueError when the NLP is built.
    ipopt_options: tuple[tuple[str, Any], ...] | dict[str, Any] = ()

    def __post_init__(self) -> None:
        try:
            pairs = (tuple(self.ipopt_options.items()) if isinstance(self.ipopt_options, dict)
                     else tuple(tuple(p) for p in self.ipopt_options))
        except TypeError:
            raise ValueError(f"ipopt_options: {self.ipopt_options!r}; valid: (name, value) "
                             "pairs or a dict") from None
        for pair in pairs:
            if len(pair) != 2 or not isinstance(pair[0], str):
                raise ValueError(f"ipopt_options: {pair!r} is not a (name, value) pair")
            name, value = pair
            number = isinstance(value, (int, float)) and not isinstance(value, bool)
            if not (isinstance(value, str) or (number and math.isfinite(value))):
                raise ValueError(f"ipopt_options: {name} = {value!r}; valid: a finite "
                                 "number or a string")
        object.__setattr__(self, "ipopt_options", pairs)


@dataclass
class Solution:
    """A solved plan: node trajectory, timings, statistics and its own dense re-check."""

    found: bool
    status: str
    final_time: float  # [s]
    solve_time: float  # [s] wall clock of the NLP solves
    iterations: int
    segment_times: np.ndarray  # (S,) [s]
    t: np.ndarray  # (N+1,) node times [s]
    x: np.ndarray  # (N+1, 9) minimal coordinates
    xd: np.ndarray  # (N+1, 9)
    xdd: np.ndarray  # (N+1, 9)
    tau: np.ndarray  # (N+1, 9) actuator torques [N m]
    theta: np.ndarray  # (N+1, 9) actuated angles [rad]
    residuals: dict[str, float]  # max violations of the NLP's equality constraints
    active_limits: list[str]
    robot: Robot  # the robot planned for
    limits: Limits  # the limits planned to (the robot's, tightened by the task)
    check: DenseCheck | None = None
    options: PlannerOptions = field(default_factory=PlannerOptions)
    task: Task | None = None
    #: NLP solves behind this plan (1 + re-solves after the dense check)
    solves: int = 1
    #: final uniform time scale applied after the NLP (1: the NLP's own timing)
    time_scale: float = 1.0
    #: the NLP's primal-dual point (x, lam_x, lam_g), to warm-start a re-solve
    nlp_point: tuple | None = field(default=None, repr=False)
    #: "ocp" (the time-optimal NLP) or "baseline" (planner.baseline: stop at every
    #: waypoint, straight lines, TOPP-RA per segment; returned when the NLP failed or
    #: was slower)
    source: str = "ocp"
    #: duration [s] of the baseline plan of the same task (None: no admissible baseline)
    baseline_time: float | None = None
    #: wall clock [s] of the whole Problem.solve() (static choices, baseline, NLPs, checks)
    wall_time: float = 0.0

    def sample(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, xd, xdd) at arbitrary times [s] from the exact piecewise-cubic motion."""
        return sample_cubic(self.t, self.x, self.xd, self.xdd, times)

    def is_feasible(self) -> bool:
        return bool(self.found and self.check is not None and self.check.ok)


def sample_cubic(t: np.ndarray, x: np.ndarray, xd: np.ndarray, xdd: np.ndarray,
                 times) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x, xd, xdd) at ``times`` of the piecewise-cubic motion with node times ``t`` and
    node values (x, xd, xdd), the acceleration linear between the nodes."""
    times = np.clip(np.asarray(times, dtype=float), 0.0, t[-1])
    k = np.clip(np.searchsorted(t, times, side="right") - 1, 0, len(t) - 2)
    h = (t[k + 1] - t[k])[:, None]
    s = (times - t[k])[:, None]
    u0, u1 = xdd[k], xdd[k + 1]
    jerk = (u1 - u0) / h
    return (x[k] + s * xd[k] + s**2 / 2 * u0 + s**3 / 6 * jerk,
            xd[k] + s * u0 + s**2 / 2 * jerk, u0 + s * jerk)


def actuated_profile(robot: Robot, x: np.ndarray, xd: np.ndarray,
                     xdd: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(theta_dot, theta_ddot, tau, tau_gravity), each (9, n), of the samples (n, 9) of a
    motion, with ``robot``'s CasADi model (:func:`dynamics.symbolic.profile_function`,
    compiled: ~20x faster than the interpreted functions on 400 samples, the same
    numbers, BENCHMARKS.md)."""
    from sixplus3.dynamics.codegen import compiled_profile

    f, p = compiled_profile(robot)
    out = f.map(len(x))(x.T, xd.T, xdd.T, p)
    return tuple(np.array(v) for v in out)  # type: ignore[return-value]


def stretch_factors(thd, thdd, tau, grav, lim: Limits, fraction: float) -> np.ndarray:
    """(n,) smallest uniform time stretch a > 0 per sample bringing the
    :func:`actuated_profile` within ``fraction`` of the velocity, acceleration and torque
    limits (theta_dot scales 1/a, theta_ddot and tau - tau_gravity 1/a^2).  Where gravity
    alone exceeds the fraction the headroom is floored at 1e-3 of the limit."""
    dyn = tau - grav
    room_hi = fraction * lim.torque - grav  # d / a^2 <= room_hi
    room_lo = fraction * lim.torque + grav  # -d / a^2 <= room_lo
    need = np.where(dyn > 0, dyn / np.maximum(room_hi, 1e-3 * lim.torque),
                    -dyn / np.maximum(room_lo, 1e-3 * lim.torque))
    a2 = np.maximum.reduce([
        (np.abs(thd) / (fraction * lim.velocity)) ** 2,
        np.abs(thdd) / (fraction * lim.acceleration), need]).max(axis=0)
    return np.sqrt(np.maximum(a2, 1e-12))


@dataclass(frozen=True)
class DenseCheck:
    """Independent re-check of a plan with the numeric model at a given density."""

    ok: bool
    samples: int
    max_torque_ratio: float  # max |tau| / limit (Pinocchio constrained inverse dynamics)
    max_velocity_ratio: float
    max_acceleration_ratio: float
    min_margin: float  # smallest official margin (leg type I/II, platform)
    min_margin_leg_type1: float
    min_margin_leg_type2: float
    min_margin_platform: float
    theta_range_ok: bool
    max_spherical_tilt: float  # [rad]
    min_clearance: float  # [m] of the collision model (kinematics.collision)
    violations: list[str]
    max_tcp_speed: float = float("nan")  # [m/s] tool centre point
    max_tcp_acceleration: float = float("nan")  # [m/s^2]


# --------------------------------------------------------------------- static choices
def static_checks(robot: Robot, limits: Limits, position, rotation, psis: np.ndarray):
    """One pose with candidate crank angles (k, 3), checked in order (batched):
    (cfg, theta_ok, spherical_ok, clearance_ok, margin), each mask implying the previous
    and margin = the smallest singularity margin where clearance_ok, else -1."""
    cfg = robot_ik(position, rotation, psis, robot)
    theta_ok, sph_ok = pose_masks(cfg, limits)
    clear_ok = sph_ok & (clearance(cfg) >= 0.0)
    margin = np.where(clear_ok, cfg.margins.minimum, -1.0)
    return cfg, theta_ok, sph_ok, clear_ok, margin


def _static_candidates(robot: Robot, limits: Limits, wp: Waypoint, locked: bool):
    """Crank-angle candidates at a waypoint with their official checks (batched)."""
    if wp.psi is not None:
        psis = wp.psi[None, :]
    elif locked:
        psis = np.asarray(robot.home_psi)[None, :]
    else:
        axis = np.radians(np.arange(35.0, 146.0, 10.0))
        psis = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3)
    return (psis, *static_checks(robot, limits, wp.position, wp.rotation, psis))


def choose_static_psi(task: Task, robot: Robot, lim: Limits, locked: bool,
                      at_rest: set[int]) -> np.ndarray:
    """Per waypoint, crank angles maximising the smallest margin; raises naming the limit."""
    from sixplus3.dynamics.closed_loop import ClosedLoopDynamics

    dyn = ClosedLoopDynamics(robot)
    out = []
    for k, wp in enumerate(task.waypoints):
        psis, cfg, theta_ok, sph_ok, clear_ok, margin = _static_candidates(robot, lim, wp,
                                                                           locked)
        where = f"waypoint {k} (position {np.round(wp.position, 4).tolist()} m)"
        if not cfg.ok.any():
            st = next(int(s) for s in cfg.leg_status[0] if s)
            leg = int(np.flatnonzero(cfg.leg_status[0])[0])
            from sixplus3.kinematics.leg import failing_chain, status_reason

            raise InfeasibleTaskError(
                f"{where} is outside the workspace: leg {leg} {failing_chain(st)} chain: "
                f"{status_reason(st)}", k, "reach",
                value=wp.position.tolist(), valid="inside the workspace")
        if not theta_ok.any():
            raise InfeasibleTaskError(
                f"{where}: an actuated angle leaves [{math.degrees(lim.theta_min):g}, "
                f"{math.degrees(lim.theta_max):g}] deg (base collision) for every crank "
                "choice", k, "theta range",
                value=wp.position.tolist(),
                valid=f"[{math.degrees(lim.theta_min):g}, {math.degrees(lim.theta_max):g}] deg")
        if not sph_ok.any():
            raise InfeasibleTaskError(
                f"{where}: a spherical joint exceeds {math.degrees(lim.spherical):g} deg for "
                "every crank choice", k, "spherical joints",
                value=wp.position.tolist(), valid=f"<= {math.degrees(lim.spherical):g} deg")
        if not clear_ok.any():
            from sixplus3.kinematics.collision import closest

            c = clearance(cfg, sph_ok)
            a, b, d = closest(cfg, int(np.argmax(c)))
            raise InfeasibleTaskError(
                f"{where}: bodies interfere for every crank choice (at the best one, "
                f"{a} and {b} overlap by {-d * 1e3:.1f} mm)",
                k, "interference", value=wp.position.tolist(), valid="clearance >= 0 m")
        # crank angles inside the NLP's range [PSI_MIN, PSI_MAX] first (its platform
        # margin rows hold there only): a waypoint at 145 deg made the NLP's start
        # clip to 135 deg and fail (BENCHMARKS.md); outside it only when nothing inside
        # passes (then the baseline can still plan it)
        inside = np.all((psis >= PSI_MIN - 1e-12) & (psis <= PSI_MAX + 1e-12), axis=1)
        order = np.argsort(-np.where(inside & (margin >= lim.margin), margin + 10.0, margin),
                           kind="stable")
        if margin[order[0]] < lim.margin:
            raise InfeasibleTaskError(
                f"{where}: no crank choice keeps every singularity margin >= {lim.margin:g} "
                f"(best {margin[order[0]]:.4f} at psi = "
                f"{np.round(np.degrees(psis[order[0]]), 1).tolist()} deg)", k, "margin",
                value=float(margin[order[0]]), valid=f">= {lim.margin:g}")
        chosen = None
        best_tau = math.inf
        for idx in order[:40]:
            if margin[idx] < lim.margin:
                break
            if k not in at_rest:
                chosen = idx
                break
            tau = dyn.gravity_torques(cfg.q[idx])
            if np.abs(tau).max() <= lim.torque * 0.95:
                chosen = idx
                break
            best_tau = min(best_tau, float(np.abs(tau).max()))
        if chosen is None:
            given = task.limits.get("torque", robot.limits.torque)
            raise InfeasibleTaskError(
                f"{where}: holding the platform at rest needs {best_tau:.2f} N m > "
                f"{lim.torque:g} N m (the torque limit planned to: {given:g} N m x "
                f"torque_fraction {task.torque_fraction:g}) for every crank choice with "
                f"margins >= {lim.margin:g}", k, "torque", value=best_tau,
                valid=f"<= {lim.torque:g} N m")
        out.append(psis[chosen])
    return np.array(out)


# --------------------------------------------------------------------- the problem
class Problem:
    """A planning problem for one task on one robot (``solve()`` -> :class:`Solution`).

    The limits are the robot's hardware limits tightened by the task's
    (:meth:`Task.limits_for`: a looser one raises :class:`LimitError`).
    """

    def __init__(self, task: Task, robot: Robot | None = None,
                 options: PlannerOptions | None = None, progress: Any = None) -> None:
        check_plan_arguments(task, robot, options)
        # the task's setup (payload, tool, mounting) on the robot; TCP waypoints become
        # platform poses through that robot's tool
        self.robot = task.robot_for(robot or Robot.default())
        self.task = task.resolved(self.robot)
        #: every limit the plan must meet; the NLP plans to ``limits``, the same without
        #: the platform-space ones, which a uniform time stretch meets afterwards
        self.motion_limits = task.limits_for(self.robot)
        self.limits = self.motion_limits.without_tcp()
        self.options = options or PlannerOptions()
        self.sr = symbolic_robot(self.robot)
        #: a :class:`sixplus3.progress.PlanProgress` (stages and IPOPT iterations) or None
        self.progress = progress
        #: upper bound [s] of the NLP's total duration (set by solve(): 1.5x the baseline's)
        self.duration_cap: float | None = None

    def _stage(self, text: str) -> None:
        if self.progress is not None:
            self.progress.stage("  " + text)  # a sub-step of the caller's "planning ..."

    # -- initial guess
    def waypoint_states(self, psi_wp: np.ndarray) -> np.ndarray:
        """(W, 9) minimal coordinates of the waypoints with the crank angles ``psi_wp``,
        the rotation vectors kept continuous (|r| near pi has two forms)."""
        rv_prev = None
        rows = []
        for k, wp in enumerate(self.task.waypoints):
            rv = rotvec(wp.rotation)
            if rv_prev is not None and np.linalg.norm(rv - rv_prev) > math.pi:
                ang = np.linalg.norm(rv)
                rv = rv - 2 * math.pi * rv / ang
            rv_prev = rv
            rows.append(np.r_[wp.position, rv, psi_wp[k]])
        return np.array(rows)

    def _guess(self, psi_wp: np.ndarray):
        task = self.task
        ns = task.segment_nodes
        S = task.n_segments
        wp_x = self.waypoint_states(psi_wp)
        frac = self.node_fractions()
        xs, seg_T = [], []
        for s in range(S):
            a, b = wp_x[s], wp_x[s + 1]
            rots = Rotation.from_rotvec([a[3:6], b[3:6]])
            c = np.r_[0.0, np.cumsum(frac[s])]  # the nodes' share of the segment
            tau = c[:-1] if s < S - 1 else c
            sm = 3 * tau**2 - 2 * tau**3  # rest-to-rest smooth blend for the guess
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
        # Time-scale each segment (rest to rest) so the guess just meets 90% of the
        # velocity, acceleration and torque limits: with time stretched by a, theta_dot
        # scales 1/a and theta_ddot and the inertial torques 1/a^2, exactly.
        stretch = self._time_stretch(x, xd, xdd, 0.9)
        seg = np.minimum(np.arange(len(x)) // ns, S - 1)
        scale = np.clip([stretch[seg == s].max() for s in range(S)], 0.05, 50.0)
        a = np.repeat(scale, ns)
        a = np.r_[a, a[-1]][:, None]
        return wp_x, x, xd / a, xdd / a**2, T * scale

    def _time_stretch(self, x, xd, xdd, fraction: float) -> np.ndarray:
        """(n,) smallest a > 0 per sample such that stretching time by a brings it within
        ``fraction`` of the velocity, acceleration and torque limits.

        Under t -> a t on a fixed path theta_dot scales by 1/a, theta_ddot and the
        inertial torques (tau - tau_gravity) by 1/a^2, exactly for the links and the
        rotors; the joint friction scales less (its viscous part by 1/a), which the
        dense check of the result covers (:meth:`_retime` keeps the original plan if it
        fails).  Samples whose gravity
        torque alone exceeds the fraction get the largest stretch the formula allows
        (1e3-fold headroom floor), i.e. they are reported as needing a very slow motion.
        """
        return stretch_factors(*actuated_profile(self.robot, x, xd, xdd), self.limits,
                               fraction)

    def solve(self) -> Solution:
        t_wall = time.perf_counter()
        task, opt = self.task, self.options
        at_rest = self.rest_waypoints()
        self._check_crank_sides()
        psi_wp = choose_static_psi(task, self.robot, self.limits, opt.lock_redundancy,
                                   at_rest)
        if opt.lock_redundancy:
            fixed = [wp.psi for wp in task.waypoints if wp.psi is not None]
            lock = fixed[0] if fixed else np.asarray(self.robot.home_psi)
            psi_wp = np.tile(lock, (len(task.waypoints), 1))
        proxy = max(0.5, 6 * self.limits.margin)
        safety = {"torque": opt.torque_safety, "velocity": opt.torque_safety,
                  "acceleration": opt.torque_safety}
        # grown by re-solves: [rad] below the spherical joints' limit, [m] of clearance
        # between the legs' links (None: those rows unbounded, see _clearance_needed)
        reserve: dict[str, Any] = {"spherical": 0.0,
                   "clearance": 0.0 if self._clearance_needed(psi_wp) else None}
        # The baseline (stop at every waypoint, straight lines, TOPP-RA per segment):
        # feasible by construction when its lines are admissible, the NLP's first warm
        # start, and the plan returned when the NLP fails or is slower.
        from sixplus3.planner.baseline import baseline_plan

        self._stage("crank angles at the waypoints chosen; building the stop-at-waypoints "
                    "baseline (TOPP-RA per segment)")
        base, self.baseline_note = baseline_plan(self, psi_wp)
        # a plan slower than the baseline is never returned, so the NLP's total duration
        # is bounded at 1.5x the baseline's: a trust region that stops IPOPT's early
        # quasi-Newton steps from running the durations up to the 60 s bound, which is how
        # most failed starts failed (BENCHMARKS.md)
        self.duration_cap = None if base is None else 1.5 * base.final_time
        self._stage(f"baseline: {base.final_time:.4f} s" if base is not None else
                    f"no admissible baseline ({self.baseline_note})")
        sol, first, failed = self._first_solve(psi_wp, proxy, safety, reserve, base)
        if sol is None:
            if base is not None:
                base.solve_time += failed
                return self._finish(base, base, t_wall, psi_wp, proxy, safety, reserve)
            assert first is not None
            raise first
        total, solves = sol.solve_time, 1
        # The OCP constrains the nodes; the dense re-check sees between them.  Tighten what
        # the check found violated and re-solve from the previous solution (at most 5x).
        for _ in range(5):
            chk = sol.check
            assert chk is not None  # _solve_once always re-checks its solution
            bad = chk.violations
            if not bad:
                break
            if all(v.startswith(("torque", "velocity", "acceleration")) for v in bad):
                # only limits that a uniform time stretch fixes: stretch the plan (up to
                # 5% slower) instead of re-solving with tighter bounds, which costs a
                # whole NLP solve and tightens the bounds everywhere, not just where the
                # overshoot is (BENCHMARKS.md)
                slow = self._retime(sol, proxy, max_stretch=1.05)
                if slow is not sol:
                    self._stage(f"the dense check found {'; '.join(bad)}: time stretched "
                                f"by {slow.time_scale / sol.time_scale:.4f} instead of a "
                                "re-solve")
                    sol = slow
                    break
            ratios = {"torque": chk.max_torque_ratio,
                      "velocity": chk.max_velocity_ratio,
                      "acceleration": chk.max_acceleration_ratio}
            fixable = False
            for name in safety:
                if any(v.startswith(name) for v in bad):
                    safety[name] *= 0.985 / ratios[name]
                    fixable = True
            if any(v.startswith("platform") for v in bad):
                proxy = min(0.9, proxy + 0.2)
                fixable = True
            if any(v.startswith("spherical") for v in bad):
                # bound the tilts below 150 deg by the overshoot found, plus 0.25 deg
                over = chk.max_spherical_tilt - (self.limits.spherical
                                                       - reserve["spherical"])
                reserve["spherical"] += over + math.radians(0.25)
                fixable = fixable or reserve["spherical"] < math.radians(10.0)
            if any(v.startswith("interference") for v in bad):
                # ask the OCP for the overlap found plus 0.5 mm of clearance at its points
                if reserve["clearance"] is None:  # the rows were unbounded: bound them
                    reserve["clearance"] = 0.0
                else:  # overshoot between the constrained points: ask for more
                    reserve["clearance"] += -chk.min_clearance + 5e-4
                fixable = fixable or reserve["clearance"] < 0.01
            if not fixable:
                break
            self._stage(f"re-solve {solves}: the dense check found {'; '.join(bad)}; "
                        "tightening those limits")
            try:
                nxt = self._solve_once(psi_wp, proxy, safety, warm=sol, reserve=reserve,
                                       margin=self.margin_rows)
            except InfeasibleTaskError as exc:
                if exc.limit is None or not exc.limit.startswith("solver"):
                    raise
                break  # keep the last iterate; the baseline below may replace it
            total += nxt.solve_time
            solves += 1
            sol = nxt
        sol.solve_time, sol.solves = total, solves
        if sol.check is not None and sol.check.ok:
            self._stage("re-timing the checked plan up to 99.5% of its binding limit")
            sol = self._retime(sol, proxy)
        return self._finish(sol, base, t_wall, psi_wp, proxy, safety, reserve)

    def _first_solve(self, psi_wp, proxy, safety, reserve, base):
        """(Solution or None, the first solver error, seconds spent in failed starts),
        trying in turn: a homotopy step in the margin from the baseline (the margin rows
        at 0.6 x the margin; its plan is kept if the dense check, against the task's own
        margin, passes: the OCP's margin rows are conservative proxies, det J-hat >= 3 m
        and the platform's line determinant >= max(0.5, 6 m), so a plan can meet the
        official margin although the NLP at the full margin was declared infeasible;
        otherwise it is re-solved from there at the task's margin); the NLP at the task's
        margin from the baseline; the kinematic guess twice as slow.  With no baseline:
        the kinematic guess, twice as slow, then the homotopy from the guess.  Failed
        starts count in the solve time.
        """
        margin = self.limits.margin
        self.margin_rows: float | None = None  # the margin of the NLP's rows (None: the task's)
        # the order is measured (BENCHMARKS.md, held-out set): the homotopy first planned
        # every task in one solve, its plans met the task's margin in the dense check, and
        # it removed the 4-7 s that a start at the full margin spent before declaring a
        # feasible task infeasible (p95 wall time 4.0 -> 3.1 s); the plain guess never
        # planned where these failed
        homotopy = {"warm": base, "margin": 0.6 * margin}
        starts: list[dict[str, Any]] = (
            [homotopy, {"warm": base}, {"time_scale": 2.0}] if base is not None
            else [{}, {"time_scale": 2.0}, homotopy])
        first = None
        failed = 0.0
        for i, start in enumerate(starts):
            t0 = time.perf_counter()
            # a start that a fallback follows stops at start_max_iter (held-out set:
            # no start that planned needed more, BENCHMARKS.md); the last runs to max_iter
            if i < len(starts) - 1 and self.options.start_max_iter < self.options.max_iter:
                start = {**start, "max_iter": self.options.start_max_iter}
            self._stage("NLP " + ("from the baseline" if start.get("warm") is not None
                                  else "from the kinematic guess")
                        + (" at 0.6 x the margin (homotopy)" if "margin" in start else "")
                        + (", twice as slow" if "time_scale" in start else ""))
            try:
                sol = self._solve_once(psi_wp, proxy, safety, reserve=reserve, **start)
                if "margin" in start and any("margin" in v for v in sol.check.violations):
                    sol = self._solve_once(psi_wp, proxy, safety, reserve=reserve, warm=sol)
                elif "margin" in start:
                    # the homotopy's plan meets the task's margin: re-solves keep its rows
                    self.margin_rows = start["margin"]
            except InfeasibleTaskError as exc:
                if exc.limit is None or not exc.limit.startswith("solver"):
                    raise
                first = first or exc
                spent = time.perf_counter() - t0
                failed += spent
                self._stage(f"  failed ({exc.value}) after {spent:.1f} s")
                continue
            sol.solve_time += failed
            return sol, None, failed
        return None, first, failed

    def _finish(self, sol: Solution, base: Solution | None, t_wall: float, psi_wp,
                proxy, safety, reserve) -> Solution:
        """The returned plan: the NLP's, or the baseline when the NLP's failed its check
        or is slower; then the task's duration or speed, if it asks for one."""
        if base is not None and sol is not base and (
                not (sol.check is not None and sol.check.ok)
                or sol.final_time > base.final_time):
            base.solve_time += sol.solve_time
            base.solves = sol.solves
            sol = base
            self._stage("returning the baseline (the NLP's plan failed its check or is "
                        "slower)")
        target = self._target_duration(sol)
        if target is not None:
            self._stage(f"stretching to the task's duration, {target:.4f} s (minimum "
                        "effort at that duration)")
            sol = self._fixed_duration(sol, target, psi_wp, proxy, safety, reserve)
        if sol.check is not None:  # limits that bind between the nodes
            for name, ratio in (("torque", sol.check.max_torque_ratio),
                                ("velocity", sol.check.max_velocity_ratio),
                                ("acceleration", sol.check.max_acceleration_ratio)):
                if ratio > 0.99 and not any(a.startswith(name) for a in sol.active_limits):
                    sol.active_limits.append(f"{name} ({ratio:.3f} of the limit in the "
                                             "dense check)")
        sol = self._tcp_limited(sol)
        sol.baseline_time = base.final_time if base is not None else None
        sol.wall_time = time.perf_counter() - t_wall
        return sol

    def _tcp_limited(self, sol: Solution, target: float = 0.995) -> Solution:
        """``sol`` within the platform-space limits (the tool centre point's speed and
        acceleration): stretched uniformly in time by the smallest factor that brings
        both within ``target`` of their limits (the speed scales 1/a, the acceleration
        1/a^2, every joint rate and inertial torque with them), then checked against
        every limit.  Without such limits: ``sol`` as it is."""
        lim = self.motion_limits
        if not lim.has_tcp:
            return sol
        if sol.check is None:
            sol.check = dense_check(sol, factor=10)
        # the dense check measured the tool centre point on the same samples
        speed, acc = sol.check.max_tcp_speed, sol.check.max_tcp_acceleration
        a = max(1.0, speed / (target * lim.tcp_speed),
                math.sqrt(acc / (target * lim.tcp_acceleration)))
        if a > 1.0:
            self._stage(f"stretching time by {a:.3f} for the tool centre point's limits "
                        f"({lim.tcp_speed:g} m/s, {lim.tcp_acceleration:g} m/s^2)")
            by_speed = speed / lim.tcp_speed >= math.sqrt(acc / lim.tcp_acceleration)
            sol = self._stretched(sol, a)
            sol.active_limits = [f"tcp {'speed' if by_speed else 'acceleration'} (uniform "
                                 f"stretch {a:.3f})"]
        sol.limits = lim
        sol.check = dense_check(sol, factor=10)
        return sol

    def _target_duration(self, sol: Solution) -> float | None:
        """The duration the task asks for (None: minimum time); raises if it is shorter
        than the minimum-time plan."""
        task = self.task
        if task.duration is None and task.speed is None:
            return None
        if not (sol.check is not None and sol.check.ok):
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

    def _stretched(self, sol: Solution, a: float) -> Solution:
        """``sol`` with time scaled uniformly by ``a`` (slower for a > 1; the path kept,
        rates / a, accelerations / a^2, torques recomputed with the whole model),
        dense-checked."""
        tau = actuated_profile(self.robot, sol.x, sol.xd / a, sol.xdd / a**2)[2].T
        new = Solution(
            found=True, status=sol.status, final_time=sol.final_time * a,
            solve_time=sol.solve_time, iterations=sol.iterations,
            segment_times=sol.segment_times * a, t=sol.t * a, x=sol.x, xd=sol.xd / a,
            xdd=sol.xdd / a**2, tau=tau, theta=sol.theta, residuals=sol.residuals,
            active_limits=[], robot=sol.robot, limits=sol.limits, options=sol.options,
            task=sol.task, nlp_point=None, solves=sol.solves,
            time_scale=sol.time_scale * a)
        new.check = dense_check(new, factor=10)
        return new

    def _fixed_duration(self, sol: Solution, target: float, psi_wp, proxy, safety,
                        reserve) -> Solution:
        """A plan of exactly ``target`` seconds that minimises the mean squared torque,
        warm-started from the minimum-time plan stretched uniformly to that duration
        (which is the fallback when the effort solve fails its dense check)."""
        slow = self._stretched(sol, target / sol.final_time)
        try:
            eff = self._solve_once(psi_wp, proxy, safety, warm=slow,
                                   reserve=reserve, duration=target)
        except InfeasibleTaskError:
            eff = None
        best = slow
        if eff is not None and eff.check is not None and eff.check.ok:
            best = eff
        best.solve_time = sol.solve_time + (eff.solve_time if eff is not None else 0.0)
        best.solves = sol.solves + 1
        if not (best.check is not None and best.check.ok):
            return sol  # neither passed: the minimum-time plan and its diagnosis
        return best

    def _retime(self, sol: Solution, platform_proxy: float, target: float = 0.995,
                max_stretch: float = 1.0) -> Solution:
        """Compress the verified plan uniformly in time up to ``target`` of its limits
        (or, with ``max_stretch`` > 1, slow down a plan whose torques, rates or
        accelerations exceed ``target`` by a stretch 1 < a <= ``max_stretch``).

        The OCP bounds the torques at the nodes and midpoints at a safety fraction of the
        limit, so the verified plan usually keeps 1-2% in reserve everywhere.  Stretching
        time by a keeps the path (and every margin) and scales theta_dot by 1/a and
        theta_ddot and the inertial torques by 1/a^2 exactly, so the smallest a that
        keeps every dense sample within ``target`` of the limits follows in closed form.
        The result is re-checked with Pinocchio; if that check fails, the original plan
        is kept.
        """
        times = np.linspace(0.0, sol.t[-1], (len(sol.t) - 1) * 10 + 1)
        x, xd, xdd = sol.sample(times)
        a = float(self._time_stretch(x, xd, xdd, target).max())
        wanted = 1.0 < a <= max_stretch if max_stretch > 1.0 else 0.5 < a < 1.0
        if not wanted:
            return sol
        new = self._stretched(sol, a)
        assert new.check is not None
        if not new.check.ok:
            return sol
        safety = {"torque": 1.0, "velocity": 1.0, "acceleration": 1.0}
        new.active_limits = self._active(new.x, new.xd, new.xdd, new.tau, new.t,
                                         platform_proxy, safety)
        return new

    def _clearance_needed(self, psi_wp: np.ndarray, near: float = 0.02) -> bool:
        """Whether the legs' links come within ``near`` [m] at some waypoint.

        Only then are the clearance rows bounded from the first solve; otherwise they
        stay unbounded (IPOPT ignores them) unless the dense check finds interference.
        Bounding them everywhere made IPOPT slower and lost a random task (BENCHMARKS.md).
        """
        wps = self.task.waypoints
        cfg = robot_ik(np.array([wp.position for wp in wps]),
                       np.array([wp.rotation for wp in wps]), psi_wp, self.robot)
        return bool(clearance(cfg).min() < near)

    def _solve_once(self, psi_wp: np.ndarray, platform_proxy: float, safety: dict,
                    warm: Solution | None = None, time_scale: float = 1.0,
                    reserve: dict | None = None, duration: float | None = None,
                    margin: float | None = None, max_iter: int | None = None) -> Solution:
        """One NLP solve from the kinematic guess (stretched by ``time_scale``) or from
        ``warm`` (a plan of this task: its primal-dual point if it has one, else its
        motion on this NLP's nodes); ``margin`` overrides the singularity margin of the
        constraints (a homotopy step: the result is still checked against the task's);
        ``max_iter`` stops the solve earlier than ``options.max_iter`` (a failed start)."""
        task, opt, sr = self.task, self.options, self.sr
        lim = self.limits if margin is None else replace(self.limits, margin=margin)
        ns, S = task.segment_nodes, task.n_segments
        N = ns * S
        wp_x, x0, xd0, xdd0, T0 = self._guess(psi_wp)
        if time_scale != 1.0:
            T0, xd0, xdd0 = T0 * time_scale, xd0 / time_scale, xdd0 / time_scale**2
        if warm is not None:
            x0, xd0, xdd0, T0 = self._on_nodes(warm)
        # the start at the nodes and the midpoints (the NLP's points), with its theta_dot,
        # theta_ddot, torques and gravity torques from the model
        t0 = self.node_times(T0)
        xm, xdm, um = sample_cubic(t0, x0, xd0, xdd0, (t0[:-1] + t0[1:]) / 2)
        pts = (np.r_[x0, xm], np.r_[xd0, xdm], np.r_[xdd0, um])
        profile = actuated_profile(self.robot, *pts)
        if warm is not None and warm.nlp_point is None and duration is None:
            # a plan at 99.5% of its limits (the baseline, a stretched plan) exceeds this
            # NLP's bounds (safety x limit): slowed uniformly to just inside them, so the
            # start is not clipped into violating the dynamics rows (the clipped baseline
            # started IPOPT with theta_ddot and torque residuals of 3-13 units and sent
            # some solves astray, BENCHMARKS.md)
            a = float(stretch_factors(*profile, self.limits,
                                      0.99 * min(safety.values())).max())
            if 1.0 < a < 2.0:
                T0, xd0, xdd0 = T0 * a, xd0 / a, xdd0 / a**2
                pts = (pts[0], pts[1] / a, pts[2] / a**2)  # the same cubics, slower
                profile = actuated_profile(self.robot, *pts)
        # Constraint signs from the guess (a margin keeps its sign inside a free region).
        m1, m2, _ = sr.margins.map(N + 1)(x0.T)
        sign1 = np.sign(np.median(np.array(m1), axis=1))
        sign2 = np.sign(np.median(np.array(m2), axis=1))

        tmpl = self._template()
        tmax = safety["torque"] * lim.torque
        lb, ub = self._node_bounds(lim, sign1, sign2, platform_proxy, safety, reserve)
        # smoothness rows (see _template): per limit, 2 x 9N rows, each in [-1, 1]
        smooth_lo, smooth_hi = np.full(36 * N, -1.0), np.full(36 * N, 1.0)
        cap = self.duration_cap
        T_lo, T_hi = ((0.0, np.inf if cap is None else cap) if duration is None
                      else (duration, duration))
        lbx, ubx = self._variable_bounds(wp_x, tmax, safety["acceleration"] * lim.acceleration,
                                         T_hi)
        lbg = np.r_[np.zeros(18 * N), np.tile(lb, 2 * N + 1), smooth_lo, T_lo]
        ubg = np.r_[np.zeros(18 * N), np.tile(ub, 2 * N + 1), smooth_hi, T_hi]
        _, acc0, tau0, _ = profile  # (9, 2N+1): the nodes, then the midpoints
        z0 = np.vstack([x0.T, xd0.T, xdd0.T, tau0[:, :N + 1]])
        w0 = np.clip(np.r_[z0.ravel(order="F"), tau0[:, N + 1:].ravel(order="F"),
                           acc0.ravel(order="F"), T0], lbx, ubx)
        if warm is not None and warm.nlp_point is not None:
            # a re-solve with tightened bounds: start IPOPT from the previous primal-dual
            # point (same variable scaling) with a small barrier parameter
            tmpl = self._template(warm_start=True)
            ws, lam_x, lam_g, D = warm.nlp_point
            args = {"x0": ws, "lam_x0": lam_x, "lam_g0": lam_g}
        else:
            D = self._variable_scale(tmax)
            args = {"x0": w0 / D}
        solver, relay = tmpl["solver"], tmpl["relay"]
        weights = (1.0, 0.0) if duration is None else (0.0, 1.0)
        args.update(p=np.r_[D, lim.jerk, lim.torque_rate, weights,
                            self.node_fractions().ravel()], lbx=lbx / D,
                    ubx=ubx / D, lbg=lbg, ubg=ubg)
        if self.progress is not None:
            relay.listener = self._iteration_listener(D[-S:], lbg, ubg)
        relay.count, relay.limit = 0, max_iter
        t_start = time.perf_counter()
        try:
            with _keyboard_interrupts():
                res = solver(**args)
        finally:
            relay.listener, relay.limit = None, None
        solve_time = time.perf_counter() - t_start
        stats = solver.stats()
        status = str(stats.get("return_status", "unknown"))
        if status == "User_Requested_Stop" and max_iter is not None:
            status = "Maximum_Iterations_Exceeded"  # the relay's cap (a start's)
        found = status in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
        w = np.array(res["x"]).ravel() * D
        Z = w[:36 * (N + 1)].reshape(N + 1, 36)
        x, xd, u, tau = Z[:, 0:9], Z[:, 9:18], Z[:, 18:27], Z[:, 27:36]
        Tv = w[-S:]
        if not found:
            raise InfeasibleTaskError(self._diagnose(x, xd, u, tau, status), None,
                                      "solver: " + status, value=status, valid="Solve_Succeeded")
        t = self.node_times(Tv)
        theta = np.array(sr.theta.map(N + 1)(x.T)).T
        residuals = {
            "dynamics": float(np.abs(
                np.array(sr.node.map(N + 1)(x.T, xd.T, u.T, tau.T))[0:9]).max()),
            "integration": float(np.abs(np.array(res["g"]).ravel()[:18 * N]).max()),
            "waypoints": float(max(np.abs(x[w_ * ns, 0:6] - wp_x[w_, 0:6]).max()
                                   for w_ in range(len(task.waypoints)))),
        }
        active = self._active(x, xd, u, tau, t, platform_proxy, safety)
        sol = Solution(found=True, status=status, final_time=float(Tv.sum()),
                       solve_time=solve_time, iterations=int(stats.get("iter_count", -1)),
                       segment_times=Tv, t=t, x=x, xd=xd, xdd=u, tau=tau, theta=theta,
                       residuals=residuals, active_limits=active, robot=self.robot,
                       limits=self.limits, options=opt, task=task,
                       nlp_point=(w / D, np.array(res["lam_x"]).ravel(),
                                  np.array(res["lam_g"]).ravel(), D))
        sol.check = dense_check(sol, factor=10)
        self._stage(f"  {status}: {sol.iterations} iterations, {solve_time:.2f} s; motion "
                    f"{sol.final_time:.4f} s; dense re-check "
                    + ("ok" if sol.check.ok else "; ".join(sol.check.violations)))
        return sol

    def _iteration_listener(self, d_time: np.ndarray, lbg: np.ndarray, ubg: np.ndarray):
        """The relay's listener for one solve: the iterate's duration (its last S scaled
        variables times their scale) and constraint violation, to ``self.progress``."""
        progress = self.progress
        assert progress is not None

        def listener(k: int, ws: np.ndarray, g: np.ndarray) -> None:
            duration = float(ws[-len(d_time):] @ d_time)
            violation = float(max(0.0, np.max(lbg - g), np.max(g - ubg)))
            progress.iteration(k, duration, violation)

        return listener

    def node_fractions(self) -> np.ndarray:
        """(S, ns) each node interval's share of its segment's duration (rows sum to 1).

        Uniform, except that the interval next to a rest (the start, the end, a
        ``stop`` waypoint) is ``REST_INTERVAL`` of a regular one: the acceleration is
        zero at rest and linear over that interval, and a full-length first interval
        made the ramp up to the limits take twice what the torque-rate limit needs
        (the certificate, planner.certificate, found 3 ms of 12 lost at each end of a
        2-waypoint plan, BENCHMARKS.md)."""
        ns, S = self.task.segment_nodes, self.task.n_segments
        rest = self.rest_waypoints()
        w = np.ones((S, ns))
        for s in range(S):
            if s in rest:
                w[s, 0] = REST_INTERVAL
            if s + 1 in rest:
                w[s, -1] = REST_INTERVAL
        return w / w.sum(axis=1, keepdims=True)

    def rest_waypoints(self) -> set[int]:
        """Indices of the waypoints where the motion is at rest: the first, the last and
        every ``stop`` waypoint (zero velocity and acceleration there)."""
        wps = self.task.waypoints
        return {0, len(wps) - 1} | {w for w, wp in enumerate(wps) if wp.stop}

    def node_times(self, T: np.ndarray) -> np.ndarray:
        """(N+1,) node times [s] for the segment durations T (S,)."""
        steps = np.asarray(T, dtype=float)[:, None] * self.node_fractions()
        return np.r_[0.0, np.cumsum(steps.ravel())]

    def _on_nodes(self, sol: Solution):
        """(x, xd, xdd, T) of a plan of this task on this NLP's node grid (its own arrays
        if it has that grid; else sampled at :meth:`node_times`)."""
        ns, S = self.task.segment_nodes, self.task.n_segments
        if sol.source == "ocp" and len(sol.t) == ns * S + 1:
            return sol.x, sol.xd, sol.xdd, sol.segment_times
        T = np.asarray(sol.segment_times, dtype=float)
        x, xd, xdd = sol.sample(self.node_times(T))
        return x, xd, xdd, T

    def _check_crank_sides(self) -> None:
        """Raise InfeasibleTaskError when one crank has to pass 0 deg between waypoints.

        A crank angle of 0 (or 180) deg is radial: the platform is singular there
        (docs/planner.md), so no motion joins a waypoint whose crank is negative to one
        where it is positive (given, or free: the static choice takes 35-145 deg).
        Without this check the solver failed from every start and the error named a
        binding torque limit instead.
        """
        wps = self.task.waypoints
        if self.options.lock_redundancy:
            return
        for i in range(3):
            side = [None if wp.psi is None else float(wp.psi[i]) for wp in wps]
            neg = [w for w, v in enumerate(side) if v is not None and v < 0.0]
            pos = [w for w, v in enumerate(side) if v is None or v > 0.0]
            if neg and pos:
                a, b = sorted((neg[0], pos[0]))
                say = [f"waypoint {w} free (35-145 deg)" if (v := side[w]) is None else
                       f"waypoint {w} at {math.degrees(v):.1f} deg" for w in (a, b)]
                raise InfeasibleTaskError(
                    f"crank {i} would have to pass the singular 0 deg between {say[0]} "
                    f"and {say[1]}: give that crank angles of one sign at every waypoint",
                    b, "crank angle sign", value=[None if v is None else
                                                  round(math.degrees(v), 3) for v in side],
                    valid="one sign per crank: all in (0, 180) deg or all in (-180, 0) deg")

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

    @staticmethod
    def _layout(N: int, S: int) -> tuple[int, int, int, int]:
        """Offsets in the decision vector [z_0 .. z_N, tau_mid, theta_ddot, T] of
        tau_mid (9 N), theta_ddot at the nodes then the midpoints (9 (2 N + 1)), the
        durations (S), and its length; z_k = (x, xd, u, tau)_k."""
        o_taum = 36 * (N + 1)
        o_acc = o_taum + 9 * N
        o_T = o_acc + 9 * (2 * N + 1)
        return o_taum, o_acc, o_T, o_T + S

    def _variable_scale(self, tmax: float) -> np.ndarray:
        """Scale of every decision variable: IPOPT works with w / D.

        Accelerations are scaled by 100 (m or rad)/s^2 and torques by their bound, so
        that both are of order one like the poses, rates and durations.  (Scaling every
        variable by the magnitudes of its guess made IPOPT's L-BFGS slower and erratic on
        the task suite; this choice was the fastest of those measured, BENCHMARKS.md.)
        """
        ns, S = self.task.segment_nodes, self.task.n_segments
        N = ns * S
        node = np.r_[np.ones(18), np.full(9, ACC_SCALE), np.full(9, tmax)]
        return np.r_[np.tile(node, N + 1), np.full(9 * N, tmax),
                     np.full(9 * (2 * N + 1), ACC_SCALE), np.ones(S)]

    def _variable_bounds(self, wp_x: np.ndarray, tmax: float, amax: float,
                         total: float = np.inf):
        """Bounds of the decision vector (:meth:`_layout`): ``tmax`` [N m] on the
        torques, ``amax`` [rad/s^2] on theta_ddot, and each segment's duration within
        [0.02, 60] s and at most ``total`` [s] (the bound of the total duration).

        Waypoints, the rest conditions and locked or given crank angles are equal bounds
        (IPOPT removes such fixed variables from the problem).
        """
        task, opt = self.task, self.options
        ns, S = task.segment_nodes, task.n_segments
        N = ns * S
        lo = np.full((N + 1, 36), -np.inf)
        hi = np.full((N + 1, 36), np.inf)
        lo[:, 27:36], hi[:, 27:36] = -tmax, tmax
        if opt.lock_redundancy:
            lo[:, 6:9] = hi[:, 6:9] = wp_x[0, 6:9]
        else:
            lo[:, 6:9], hi[:, 6:9] = self.crank_range()
        for w, wp in enumerate(task.waypoints):
            k = w * ns
            lo[k, 0:6] = hi[k, 0:6] = wp_x[w, 0:6]
            if wp.psi is not None and not opt.lock_redundancy:
                lo[k, 6:9] = hi[k, 6:9] = wp_x[w, 6:9]
        # at rest (the start, the end, a stop): zero velocity and zero acceleration, so
        # that the torque starts and ends at the holding torque (no step at either end)
        for w in self.rest_waypoints():
            lo[w * ns, 9:27] = hi[w * ns, 9:27] = 0.0
        n_acc = 9 * (2 * N + 1)
        t_lo, t_hi = min(0.02, total), min(60.0, total)
        return (np.r_[lo.ravel(), np.full(9 * N, -tmax), np.full(n_acc, -amax), np.full(S, t_lo)],
                np.r_[hi.ravel(), np.full(9 * N, tmax), np.full(n_acc, amax), np.full(S, t_hi)])

    def _template(self, warm_start: bool = False) -> dict:
        """The NLP of this task's size, built once per process and reused.

        The structure depends only on (nodes per segment, segments) and the solver
        options: waypoints, locked or given crank angles, limits and margin signs are
        bounds, set per solve.  The node functions are the compiled ones of
        :mod:`dynamics.codegen` (mapped over the nodes on two threads) when a C compiler is
        available, otherwise CasADi's interpreted SX functions (expanded).
        """
        from sixplus3.dynamics.codegen import compiled_functions, single_threaded_solver_blas

        task, opt, sr = self.task, self.options, self.sr
        ns, S = task.segment_nodes, task.n_segments
        compiled = compiled_functions(self.robot)
        key = (self.robot.hash, ns, S, opt.max_iter, opt.tol, opt.constr_viol_tol,
               opt.regularisation, opt.verbose, opt.ipopt_options, bool(compiled), warm_start)
        if key in _TEMPLATES:
            return _TEMPLATES[key]
        N = ns * S
        nw = self._layout(N, S)[-1]
        # parameters: the variable scaling D (IPOPT's variables are w / D), then the
        # jerk [rad/s^3] and torque-rate [N m/s] limits of the smoothness rows below
        P = ca.MX.sym("p", nw + 4 + N)
        Ws, D = ca.MX.sym("w", nw), P[0:nw]
        jerk_lim, rate_lim = P[nw], P[nw + 1]
        # objective weights: duration (minimum time) and effort (fixed duration)
        w_time, w_effort = P[nw + 2], P[nw + 3]
        # each interval's share of its segment's duration (:meth:`node_fractions`)
        frac = P[nw + 4:]
        W = Ws * D
        o_taum, o_acc, o_T, _ = self._layout(N, S)
        Z = ca.reshape(W[0:o_taum], 36, N + 1)
        TAUM = ca.reshape(W[o_taum:o_acc], 9, N)
        ACC = ca.reshape(W[o_acc:o_T], 9, 2 * N + 1)  # theta_ddot at the nodes, the midpoints
        T = W[o_T:]
        X, XD, U, TAU = Z[0:9, :], Z[9:18, :], Z[18:27, :], Z[27:36, :]
        hm = ca.horzcat(*[T[s] * frac[s * ns + i] for s in range(S) for i in range(ns)])
        Hm = ca.repmat(hm, 9, 1)
        Uk, Uk1 = U[:, 0:N], U[:, 1:N + 1]
        # dynamics of the double integrator (exact for piecewise-linear acceleration)
        g_int = ca.vertcat(
            X[:, 1:] - X[:, 0:N] - Hm * XD[:, 0:N] - Hm**2 * (2 * Uk + Uk1) / 6,
            XD[:, 1:] - XD[:, 0:N] - Hm * (Uk + Uk1) / 2)
        # every constraint row again at every interval's midpoint (the exact cubic state
        # there, with its own torque variables): theta_ddot and the torques are strongly
        # nonlinear inside an interval (overshoots of 37% in acceleration and 16% in torque
        # between nodes were measured on the torsion task with nodes only).
        jerk = (Uk1 - Uk) / Hm
        half = Hm / 2
        Xm = X[:, 0:N] + half * XD[:, 0:N] + half**2 / 2 * Uk + half**3 / 6 * jerk
        XDm = XD[:, 0:N] + half * Uk + half**2 / 2 * jerk
        Um = (Uk + Uk1) / 2
        node = compiled.get("node", sr.node)
        mapped = node.map(2 * N + 1, "thread", 2) if compiled else node.map(2 * N + 1)
        G = mapped(ca.horzcat(X, Xm), ca.horzcat(XD, XDm), ca.horzcat(U, Um),
                   ca.horzcat(TAU, TAUM))
        # theta_ddot is a variable (ACC) tied to the model by these 9 equality rows per
        # point: its limit is then a variable bound and the jerk rows below involve two
        # variables each, instead of two dense theta_ddot expressions (that made the jerk
        # rows half of the constraint Jacobian's nonzeros and ~40% of the time of an
        # IPOPT iteration, BENCHMARKS.md)
        # The torque-balance rows (N or N m) and the theta_ddot ties (rad/s^2) in the units
        # of their variables' scales (ROW_SCALE): IPOPT's constr_viol_tol (1e-4) then
        # leaves at most 1e-3 N (m) in a balance row, 1e-4 of the nominal torque, and
        # 1e-2 rad/s^2 in a tie.  Unscaled, it asked for ~1e-6 of their size, and IPOPT
        # spent 10-15 iterations at the end of a solve on that (BENCHMARKS.md)
        G = ca.vertcat(G[0:9, :] / ROW_SCALE["torque"], G[9:18, :],
                       (G[18:27, :] - ACC) / ROW_SCALE["acceleration"], G[27:, :])
        # smoothness: actuated jerk and torque rate bounded between consecutive points
        # (node k, midpoint k, node k+1; half an interval apart): |d| <= limit * h / 2,
        # as one row d / (limit h / 2) in [-1, 1] (h >= 0.02 s / nodes per segment > 0).
        # The two linear rows d -+ limit h/2 <= / >= 0 it replaces made 40% of the
        # inequality rows; one two-sided row per bound gave a lower wall time and the same
        # or shorter plans on the held-out set (BENCHMARKS.md).
        def rate_rows(nodes, mids, limit):
            d1, d2 = mids - nodes[:, 0:N], nodes[:, 1:N + 1] - mids
            room = limit * half
            return ca.vertcat(ca.vec(d1 / room), ca.vec(d2 / room))

        g_smooth = ca.vertcat(
            rate_rows(ACC[:, 0:N + 1], ACC[:, N + 1:2 * N + 1], jerk_lim),
            rate_rows(TAU, TAUM, rate_lim))
        # the total duration, as a row: free for minimum time, fixed by its bounds
        g = ca.vertcat(ca.vec(g_int), ca.vec(G), g_smooth, ca.sum1(T))
        # regularisation: mean squared acceleration, scaled to ~1 at 100 (m or rad)/s^2;
        # effort: mean squared torque over the nodes and midpoints, ~1 at 10 N m
        effort = (ca.sumsqr(TAU) + ca.sumsqr(TAUM)) / (100.0 * (2 * N + 1))
        f = (w_time * ca.sum1(T)
             + opt.regularisation * ca.sumsqr(U / 100.0) / (N + 1) * ca.sum1(T)
             + w_effort * effort)
        nlp: dict[str, Any] = {"x": Ws, "p": P, "f": f, "g": g}
        ipopt: dict[str, Any] = {"max_iter": opt.max_iter, "tol": opt.tol,
                 "acceptable_tol": 10 * opt.tol, "acceptable_iter": 5,
                 "constr_viol_tol": opt.constr_viol_tol,
                 "acceptable_constr_viol_tol": opt.constr_viol_tol,
                 "hessian_approximation": "limited-memory",
                 # 3 pairs instead of IPOPT's 6: fewer back-solves per iteration, and a
                 # lower median solve time on the suite and on random tasks (BENCHMARKS.md)
                 "limited_memory_max_history": 3,
                 # MUMPS's own row/column scaling cost ~25% of each iteration and did not
                 # reduce the iteration count on the task suite
                 "mumps_permuting_scaling": 0, "mumps_scaling": 0,
                 # MUMPS's approximate minimum fill ordering: its factorisations and
                 # back-solves took 38% less time than with its automatic choice, same
                 # iterates (BENCHMARKS.md; AMD, PORD, METIS and QAMD were slower)
                 "mumps_pivot_order": 2,
                 "print_level": 5 if opt.verbose else 0, "sb": "yes"}
        if warm_start:
            ipopt.update({"warm_start_init_point": "yes", "mu_init": 1e-5,
                          "warm_start_bound_push": 1e-7, "warm_start_slack_bound_push": 1e-7,
                          "warm_start_mult_bound_push": 1e-7})
        ipopt.update(dict(opt.ipopt_options))  # the caller's, over the planner's
        relay = _IterationRelay(nw, g.numel())
        solver_opts: dict[str, Any] = {"expand": not compiled, "print_time": False,
                                       "ipopt": ipopt, "iteration_callback": relay}
        single_threaded_solver_blas()
        try:
            solver = ca.nlpsol("planner", "ipopt", nlp, solver_opts)
        except RuntimeError as exc:
            if not opt.ipopt_options:
                raise
            reason = str(exc).strip().splitlines()[-1].split(": ", 1)[-1]
            raise ValueError(f"IPOPT rejected ipopt_options {dict(opt.ipopt_options)}: "
                             f"{reason}") from None
        tmpl = {"solver": solver, "relay": relay}  # the relay must outlive the solver
        _TEMPLATES[key] = tmpl
        return tmpl

    @staticmethod
    def _node_bounds(lim: Limits, sign1, sign2, platform_proxy, safety=None, reserve=None):
        """Lower/upper bounds of the 70 rows of ``SymbolicRobot.node``."""
        safety = safety or {"velocity": 1.0, "acceleration": 1.0}
        inf = np.inf
        lb, ub = np.zeros(70), np.zeros(70)
        v = safety["velocity"] * lim.velocity
        lb[9:18], ub[9:18] = -v, v
        lb[18:27], ub[18:27] = 0.0, 0.0  # theta_ddot(x, xd, u) - ACC (bounded: ACC's bounds)
        lb[27:36], ub[27:36] = lim.theta_min, lim.theta_max
        lb[36:45], ub[36:45] = 0.0, inf
        reserve = reserve or {"spherical": 0.0, "clearance": None}
        lb[45:54], ub[45:54] = math.cos(lim.spherical - reserve["spherical"]), inf
        for rows, sign, m in ((slice(54, 63), sign1, lim.margin),
                              (slice(63, 66), sign2, 3 * lim.margin)):
            lb[rows] = np.where(sign > 0, m, -inf)
            ub[rows] = np.where(sign > 0, inf, -m)
        lb[66], ub[66] = platform_proxy, inf
        lb[67:70], ub[67:70] = (-inf if reserve["clearance"] is None
                                else reserve["clearance"]), inf  # between the legs' links
        return lb, ub

    # -- reporting
    def _active(self, x, xd, u, tau, t, platform_proxy, safety) -> list[str]:
        """Limits within 0.5% of their bound at some node, with the bounds of this solve."""
        sr, lim = self.sr, self.limits
        tmax = safety["torque"] * lim.torque
        vmax = safety["velocity"] * lim.velocity
        amax = safety["acceleration"] * lim.acceleration
        names = []
        n = len(t)
        thd, thdd, _, _ = (v.T for v in actuated_profile(self.robot, x, xd, u))
        m1, m2, mp = (np.array(a) for a in sr.margins.map(n)(x.T))
        crank_lo, crank_hi = self.crank_range()
        checks = [
            ("torque", np.abs(tau).max(axis=1) / tmax),
            ("velocity", np.abs(thd).max(axis=1) / vmax),
            ("acceleration", np.abs(thdd).max(axis=1) / amax),
            ("leg type I margin", lim.margin / np.abs(m1).min(axis=0)),
            ("leg type II margin", 3 * lim.margin / np.abs(m2).min(axis=0)),
            ("platform margin", platform_proxy / mp.ravel()),
            ("crank angle range", np.maximum(crank_lo / x[:, 6:9], x[:, 6:9] / crank_hi)
             .max(axis=1)),
        ]
        for name, ratio in checks:
            hit = np.flatnonzero(ratio > 0.995)
            if len(hit):
                names.append(f"{name} ({len(hit)} of {n} nodes, first at t = "
                             f"{t[hit[0]]:.3f} s)")
        return names

    def _diagnose(self, x, xd, u, tau, status) -> str:
        """Name the limits most violated by the solver's last iterate."""
        sr, lim = self.sr, self.limits
        n = x.shape[0]
        ns = self.task.segment_nodes
        tmax = self.options.torque_safety * lim.torque
        thd, _, dyn_tau, _ = actuated_profile(self.robot, x, xd, u)
        items = [
            ("torque", np.abs(dyn_tau).max(axis=0) / tmax - 1.0, f"{lim.torque:g} N m"),
            ("velocity", np.abs(thd).max(axis=0) / lim.velocity - 1.0,
             f"{lim.velocity:g} rad/s"),
        ]
        m1, m2, mp = (np.array(a) for a in sr.margins.map(n)(x.T))
        items.append(("singularity margin", lim.margin - np.minimum(np.abs(m1).min(axis=0),
                                                                     np.abs(m2).min(axis=0) / 3),
                      f"{lim.margin:g}"))
        worst = sorted(((float(v.max()), name, int(np.argmax(v)), rng)
                        for name, v, rng in items), reverse=True)
        v, name, k, rng = worst[0]
        seg = min(k // ns, self.task.n_segments - 1)
        how = (f"violated by {max(v, 0) * 100:.1f}% at the solver's last iterate"
               if v < 10 else "the solver's last iterate diverged there")
        return (f"planning failed ({status}): the {name} limit ({rng}) binds between "
                f"waypoints {seg} and {seg + 1} ({how}); lower the demand or move the "
                "waypoints")


def check_plan_arguments(task: object, robot: object, options: object) -> None:
    """Named errors for arguments of the wrong kind or out of range (a Task made with
    ``dataclasses.replace`` skips the task schema)."""
    if not isinstance(task, Task):
        raise TaskError("task must be a Task (load_task, task_from_dict)",
                        value=type(task).__name__, valid="a Task")
    if robot is not None and not isinstance(robot, Robot):
        raise InputError("robot must be a Robot or None", value=type(robot).__name__,
                         valid="a Robot or None")
    if options is not None and not isinstance(options, PlannerOptions):
        raise InputError("options must be PlannerOptions or None",
                         value=type(options).__name__, valid="PlannerOptions or None")
    n = task.nodes_per_segment
    if n is not None and (isinstance(n, bool) or not isinstance(n, int) or not 4 <= n <= 60):
        raise TaskError(f"task field nodes_per_segment must be an integer in [4, 60], got "
                        f"{n!r}", value=n, valid="[4, 60]")
    for name, lo, hi in (("duration", 0.0, 600.0), ("speed", 0.0, 1.0)):
        v = getattr(task, name)
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float))
                              or not lo < v <= hi):
            raise TaskError(f"task field {name} must be in ({lo:g}, {hi:g}], got {v!r}",
                            value=v, valid=f"({lo:g}, {hi:g}]")


def plan(task: Task, robot: Robot | None = None,
         options: PlannerOptions | None = None, progress: Any = None) -> Solution:
    """Plan a task for ``robot`` (default ``Robot.default()``); raises
    :class:`InfeasibleTaskError` (never returns an unsafe plan).  ``progress``: a
    :class:`sixplus3.progress.PlanProgress` told each stage and IPOPT iteration."""
    sol = Problem(task, robot, options, progress).solve()
    if not sol.is_feasible():
        raise InfeasibleTaskError(
            "the solved plan fails its dense re-check: "
            + "; ".join(sol.check.violations if sol.check else ["not checked"]),
            None, "dense check",
                value=sol.check.violations if sol.check else None, valid="every limit met")
    return sol


# --------------------------------------------------------------------- dense re-check
def dense_check(sol: Solution, factor: int = 10) -> DenseCheck:
    """Re-evaluate a plan with the numeric model at ``factor`` x the node density.

    Torques come from Pinocchio's constrained inverse dynamics (dynamics.closed_loop),
    margins and the exact capsule clearance between the legs from the numeric
    kinematics (kinematics.robot), independently of the CasADi expressions used inside
    the optimisation; the same rule as the file validation
    (:func:`sixplus3.kinematics.checks.measure_limits`), against ``sol.limits``.
    """
    from sixplus3.dynamics.closed_loop import ClosedLoopDynamics

    n = (len(sol.t) - 1) * factor + 1
    times = np.linspace(0.0, sol.t[-1], n)
    x, xd, xdd = sol.sample(times)
    R = Rotation.from_rotvec(x[:, 3:6]).as_matrix()
    cfg = robot_ik(x[:, 0:3], R, x[:, 6:9], sol.robot)
    violations = []
    if not cfg.ok.all():
        violations.append(f"unreachable at {int((~cfg.ok).sum())} samples")
    thd, thdd, _, _ = (v.T for v in actuated_profile(sol.robot, x, xd, xdd))
    # Pinocchio's constrained inverse dynamics of all samples at once (the validator's,
    # tests/test_dynamics.py checks it against the per-state one); NaN at a parallel
    # singularity, where no torque is defined
    tau, _ = ClosedLoopDynamics(sol.robot).actuated_inverse_dynamics_batch(cfg.q, thd, thdd)
    if not np.isfinite(tau).all():
        violations.append(f"no torque defined (singular) at "
                          f"{int((~np.isfinite(tau).all(axis=1)).sum())} samples")
    lm = measure_limits(cfg, tau, cfg.theta, thd, thdd, sol.limits, times)
    violations += lm.violations
    return DenseCheck(ok=not violations, samples=n, max_torque_ratio=lm.max_torque_ratio,
                      max_velocity_ratio=lm.max_velocity_ratio,
                      max_acceleration_ratio=lm.max_acceleration_ratio,
                      min_margin=min(lm.min_margin_leg_type1, lm.min_margin_leg_type2,
                                     lm.min_margin_platform),
                      min_margin_leg_type1=lm.min_margin_leg_type1,
                      min_margin_leg_type2=lm.min_margin_leg_type2,
                      min_margin_platform=lm.min_margin_platform,
                      theta_range_ok=lm.theta_range_ok,
                      max_spherical_tilt=lm.max_spherical_tilt,
                      min_clearance=lm.min_clearance, violations=violations,
                      max_tcp_speed=lm.max_tcp_speed,
                      max_tcp_acceleration=lm.max_tcp_acceleration)


__all__ = ["DenseCheck", "InfeasibleTaskError", "PlannerOptions", "Problem", "Solution",
           "dense_check", "plan", "pose_masks", "static_checks"]
