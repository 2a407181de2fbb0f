"""The planner on random tasks: success rate and solve times away from the tuned suite.

    .venv/bin/python benchmarks/bench_planner_random.py [--n 24] [--seed 0] [--locked]

The solver options were chosen on examples/ (BENCHMARKS.md), so this is the held-out
check: rest-to-rest tasks through 1-2 random intermediate waypoints, positions within
+-0.05 m of home (z from 3 cm below home to 5 cm above) and roll/pitch/yaw within
+-40 deg, 10 intervals per segment.  Tasks whose waypoints fail the static checks
(reach, ranges, margins, holding
torque) are counted apart: they are refused before any optimisation, by design.
"""

from __future__ import annotations

import argparse
import collections
import statistics
import time

import numpy as np

from sixplus3.dynamics.codegen import ensure_optimised
from sixplus3.errors import InfeasibleTaskError
from sixplus3.planner.options import PlannerOptions
from sixplus3.planner.problem import Problem
from sixplus3.planner.strategy import solve
from sixplus3.planner.task import task_from_dict
from sixplus3.robot_description.robot import Robot

#: Height of the default robot's home [m].
HOME_Z = Robot.default().home_position[2]


def random_task(rng: np.random.Generator, k: int) -> dict:
    wps = [{"position": [0.0, 0.0, HOME_Z]}]
    for _ in range(int(rng.integers(1, 3))):
        wps.append({"position": [float(rng.uniform(-0.05, 0.05)),
                                 float(rng.uniform(-0.05, 0.05)),
                                 float(HOME_Z + rng.uniform(-0.03, 0.05))],
                    "rpy": [float(v) for v in rng.uniform(-40, 40, 3)]})
    wps.append({"position": [0.0, 0.0, HOME_Z]})
    return {"name": f"random_{k}", "waypoints": wps, "nodes_per_segment": 10}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=24)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--locked", action="store_true")
    args = ap.parse_args()
    # time the planner as it runs after its first use: with the optimised build
    ensure_optimised(Robot.default())
    rng = np.random.default_rng(args.seed)
    solves, outcome = [], collections.Counter()
    for k in range(args.n):
        task = task_from_dict(random_task(rng, k))
        t0 = time.perf_counter()
        try:
            opts = PlannerOptions(lock_redundancy=args.locked)
            sol = solve(Problem(task, Robot.default(), options=opts))
            if sol.is_feasible():
                outcome["planned"] += 1
                solves.append(sol.solve_time)
                note = (f"T {sol.final_time:.4f} s, solve {sol.solve_time:.2f} s, "
                        f"{sol.solves} solve(s), max|tau|/lim {sol.check.max_torque_ratio:.3f}")
            else:
                outcome["refused by the dense check"] += 1
                note = "dense check: " + "; ".join(sol.check.violations)
        except InfeasibleTaskError as exc:
            kind = ("solver failure" if exc.limit and exc.limit.startswith("solver")
                    else f"waypoint refused ({exc.limit})")
            outcome[kind] += 1
            note = f"{kind}: {str(exc)[:100]}"
        print(f"{task.name:10s} {len(task.waypoints)} waypoints  "
              f"{time.perf_counter() - t0:6.2f} s wall  {note}", flush=True)
    print("\noutcomes:", dict(outcome))
    if solves:
        print(f"median solve time over {len(solves)} planned: {statistics.median(solves):.2f} s "
              f"(min {min(solves):.2f}, max {max(solves):.2f})")


if __name__ == "__main__":
    main()
