"""A study of the planner-v2 solvers: today's NLP in stage order, solved by FATROP and by
IPOPT with the exact Hessian.

    .venv/bin/python benchmarks/study_fatrop.py [--n 2] [--max-iter 300]

For each of the first ``n`` solvable tasks of the narrow held-out set (seed 2026), the
planner's first start (from the baseline, at 0.6 x the margin) is solved three times from
the same point: by today's NLP (``planner.nlp.solve_nlp``: L-BFGS, IPOPT and MUMPS), and
by the same rows in stage order, once by IPOPT with the exact Hessian and once by FATROP
(which needs the exact Hessian and a stage structure).

**Stage order** (FATROP's manual structure).  Stage k = 0..N-1 has

- the state s_k = (x, xd, u, tau, theta_ddot)_k at node k and the segment durations T
  (45 + S; T is carried from stage to stage, so every row of a stage sees it);
- the controls c_k = (u, tau, theta_ddot) at node k+1 and (tau, theta_ddot) at the
  interval's midpoint (45);
- the gap rows s_{k+1} = F(s_k, c_k): today's integration rows, the copies of node k+1's
  values and T;
- the path rows of stage k: the 70 rows of node k, the 70 of the midpoint, the 36 jerk
  and torque-rate rows of the interval (all three points are in s_k and c_k), and at
  stage 0 the total duration.

The last stage has node N's 70 rows.  The bounds, the start and the scaling are today's,
selected into stage order (the values of node k+1 appear in c_k and in s_{k+1}, tied by
the gap rows; each is bounded once, :func:`stage_problem`).  All three solves use
CasADi's interpreted SX node function (the exact Hessian is not in the compiled
library; ``SIXPLUS3_NO_CODEGEN=1``), so compare iterations, durations and the
solver's own time per iteration (the wall time less the function evaluations), not the
total seconds with today's compiled solve.  Not the planner: a measurement for the
reformulation.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("SIXPLUS3_NO_CODEGEN", "1")  # the SX node function: its Hessian

import casadi as ca  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))
from bench_planner_heldout import first_solve, first_starts  # noqa: E402

from sixplus3.planner import solvers  # noqa: E402
from sixplus3.planner.nlp import point_bounds, start_point  # noqa: E402
from sixplus3.planner.problem import Problem
from sixplus3.planner.transcription import (  # noqa: E402
    CLEARANCE_ROWS,
    NODE_ROWS,
    layout,
    midpoint_states,
    objective,
    path_rows,
    smoothness_rows,
    variable_bounds,
    variable_scale,
)
from sixplus3.robot_description.robot import Robot  # noqa: E402

#: rows of a stage beside its gap rows: node, midpoint, smoothness
STAGE_ROWS = 2 * NODE_ROWS + 36


def stage_index(N: int, S: int) -> tuple[np.ndarray, int, int]:
    """Indices into today's decision vector (:func:`transcription.layout`) of the stage
    order [s_0, c_0, s_1, c_1, ..., s_N], and the sizes of s and c."""
    o_taum, o_acc, o_T, _ = layout(N, S)
    o_accm = o_acc + 9 * (N + 1)

    def r(a: int, n: int = 9) -> list[int]:
        return list(range(a, a + n))

    idx: list[int] = []
    for k in range(N + 1):
        idx += r(36 * k, 36) + r(o_acc + 9 * k) + r(o_T, S)  # s_k
        if k < N:
            idx += (r(36 * (k + 1) + 18) + r(o_taum + 9 * k) + r(o_accm + 9 * k)
                    + r(36 * (k + 1) + 27) + r(o_acc + 9 * (k + 1)))  # c_k
    return np.array(idx), 45 + S, 45


def build(problem: Problem, equality: list[bool] | None = None,
          solver: str = "ipopt", opts: dict | None = None) -> tuple[ca.Function, list[bool]]:
    """The stage-order NLP of ``problem``'s size, solved by ``solver``."""
    sr = problem.sr
    segments = tuple(int(n) for n in problem.segment_intervals())
    S, N = len(segments), sum(segments)
    seg = [s for s, n in enumerate(segments) for _ in range(n)]
    _, nx, nu = stage_index(N, S)
    nv = (N + 1) * nx + N * nu
    P = ca.MX.sym("p", nv + 4 + N)
    Vs, Dv = ca.MX.sym("v", nv), P[0:nv]
    jerk_lim, rate_lim, w_time = P[nv], P[nv + 1], P[nv + 2]  # P[nv + 3]: w_effort
    frac = P[nv + 4:]
    V = Vs * Dv
    st = [V[k * (nx + nu):k * (nx + nu) + nx] for k in range(N + 1)]
    ct = [V[k * (nx + nu) + nx:(k + 1) * (nx + nu)] for k in range(N)]
    Ds = [Dv[k * (nx + nu):k * (nx + nu) + nx] for k in range(N + 1)]
    X = ca.horzcat(*[s[0:9] for s in st])
    XD = ca.horzcat(*[s[9:18] for s in st])
    U = ca.horzcat(*[s[18:27] for s in st])
    TAU = ca.horzcat(*[s[27:36] for s in st])
    ACCn = ca.horzcat(*[s[36:45] for s in st])
    TAUM = ca.horzcat(*[c[9:18] for c in ct])
    ACCm = ca.horzcat(*[c[18:27] for c in ct])
    h = [st[k][45 + seg[k]] * frac[k] for k in range(N)]
    # today's row families, each on stage k's own values (node k+1's u, tau and
    # theta_ddot are the control's copies c_k[0:9], c_k[27:36], c_k[36:45])
    mids = [midpoint_states(ca.horzcat(st[k][0:9], st[k][0:9]),
                            ca.horzcat(st[k][9:18], st[k][9:18]),
                            ca.horzcat(st[k][18:27], ct[k][0:9]), h[k]) for k in range(N)]
    pts = (ca.horzcat(X, *[m[0] for m in mids]), ca.horzcat(XD, *[m[1] for m in mids]),
           ca.horzcat(U, *[m[2] for m in mids]), ca.horzcat(TAU, TAUM))
    G = path_rows(sr.node, 1, pts, ca.horzcat(ACCn, ACCm))
    g = []
    for k in range(N):
        s, c, sn = st[k], ct[k], Vs[(k + 1) * (nx + nu):(k + 1) * (nx + nu) + nx]
        x, xd, u, up = s[0:9], s[9:18], s[18:27], c[0:9]
        F = ca.vertcat(x + h[k] * xd + h[k]**2 * (2 * u + up) / 6, xd + h[k] * (u + up) / 2,
                       up, c[27:36], c[36:45], s[45:45 + S])
        g.append(sn - F / Ds[k + 1])  # the next state, scaled: identity in the gap rows
        smooth = smoothness_rows(ca.horzcat(s[36:45], c[36:45], c[18:27]),
                                 ca.horzcat(s[27:36], c[27:36]), c[9:18], h[k] / 2,
                                 jerk_lim, rate_lim)
        g += [G[:, k], G[:, N + 1 + k], smooth]
        if k == 0:
            g.append(ca.sum1(s[45:45 + S]))
    g.append(G[:, N])
    f = objective(st[0][45:45 + S], U, TAU, TAUM, w_time, P[nv + 3],
                  problem.options.regularisation)
    nlp = {"x": Vs, "p": P, "f": f, "g": ca.vertcat(*g)}
    if equality is None:  # the gap rows, the torque balance and the theta_ddot ties
        point = [True] * 9 + [False] * 9 + [True] * 9 + [False] * (NODE_ROWS - 27)
        equality = []
        for k in range(N):
            equality += [True] * nx + point + point + [False] * 36 + ([False] if k == 0 else [])
        equality += point
    options: dict = {"print_time": False, "expand": False}
    if solver == "fatrop":
        options.update(structure_detection="manual", N=N, nx=[nx] * (N + 1),
                       nu=[nu] * N + [0], ng=[STAGE_ROWS + 1] + [STAGE_ROWS] * (N - 1)
                       + [NODE_ROWS], equality=equality)
    options.update(opts or {})
    return ca.nlpsol("stages_" + solver, solver, nlp, options), equality


