"""The planner on a held-out random set: wall time, success, duration against the baseline.

    .venv/bin/python benchmarks/bench_planner_heldout.py [--n 30] [--seed 2026] [--out r.jsonl]
    .venv/bin/python benchmarks/bench_planner_heldout.py --broad --seed 1   # the broad set
    .venv/bin/python benchmarks/bench_planner_heldout.py --examples   # the example suite
    .venv/bin/python benchmarks/bench_planner_heldout.py --certify    # + the certificate
    .venv/bin/python benchmarks/bench_planner_heldout.py --multi-nodes 16
        # 16 node intervals per segment on the tasks of 3-4 waypoints (default 12)
    .venv/bin/python benchmarks/bench_planner_heldout.py --tasks 0,1,2 --ipopt mumps_pivtol=1e-8
        # a subset of the tasks, with IPOPT options over the planner's (PlannerOptions)

The task generator is broader than bench_planner_random.py, as in the planner-speed issue:
2-4 waypoints, all random (start and end away from home): positions x, y in +-0.06 m,
z from 5 cm below the default robot's home to 6 cm above, roll/pitch/yaw in +-45 deg,
the task defaults otherwise (18 intervals for one segment and 12 per segment for more,
``planner.task.AUTO_NODES``; 90 % torque fraction; cranks at home at the start and back
at the end).  Tasks whose waypoints fail
the static checks (reach, ranges, margins, holding torque) are refused before any
optimisation, by design, and counted apart.

Per task: the wall time of ``solve(Problem(task, robot))`` (everything from the task to a
dense-checked Solution; the one-time C compilation of the model is done before the clock
starts), the NLP solve time, IPOPT iterations, the plan's duration, and the duration of
the stop-at-waypoints baseline (straight lines, static crank angles, TOPP-RA per segment,
made jerk- and torque-rate-limited: ``planner.baseline``) when the code has it.  With
``--certify``, after the clock: the fastest re-timing of the plan's own path under all of
its limits (``planner.certificate.certify``) and the ratio plan / re-timed.
"""

from __future__ import annotations

import argparse
import collections
import json
import statistics
import time

import numpy as np

from sixplus3.dynamics.codegen import ensure_optimised
from sixplus3.errors import InfeasibleTaskError
from sixplus3.planner.certificate import certify
from sixplus3.planner.options import PlannerOptions
from sixplus3.planner.problem import Problem
from sixplus3.planner.strategy import solve
from sixplus3.planner.task import task_from_dict
from sixplus3.robot_description.robot import Robot

#: Height of the default robot's home [m]: the tasks' z range is around it.
HOME_Z = Robot.default().home_position[2]


def heldout_task(rng: np.random.Generator, k: int) -> dict:
    wps = []
    for _ in range(int(rng.integers(2, 5))):
        wps.append({"position": [float(rng.uniform(-0.06, 0.06)),
                                 float(rng.uniform(-0.06, 0.06)),
                                 float(HOME_Z + rng.uniform(-0.05, 0.06))],
                    "rpy": [float(v) for v in rng.uniform(-45, 45, 3)]})
    return {"name": f"heldout_{k}", "waypoints": wps}


def broad_task(rng: np.random.Generator, k: int) -> dict:
    """The broader generator of the planner-speed issue: 2-4 waypoints, x and y within
    +-9 cm of home, z from 6 cm below it to 10 cm above, roll and pitch within +-55 deg,
    yaw within +-70 deg."""
    wps = []
    for _ in range(int(rng.integers(2, 5))):
        wps.append({"position": [float(rng.uniform(-0.09, 0.09)),
                                 float(rng.uniform(-0.09, 0.09)),
                                 float(HOME_Z + rng.uniform(-0.06, 0.10))],
                    "rpy": [float(rng.uniform(-55, 55)), float(rng.uniform(-55, 55)),
                            float(rng.uniform(-70, 70))]})
    return {"name": f"broad_{k}", "waypoints": wps}


def first_starts(n: int, robot: Robot, seed: int = 2026) -> list[tuple[dict, np.ndarray, object]]:
    """(task document, static crank angles, baseline) of the first ``n`` tasks of the
    narrow held-out set that pass the static checks and have a baseline: the planner's
    first start, for the studies of one solve (profile_nlp.py, study_implicit_nlp.py)."""
    from sixplus3.planner import baseline
    from sixplus3.planner.statics import choose_static_psi

    rng = np.random.default_rng(seed)
    starts = []
    for k in range(40):
        doc = heldout_task(rng, k)
        if len(starts) == n:
            break
        problem = Problem(task_from_dict(doc), robot)
        try:
            psi = choose_static_psi(problem.task, robot, problem.limits, False,
                                    problem.rest_waypoints())
        except InfeasibleTaskError:
            continue
        base, _ = baseline.baseline_plan(problem, psi)
        if base is not None:
            starts.append((doc, psi, base))
    return starts


