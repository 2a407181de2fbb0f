"""Re-timing a plan along its own path: locally, not by one uniform stretch.

The NLP bounds the tool centre point's speed and acceleration, and power and force
limiting, at its nodes and midpoints.  Between them its cubics ripple by a few percent,
and where the NLP's grid is coarser than the motion (the turn from a ramp into a
cruise) it leaves time unused.  A uniform stretch (:func:`timing.tcp_limited`) then
scales the whole plan by its worst point: a cruise that could run at the limit runs a
few percent below it everywhere.

This module keeps the path and chooses a new time law for it, the convex formulation of
Verscheure et al., "Time-optimal path tracking for robots: a convex optimization
approach", IEEE TAC 54(10), 2009.  The path parameter is the plan's own time tau; the
unknown is b(tau) = (d tau / dt)^2, quadratic over each cell of a grid (:data:`SUB` cells
per interval of the plan), b and b' continuous (:func:`law_matrices`), so the new
accelerations are continuous too.  For the new motion x(tau(t)):

    xd_new = x' sqrt(b),   xdd_new = x'' b + x' b' / 2

(x', x'': the plan's own rates and accelerations).  Every rate is sqrt(b) times the
plan's; every acceleration, the tool centre point's, the actuated joints' and the
inertial torques, is linear in (b, b').  So the rows are linear in b: joint velocity,
acceleration and torque (friction bounded at the largest speed allowed), the tool centre
point's speed and power and force limiting's ratio (both times b), the tool centre
point's acceleration (a second-order cone), jerk and torque rate between consecutive
points (linear with the time step bounded by its smallest), all at the grid points and
the cells' midpoints.  Over the first and last interval of each rest-to-rest piece the
law is constant (the NLP's jerk-shaped start and stop, uniformly re-timed).  The total
time, sum of d tau / sqrt(b), is convex in b.  cvxpy with Clarabel solves it.

The result is written back as a plan of the usual form (:class:`Solution`: cubics with
a linear acceleration, :func:`solution.sample_cubic`): the C2 spline through the path's
points at their new times, at rest (zero velocity and acceleration) at both ends of
every rest-to-rest piece (:func:`rest_spline`).  Every node of the plan is one of its
points, so the waypoints are kept exactly.  The caller re-checks it densely and keeps
whichever of it and the uniform stretch is shorter and passes.
"""

from __future__ import annotations

import functools
import warnings
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
import scipy.sparse as sps
from scipy.linalg import lu_factor, lu_solve

from sixplus3.dynamics.symbolic_ik import rotvec_matrix
from sixplus3.kinematics import rotations as rot
from sixplus3.kinematics.robot import robot_ik
from sixplus3.planner.pfl import pfl_ratios
from sixplus3.planner.problem import Problem
from sixplus3.planner.smoothing import rest_pieces
from sixplus3.planner.solution import Solution, actuated_profile

#: cells of the time law per interval of the plan
SUB = 6
#: the new law may run the path at most this many times faster than the plan
MAX_SPEEDUP = 2.0
#: ... and at most this many times slower
MAX_SLOWDOWN = 10.0


@functools.lru_cache(maxsize=8)
def _tcp_vectors(tool: tuple[float, float, float]) -> ca.Function:
    x, xd, u = ca.SX.sym("x", 9), ca.SX.sym("xd", 9), ca.SX.sym("u", 9)
    p_tcp = x[0:3] + rotvec_matrix(x[3:6]) @ ca.DM(tool)
    J = ca.jacobian(p_tcp, x)
    v = J @ xd
    return ca.Function("tcp_vectors", [x, xd, u], [v, ca.jtimes(v, x, xd) + J @ u])


