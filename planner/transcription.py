"""The NLP: direct multiple shooting of the platform's motion, one function per family.

Decision vector ``w`` (:func:`layout`): per node k = 0..N the state z_k = (x, xd, u, tau)
(minimal coordinates, their rates, the acceleration u = xdd, the actuator torques); then
the torques at the interval midpoints, the actuated accelerations theta_ddot at the
nodes and the midpoints, and the segment durations T_s.  IPOPT sees w / D
(:func:`variable_scale`).  Interval k of segment s lasts h_k = T_s * fraction_k
(:meth:`Problem.interval_fractions`: graded next to a rest).

Rows, assembled in :func:`build_nlp`:

- :func:`integration_rows`: x+ = x + h xd + h^2 (2 u + u+) / 6, xd+ = xd + h (u + u+) / 2
  (exact for an acceleration linear over the interval: the states are cubics);
- :func:`path_rows`: the 70 rows of ``SymbolicRobot.node`` at every node and every
  interval's midpoint (the exact cubic state there, :func:`midpoint_states`): torque
  balance, actuated rates, the theta_ddot ties, actuated range, reach, spherical joints,
  singularity margins, platform margin, clearance.  Their bounds: :func:`node_bounds`;
- :func:`smoothness_rows`: actuated jerk and torque rate between consecutive points;
- the total duration (a row: free for minimum time, fixed for a given duration);
- with platform-space limits only, :func:`tcp_rows.tcp_rows`: the tool centre point's
  squared speed and acceleration over their limits at every node and midpoint;
- :func:`objective`: the total duration plus a small regularisation, or the effort.

Waypoints, rest and locked or given crank angles are equal variable bounds
(:func:`variable_bounds`): the NLP's structure depends only on the task's size, so one
built NLP serves every task of that size (:mod:`sixplus3.planner.solvers`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import casadi as ca
import numpy as np

from sixplus3.planner.options import ACC_SCALE, ROW_SCALE
from sixplus3.planner.tcp_rows import pfl_rows, tcp_rows
from sixplus3.robot_description.limits import Limits

if TYPE_CHECKING:
    from sixplus3.planner.problem import Problem

#: rows of ``SymbolicRobot.node`` per point
NODE_ROWS = 70
#: the clearance rows among them
CLEARANCE_ROWS = slice(67, 70)


def layout(N: int, S: int) -> tuple[int, int, int, int]:
    """Offsets in the decision vector [z_0 .. z_N, tau_mid, theta_ddot, T] of tau_mid
    (9 N), theta_ddot at the nodes then the midpoints (9 (2 N + 1)), the durations (S),
    and its length; z_k = (x, xd, u, tau)_k."""
    o_taum = 36 * (N + 1)
    o_acc = o_taum + 9 * N
    o_T = o_acc + 9 * (2 * N + 1)
    return o_taum, o_acc, o_T, o_T + S


def variable_scale(N: int, S: int, tmax: float) -> np.ndarray:
    """Scale of every decision variable: IPOPT works with w / D.

    Accelerations are scaled by 100 (m or rad)/s^2 and torques by their bound, so that
    both are of order one like the poses, rates and durations.  (Scaling every variable
    by the magnitudes of its guess made IPOPT's L-BFGS slower and erratic on the task
    suite; this choice was the fastest of those measured, BENCHMARKS.md.)
    """
    node = np.r_[np.ones(18), np.full(9, ACC_SCALE), np.full(9, tmax)]
    return np.r_[np.tile(node, N + 1), np.full(9 * N, tmax),
                 np.full(9 * (2 * N + 1), ACC_SCALE), np.ones(S)]


def variable_bounds(problem: Problem, wp_x: np.ndarray, tmax: float, amax: float,
                    total: float = np.inf,
                    cranks: tuple[np.ndarray, np.ndarray] | None = None,
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of the decision vector (:func:`layout`): ``tmax`` [N m] on the torques,
    ``amax`` [rad/s^2] on theta_ddot, the crank angles in ``cranks`` = (lo, hi) [rad]
    (default :meth:`Problem.crank_range`), and each segment's duration within [0.02, 60] s
    and at most ``total`` [s] (the bound of the total duration).

    Waypoints, the rest conditions and locked or given crank angles are equal bounds
    (IPOPT removes such fixed variables from the problem).
    """
    task, opt = problem.task, problem.options
    S, N = task.n_segments, problem.n_intervals
    nodes = problem.waypoint_nodes()
    lo = np.full((N + 1, 36), -np.inf)
    hi = np.full((N + 1, 36), np.inf)
    lo[:, 27:36], hi[:, 27:36] = -tmax, tmax
    if opt.lock_redundancy:
        lo[:, 6:9] = hi[:, 6:9] = wp_x[0, 6:9]
    else:
        lo[:, 6:9], hi[:, 6:9] = problem.crank_range() if cranks is None else cranks
    for w, wp in enumerate(task.waypoints):
        k = nodes[w]
        lo[k, 0:6] = hi[k, 0:6] = wp_x[w, 0:6]
        if wp.psi is not None and not opt.lock_redundancy:
            lo[k, 6:9] = hi[k, 6:9] = wp_x[w, 6:9]
    # at rest (the start, the end, a stop): zero velocity and zero acceleration, so that
    # the torque starts and ends at the holding torque (no step at either end)
    for w in problem.rest_waypoints():
        lo[nodes[w], 9:27] = hi[nodes[w], 9:27] = 0.0
    n_acc = 9 * (2 * N + 1)
    t_lo, t_hi = min(0.02, total), min(60.0, total)
    return (np.r_[lo.ravel(), np.full(9 * N, -tmax), np.full(n_acc, -amax), np.full(S, t_lo)],
            np.r_[hi.ravel(), np.full(9 * N, tmax), np.full(n_acc, amax), np.full(S, t_hi)])