def stage_problem(problem: Problem, psi: np.ndarray, bounds, base) -> dict:
    """Today's first start in stage order: bounds, start, scaling, parameters."""
    import dataclasses

    lim = dataclasses.replace(problem.limits, margin=bounds.margin)
    S, N = problem.task.n_segments, problem.n_intervals
    wp_x, x0, xd0, xdd0, T0, _, profile = start_point(problem, psi, bounds, base)
    tmax = bounds.safety["torque"] * lim.torque
    lb, ub = point_bounds(problem, x0, lim, bounds)
    lbx, ubx = variable_bounds(problem, wp_x, tmax,
                               bounds.safety["acceleration"] * lim.acceleration,
                               bounds.duration_cap or np.inf, bounds.cranks)
    _, acc0, tau0, _ = profile
    z0 = np.vstack([x0.T, xd0.T, xdd0.T, tau0[:, :N + 1]])
    w0 = np.clip(np.r_[z0.ravel(order="F"), tau0[:, N + 1:].ravel(order="F"),
                       acc0.ravel(order="F"), T0], lbx, ubx)
    D = variable_scale(N, S, tmax)
    idx, nx, _ = stage_index(N, S)
    node_lb = [lb.copy() for _ in range(N + 1)]
    if bounds.clearance is not None and bounds.clearance_waypoints is not None:
        for k in problem.waypoint_nodes():
            node_lb[k][CLEARANCE_ROWS] = bounds.clearance_waypoints
    cap = bounds.duration_cap or np.inf
    lbg, ubg = [], []
    for k in range(N):
        lbg += [np.zeros(nx), node_lb[k], lb, -np.ones(36)] + ([[0.0]] if k == 0 else [])
        ubg += [np.zeros(nx), ub, ub, np.ones(36)] + ([[cap]] if k == 0 else [])
    lbg.append(node_lb[N])
    ubg.append(ub)
    p = np.r_[D[idx], lim.jerk, lim.torque_rate, 1.0, 0.0, problem.interval_fractions()]
    lo, hi = lbx[idx], ubx[idx]
    # each value bounded once: node k+1's copies in c_k and the durations after stage 0
    # are tied to a bounded variable by the gap rows.  Bounded twice, a fixed value (a
    # rest, a waypoint) made FATROP's constraint Jacobian rank-deficient at every
    # iteration (IPOPT removes fixed variables; FATROP keeps them).
    _, nx, nu = stage_index(N, S)
    free = np.zeros(len(idx), bool)
    for k in range(N + 1):
        a = k * (nx + nu)
        if k > 0:
            free[a + 45:a + nx] = True
        if k < N:
            c = a + nx
            free[np.r_[c:c + 9, c + 27:c + 45]] = True
    lo, hi = np.where(free, -np.inf, lo), np.where(free, np.inf, hi)
    return {"x0": w0[idx] / D[idx], "lbx": lo / D[idx], "ubx": hi / D[idx],
            "lbg": np.concatenate(lbg), "ubg": np.concatenate(ubg), "p": p,
            "D": D[idx], "N": N, "S": S, "nx": nx}