def first_solve(doc: dict, psi: np.ndarray, base: object, robot: Robot
                ) -> tuple[Problem, object, object, dict]:
    """(problem, bounds, solution, IPOPT's stats) of the planner's first solve of a
    :func:`first_starts` entry: from the baseline at 0.6 x the task's margin (the
    homotopy's first step), as ``planner.strategy.first_solve`` does it."""
    from sixplus3.planner import solvers
    from sixplus3.planner.nlp import solve_nlp
    from sixplus3.planner.options import PlannerOptions
    from sixplus3.planner.strategy import initial_bounds

    problem = Problem(task_from_dict(doc), robot, PlannerOptions(max_iter=300))
    bounds = initial_bounds(problem, psi, base).replace(margin=0.6 * problem.limits.margin)
    solvers.ipopt_solver(problem)
    sol = solve_nlp(problem, psi, bounds, warm=base)
    return problem, bounds, sol, solvers.ipopt_solver(problem).solver.stats()


def pct(values: list[float], q: float) -> float:
    return float(np.percentile(values, q)) if values else float("nan")


def ipopt_pair(text: str) -> tuple[str, object]:
    """NAME=VALUE from the command line: the value as an int, a float or a string."""
    name, sep, value = text.partition("=")
    if not sep or not name:
        raise argparse.ArgumentTypeError(f"{text!r}: expected NAME=VALUE")
    for kind in (int, float):
        try:
            return name, kind(value)
        except ValueError:
            pass
    return name, value


