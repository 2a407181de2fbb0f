"""Time-optimal planning: Problem -> solve() -> Solution (CasADi + IPOPT).

Minimal coordinates x = (platform position [m], rotation vector [rad], crank angles psi
[rad]).  Direct multiple shooting on a chain of segments, one per pair of consecutive
waypoints, each with ``nodes_per_segment`` intervals of a free duration T_s:

- variables: x, xd (nodes), acceleration u = xdd (nodes, linear in between: the states
  integrate exactly as cubics), actuator torques tau (nodes), durations T_s;
- dynamics: x+ = x + h xd + h^2 (2 u + u+) / 6,  xd+ = xd + h (u + u+) / 2;
- torques: (d theta / dx)^T tau = Q(x, xd, u) at every node (planner.model), and
  |tau| <= safety * limit;
- path constraints at every node: |theta_dot| <= velocity, |theta_ddot| <= acceleration,
  theta in [0, 270] deg, every spherical joint within 150 deg, every chain inside its
  reach, each leg's type I margin and type II margin (through det J-hat >= 3 m, which
  implies sigma_min >= m) and the platform (line determinant >= max(0.3, 6 m) with psi in
  [30, 150] deg), all >= the task's margin;
- waypoints: x at the first node of each segment equals the waypoint (position,
  orientation, psi when given); start and end at rest;
- objective: sum T_s + a small regularisation of u.

Warm start: kinematic interpolation between the waypoints, the free crank angles chosen
statically at each waypoint to maximise the smallest singularity margin.  The solution
is re-checked with the numeric model (Pinocchio, official margins) at 10x the node
density; a platform margin below the task's triggers one re-solve with a tighter proxy.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from kinematics.leg import DEFAULT_MODE
from kinematics.robot import robot_ik, spherical_tilts
from planner.model import symbolic_robot
from planner.task import Task, Waypoint, rotvec
from robot_description.robot import NUM_LEGS
from robot_description.urdf import SPHERICAL_LIMIT
from sixplus3.errors import Sixplus3Error

PSI_MIN, PSI_MAX = math.radians(45.0), math.radians(135.0)
THETA_MIN, THETA_MAX = 0.0, 1.5 * math.pi
NOMINAL_PSI = np.full(NUM_LEGS, math.pi / 2)
#: Built NLPs by structure (see Problem._template); one per process.
_TEMPLATES: dict[tuple, dict] = {}


class InfeasibleTaskError(Sixplus3Error):
    """No motion satisfies the task's limits; says which waypoint or limit binds."""

    def __init__(self, message: str, waypoint: int | None = None, limit: str | None = None):
        self.waypoint = waypoint
        self.limit = limit
        super().__init__(message)


