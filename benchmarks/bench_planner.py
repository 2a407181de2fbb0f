"""The planner on the task suite (examples/*.yaml): free vs locked redundancy, TOPP-RA.

    .venv/bin/python benchmarks/bench_planner.py [--tasks a.yaml ...]

For every task: our OCP with the cranks free and locked at 90 deg (duration, solve time,
IPOPT iterations, max |tau| / limit and the smallest margin from the 10x Pinocchio
re-check); TOPP-RA on our free solution's platform path with the cranks locked at 90 deg
(the redundancy-less baseline on the same geometric path); and the time-optimality
certificate: TOPP-RA along our own path (ParametrizeConstAccel, 800 gridpoints) must not
be more than 2% faster.  Then the largest static tilt at home, free and locked.
"""

from __future__ import annotations

import argparse
import statistics
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from kinematics.robot import robot_ik
from planner.analysis import largest_tilt
from planner.ocp import InfeasibleTaskError, PlannerOptions, Problem
from planner.task import load_task
from planner.toppra_baseline import toppra_time


def run(task, locked: bool):
    try:
        return Problem(task, PlannerOptions(lock_redundancy=locked)).solve()
    except InfeasibleTaskError as exc:
        print(f"  {task.name} locked={locked}: infeasible: {exc}", flush=True)
        return None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", nargs="*", type=Path,
                    default=sorted(Path(__file__).parents[1].glob("examples/*.yaml")))
    args = ap.parse_args()
    print("| task | T free [s] | solve [s] | iters | max\\|tau\\|/lim | min margin | "
          "T locked [s] | solve [s] | TOPP-RA, our path, cranks locked [s] | "
          "TOPP-RA along our path [s] | ours / TOPP-RA |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    solves = []
    for path in args.tasks:
        task = load_task(path)
        free, locked = run(task, False), run(task, True)
        cells = []
        for sol in (free, locked):
            if sol is None or not sol.is_feasible():
                cells.append(None)
                continue
            solves.append(sol.solve_time)
            cells.append(sol)
        row = [task.name]
        if cells[0] is not None:
            s = cells[0]
            row += [f"{s.final_time:.4f}", f"{s.solve_time:.1f}", str(s.iterations),
                    f"{s.check.max_torque_ratio:.3f}", f"{s.check.min_margin:.3f}"]
        else:
            row += ["infeasible", "", "", "", ""]
        if cells[1] is not None:
            row += [f"{cells[1].final_time:.4f}", f"{cells[1].solve_time:.1f}"]
        else:
            row += ["infeasible", ""]
        if cells[0] is not None:
            s = cells[0]
            t = np.linspace(0, s.final_time, 201)
            x, _, _ = s.sample(t)
            xl = x.copy()
            xl[:, 6:9] = np.pi / 2
            cfg = robot_ik(xl[:, 0:3], Rotation.from_rotvec(xl[:, 3:6]).as_matrix(), xl[:, 6:9])
            try:
                tl = toppra_time(xl, task.limits, gridpoints=800).duration
                note = "" if cfg.ok.all() and cfg.margins.minimum.min() >= task.limits.margin \
                    else f" (margin {cfg.margins.minimum.min():.3f} on it)"
                row.append(f"{tl:.4f}{note}")
            except RuntimeError:
                row.append("no parametrisation")
            try:
                tc = toppra_time(x, task.limits, gridpoints=800).duration
                row += [f"{tc:.4f}", f"{s.final_time / tc:.3f}"]
            except RuntimeError:
                row += ["no parametrisation", ""]
        else:
            row += ["", "", ""]
        print("| " + " | ".join(row) + " |", flush=True)
    if solves:
        print(f"\nmedian solve time over {len(solves)} solves: {statistics.median(solves):.1f} s "
              f"(min {min(solves):.1f}, max {max(solves):.1f})")
    print("\nlargest static tilt at home (0, 0, 0.30 m), margins >= 0.05, 10 N m:")
    for axis in ("x", "y"):
        for locked in (False, True):
            r = largest_tilt(axis, locked, max_deg=179.0)
            print(f"  about {axis}, redundancy {'locked' if locked else 'free  '}: "
                  f"{r.tilt_deg:.1f} deg (psi {r.psi_deg} deg, margin {r.min_margin:.3f}, "
                  f"|tau_g| {r.max_gravity_torque:.2f} N m; beyond: "
                  f"{r.binding or 'scan limit 175 deg'})")


if __name__ == "__main__":
    main()
