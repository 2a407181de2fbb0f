"""Where one IPOPT iteration of the planner goes: the NLP's constraint Jacobian against the
compiled node Jacobian inside it.

    .venv/bin/python benchmarks/profile_planner.py [--task 2] [--seed 2026] [--repeat 20]

Plans one held-out task (``bench_planner_heldout.py``'s generator), then times, on that
task's NLP and at its solution's size:
- ``nlp_jac_g`` (CasADi's MX function that IPOPT calls once per iteration: the compiled
  node Jacobian mapped over the nodes and midpoints, the integration and rate rows, and
  the assembly of the sparse matrix);
- the compiled node Jacobian alone, mapped over the same points, on two threads (as the
  NLP maps it) and on one;
- ``nlp_g``, the constraint values.

The linear algebra's share comes from IPOPT itself:
``bench_planner_heldout.py --tasks 2 --ipopt print_timing_statistics=yes --ipopt print_level=5``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from bench_planner_heldout import heldout_task

from sixplus3.dynamics.codegen import compiled_functions, ensure_optimised
from sixplus3.planner.problem import Problem
from sixplus3.planner.solvers import ipopt_solver
from sixplus3.planner.strategy import solve
from sixplus3.planner.task import task_from_dict
from sixplus3.robot_description.robot import Robot


def per_call(f, args, repeat: int) -> float:
    """Mean wall time [ms] of one call, after one warm-up call."""
    f(*args)
    t0 = time.perf_counter()
    for _ in range(repeat):
        f(*args)
    return (time.perf_counter() - t0) / repeat * 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--task", type=int, default=2)
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--repeat", type=int, default=20)
    args = ap.parse_args()
    if args.task < 0 or args.repeat < 1:
        ap.error(f"--task {args.task}, --repeat {args.repeat}: valid: --task >= 0, "
                 "--repeat >= 1")
    robot = Robot.default()
    ensure_optimised(robot)
    rng = np.random.default_rng(args.seed)
    # the generator draws the tasks in turn: task k is the (k+1)-th draw of the seed
    docs = [heldout_task(rng, k) for k in range(args.task + 1)]
    problem = Problem(task_from_dict(docs[-1]), robot)
    sol = solve(problem)
    print(f"heldout_{args.task}: {len(sol.task.waypoints)} waypoints, {len(sol.t) - 1} "
          f"intervals, {sol.iterations} IPOPT iterations, solve {sol.solve_time:.2f} s")
    solver = ipopt_solver(problem).solver
    jac_g, g = solver.get_function("nlp_jac_g"), solver.get_function("nlp_g")
    nx, n_par = jac_g.size1_in(0), jac_g.size1_in(1)
    print(f"NLP: {nx} variables, {jac_g.size1_out(1)} rows, {jac_g.nnz_out(1)} Jacobian "
          "nonzeros")
    rs = np.random.default_rng(0)
    point = [rs.uniform(-0.1, 0.1, nx), rs.uniform(0.5, 1.5, n_par)]
    print(f"nlp_jac_g: {per_call(jac_g, point, args.repeat):.2f} ms per call")
    print(f"nlp_g: {per_call(g, point, args.repeat):.2f} ms per call")
    jac_node = compiled_functions(robot)["node"].jacobian()
    m = 2 * (len(sol.t) - 1) + 1  # the nodes and the midpoints
    for label, f in (("two threads", jac_node.map(m, "thread", 2)),
                     ("one thread", jac_node.map(m))):
        inputs = [rs.uniform(-0.1, 0.1, (f.size1_in(i), f.size2_in(i)))
                  for i in range(f.n_in())]
        print(f"compiled node Jacobian over {m} points, {label}: "
              f"{per_call(f, inputs, args.repeat):.2f} ms per call")


if __name__ == "__main__":
    main()