def type2_det_bound(margin: float) -> float:
    """The smallest det J-hat that guarantees a leg's type II margin >= ``margin``.

    J-hat is the leg's Jacobian with unit rows, and its type II margin is sigma_min.  With
    unit rows, sigma_1^2 + sigma_2^2 + sigma_3^2 = 3, so sigma_1 sigma_2 <= (3 - sigma_3^2)/2
    and |det| <= g(sigma_3) with g(s) = s (3 - s^2) / 2, increasing on [0, 1].  So
    |det| >= g(m) implies sigma_3 >= m, and the bound is tight (unit rows with sigma_1 =
    sigma_2 reach it).  The rows used 3 m before (twice as strict for small m): a held-out
    task whose stop-at-waypoints baseline passed every official margin had det J-hat =
    0.077 < 0.15 on its path, and every NLP start was declared infeasible.
    """
    return margin * (3.0 - margin**2) / 2.0


def node_bounds(lim: Limits, sign1: np.ndarray, sign2: np.ndarray, platform_proxy: float,
                velocity_safety: float = 1.0, spherical_reserve: float = 0.0,
                clearance: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Lower/upper bounds of the 70 rows of ``SymbolicRobot.node``.

    ``sign1``, ``sign2``: the side of zero each leg's type I (9) and type II (3) margin
    keeps (from the start); ``spherical_reserve`` [rad] below the spherical joints'
    limit; ``clearance`` [m] between the legs' bodies (None: those rows unbounded).
    """
    inf = np.inf
    lb, ub = np.zeros(NODE_ROWS), np.zeros(NODE_ROWS)
    v = velocity_safety * lim.velocity
    lb[9:18], ub[9:18] = -v, v
    lb[18:27], ub[18:27] = 0.0, 0.0  # theta_ddot(x, xd, u) - ACC (bounded: ACC's bounds)
    lb[27:36], ub[27:36] = lim.theta_min, lim.theta_max
    lb[36:45], ub[36:45] = 0.0, inf
    lb[45:54], ub[45:54] = math.cos(lim.spherical - spherical_reserve), inf
    for rows, sign, m in ((slice(54, 63), sign1, lim.margin),
                          (slice(63, 66), sign2, type2_det_bound(lim.margin))):
        lb[rows] = np.where(sign > 0, m, -inf)
        ub[rows] = np.where(sign > 0, inf, -m)
    lb[66], ub[66] = platform_proxy, inf
    lb[CLEARANCE_ROWS] = -inf if clearance is None else clearance
    ub[CLEARANCE_ROWS] = inf
    return lb, ub


def integration_rows(X: Any, XD: Any, U: Any, Hm: Any) -> Any:
    """The double integrator, exact for an acceleration linear over each interval."""
    N = X.shape[1] - 1
    Uk, Uk1 = U[:, 0:N], U[:, 1:N + 1]
    return ca.vertcat(X[:, 1:] - X[:, 0:N] - Hm * XD[:, 0:N] - Hm**2 * (2 * Uk + Uk1) / 6,
                      XD[:, 1:] - XD[:, 0:N] - Hm * (Uk + Uk1) / 2)


def midpoint_states(X: Any, XD: Any, U: Any, Hm: Any) -> tuple[Any, Any, Any]:
    """(x, xd, u) at every interval's midpoint, exact on the cubic.

    Every path row is imposed there too: theta_ddot and the torques are strongly
    nonlinear inside an interval (overshoots of 37% in acceleration and 16% in torque
    between nodes were measured on the torsion task with nodes only)."""
    N = X.shape[1] - 1
    Uk, Uk1 = U[:, 0:N], U[:, 1:N + 1]
    jerk = (Uk1 - Uk) / Hm
    half = Hm / 2
    return (X[:, 0:N] + half * XD[:, 0:N] + half**2 / 2 * Uk + half**3 / 6 * jerk,
            XD[:, 0:N] + half * Uk + half**2 / 2 * jerk, (Uk + Uk1) / 2)


def path_rows(node: ca.Function, threads: int, points: tuple[Any, Any, Any, Any],
              ACC: Any) -> Any:
    """``node`` mapped over the points (x, xd, u, tau) (the nodes, then the midpoints),
    with the torque-balance rows and the theta_ddot ties scaled (ROW_SCALE).

    theta_ddot is a variable (ACC) tied to the model by 9 equality rows per point: its
    limit is then a variable bound and the jerk rows involve two variables each,
    instead of two dense theta_ddot expressions (that made the jerk rows half of the
    constraint Jacobian's nonzeros and ~40% of the time of an IPOPT iteration,
    BENCHMARKS.md).  The torque-balance rows (N or N m) and the ties (rad/s^2) are in
    the units of their variables' scales: IPOPT's constr_viol_tol (1e-4) then leaves at
    most 1e-3 N (m) in a balance row and 1e-2 rad/s^2 in a tie.  Unscaled, it asked for
    ~1e-6 of their size, and IPOPT spent 10-15 iterations at the end of a solve on that.
    """
    n = points[0].shape[1]
    mapped = node.map(n, "thread", threads) if threads > 1 else node.map(n)
    G = mapped(*points)
    return ca.vertcat(G[0:9, :] / ROW_SCALE["torque"], G[9:18, :],
                      (G[18:27, :] - ACC) / ROW_SCALE["acceleration"], G[27:, :])


def smoothness_rows(ACC: Any, TAU: Any, TAUM: Any, half: Any, jerk_lim: Any,
                    rate_lim: Any) -> Any:
    """Actuated jerk and torque rate bounded between consecutive points (node k,
    midpoint k, node k+1; half an interval apart): |d| <= limit * h / 2, as one row
    d / (limit h / 2) in [-1, 1] (h >= 0.02 s / nodes per segment > 0).

    The two linear rows d -+ limit h/2 <= / >= 0 it replaces made 40% of the inequality
    rows; one two-sided row per bound gave a lower wall time and the same or shorter
    plans on the held-out set (BENCHMARKS.md)."""
    N = TAUM.shape[1]

    def rate_rows(nodes: Any, mids: Any, limit: Any) -> Any:
        d1, d2 = mids - nodes[:, 0:N], nodes[:, 1:N + 1] - mids
        room = limit * half
        return ca.vertcat(ca.vec(d1 / room), ca.vec(d2 / room))

    return ca.vertcat(rate_rows(ACC[:, 0:N + 1], ACC[:, N + 1:2 * N + 1], jerk_lim),
                      rate_rows(TAU, TAUM, rate_lim))


def objective(T: Any, U: Any, TAU: Any, TAUM: Any, w_time: Any, w_effort: Any,
              regularisation: float) -> Any:
    """``w_time`` (total duration + the regularisation: mean squared acceleration, ~1 at
    100 (m or rad)/s^2) + ``w_effort`` (mean squared torque over the nodes and
    midpoints, ~1 at 10 N m)."""
    N = TAUM.shape[1]
    effort = (ca.sumsqr(TAU) + ca.sumsqr(TAUM)) / (100.0 * (2 * N + 1))
    return (w_time * ca.sum1(T)
            + regularisation * ca.sumsqr(U / 100.0) / (N + 1) * ca.sum1(T)
            + w_effort * effort)


@dataclass(frozen=True)
class Transcription:
    """A built NLP (CasADi's ``{"x", "p", "f", "g"}``) and its sizes.

    Parameters p = [D (nw), jerk limit, torque-rate limit, w_time, w_effort, the N
    interval fractions (:meth:`Problem.interval_fractions`)], then with platform-space
    rows 1 / v_max^2 and 1 / a_max^2 of the tool centre point."""

    nlp: dict[str, Any]
    N: int
    S: int
    nw: int
    ng: int


def build_nlp(node: ca.Function, threads: int, segments: tuple[int, ...],
              regularisation: float, tcp: ca.Function | None = None,
              pfl: tuple[ca.Function, ...] = ()) -> Transcription:
    """The NLP of ``len(segments)`` segments of ``segments[s]`` intervals each, with
    ``node`` the path rows' function (compiled, mapped on ``threads``, or CasADi's SX
    function); with ``tcp`` (:func:`tcp_rows.tcp_function`), the platform-space rows
    last (:func:`tcp_rows.tcp_rows`: 2 (2 N + 1) rows, the speeds then the
    accelerations, at the nodes then the midpoints) and two more parameters
    (1 / v_max^2, 1 / a_max^2); with ``pfl`` (:func:`tcp_rows.pfl_function`, one per
    platform point; :func:`tcp_rows.leg_pfl_function`, one per leg for its k vertices),
    the power and force limiting rows after them (:func:`tcp_rows.pfl_rows`: k (2 N + 1)
    rows per function, v^T C v at the nodes then the midpoints, each NLP point's k
    together) and each NLP point's C (9 k entries per function) as parameters."""
    S, N = len(segments), sum(segments)
    seg = [s for s, n in enumerate(segments) for _ in range(n)]
    o_taum, o_acc, o_T, nw = layout(N, S)
    n_tcp = 2 if tcp is not None else 0
    sizes = [int(fn.size1_out(0)) for fn in pfl]  # points per function (a leg's: its vertices)
    n_pfl = 9 * (2 * N + 1) * sum(sizes)
    P = ca.MX.sym("p", nw + 4 + N + n_tcp + n_pfl)
    o_tcp = nw + 4 + N
    Ws, D = ca.MX.sym("w", nw), P[0:nw]
    jerk_lim, rate_lim, w_time, w_effort = P[nw], P[nw + 1], P[nw + 2], P[nw + 3]
    frac = P[nw + 4:nw + 4 + N]
    W = Ws * D
    Z = ca.reshape(W[0:o_taum], 36, N + 1)
    TAUM = ca.reshape(W[o_taum:o_acc], 9, N)
    ACC = ca.reshape(W[o_acc:o_T], 9, 2 * N + 1)  # theta_ddot at the nodes, the midpoints
    T = W[o_T:]
    X, XD, U, TAU = Z[0:9, :], Z[9:18, :], Z[18:27, :], Z[27:36, :]
    hm = ca.horzcat(*[T[seg[k]] * frac[k] for k in range(N)])
    Hm = ca.repmat(hm, 9, 1)
    Xm, XDm, Um = midpoint_states(X, XD, U, Hm)
    G = path_rows(node, threads, (ca.horzcat(X, Xm), ca.horzcat(XD, XDm),
                                  ca.horzcat(U, Um), ca.horzcat(TAU, TAUM)), ACC)
    g = ca.vertcat(ca.vec(integration_rows(X, XD, U, Hm)), ca.vec(G),
                   smoothness_rows(ACC, TAU, TAUM, Hm / 2, jerk_lim, rate_lim), ca.sum1(T))
    if tcp is not None:
        g = ca.vertcat(g, tcp_rows(tcp, (ca.horzcat(X, Xm), ca.horzcat(XD, XDm),
                                         ca.horzcat(U, Um)), P[o_tcp], P[o_tcp + 1]))
    o = o_tcp + n_tcp
    for fn, k in zip(pfl, sizes, strict=True):
        C = ca.reshape(P[o:o + 9 * k * (2 * N + 1)], 9 * k, 2 * N + 1)
        g = ca.vertcat(g, pfl_rows(fn, (ca.horzcat(X, Xm), ca.horzcat(XD, XDm)), C))
        o += 9 * k * (2 * N + 1)
    f = objective(T, U, TAU, TAUM, w_time, w_effort, regularisation)
    return Transcription({"x": Ws, "p": P, "f": f, "g": g}, N, S, nw, int(g.numel()))


__all__ = ["CLEARANCE_ROWS", "NODE_ROWS", "Transcription", "build_nlp", "integration_rows",
           "layout", "midpoint_states", "node_bounds", "objective", "path_rows",
           "smoothness_rows", "type2_det_bound", "variable_bounds", "variable_scale"]