@dataclass(frozen=True)
class PlannerOptions:
    lock_redundancy: bool = False  # psi fixed at 90 deg (or the waypoints' psi) throughout
    torque_safety: float = 0.99  # initial node bound = safety * limit (then tightened only
    #                              where the dense re-check finds an overshoot between nodes)
    max_iter: int = 600
    tol: float = 1e-6
    regularisation: float = 1e-4
    verbose: bool = False


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
    check: DenseCheck | None = None
    options: PlannerOptions = field(default_factory=PlannerOptions)
    task: Task | None = None

    def sample(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, xd, xdd) at arbitrary times [s] from the exact piecewise-cubic motion."""
        times = np.clip(np.asarray(times, dtype=float), 0.0, self.t[-1])
        k = np.clip(np.searchsorted(self.t, times, side="right") - 1, 0, len(self.t) - 2)
        h = (self.t[k + 1] - self.t[k])[:, None]
        s = (times - self.t[k])[:, None]
        u0, u1 = self.xdd[k], self.xdd[k + 1]
        jerk = (u1 - u0) / h
        x = self.x[k] + s * self.xd[k] + s**2 / 2 * u0 + s**3 / 6 * jerk
        xd = self.xd[k] + s * u0 + s**2 / 2 * jerk
        xdd = u0 + s * jerk
        return x, xd, xdd

    def is_feasible(self) -> bool:
        return bool(self.found and self.check is not None and self.check.ok)


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
    violations: list[str]


# --------------------------------------------------------------------- static choices
def pose_masks(cfg) -> tuple[np.ndarray, np.ndarray]:
    """(theta_ok, spherical_ok) of batched configurations: solved with every actuated
    angle in [0, 270] deg, and additionally every spherical joint within 150 deg."""
    theta_ok = cfg.ok & np.all((cfg.theta >= THETA_MIN) & (cfg.theta <= THETA_MAX), axis=1)
    sph_ok = theta_ok & np.all(spherical_tilts(cfg) <= SPHERICAL_LIMIT, axis=(1, 2))
    return theta_ok, sph_ok


def _static_candidates(wp: Waypoint, limits, locked: bool):
    """Crank-angle candidates at a waypoint with their official checks (batched)."""
    if wp.psi is not None:
        psis = wp.psi[None, :]
    elif locked:
        psis = NOMINAL_PSI[None, :]
    else:
        axis = np.radians(np.arange(35.0, 146.0, 10.0))
        psis = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3)
    cfg = robot_ik(wp.position, wp.rotation, psis)
    theta_ok, sph_ok = pose_masks(cfg)
    margin = np.where(sph_ok, cfg.margins.minimum, -1.0)
    return psis, cfg, theta_ok, sph_ok, margin


def choose_static_psi(task: Task, locked: bool, at_rest: set[int]) -> np.ndarray:
    """Per waypoint, crank angles maximising the smallest margin; raises naming the limit."""
    from dynamics.closed_loop import ClosedLoopDynamics

    dyn = ClosedLoopDynamics()
    lim = task.limits
    out = []
    for k, wp in enumerate(task.waypoints):
        psis, cfg, theta_ok, sph_ok, margin = _static_candidates(wp, lim, locked)
        where = f"waypoint {k} (position {np.round(wp.position, 4).tolist()} m)"
        if not cfg.ok.any():
            st = next(int(s) for s in cfg.leg_status[0] if s)
            leg = int(np.flatnonzero(cfg.leg_status[0])[0])
            from kinematics.leg import failing_chain, status_reason

            raise InfeasibleTaskError(
                f"{where} is outside the workspace: leg {leg} {failing_chain(st)} chain: "
                f"{status_reason(st)}", k, "reach")
        if not theta_ok.any():
            raise InfeasibleTaskError(
                f"{where}: an actuated angle leaves [0, 270] deg (base collision) for every "
                "crank choice", k, "theta range")
        if not sph_ok.any():
            raise InfeasibleTaskError(
                f"{where}: a spherical joint exceeds 150 deg for every crank choice", k,
                "spherical joints")
        order = np.argsort(-margin)
        if margin[order[0]] < lim.margin:
            raise InfeasibleTaskError(
                f"{where}: no crank choice keeps every singularity margin >= {lim.margin:g} "
                f"(best {margin[order[0]]:.4f} at psi = "
                f"{np.round(np.degrees(psis[order[0]]), 1).tolist()} deg)", k, "margin")
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
            raise InfeasibleTaskError(
                f"{where}: holding the platform at rest needs {best_tau:.2f} N m > "
                f"{lim.torque:g} N m (torque limit) for every crank choice with margins "
                f">= {lim.margin:g}", k, "torque")
        out.append(psis[chosen])
    return np.array(out)


# --------------------------------------------------------------------- the problem
class Problem:
    """A planning problem for one task (``solve()`` -> :class:`Solution`)."""

    def __init__(self, task: Task, options: PlannerOptions | None = None) -> None:
        self.task = task
        self.options = options or PlannerOptions()
        self.sr = symbolic_robot(DEFAULT_MODE.name)

    # -- initial guess
    def _guess(self, psi_wp: np.ndarray):
        task = self.task
        ns = task.nodes_per_segment
        S = task.n_segments
        rv_prev = None
        wp_x = []
        for k, wp in enumerate(task.waypoints):
            rv = rotvec(wp.rotation)
            if rv_prev is not None and np.linalg.norm(rv - rv_prev) > math.pi:
                # keep the rotation vector continuous (|r| near pi has two forms)
                ang = np.linalg.norm(rv)
                rv = rv - 2 * math.pi * rv / ang
            rv_prev = rv
            wp_x.append(np.r_[wp.position, rv, psi_wp[k]])
        wp_x = np.array(wp_x)
        xs, seg_T = [], []
        for s in range(S):
            a, b = wp_x[s], wp_x[s + 1]
            rots = Rotation.from_rotvec([a[3:6], b[3:6]])
            tau = np.linspace(0, 1, ns + 1)[:-1] if s < S - 1 else np.linspace(0, 1, ns + 1)
            sm = 3 * tau**2 - 2 * tau**3  # rest-to-rest smooth blend for the guess
            rv = Slerp([0, 1], rots)(sm).as_rotvec()
            seg = np.c_[a[:3] + sm[:, None] * (b[:3] - a[:3]), rv,
                        a[6:] + sm[:, None] * (b[6:] - a[6:])]
            xs.append(seg)
            th = np.array(self.sr.theta(a)).ravel()
            th_b = np.array(self.sr.theta(b)).ravel()
            dth = np.abs(th_b - th).max()
            seg_T.append(max(0.15, 2.0 * math.sqrt(2.0 * dth / 40.0), 1.5 * dth / 4.0))
        x = np.vstack(xs)
        T = np.array(seg_T)
        t = np.concatenate([[0.0], np.cumsum(np.repeat(T / ns, ns))])
        xd = np.gradient(x, t, axis=0)
        xd[0] = xd[-1] = 0.0
        xdd = np.gradient(xd, t, axis=0)
        return wp_x, x, xd, xdd, T

    def solve(self) -> Solution:
        task, opt = self.task, self.options
        at_rest = {0, len(task.waypoints) - 1}
        psi_wp = choose_static_psi(task, opt.lock_redundancy, at_rest)
        if opt.lock_redundancy:
            fixed = [wp.psi for wp in task.waypoints if wp.psi is not None]
            lock = fixed[0] if fixed else NOMINAL_PSI
            psi_wp = np.tile(lock, (len(task.waypoints), 1))
        proxy = max(0.5, 6 * task.limits.margin)
        safety = {"torque": opt.torque_safety, "velocity": opt.torque_safety,
                  "acceleration": opt.torque_safety}
        try:
            sol = self._solve_once(psi_wp, proxy, safety)
        except InfeasibleTaskError as first:
            if first.limit is None or not first.limit.startswith("solver"):
                raise
            # IPOPT failed from the kinematic guess: once more from a guess twice as slow
            # (a different starting point, still kinematically feasible); if that fails
            # too the task is reported infeasible with the first diagnosis.
            try:
                sol = self._solve_once(psi_wp, proxy, safety, time_scale=2.0)
            except InfeasibleTaskError:
                raise first from None
        total = sol.solve_time
        # The OCP constrains the nodes; the dense re-check sees between them.  Tighten what
        # the check found violated and re-solve from the previous solution (at most 5x).
        for _ in range(5):
            bad = sol.check.violations if sol.check is not None else []
            if not bad:
                break
            ratios = {"torque": sol.check.max_torque_ratio,
                      "velocity": sol.check.max_velocity_ratio,
                      "acceleration": sol.check.max_acceleration_ratio}
            fixable = False
            for name in safety:
                if any(v.startswith(name) for v in bad):
                    safety[name] *= 0.985 / ratios[name]
                    fixable = True
            if any(v.startswith("platform") for v in bad):
                proxy = min(0.9, proxy + 0.2)
                fixable = True
            if not fixable:
                break
            sol = self._solve_once(psi_wp, proxy, safety, warm=sol)
            total += sol.solve_time
        sol.solve_time = total
        return sol

    def _solve_once(self, psi_wp: np.ndarray, platform_proxy: float, safety: dict,
                    warm: Solution | None = None, time_scale: float = 1.0) -> Solution:
        task, opt, sr = self.task, self.options, self.sr
        lim = task.limits
        ns, S = task.nodes_per_segment, task.n_segments
        N = ns * S
        wp_x, x0, xd0, xdd0, T0 = self._guess(psi_wp)
        if time_scale != 1.0:
            T0, xd0, xdd0 = T0 * time_scale, xd0 / time_scale, xdd0 / time_scale**2
        if warm is not None:
            x0, xd0, xdd0, T0 = warm.x, warm.xd, warm.xdd, warm.segment_times
        # Constraint signs from the guess (a margin keeps its sign inside a free region).
        m1 = np.array(sr.margins.map(N + 1)(x0.T)[0])
        m2 = np.array(sr.margins.map(N + 1)(x0.T)[1])
        sign1 = np.sign(np.median(m1, axis=1))
        sign2 = np.sign(np.median(m2, axis=1))

        tmpl = self._template()
        op, X, XD, U, TAU, T = tmpl["op"], tmpl["X"], tmpl["XD"], tmpl["U"], tmpl["TAU"], tmpl["T"]
        lb, ub = self._node_bounds(lim, sign1, sign2, platform_proxy, safety)
        op.set_value(tmpl["lb"], lb)
        op.set_value(tmpl["ub"], ub)
        op.set_value(tmpl["tmax"], safety["torque"] * lim.torque)
        op.set_value(tmpl["wp"], wp_x.T)
        tmax = safety["torque"] * lim.torque
        op.set_initial(X, x0.T)
        op.set_initial(XD, xd0.T)
        op.set_initial(U, xdd0.T)
        op.set_initial(T, T0)
        tau0 = np.array(sr.tau.map(N + 1)(x0.T, xd0.T, xdd0.T))
        op.set_initial(TAU, np.clip(tau0, -tmax, tmax))
        for lam in (op.lam_g,):  # cold-start the multipliers: a new task, not a re-solve
            op.set_initial(lam, 0)
        t_start = time.perf_counter()
        try:
            res = op.solve()
            found = True
        except RuntimeError:
            res = op.debug
            found = False
        solve_time = time.perf_counter() - t_start
        stats = op.stats()
        status = str(stats.get("return_status", "unknown"))
        found = found and status in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
        val = res.value
        Tv = np.atleast_1d(np.array(val(T), dtype=float)).ravel()
        x = np.array(val(X)).T
        xd = np.array(val(XD)).T
        u = np.array(val(U)).T
        tau = np.array(val(TAU)).T
        if not found:
            raise InfeasibleTaskError(self._diagnose(x, xd, u, tau, status), None,
                                      "solver: " + status)
        t = np.concatenate([[0.0], np.cumsum(np.repeat(Tv / ns, ns))])
        theta = np.array(sr.theta.map(N + 1)(x.T)).T
        residuals = {
            "dynamics": float(np.abs(
                np.array(sr.node.map(N + 1)(x.T, xd.T, u.T, tau.T))[0:9]).max()),
            "waypoints": float(max(np.abs(x[w * ns, 0:6] - wp_x[w, 0:6]).max()
                                   for w in range(len(task.waypoints)))),
        }
        active = self._active(x, xd, u, tau, t, platform_proxy, safety)
        sol = Solution(found=True, status=status, final_time=float(Tv.sum()),
                       solve_time=solve_time, iterations=int(stats.get("iter_count", -1)),
                       segment_times=Tv, t=t, x=x, xd=xd, xdd=u, tau=tau, theta=theta,
                       residuals=residuals, active_limits=active, options=opt, task=task)
        sol.check = dense_check(sol, factor=10)
        return sol

    def _template(self) -> dict:
        """The NLP of this task's structure, built once per process and reused.

        The structure is (nodes per segment, segments, which waypoints fix psi, locked);
        waypoint values, limits and margin signs are parameters, so a new task of the same
        structure only sets values and re-solves (CasADi keeps the expanded NLP and its
        derivative functions).
        """
        task, opt, sr = self.task, self.options, self.sr
        ns, S = task.nodes_per_segment, task.n_segments
        fixed = tuple(wp.psi is not None for wp in task.waypoints)
        key = (ns, S, fixed, opt.lock_redundancy, opt.max_iter, opt.tol, opt.regularisation,
               opt.verbose)
        if key in _TEMPLATES:
            return _TEMPLATES[key]
        N = ns * S
        op = ca.Opti()
        X, XD, U = op.variable(9, N + 1), op.variable(9, N + 1), op.variable(9, N + 1)
        TAU = op.variable(9, N + 1)
        T = op.variable(S)
        lb, ub = op.parameter(67), op.parameter(67)
        tmax = op.parameter()
        wp = op.parameter(9, S + 1)
        h = ca.vertcat(*[T[s] / ns for s in range(S) for _ in range(ns)])
        # dynamics of the double integrator (exact for piecewise-linear acceleration)
        for k in range(N):
            op.subject_to(X[:, k + 1] == X[:, k] + h[k] * XD[:, k]
                          + h[k] ** 2 * (2 * U[:, k] + U[:, k + 1]) / 6)
            op.subject_to(XD[:, k + 1] == XD[:, k] + h[k] * (U[:, k] + U[:, k + 1]) / 2)
        # every path constraint of a node: one SX function mapped over the nodes
        op.subject_to(op.bounded(-tmax, ca.vec(TAU), tmax))
        G = sr.node.map(N + 1)(X, XD, U, TAU)
        LB, UB = ca.repmat(lb, 1, N + 1), ca.repmat(ub, 1, N + 1)
        op.subject_to(ca.vec(G[0:9, :]) == 0)
        for r0, r1 in ((9, 36), (36, 45), (45, 54), (54, 66), (66, 67)):
            op.subject_to(ca.vec(G[r0:r1, :] - LB[r0:r1, :]) >= 0)
            op.subject_to(ca.vec(UB[r0:r1, :] - G[r0:r1, :]) >= 0)
        # the kinematic rows again at every interval's midpoint (exact cubic state there):
        # theta_ddot is strongly nonlinear inside an interval (a 37% overshoot between
        # nodes was measured on the torsion task); torques between nodes are left to the
        # dense re-check.
        hm = ca.horzcat(*[h[k] for k in range(N)])
        Uk, Uk1 = U[:, 0:N], U[:, 1:N + 1]
        jerk = (Uk1 - Uk) / ca.repmat(hm, 9, 1)
        half = ca.repmat(hm / 2, 9, 1)
        Xm = X[:, 0:N] + half * XD[:, 0:N] + half**2 / 2 * Uk + half**3 / 6 * jerk
        XDm = XD[:, 0:N] + half * Uk + half**2 / 2 * jerk
        Um = (Uk + Uk1) / 2
        Gm = sr.node_kin.map(N)(Xm, XDm, Um)
        LBm, UBm = ca.repmat(lb[9:67], 1, N), ca.repmat(ub[9:67], 1, N)
        op.subject_to(ca.vec(Gm - LBm) >= 0)
        op.subject_to(ca.vec(UBm - Gm) >= 0)
        if opt.lock_redundancy:  # fixed variables (equal bounds), not equality rows
            lock = ca.repmat(wp[6:9, 0], 1, N + 1)
            op.subject_to(op.bounded(ca.vec(lock), ca.vec(X[6:9, :]), ca.vec(lock)))
        else:
            op.subject_to(op.bounded(PSI_MIN, ca.vec(X[6:9, :]), PSI_MAX))
        for w in range(S + 1):
            k = w * ns
            op.subject_to(X[0:6, k] == wp[0:6, w])
            if fixed[w] and not opt.lock_redundancy:  # locked: the global lock covers it
                op.subject_to(X[6:9, k] == wp[6:9, w])
        op.subject_to(XD[:, 0] == 0)
        op.subject_to(XD[:, N] == 0)
        op.subject_to(op.bounded(0.02, T, 60.0))
        # regularisation: mean squared acceleration, scaled to ~1 at 100 (m or rad)/s^2
        reg = opt.regularisation * ca.sumsqr(U / 100.0) / (N + 1) * ca.sum1(T)
        op.minimize(ca.sum1(T) + reg)
        op.solver("ipopt", {"expand": True, "print_time": False},
                  {"max_iter": opt.max_iter, "tol": opt.tol, "acceptable_tol": 1e-4,
                   "hessian_approximation": "limited-memory", "print_level":
                   5 if opt.verbose else 0, "sb": "yes"})
        tmpl = {"op": op, "X": X, "XD": XD, "U": U, "TAU": TAU, "T": T, "lb": lb, "ub": ub,
                "tmax": tmax, "wp": wp}
        _TEMPLATES[key] = tmpl
        return tmpl

    @staticmethod
    def _node_bounds(lim, sign1, sign2, platform_proxy, safety=None):
        """Lower/upper bounds of the 67 rows of ``SymbolicRobot.node``."""
        safety = safety or {"velocity": 1.0, "acceleration": 1.0}
        inf = 1e9  # parameters must be finite; 1e9 is "no bound" for every row here
        lb, ub = np.zeros(67), np.zeros(67)
        v, a = safety["velocity"] * lim.velocity, safety["acceleration"] * lim.acceleration
        lb[9:18], ub[9:18] = -v, v
        lb[18:27], ub[18:27] = -a, a
        lb[27:36], ub[27:36] = THETA_MIN, THETA_MAX
        lb[36:45], ub[36:45] = 0.0, inf
        lb[45:54], ub[45:54] = math.cos(SPHERICAL_LIMIT), inf
        for rows, sign, m in ((slice(54, 63), sign1, lim.margin),
                              (slice(63, 66), sign2, 3 * lim.margin)):
            lb[rows] = np.where(sign > 0, m, -inf)
            ub[rows] = np.where(sign > 0, inf, -m)
        lb[66], ub[66] = platform_proxy, inf
        return lb, ub

    # -- reporting
    def _active(self, x, xd, u, tau, t, platform_proxy, safety) -> list[str]:
        """Limits within 0.5% of their bound at some node, with the bounds of this solve."""
        sr, lim = self.sr, self.task.limits
        tmax = safety["torque"] * lim.torque
        vmax = safety["velocity"] * lim.velocity
        amax = safety["acceleration"] * lim.acceleration
        names = []
        n = len(t)
        thd = np.array(sr.theta_dot.map(n)(x.T, xd.T)).T
        thdd = np.array(sr.theta_ddot.map(n)(x.T, xd.T, u.T)).T
        m1, m2, mp = (np.array(a) for a in sr.margins.map(n)(x.T))
        checks = [
            ("torque", np.abs(tau).max(axis=1) / tmax),
            ("velocity", np.abs(thd).max(axis=1) / vmax),
            ("acceleration", np.abs(thdd).max(axis=1) / amax),
            ("leg type I margin", lim.margin / np.abs(m1).min(axis=0)),
            ("leg type II margin", 3 * lim.margin / np.abs(m2).min(axis=0)),
            ("platform margin", platform_proxy / mp.ravel()),
            ("crank angle range", np.maximum(PSI_MIN / x[:, 6:9].min(axis=1),
                                             x[:, 6:9].max(axis=1) / PSI_MAX)),
        ]
        for name, ratio in checks:
            hit = np.flatnonzero(ratio > 0.995)
            if len(hit):
                names.append(f"{name} ({len(hit)} of {n} nodes, first at t = "
                             f"{t[hit[0]]:.3f} s)")
        return names

    def _diagnose(self, x, xd, u, tau, status) -> str:
        """Name the limits most violated by the solver's last iterate."""
        sr, lim = self.sr, self.task.limits
        n = x.shape[0]
        ns = self.task.nodes_per_segment
        tmax = self.options.torque_safety * lim.torque
        dyn_tau = np.array(sr.tau.map(n)(x.T, xd.T, u.T)).T
        items = [
            ("torque", np.abs(dyn_tau).max(axis=1) / tmax - 1.0, f"{lim.torque:g} N m"),
            ("velocity", np.abs(np.array(sr.theta_dot.map(n)(x.T, xd.T))).max(axis=0)
             / lim.velocity - 1.0, f"{lim.velocity:g} rad/s"),
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


def plan(task: Task, options: PlannerOptions | None = None) -> Solution:
    """Plan a task; raises :class:`InfeasibleTaskError` (never returns an unsafe plan)."""
    sol = Problem(task, options).solve()
    if not sol.is_feasible():
        raise InfeasibleTaskError(
            "the solved plan fails its dense re-check: " + "; ".join(sol.check.violations),
            None, "dense check")
    return sol


# --------------------------------------------------------------------- dense re-check
def dense_check(sol: Solution, factor: int = 10) -> DenseCheck:
    """Re-evaluate a plan with the numeric model at ``factor`` x the node density.

    Torques come from Pinocchio's constrained inverse dynamics (dynamics.closed_loop),
    margins from the numeric kinematics (kinematics.robot), independently of the CasADi
    expressions used inside the optimisation.
    """
    from dynamics.closed_loop import ClosedLoopDynamics

    task = sol.task
    lim = task.limits
    sr = symbolic_robot(DEFAULT_MODE.name)
    n = (len(sol.t) - 1) * factor + 1
    times = np.linspace(0.0, sol.t[-1], n)
    x, xd, xdd = sol.sample(times)
    R = Rotation.from_rotvec(x[:, 3:6]).as_matrix()
    cfg = robot_ik(x[:, 0:3], R, x[:, 6:9])
    violations = []
    if not cfg.ok.all():
        violations.append(f"unreachable at {int((~cfg.ok).sum())} samples")
    thd = np.array(sr.theta_dot.map(n)(x.T, xd.T)).T
    thdd = np.array(sr.theta_ddot.map(n)(x.T, xd.T, xdd.T)).T
    dyn = ClosedLoopDynamics()
    tau = np.zeros((n, 9))
    for k in range(n):
        v, a = dyn.consistent_state(cfg.q[k], thd[k], thdd[k])
        tau[k] = dyn.inverse_dynamics(cfg.q[k], v, a)
    torque_ratio = float(np.abs(tau).max() / lim.torque)
    vel_ratio = float(np.abs(thd).max() / lim.velocity)
    acc_ratio = float(np.abs(thdd).max() / lim.acceleration)
    m = cfg.margins
    min1, min2, minp = (float(m.leg_type1.min()), float(m.leg_type2.min()),
                        float(m.platform.min()))
    theta_ok = bool(np.all((cfg.theta >= THETA_MIN - 1e-9) & (cfg.theta <= THETA_MAX + 1e-9)))
    tilt = float(spherical_tilts(cfg).max())
    if torque_ratio > 1.0:
        violations.append(f"torque {torque_ratio * lim.torque:.3f} N m > {lim.torque:g} N m")
    if vel_ratio > 1.0:
        violations.append(f"velocity {vel_ratio * lim.velocity:.3f} rad/s > {lim.velocity:g}")
    if acc_ratio > 1.0:
        violations.append(f"acceleration {acc_ratio * lim.acceleration:.1f} rad/s^2 > "
                          f"{lim.acceleration:g}")
    if min(min1, min2) < lim.margin:
        violations.append(f"leg margin {min(min1, min2):.4f} < {lim.margin:g}")
    if minp < lim.margin:
        violations.append(f"platform margin {minp:.4f} < {lim.margin:g}")
    if not theta_ok:
        violations.append("actuated angle outside [0, 270] deg")
    if tilt > SPHERICAL_LIMIT:
        violations.append(f"spherical joint at {math.degrees(tilt):.1f} deg > 150 deg")
    return DenseCheck(ok=not violations, samples=n, max_torque_ratio=torque_ratio,
                      max_velocity_ratio=vel_ratio, max_acceleration_ratio=acc_ratio,
                      min_margin=min(min1, min2, minp),
                      min_margin_leg_type1=min1, min_margin_leg_type2=min2,
                      min_margin_platform=minp, theta_range_ok=theta_ok,
                      max_spherical_tilt=tilt, violations=violations)


__all__ = ["DenseCheck", "InfeasibleTaskError", "PlannerOptions", "Problem", "Solution",
           "dense_check", "plan", "pose_masks"]
