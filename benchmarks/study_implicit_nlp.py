"""A study of the planner-v2 formulation: today's NLP with its torque balance replaced
by the implicit lifted form (:func:`sixplus3.dynamics.lifted.implicit_functions`).

    .venv/bin/python benchmarks/study_implicit_nlp.py [--n 2] [--hessian exact|limited-memory]
        [--tol 1e-4]

For each of the first ``n`` solvable tasks of the narrow held-out set (seed 2026), the
planner's first start (from the baseline, at 0.6 x the margin) is solved twice from the
same point, one after the other: by today's NLP (``planner.nlp.solve_nlp``), and by the
same NLP in which every point (node and midpoint) also carries the legs' 27 joint values,
rates and accelerations and the 27 closure forces, tied by the tree's 81 loop-closure
rows, with the 36 equations of motion instead of the 9 balance rows.  All other rows
(actuated rates, ranges, tilts, margins, clearance, smoothness, integration) are today's.
Both run CasADi's interpreted functions mapped over the points (the NLP not expanded), so
compare iterations, durations and the split of each iteration, not seconds with the
planner's compiled ones.  Not the planner: a measurement for the reformulation.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("SIXPLUS3_NO_CODEGEN", "1")  # interpreted, both forms alike

import casadi as ca  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))
from bench_planner_heldout import first_solve, first_starts  # noqa: E402

from sixplus3.dynamics.lifted import NQ, implicit_functions, lifted_functions  # noqa: E402
from sixplus3.dynamics.symbolic import setup_parameters  # noqa: E402
from sixplus3.planner import solvers  # noqa: E402
from sixplus3.planner.nlp import point_bounds, start_point  # noqa: E402
from sixplus3.planner.options import ACC_SCALE, ROW_SCALE  # noqa: E402
from sixplus3.planner.problem import Problem
from sixplus3.planner.transcription import (  # noqa: E402
    integration_rows,
    layout,
    midpoint_states,
    objective,
    smoothness_rows,
    variable_bounds,
    variable_scale,
)
from sixplus3.robot_description.robot import Robot  # noqa: E402

#: per point: qv, qd, qdd, the closure forces
NY = 4 * NQ
#: their scales (rad, rad/s, rad/s^2, N)
Y_SCALE = np.r_[np.ones(NQ), np.ones(NQ), np.full(NQ, ACC_SCALE), np.full(NQ, 10.0)]


def build(problem: Problem, hessian: str, tol: float) -> tuple[ca.Function, int, int]:
    """The implicit NLP of ``problem``'s size and its solver."""
    sr, robot = problem.sr, problem.robot
    G = implicit_functions(robot)
    p_set = ca.DM(setup_parameters(robot))
    segments = tuple(int(n) for n in problem.segment_intervals())
    S, N = len(segments), sum(segments)
    P_pts = 2 * N + 1
    seg = [s for s, n in enumerate(segments) for _ in range(n)]
    o_taum, o_acc, o_T, nw = layout(N, S)
    n_all = nw + NY * P_pts
    Pp = ca.MX.sym("p", n_all + 4 + N)
    Ws, D = ca.MX.sym("w", n_all), Pp[0:n_all]
    jerk_lim, rate_lim, w_time, w_effort = (Pp[n_all + k] for k in range(4))
    frac = Pp[n_all + 4:]
    W = Ws * D
    Z = ca.reshape(W[0:o_taum], 36, N + 1)
    TAUM = ca.reshape(W[o_taum:o_acc], 9, N)
    ACC = ca.reshape(W[o_acc:o_T], 9, 2 * N + 1)
    T = W[o_T:nw]
    Y = ca.reshape(W[nw:], NY, P_pts)
    X, XD, U, TAU = Z[0:9, :], Z[9:18, :], Z[18:27, :], Z[27:36, :]
    hm = ca.horzcat(*[T[seg[k]] * frac[k] for k in range(N)])
    Hm = ca.repmat(hm, 9, 1)
    Xm, XDm, Um = midpoint_states(X, XD, U, Hm)
    pts = (ca.horzcat(X, Xm), ca.horzcat(XD, XDm), ca.horzcat(U, Um), ca.horzcat(TAU, TAUM))
    # today's rows but the balance (a function without it: its unused operations dropped)
    ins = [ca.SX.sym(n, 9) for n in ("x", "xd", "u", "tau")]
    rest = ca.Function("rest", ins, [sr.node(*ins)[9:]], {"cse": True})
    rows = rest.map(P_pts)(*pts)
    other = ca.vertcat(rows[0:9, :], (rows[9:18, :] - ACC) / ROW_SCALE["acceleration"],
                       rows[18:, :])
    qv, qd, qdd, lam = Y[0:NQ, :], Y[NQ:2 * NQ, :], Y[2 * NQ:3 * NQ, :], Y[3 * NQ:, :]
    closure = G["closure"].map(P_pts)(pts[0], pts[1], pts[2], qv, qd, qdd)
    dyn = G["dynamics"].map(P_pts)(*pts, qv, qd, qdd, lam,
                                   ca.repmat(p_set, 1, P_pts)) / ROW_SCALE["torque"]
    g = ca.vertcat(ca.vec(integration_rows(X, XD, U, Hm)), ca.vec(other), ca.vec(closure),
                   ca.vec(dyn), smoothness_rows(ACC, TAU, TAUM, Hm / 2, jerk_lim, rate_lim),
                   ca.sum1(T))
    f = objective(T, U, TAU, TAUM, w_time, w_effort, problem.options.regularisation)
    ipopt = solvers.ipopt_settings(problem.options, False)
    ipopt["hessian_approximation"] = hessian
    ipopt["tol"], ipopt["acceptable_tol"] = tol, 10 * tol
    solver = ca.nlpsol("implicit", "ipopt", {"x": Ws, "p": Pp, "f": f, "g": g},
                       {"expand": False, "print_time": False, "ipopt": ipopt})
    return solver, n_all, int(g.numel())