def run(solver: ca.Function, args: dict) -> dict:
    t = time.perf_counter()
    res = solver(x0=args["x0"], lbx=args["lbx"], ubx=args["ubx"], lbg=args["lbg"],
                 ubg=args["ubg"], p=args["p"])
    wall = time.perf_counter() - t
    st = solver.stats()
    v = np.array(res["x"]).ravel()
    T = float((v[45:45 + args["S"]] * args["D"][45:45 + args["S"]]).sum())
    fe = sum(float(val) for key, val in st.items()
             if key.startswith("t_wall_nlp_") and isinstance(val, float))
    iters = int(st.get("iter_count", -1))
    # IPOPT's return status is a name; FATROP's is a code (0: converged)
    status = str(st.get("return_status", ""))
    if status.lstrip("-").isdigit() or not status:
        status = "converged" if st.get("success") else f"failed ({status})"
    return {"status": status, "iterations": iters,
            "T": T, "wall": wall, "fe": fe}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=2)
    ap.add_argument("--max-iter", type=int, default=300)
    ap.add_argument("--tol", type=float, default=1e-4, help="both stage-order solvers' tol")
    ap.add_argument("--solvers", default="ipopt,fatrop",
                    help="the stage-order solvers to run, of ipopt,fatrop")
    ap.add_argument("--print-level", type=int, default=0, help="FATROP's print level")
    ap.add_argument("--convexify", default=None,
                    choices=("regularize", "eigen-reflect", "eigen-clip"),
                    help="CasADi's convexification of the Hessian for FATROP (default none)")
    args = ap.parse_args()
    if args.n < 1 or args.max_iter < 1 or not args.tol > 0:
        ap.error("valid: --n >= 1, --max-iter >= 1, --tol > 0")
    if not set(args.solvers.split(",")) <= {"ipopt", "fatrop"}:
        ap.error(f"--solvers {args.solvers!r}: valid: ipopt, fatrop, or both, comma-separated")
    robot = Robot.default()
    print("| task | solver | status | iterations | T [s] | wall [s] | function evaluations "
          "[s] | solver's own per iteration [ms] |")
    print("| --- | --- | --- | ---: | ---: | ---: | ---: | ---: |")
    for doc, psi, base in first_starts(args.n, robot):
        problem, bounds, sol, st = first_solve(doc, psi, base, robot)
        fe = sum(float(v) for k, v in st.items()
                 if k.startswith("t_wall_nlp_") and isinstance(v, float))
        print(f"| {doc['name']} | today: IPOPT, L-BFGS | {sol.status} | "
              f"{sol.iterations} | {sol.final_time:.4f} | {sol.solve_time:.2f} | {fe:.2f} | "
              f"{1e3 * (sol.solve_time - fe) / max(sol.iterations, 1):.1f} |", flush=True)
        sp = stage_problem(problem, psi, bounds, base)
        ip = solvers.ipopt_settings(problem.options, False)
        ip.update(hessian_approximation="exact", max_iter=args.max_iter, tol=args.tol,
                  acceptable_tol=10 * args.tol, print_level=0)
        ip.pop("limited_memory_max_history", None)
        t = time.perf_counter()
        ipopt, eq = build(problem, solver="ipopt", opts={"ipopt": ip})
        fopts: dict = {"fatrop": {"print_level": args.print_level, "tol": args.tol,
                                  "max_iter": args.max_iter}}
        if args.convexify:
            fopts["convexify_strategy"] = args.convexify
        fatrop, _ = build(problem, eq, "fatrop", fopts)
        print(f"(built both in {time.perf_counter() - t:.1f} s)", file=sys.stderr, flush=True)
        for name, s in (("stages: IPOPT, exact Hessian", ipopt), ("stages: FATROP", fatrop)):
            if name.split()[1].rstrip(",").lower() not in args.solvers.split(","):
                continue
            r = run(s, sp)
            print(f"| {doc['name']} | {name} | {r['status']} | {r['iterations']} | "
                  f"{r['T']:.4f} | {r['wall']:.2f} | {r['fe']:.2f} | "
                  f"{1e3 * (r['wall'] - r['fe']) / max(r['iterations'], 1):.1f} |", flush=True)


if __name__ == "__main__":
    main()
