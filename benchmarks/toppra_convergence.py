"""TOPP-RA along the planner's own path as its grid is refined (the certificate's ratio).

    .venv/bin/python benchmarks/toppra_convergence.py [--tasks tilt30_x torsion_z] [--free]

For each example task (cranks locked unless --free), plans it, then runs TOPP-RA
(planner.toppra_baseline.toppra_along, per rest-to-rest piece) with 800 to 6400
gridpoints and prints ours / TOPP-RA.  A ratio that climbs towards 1 as the grid is
refined means TOPP-RA is not yet converged there and errs on the slow (safe) side.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from sixplus3.dynamics.codegen import ensure_optimised
from sixplus3.planner.options import PlannerOptions
from sixplus3.planner.problem import Problem
from sixplus3.planner.strategy import solve
from sixplus3.planner.task import load_task
from sixplus3.planner.toppra_baseline import toppra_along
from sixplus3.robot_description.robot import Robot

GRIDS = (800, 1600, 3200, 6400)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", nargs="*", default=["tilt30_x", "torsion_z"])
    ap.add_argument("--free", action="store_true", help="cranks free (default: locked)")
    args = ap.parse_args()
    # time the planner as it runs after its first use: with the optimised build
    ensure_optimised(Robot.default())
    root = Path(__file__).resolve().parents[1] / "examples"
    print("| task | interior min speed / max | " + " | ".join(map(str, GRIDS)) + " |")
    print("| --- | ---: | " + " | ".join("---:" for _ in GRIDS) + " |")
    for name in args.tasks:
        task = load_task(root / f"{name}.yaml")
        opts = PlannerOptions(lock_redundancy=not args.free)
        sol = solve(Problem(task, Robot.default(), options=opts))
        speed = np.linalg.norm(sol.xd, axis=1)
        ratios = [sol.final_time / toppra_along(sol, sol.limits, gp) for gp in GRIDS]
        print(f"| {name} {'free' if args.free else 'locked'} | "
              f"{speed[1:-1].min() / speed.max():.3f} | "
              + " | ".join(f"{r:.3f}" for r in ratios) + " |", flush=True)


if __name__ == "__main__":
    main()