def split(planned: list[dict]) -> None:
    """Where the planned tasks' wall time goes: the NLP solves' iterations (every solve
    of a plan), the time per iteration in function evaluations (CasADi's t_wall_nlp_*)
    and in IPOPT's own work (the rest of the solve time: linear algebra, line search),
    the time outside the NLP (static choices, baseline, dense checks), and two bounds:
    the wall time if IPOPT's own work took nothing, and if the function evaluations
    took nothing."""
    its = [r["total_iterations"] for r in planned]
    fn = [r["functions"] for r in planned]
    own = [r["solve"] - r["functions"] for r in planned]
    outside = [r["wall"] - r["solve"] for r in planned]
    per_fn = [1e3 * f / max(i, 1) for f, i in zip(fn, its, strict=True)]
    per_own = [1e3 * o / max(i, 1) for o, i in zip(own, its, strict=True)]
    no_own = [r["wall"] - o for r, o in zip(planned, own, strict=True)]
    no_fn = [r["wall"] - f for r, f in zip(planned, fn, strict=True)]
    med = statistics.median
    print(f"NLP work over {len(planned)} plans (every solve): iterations median "
          f"{med(its):g}, range {min(its)}-{max(its)}; per iteration median "
          f"{med(per_fn):.1f} ms of function evaluations + {med(per_own):.1f} ms of IPOPT's "
          f"own work; outside the NLP median {med(outside):.2f} s")
    print(f"wall [s] with IPOPT's own work taken out: median {med(no_own):.2f}, p95 "
          f"{pct(no_own, 95):.2f}; with the function evaluations taken out: median "
          f"{med(no_fn):.2f}, p95 {pct(no_fn, 95):.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=30)
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--out", default=None, help="write one JSON line per task")
    ap.add_argument("--broad", action="store_true",
                    help="the broader generator (broad_task: +-9 cm, z -6/+10 cm, roll and "
                    "pitch +-55 deg, yaw +-70 deg) instead of the narrow one")
    ap.add_argument("--examples", action="store_true",
                    help="the example suite (examples/*.yaml) instead of random tasks")
    ap.add_argument("--certify", action="store_true",
                    help="also re-time each plan's path under all its limits (after the clock)")
    ap.add_argument("--tasks", default=None,
                    help="comma-separated indices of the tasks to run (default: all)")
    ap.add_argument("--ipopt", type=ipopt_pair, action="append", default=[],
                    metavar="NAME=VALUE",
                    help="an IPOPT option over the planner's (repeatable)")
    ap.add_argument("--multi-nodes", type=int, default=None, metavar="N",
                    help="node intervals per segment on random tasks of more than one segment "
                    "(default: the task's, planner.task.AUTO_NODES)")
    ap.add_argument("--regularisation", type=float, default=None,
                    help="the NLP's acceleration regularisation (PlannerOptions)")
    args = ap.parse_args()
    reg = {} if args.regularisation is None else {"regularisation": args.regularisation}
    try:
        opts = PlannerOptions(ipopt_options=tuple(args.ipopt), **reg)
    except ValueError as exc:
        ap.error(str(exc))
    # time the planner as it runs after its first use: with the optimised build
    ensure_optimised(Robot.default())  # the one-time compile, outside the clock
    rng = np.random.default_rng(args.seed)
    out = open(args.out, "w") if args.out else None  # noqa: SIM115
    if args.examples:
        from pathlib import Path

        from sixplus3.planner.task import load_task

        tasks = [load_task(p) for p in sorted(
            (Path(__file__).parents[1] / "examples").glob("*.yaml"))]
    else:
        make = broad_task if args.broad else heldout_task
        docs = [make(rng, k) for k in range(args.n)]
        if args.multi_nodes is not None:
            if not 4 <= args.multi_nodes <= 60:
                ap.error(f"--multi-nodes {args.multi_nodes}: valid: 4-60")
            for doc in docs:
                if len(doc["waypoints"]) > 2:
                    doc["nodes_per_segment"] = args.multi_nodes
        tasks = [task_from_dict(doc) for doc in docs]
    if args.tasks:
        try:
            picked = [int(k) for k in args.tasks.split(",")]
        except ValueError:
            ap.error(f"--tasks {args.tasks!r}: expected comma-separated integers")
        if not all(0 <= k < len(tasks) for k in picked):
            ap.error(f"--tasks {args.tasks}: valid indices are 0-{len(tasks) - 1}")
        tasks = [tasks[k] for k in picked]
    rows = []
    for task in tasks:
        row = run_task(task, opts, args.certify)
        rows.append(row)
        if out:
            out.write(json.dumps(row) + "\n")
            out.flush()
        print(json.dumps(row), flush=True)
    print()
    summary(rows)


def run_task(task: object, opts: PlannerOptions, certify_plans: bool) -> dict:
    """One task's row: wall time, outcome, the plan's figures (and its certificate)."""
    row: dict = {"name": task.name, "waypoints": len(task.waypoints)}
    t0 = time.perf_counter()
    try:
        sol = solve(Problem(task, Robot.default(), options=opts))
        row["wall"] = time.perf_counter() - t0
        row.update(ok=sol.is_feasible(), T=sol.final_time, solve=sol.solve_time,
                   iterations=sol.iterations, solves=sol.solves, status=sol.status,
                   total_iterations=sol.total_iterations, functions=sol.function_time,
                   baseline=getattr(sol, "baseline_time", None),
                   source=getattr(sol, "source", "ocp"))
        kind = "planned" if row["ok"] else "refused by the dense check"
        if certify_plans and row["ok"]:
            cert = certify(sol)
            row.update(cert_T=cert.duration, cert_ratio=cert.ratio,
                       cert_status=cert.status)
    except InfeasibleTaskError as exc:
        row["wall"] = time.perf_counter() - t0
        kind = ("reported infeasible after optimising"
                if exc.limit and (exc.limit.startswith("solver")
                                  or exc.limit == "dense check")
                else f"waypoint refused ({exc.limit})")
        row.update(ok=False, error=str(exc)[:160])
    row["outcome"] = kind
    return row


def summary(rows: list[dict]) -> None:
    """The set's outcomes, wall and solve times, the NLP work, and the plans' figures."""
    outcome = collections.Counter(r["outcome"].split(" (")[0] for r in rows)
    planned = [r for r in rows if r.get("ok")]
    tried = [r for r in rows if not r["outcome"].startswith("waypoint refused")]
    print("outcomes:", dict(outcome))
    if tried:
        print(f"success on tasks passing the static checks: {len(planned)}/{len(tried)}")
        walls = [r["wall"] for r in tried]
        print(f"wall [s] over {len(tried)} tasks: median {statistics.median(walls):.2f}, "
              f"p95 {pct(walls, 95):.2f}, max {max(walls):.2f}")
    if planned:
        solves = [r["solve"] for r in planned]
        iters = [r["iterations"] for r in planned]
        print(f"solve [s] over {len(planned)} plans: median {statistics.median(solves):.2f}, "
              f"p95 {pct(solves, 95):.2f}, max {max(solves):.2f}; iterations median "
              f"{statistics.median(iters):g}, range {min(iters)}-{max(iters)}")
        split(planned)
        ratio = [r["T"] / r["baseline"] for r in planned if r.get("baseline")]
        if ratio:
            print(f"duration / baseline over {len(ratio)}: median "
                  f"{statistics.median(ratio):.3f}, worst {max(ratio):.3f}")
        cr = [r["cert_ratio"] for r in planned if "cert_ratio" in r]
        if cr:
            statuses = collections.Counter(r["cert_status"] for r in planned
                                           if "cert_status" in r)
            print(f"plan / re-timed along its path (all limits) over {len(cr)}: median "
                  f"{statistics.median(cr):.3f}, range {min(cr):.3f}-{max(cr):.3f}, "
                  f"<= 1.02 on {sum(c <= 1.02 for c in cr)}; solver statuses "
                  f"{dict(statuses)}")
        src = collections.Counter(r.get("source", "ocp") for r in planned)
        print("plans from:", dict(src))


if __name__ == "__main__":
    main()
