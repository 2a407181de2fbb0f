"""Rest ends: two-waypoint plans against TOPP-RA and against their certificate.

    .venv/bin/python benchmarks/bench_rest_ends.py [--n 8] [--seed 5]
        [--grading 0.4 --grading 0.15,0.5]   # REST_GRADING values, side by side
        [--no-third-order]                   # also plan with jerk and torque rate lifted

For each random two-waypoint task (+-6 cm around home, +-40 deg; tasks the static checks
refuse are skipped) and each grading of the node intervals next to rest
(``planner.options.REST_GRADING``), prints the plan's duration T and:

- ``T / TOPP-RA line``: TOPP-RA, unjerked, on the straight line between the waypoints
  with the static crank angles (the stop-at-waypoints plan before the baseline smooths
  it; the NLP may take another path, so this can be below 1);
- ``T / TOPP-RA path``: TOPP-RA, unjerked, along the plan's own path;
- ``T / certificate``: the fastest re-timing of the plan's own path under all of its
  limits, jerk and torque rate included (``planner.certificate``): the like-for-like
  measure of what the rest ends cost.

``--no-third-order`` plans once more with the jerk and torque-rate limits lifted (1e8
rad/s^3, 1e7 N m/s; for this measurement only: no robot allows them, so the limits are
set on the Problem directly): then the plan's gap to TOPP-RA along its path is what the
grid costs, and the difference is what the third-order limits cost.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import time

import numpy as np

from sixplus3.dynamics.codegen import ensure_optimised
from sixplus3.errors import InfeasibleTaskError
from sixplus3.planner import options as planner_options
from sixplus3.planner.certificate import certify
from sixplus3.planner.problem import Problem
from sixplus3.planner.statics import choose_static_psi
from sixplus3.planner.strategy import solve
from sixplus3.planner.task import task_from_dict
from sixplus3.planner.toppra_baseline import toppra_along, toppra_trajectory
from sixplus3.robot_description.robot import Robot


def grading(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: comma-separated numbers") from None
    if not values or not all(0.0 < v <= 1.0 for v in values):
        raise argparse.ArgumentTypeError(f"{text!r}: shares in (0, 1]")
    return values


def tasks(robot: Robot, n: int, seed: int) -> list[dict]:
    rng = np.random.default_rng(seed)
    z = robot.home_position[2]
    out = []
    for k in range(4 * n):
        wps = [{"position": [float(rng.uniform(-0.06, 0.06)), float(rng.uniform(-0.06, 0.06)),
                             float(z + rng.uniform(-0.05, 0.06))],
                "rpy": [float(v) for v in rng.uniform(-40, 40, 3)]} for _ in range(2)]
        out.append({"name": f"two_{k}", "waypoints": wps})
    return out


def measure(problem: Problem) -> dict:
    t0 = time.perf_counter()
    sol = solve(problem)
    wall = time.perf_counter() - t0
    psi = choose_static_psi(problem.task, problem.robot, problem.limits, False, {0, 1})
    wx = problem.waypoint_states(psi)
    line = wx[0] + np.linspace(0.0, 1.0, 11)[:, None] * (wx[1] - wx[0])
    topp_line = float(toppra_trajectory(problem.robot, line, problem.limits, 400).duration)
    return {"T": sol.final_time, "line": sol.final_time / topp_line,
            "path": sol.final_time / toppra_along(sol), "cert": certify(sol).ratio,
            "source": sol.source, "iterations": sol.iterations, "wall": wall}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=8)
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--grading", type=grading, action="append", default=[])
    ap.add_argument("--no-third-order", action="store_true")
    args = ap.parse_args()
    if args.n < 1:
        ap.error(f"--n {args.n}: valid: >= 1")
    gradings = args.grading or [planner_options.REST_GRADING]
    robot = Robot.default()
    ensure_optimised(robot)
    docs, kept = tasks(robot, args.n, args.seed), []
    for doc in docs:  # the first n tasks the static checks accept
        if len(kept) == args.n:
            break
        problem = Problem(task_from_dict(doc), robot)
        try:
            choose_static_psi(problem.task, robot, problem.limits, False, {0, 1})
        except InfeasibleTaskError:
            continue
        kept.append(doc)
    print("| grading | task | T [s] | T / TOPP-RA line | T / TOPP-RA path | T / certificate "
          "| from | iterations | wall [s] |")
    print("| --- | --- | ---: | ---: | ---: | ---: | --- | ---: | ---: |")
    for g in gradings:
        planner_options.REST_GRADING = g
        runs = [(str(g), False)] + ([(f"{g}, no third order", True)]
                                    if args.no_third_order else [])
        for label, lifted in runs:
            rows = []
            for doc in kept:
                problem = Problem(task_from_dict(doc), robot)
                if lifted:
                    for name in ("limits", "motion_limits"):
                        object.__setattr__(problem, name, dataclasses.replace(
                            getattr(problem, name), jerk=1e8, torque_rate=1e7))
                r = measure(problem)
                rows.append(r)
                print(f"| {label} | {doc['name']} | {r['T']:.4f} | {r['line']:.3f} | "
                      f"{r['path']:.3f} | {r['cert']:.3f} | {r['source']} | "
                      f"{r['iterations']} | {r['wall']:.2f} |", flush=True)
            for key in ("line", "path", "cert"):
                v = [r[key] for r in rows]
                print(f"{label}: T / {key}: median {statistics.median(v):.3f}, "
                      f"worst {max(v):.3f}")


if __name__ == "__main__":
    main()