def solve_implicit(problem: Problem, psi: np.ndarray, bounds, base, hessian: str,
                   tol: float) -> dict:
    """Today's first start (from the baseline, the homotopy's margin) on the implicit NLP."""
    import dataclasses

    lim = dataclasses.replace(problem.limits, margin=bounds.margin)
    S, N = problem.task.n_segments, problem.n_intervals
    wp_x, x0, xd0, xdd0, T0, pts, profile = start_point(problem, psi, bounds, base)
    safety = bounds.safety
    tmax = safety["torque"] * lim.torque
    lb, ub = point_bounds(problem, x0, lim, bounds)
    lbx, ubx = variable_bounds(problem, wp_x, tmax, safety["acceleration"] * lim.acceleration,
                               bounds.duration_cap or np.inf, bounds.cranks)
    P_pts = 2 * N + 1
    # the lifted start: the closed forms at every point, the closure forces solved
    L, G = lifted_functions(problem.robot), implicit_functions(problem.robot)
    _, acc0, tau0, _ = profile
    qv, qd, qdd = (np.array(v) for v in L["lift"].map(P_pts)(pts[0].T, pts[1].T, pts[2].T))
    p_set = setup_parameters(problem.robot)
    lam0 = np.zeros((NQ, P_pts))
    for k in range(P_pts):
        args = (pts[0][k], pts[1][k], pts[2][k])
        f0 = np.array(G["dynamics"](*args, tau0[:, k], qv[:, k], qd[:, k], qdd[:, k],
                                    np.zeros(NQ), p_set)).ravel()
        A = np.hstack([np.array(G["dynamics"](*args, tau0[:, k], qv[:, k], qd[:, k],
                                              qdd[:, k], e, p_set)).ravel()[:, None] - f0[:, None]
                       for e in np.eye(NQ)])
        lam0[:, k] = np.linalg.lstsq(A, -f0, rcond=None)[0]
    z0 = np.vstack([x0.T, xd0.T, xdd0.T, tau0[:, :N + 1]])
    w0 = np.clip(np.r_[z0.ravel(order="F"), tau0[:, N + 1:].ravel(order="F"),
                       acc0.ravel(order="F"), T0], lbx, ubx)
    y0 = np.vstack([qv, qd, qdd, lam0]).ravel(order="F")
    D = np.r_[variable_scale(N, S, tmax), np.tile(Y_SCALE, P_pts)]
    t_build = time.perf_counter()
    solver, n_all, ng = build(problem, hessian, tol)
    t_build = time.perf_counter() - t_build
    lbg = np.r_[np.zeros(18 * N), np.tile(lb[9:], P_pts), np.zeros((81 + 36) * P_pts),
                np.full(36 * N, -1.0), 0.0]
    ubg = np.r_[np.zeros(18 * N), np.tile(ub[9:], P_pts), np.zeros((81 + 36) * P_pts),
                np.full(36 * N, 1.0), bounds.duration_cap or np.inf]
    big = np.full(NY * P_pts, np.inf)
    t = time.perf_counter()
    res = solver(x0=np.r_[w0, y0] / D, p=np.r_[D, lim.jerk, lim.torque_rate, 1.0, 0.0,
                                               problem.interval_fractions()],
                 lbx=np.r_[lbx, -big] / D, ubx=np.r_[ubx, big] / D, lbg=lbg, ubg=ubg)
    wall = time.perf_counter() - t
    st = solver.stats()
    w = np.array(res["x"]).ravel() * D
    T = w[layout(N, S)[2]:layout(N, S)[3]]
    evals = {k: float(st.get(f"t_wall_{k}", 0.0)) for k in ("nlp_jac_g", "nlp_hess_l")}
    return {"status": st["return_status"], "iterations": st["iter_count"], "T": float(T.sum()),
            "wall": wall, "build": t_build, "variables": n_all, "rows": ng, **evals}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=2)
    ap.add_argument("--hessian", default="exact", choices=("exact", "limited-memory"))
    ap.add_argument("--tol", type=float, default=1e-4,
                    help="IPOPT's tol for the implicit NLP (the planner's: 1e-4)")
    args = ap.parse_args()
    robot = Robot.default()
    print("| task | form | status | iterations | T [s] | wall [s] | per iteration [ms] | "
          "jac g / Hessian [s] | variables / rows |")
    print("| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | --- |")
    for doc, psi, base in first_starts(args.n, robot):
        problem, bounds, sol, st = first_solve(doc, psi, base, robot)
        print(f"| {doc['name']} | today, L-BFGS | {sol.status} | {sol.iterations} | "
              f"{sol.final_time:.4f} | {sol.solve_time:.1f} | "
              f"{1e3 * sol.solve_time / max(sol.iterations, 1):.0f} | "
              f"{st.get('t_wall_nlp_jac_g', 0.0):.1f} / - | |", flush=True)
        r = solve_implicit(problem, psi, bounds, base, args.hessian, args.tol)
        print(f"| {doc['name']} | implicit, {args.hessian}, tol {args.tol:g} | {r['status']} | "
              f"{r['iterations']} | {r['T']:.4f} | {r['wall']:.1f} | "
              f"{1e3 * r['wall'] / max(r['iterations'], 1):.0f} | {r['nlp_jac_g']:.1f} / "
              f"{r['nlp_hess_l']:.1f} | {r['variables']} / {r['rows']} |", flush=True)


if __name__ == "__main__":
    main()
