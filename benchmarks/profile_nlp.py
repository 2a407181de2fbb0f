"""Where an NLP solve's time goes: iterations, time per iteration, function evaluations
against IPOPT's own work (linear algebra), for several formulations side by side.

    .venv/bin/python benchmarks/profile_nlp.py [--n 6] [--seed 2026]
        [--configs compiled-lbfgs,sx-lbfgs,mx-exact]   # sx-exact: see below

Each task of the narrow held-out generator (``bench_planner_heldout.heldout_task``) that
passes the static checks and has a baseline is solved once per configuration, the way
the planner's first start does it (from the baseline, the margin homotopy,
``planner.nlp.solve_nlp``):

- ``compiled-lbfgs``: the planner's default (compiled C node functions, L-BFGS);
- ``sx-lbfgs``: CasADi's interpreted SX functions, expanded, L-BFGS;
- ``sx-exact``: the same with IPOPT's exact Hessian of the Lagrangian (CasADi builds it
  from the SX graph; the compiled C functions have no second derivatives).  Not run by
  default: on this formulation (the passive angles in closed form inside the torque
  balance) building it took more than 18 GB within 3 minutes and was stopped
  (BENCHMARKS.md, "Planner v2, first steps");
- ``mx-exact``: the exact Hessian without expanding the NLP into one SX graph: the
  interpreted node function stays a function, mapped over the points, and CasADi
  derives its second-order directional derivatives point by point (a point's Hessian of
  the Lagrangian has 582 nonzeros and 1.44 million SX instructions, against 453,000 for
  its Jacobian).  Interpreted, so its times are not the compiled planner's: compare its
  iterations, and the Hessian's share against the Jacobian's, with ``mx-lbfgs`` (the
  same functions, L-BFGS).

Printed per solve: IPOPT's status and iterations, the wall time, the time per iteration,
and IPOPT's own split (``solver.stats()``): the evaluations of f, g, grad f, jac g and
the Lagrangian's Hessian, and the rest (IPOPT's linear algebra: MUMPS factorisations and
back-solves, and its own bookkeeping).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from bench_planner_heldout import first_starts  # noqa: E402

from sixplus3.dynamics.codegen import ensure_optimised  # noqa: E402
from sixplus3.errors import InfeasibleTaskError  # noqa: E402
from sixplus3.planner import solvers  # noqa: E402
from sixplus3.planner.nlp import solve_nlp  # noqa: E402
from sixplus3.planner.options import PlannerOptions
from sixplus3.planner.problem import Problem
from sixplus3.planner.strategy import initial_bounds  # noqa: E402
from sixplus3.planner.task import task_from_dict  # noqa: E402
from sixplus3.robot_description.robot import Robot  # noqa: E402

#: name -> (interpreted, IPOPT options, expand the NLP into one SX graph)
CONFIGS = {
    "compiled-lbfgs": (False, (), False),
    "sx-lbfgs": (True, (), True),
    "sx-exact": (True, (("hessian_approximation", "exact"),), True),
    "mx-lbfgs": (True, (), False),
    "mx-exact": (True, (("hessian_approximation", "exact"),), False),
}
EVALS = ("nlp_f", "nlp_g", "nlp_grad_f", "nlp_jac_g", "nlp_hess_l")


_NLPSOL = solvers.ca.nlpsol


def _expand_interpreted(expand: bool) -> None:
    """Whether the planner's IPOPT expands interpreted node functions into one SX graph
    (its default) or keeps them as functions in the MX graph (``mx-exact``)."""
    if expand:
        solvers.ca.nlpsol = _NLPSOL
        return

    def nlpsol(name, kind, nlp, settings):  # noqa: ANN001, ANN202 - CasADi's signature
        return _NLPSOL(name, kind, nlp, {**settings, "expand": False})

    solvers.ca.nlpsol = nlpsol


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=6)
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--configs", default="compiled-lbfgs,sx-lbfgs")
    args = ap.parse_args()
    configs = args.configs.split(",")
    if args.n < 1 or not all(c in CONFIGS for c in configs):
        ap.error(f"--n >= 1 and --configs from {', '.join(CONFIGS)}")
    robot = Robot.default()
    ensure_optimised(robot)
    starts = []
    for doc, psi, base in first_starts(args.n, robot, args.seed):
        problem = Problem(task_from_dict(doc), robot)
        starts.append((doc, psi, base, initial_bounds(problem, psi, base)))
    print("| config | task | status | iterations | wall [s] | per iteration [ms] | "
          + " | ".join(f"{e} [s]" for e in EVALS) + " | IPOPT's own [s] |")
    print("| --- | --- | --- | ---: | ---: | ---: | " + " | ".join("---:" for _ in EVALS)
          + " | ---: |")
    summary: dict[str, list[tuple[float, float, float]]] = {}
    summary_T: dict[str, list[tuple[str, float]]] = {}
    for name in configs:
        interpreted, extra, expand = CONFIGS[name]
        _expand_interpreted(expand)
        if interpreted:
            os.environ["SIXPLUS3_NO_CODEGEN"] = "1"
        else:
            os.environ.pop("SIXPLUS3_NO_CODEGEN", None)
        solvers.SOLVERS.clear()
        opts = PlannerOptions(ipopt_options=extra, max_iter=400)
        durations = summary_T.setdefault(name, [])
        for doc, psi, base, bounds in starts:
            problem = Problem(task_from_dict(doc), robot, opts)
            homotopy = bounds.replace(margin=0.6 * problem.limits.margin)
            solvers.ipopt_solver(problem)  # built outside the clock
            try:
                sol = solve_nlp(problem, psi, homotopy, warm=base)
                status, iters, wall = sol.status, sol.iterations, sol.solve_time
                durations.append((doc["name"], sol.final_time))
            except InfeasibleTaskError as exc:
                status, iters, wall = str(exc.value), -1, float("nan")
            stats = solvers.ipopt_solver(problem).solver.stats()
            t_eval = [float(stats.get(f"t_wall_{e}", 0.0)) for e in EVALS]
            total = float(stats.get("t_wall_total", wall))
            n_it = max(1, int(stats.get("iter_count", 1)))
            own = total - sum(t_eval)
            print(f"| {name} | {doc['name']} | {status} | {iters} | {total:.2f} | "
                  f"{1e3 * total / n_it:.1f} | " + " | ".join(f"{v:.2f}" for v in t_eval)
                  + f" | {own:.2f} |", flush=True)
            summary.setdefault(name, []).append((n_it, total, own / max(total, 1e-12)))
    for name, rows in summary.items():
        its, walls, shares = zip(*rows, strict=True)
        print(f"{name}: iterations median {statistics.median(its):.0f}, wall median "
              f"{statistics.median(walls):.2f} s, per iteration median "
              f"{1e3 * statistics.median(w / i for i, w in zip(its, walls, strict=True)):.1f}"
              f" ms, IPOPT's own share median {statistics.median(shares):.2f}; durations "
              + ", ".join(f"{n} {t:.4f} s" for n, t in summary_T.get(name, [])))


if __name__ == "__main__":
    main()
