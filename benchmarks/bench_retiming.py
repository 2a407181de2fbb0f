"""What the re-timing along the path costs a plan (BENCHMARKS.md, "Re-timing along the
path").

    .venv/bin/python benchmarks/bench_retiming.py [--tasks gentle_translate translate]
        [--repeat 2]

Plans each example in process ``--repeat`` times (``translate`` under 0.25 m/s, the
others with their own limits) and prints the planner's wall time, the time of
``timing.platform_limited`` alone (the uniform stretch, the re-timing and their checks;
the first call in a process also imports cvxpy), the duration and which one was kept.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import sixplus3.planner.strategy as strategy
from sixplus3.planner.ocp import plan
from sixplus3.planner.task import load_task
from sixplus3.robot_description.robot import Robot

ROOT = Path(__file__).parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", nargs="+", default=["gentle_translate", "translate"])
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    robot = Robot.default()
    spent: list[float] = []
    inner = strategy.platform_limited

    def timed(problem, sol):  # type: ignore[no-untyped-def]
        t0 = time.perf_counter()
        out = inner(problem, sol)
        spent.append(time.perf_counter() - t0)
        return out

    strategy.platform_limited = timed  # type: ignore[assignment]
    print("| task | run | plan wall [s] | platform_limited [s] | duration [s] | kept |")
    print("|---|---|---|---|---|---|")
    for name in args.tasks:
        task = load_task(ROOT / "examples" / f"{name}.yaml")
        if not any(k.startswith("tcp") for k in task.limits):
            task = dataclasses.replace(task, limits={**task.limits, "tcp_speed": 0.25})
        for run in range(args.repeat):
            t0 = time.perf_counter()
            sol = plan(task, robot)
            wall = time.perf_counter() - t0
            kept = ("re-timed" if sol.active_limits and
                    sol.active_limits[-1].startswith("re-timed") else "uniform")
            print(f"| {name} | {run + 1} | {wall:.2f} | {spent[-1]:.2f} | "
                  f"{sol.final_time:.4f} | {kept} |", flush=True)


if __name__ == "__main__":
    main()
