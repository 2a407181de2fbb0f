"""Platform-space limits as NLP rows against the uniform stretch they replaced.

    .venv/bin/python benchmarks/bench_tcp_rows.py [--tasks t10 translate tilt30_x ...]

For each task and each set of platform limits (0.25 m/s; 0.25 m/s and 2 g; the named
``people: collaborative`` set, 0.25 m/s and 2 m/s^2) prints:

- ``free``: the minimum-time plan without platform limits [s];
- ``stretch``: that plan stretched uniformly by the smallest factor that brings its
  tool centre point within 99.5 % of both limits (what the planner returned before the
  rows: ``timing.tcp_limited`` on the free plan) [s];
- ``rows``: the plan with the limits as rows of the NLP [s], its ratio to the stretch;
- ``uniform``: what the rows' plan took with a last uniform stretch only, before the
  re-timing along the path (planner/retiming.py) [s]; ``-`` where the planner kept
  the uniform stretch (then ``rows`` is it);
- ``cruise``: the share of the time the tool centre point moves faster than half the
  speed limit that it spends within 2 % of the limit (exact speed on 2001 samples);
- ``moving``: the share of the moving time (faster than 1 % of the limit) within 2 %;
- the peaks (exact, 2001 samples) and the planner's wall time.

``t10`` is the 10 cm translation along x at home height (two waypoints); the others
are files of examples/, each planned without its own platform limits first.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import re
import time
from pathlib import Path

import numpy as np

from sixplus3.dynamics.codegen import ensure_optimised
from sixplus3.planner.ocp import plan
from sixplus3.planner.task import load_task, task_from_dict
from sixplus3.planner.tcp_rows import tcp_rates_at
from sixplus3.robot_description.robot import Robot

ROOT = Path(__file__).parents[1]
T10 = {"name": "t10", "waypoints": [{"position": [0.0, 0.0, 0.58]},
                                    {"position": [0.10, 0.0, 0.58]}]}
SETS = {"0.25 m/s": {"tcp_speed": 0.25},
        "0.25 m/s, 2 g": {"tcp_speed": 0.25, "tcp_acceleration": 19.62},
        "collaborative": {"tcp_speed": 0.25, "tcp_acceleration": 2.0}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", nargs="+", default=["t10", "translate", "tilt30_x"])
    args = ap.parse_args()
    robot = Robot.default()
    ensure_optimised(robot)
    print("| task | limits | free [s] | stretch [s] | rows [s] | rows / stretch | uniform [s] "
          "| cruise within 2 % | moving within 2 % | peak speed [m/s] | peak acc [m/s²] "
          "| wall [s] |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name in args.tasks:
        task = (task_from_dict(T10) if name == "t10"
                else load_task(ROOT / "examples" / f"{name}.yaml"))
        # without any platform limit (an example's own, e.g. people: collaborative)
        joint_limits = {k: v for k, v in task.limits.items() if not k.startswith("tcp")}
        task = dataclasses.replace(task, limits=joint_limits)
        free = plan(task, robot)
        assert free.check is not None
        for label, lim in SETS.items():
            a = max(1.0, free.check.max_tcp_speed / (0.995 * lim["tcp_speed"]),
                    math.sqrt(free.check.max_tcp_acceleration
                              / (0.995 * lim.get("tcp_acceleration", 1e3))))
            limited = dataclasses.replace(task, limits={**task.limits, **lim})
            t0 = time.perf_counter()
            sol = plan(limited, robot)
            wall = time.perf_counter() - t0
            t = np.linspace(0.0, sol.final_time, 2001)
            speed, acc = tcp_rates_at(robot.tool.xyz, *sol.sample(t))
            near = np.abs(speed - lim["tcp_speed"]) < 0.02 * lim["tcp_speed"]
            fast = speed > 0.5 * lim["tcp_speed"]
            cruise = float(np.mean(near[fast])) if fast.any() else 0.0
            moving = speed > 0.01 * lim["tcp_speed"]
            moved = float(np.mean(near[moving])) if moving.any() else 0.0
            found = re.search(r"the uniform stretch: ([0-9.]+) s", sol.active_limits[-1])
            uniform = found.group(1) if found else "-"
            ok = "" if sol.is_feasible() else " (FAILED its check)"
            print(f"| {name} | {label} | {free.final_time:.4f} | {a * free.final_time:.4f} "
                  f"| {sol.final_time:.4f}{ok} | {sol.final_time / (a * free.final_time):.3f} "
                  f"| {uniform} | {cruise:.0%} | {moved:.0%} | {speed.max():.4f} "
                  f"| {acc.max():.3f} | {wall:.1f} |", flush=True)


if __name__ == "__main__":
    main()