def tcp_vectors_at(tool: Any, x: np.ndarray, xd: np.ndarray,
                   u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(velocity (n, 3) [m/s], acceleration (n, 3) [m/s^2]) of the platform point
    ``tool`` (platform frame) at the states (n, 9) each."""
    t = tuple(float(c) for c in np.asarray(tool, dtype=float).ravel())
    if len(t) != 3:
        raise ValueError(f"a platform point has 3 coordinates, not {len(t)}")
    v, a = _tcp_vectors(t).map(len(x))(x.T, xd.T, u.T)  # type: ignore[arg-type]
    return np.array(v).T, np.array(a).T


@dataclass(frozen=True)
class PathProfile:
    """The plan's rates along its path at the points ``tau`` of one rest-to-rest piece
    (the grid and its cells' midpoints): what the rows of the new time law are made of."""

    tau: np.ndarray  # (P,) plan time [s]
    thd: np.ndarray  # (P, 9) actuated rates of the plan
    thdd: np.ndarray  # (P, 9) actuated accelerations of the plan
    inertial: np.ndarray  # (P, 9) the torque that scales with b (tau - g - friction)
    tangent: np.ndarray  # (P, 9) the torque of the acceleration x' (M x')
    gravity: np.ndarray  # (P, 9)
    tcp_v: np.ndarray  # (P, 3) the tool centre point's velocity in the plan
    tcp_a: np.ndarray  # (P, 3) its acceleration
    pfl: np.ndarray  # (P,) power and force limiting's ratio v^T C v (0: none)


def path_profile(problem: Problem, sol: Solution, tau: np.ndarray) -> PathProfile:
    """The plan's :class:`PathProfile` at the plan times ``tau``."""
    robot = problem.robot
    x, xd, xdd = sol.sample(tau)
    thd, thdd, torque, grav = (v.T for v in actuated_profile(robot, x, xd, xdd))
    tangent = actuated_profile(robot, x, np.zeros_like(xd), xd)[2].T - grav
    m = robot.motors
    friction = (np.asarray(m.viscous_per_joint) * thd
                + np.asarray(m.coulomb_per_joint) * np.tanh(thd / m.coulomb_velocity))
    tcp_v, tcp_a = tcp_vectors_at(robot.tool.xyz, x, xd, xdd)
    pfl = np.zeros(len(tau))
    if problem.pfl:
        pfl = pfl_ratios(robot, x, xd, problem.pfl, problem.pfl_links)
    return PathProfile(tau=tau, thd=thd, thdd=thdd, inertial=torque - grav - friction,
                       tangent=tangent, gravity=grav, tcp_v=tcp_v, tcp_a=tcp_a, pfl=pfl)


def piece_grid(sol: Solution, t0: float, t1: float) -> np.ndarray:
    """The grid of one piece: every node of the plan in [t0, t1], each interval cut in
    :data:`SUB` equal cells."""
    nodes = sol.t[(sol.t >= t0 - 1e-12) & (sol.t <= t1 + 1e-12)]
    cells = [np.linspace(a, b, SUB + 1)[:-1] for a, b in zip(nodes[:-1], nodes[1:],
                                                             strict=True)]
    return np.r_[np.concatenate(cells), nodes[-1]]


def law_matrices(dtau: np.ndarray) -> tuple[sps.csr_matrix, sps.csr_matrix, sps.csr_matrix]:
    """The law's unknowns w = (b_0..b_G, s_0..s_G): b and its slope s = b' at the grid
    points, b quadratic over each cell (so b' is continuous and the accelerations too).
    Returns (B, S, C): b and b' at the 2 G + 1 points (grid points and the cells'
    midpoints, interleaved) as B w and S w, and the G continuity rows C w = 0
    (b_{i+1} - b_i = dtau (s_i + s_{i+1}) / 2)."""
    G = len(dtau)
    n = 2 * G + 1
    B, S, C = (sps.lil_matrix(shape) for shape in ((n, 2 * G + 2), (n, 2 * G + 2),
                                                    (G, 2 * G + 2)))
    o = G + 1  # the slopes' offset in w
    for i in range(G + 1):
        B[2 * i, i] = 1.0
        S[2 * i, o + i] = 1.0
    for c, h in enumerate(dtau):
        # b(mid) = b_c + h (3 s_c + s_{c+1}) / 8, b'(mid) = (s_c + s_{c+1}) / 2
        B[2 * c + 1, c] = 1.0
        B[2 * c + 1, o + c] = 3.0 * h / 8.0
        B[2 * c + 1, o + c + 1] = h / 8.0
        S[2 * c + 1, o + c] = S[2 * c + 1, o + c + 1] = 0.5
        C[c, c + 1], C[c, c] = 1.0, -1.0
        C[c, o + c] = C[c, o + c + 1] = -h / 2.0
    return B.tocsr(), S.tocsr(), C.tocsr()


def time_law(problem: Problem, prof: PathProfile, target: float) -> np.ndarray | None:
    """b (2 G + 1,) at the points of ``prof`` of one piece (its grid points and its
    cells' midpoints, interleaved): the fastest law within ``target`` of every limit;
    None if the solver finds none."""
    import cvxpy as cp  # deferred: ~1 s of import, only for plans with platform limits

    lim = problem.motion_limits
    n_pts = len(prof.tau)
    G = (n_pts - 1) // 2
    dtau = prof.tau[2::2] - prof.tau[0:-1:2]  # (G,) the cells' lengths
    B, S, C = law_matrices(dtau)
    w = cp.Variable(2 * G + 2)
    b = B @ w
    q_cap = MAX_SPEEDUP
    cons = [C @ w == 0, b >= 1.0 / MAX_SLOWDOWN**2, b <= q_cap**2]
    # the plan's own shape over its first and last interval, uniformly re-timed: the
    # start from rest and the stop, where the NLP shaped the jerk on its finest
    # intervals and the path's rate is too small to bound the law
    for ends in (np.r_[0:SUB + 1], np.r_[G - SUB:G + 1]):
        cons += [w[ends] == w[ends[0]], w[G + 1 + ends] == 0.0]
    # first order: velocities and power and force limiting scale with b
    speed2 = np.max(prof.thd**2 / (target * lim.velocity) ** 2, axis=1)
    if lim.has_tcp:
        speed2 = np.maximum(speed2, np.sum(prof.tcp_v**2, axis=1)
                            / (target * lim.tcp_speed) ** 2)
    if problem.pfl:
        speed2 = np.maximum(speed2, prof.pfl / (target * problem.options.pfl_share))
    moving = speed2 > 1e-12
    cons.append(cp.multiply(speed2[moving], b[moving]) <= 1.0)
    # the largest rate each point may take (what the rates of the rows below are bounded by)
    q_max = np.sqrt(np.minimum(q_cap**2, 1.0 / np.maximum(speed2, 1e-12)))
    # second order: accelerations and torques are k b + m b' / 2
    motors = problem.robot.motors
    fric = (np.asarray(motors.viscous_per_joint) * np.abs(prof.thd) * q_max[:, None]
            + np.abs(np.asarray(motors.coulomb_per_joint)))
    room = np.maximum(target * lim.torque - fric, 1e-3 * lim.torque)
    b_col = cp.reshape(b, (n_pts, 1), order="F")
    half = cp.reshape(0.5 * (S @ w), (n_pts, 1), order="F")

    def rows(k: np.ndarray, m: np.ndarray, scale: float | np.ndarray) -> cp.Expression:
        """k b + m b' / 2 over ``scale``: every row of order 1 at its limit."""
        return cp.multiply(k / scale, b_col) + cp.multiply(m / scale, half)

    acc = rows(prof.thdd, prof.thd, 1.0)
    torque = rows(prof.inertial, prof.tangent, 1.0)
    cons += [cp.abs(acc) <= target * lim.acceleration,
             cp.abs(rows(prof.inertial, prof.tangent, room) + prof.gravity / room) <= 1.0]
    if lim.has_tcp:
        a_tcp = rows(prof.tcp_a, prof.tcp_v, target * lim.tcp_acceleration)
        cons.append(cp.norm(a_tcp, 2, axis=1) <= 1.0)
    # jerk and torque rate between consecutive points: the step between them lasts at
    # least their distance in tau over the fastest rate allowed
    step = (np.diff(prof.tau) / np.maximum(q_max[1:], q_max[:-1]))[:, None]
    for val, limit in ((acc, lim.jerk), (torque, lim.torque_rate)):
        cons.append(cp.abs(val[1:] - val[:-1]) <= target * limit * step)
    # the time, sum of dtau / sqrt(b) by Simpson's rule over each cell (convex)
    weights = np.zeros(n_pts)
    weights[0:-1:2] += dtau / 6.0
    weights[2::2] += dtau / 6.0
    weights[1::2] += 4.0 * dtau / 6.0
    prob = cp.Problem(cp.Minimize(weights @ cp.power(b, -0.5)), cons)
    try:
        with warnings.catch_warnings():  # an inaccurate optimum is taken: it is checked
            warnings.filterwarnings("ignore", message="Solution may be inaccurate")
            prob.solve(solver=cp.CLARABEL, tol_gap_abs=1e-6, tol_gap_rel=1e-6, tol_feas=1e-7)
    except cp.SolverError:
        return None
    if prob.status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) or w.value is None:
        return None
    return np.clip(B @ np.asarray(w.value, dtype=float), 1.0 / MAX_SLOWDOWN**2, q_cap**2)


def new_times(tau: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The new times of the grid points (from 0) of the law b at the grid points and the
    cells' midpoints (interleaved), by Simpson's rule on d tau / sqrt(b)."""
    r = 1.0 / np.sqrt(b)
    dtau = tau[2::2] - tau[0:-1:2]
    return np.r_[0.0, np.cumsum(dtau / 6.0 * (r[0:-1:2] + 4.0 * r[1::2] + r[2::2]))]


def rest_spline(t: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(xd, u) at the knots t (G+1,) of the C2 cubic spline (an acceleration linear
    between the knots, the NLP's integration rule) at rest at both ends (zero velocity
    and acceleration) through the points x (G+1, n), and x with its second and
    second-to-last points moved onto the spline (the two rest conditions more than a
    clamped spline has take their interpolation's place)."""
    G = len(t) - 1
    if G < 3:
        raise ValueError("a rest-to-rest spline needs at least 3 cells")
    h = np.diff(t)
    # unknowns: xd_1..xd_{G-1}, u_1..u_{G-1}, x_1, x_{G-1}
    n_u = 2 * (G - 1) + 2
    A = np.zeros((2 * G, n_u))
    rhs = np.zeros((2 * G, x.shape[1]))

    def col(kind: str, i: int) -> int | None:
        if kind in ("xd", "u"):
            if i in (0, G):
                return None  # at rest: zero
            return (i - 1) + (0 if kind == "xd" else G - 1)
        return 2 * (G - 1) + (0 if i == 1 else 1) if i in (1, G - 1) else None

    for i in range(G):
        r_x, r_v = 2 * i, 2 * i + 1
        # x_{i+1} - x_i - h xd_i - h^2 (2 u_i + u_{i+1}) / 6 = 0
        for kind, j, coef, row in (("x", i + 1, 1.0, r_x), ("x", i, -1.0, r_x),
                                   ("xd", i, -h[i], r_x),
                                   ("u", i, -h[i] ** 2 / 3.0, r_x),
                                   ("u", i + 1, -h[i] ** 2 / 6.0, r_x),
                                   ("xd", i + 1, 1.0, r_v), ("xd", i, -1.0, r_v),
                                   ("u", i, -h[i] / 2.0, r_v), ("u", i + 1, -h[i] / 2.0, r_v)):
            c = col(kind, j)
            if c is not None:
                A[row, c] += coef
            elif kind == "x":
                rhs[row] -= coef * x[j]
    sol = lu_solve(lu_factor(A), rhs)
    xd = np.zeros_like(x)
    u = np.zeros_like(x)
    xd[1:G] = sol[0:G - 1]
    u[1:G] = sol[G - 1:2 * (G - 1)]
    x_new = x.copy()
    x_new[1], x_new[G - 1] = sol[2 * (G - 1)], sol[2 * (G - 1) + 1]
    return xd, u, x_new


def retimed(problem: Problem, sol: Solution, target: float = 0.995) -> Solution | None:
    """``sol`` re-timed along its path (module doc), dense-checked; None when a piece's
    time law cannot be found."""
    ts: list[np.ndarray] = []
    xs: list[np.ndarray] = []
    xds: list[np.ndarray] = []
    us: list[np.ndarray] = []
    seg_bounds = np.concatenate([[0.0], np.cumsum(sol.segment_times)])
    bound_new = np.full(len(seg_bounds), np.nan)
    t_off = 0.0
    for t0, t1, _ in rest_pieces(sol):
        grid = piece_grid(sol, t0, t1)
        pts = np.empty(2 * len(grid) - 1)
        pts[0::2], pts[1::2] = grid, 0.5 * (grid[:-1] + grid[1:])
        b = time_law(problem, path_profile(problem, sol, pts), target)
        if b is None:
            return None
        t_new = new_times(pts, b)
        x_pts = sol.sample(grid)[0]
        xd, u, x_pts = rest_spline(t_new, x_pts)
        for k, tb in enumerate(seg_bounds):
            hit = np.flatnonzero(np.abs(grid - tb) < 1e-12)
            if hit.size:
                bound_new[k] = t_off + t_new[hit[0]]
        first = 0 if not ts else 1  # a piece starts where the last one stopped
        ts.append(t_off + t_new[first:])
        xs.append(x_pts[first:])
        xds.append(xd[first:])
        us.append(u[first:])
        t_off += t_new[-1]
    t, x, xd, xdd = (np.concatenate(v) for v in (ts, xs, xds, us))
    tau = actuated_profile(problem.robot, x, xd, xdd)[2].T
    theta = robot_ik(x[:, 0:3], rot.matrix_from_rotvec(x[:, 3:6]), x[:, 6:9],
                     problem.robot, platform_margins=False).theta
    return sol.replace(final_time=float(t[-1]), segment_times=np.diff(bound_new), t=t, x=x,
                       xd=xd, xdd=xdd, tau=tau, theta=theta, nlp_point=None).checked()


__all__ = ["MAX_SLOWDOWN", "MAX_SPEEDUP", "SUB", "PathProfile", "new_times", "path_profile",
           "law_matrices", "piece_grid", "rest_spline", "retimed", "tcp_vectors_at", "time_law"]
