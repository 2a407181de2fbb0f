"""The planner on the task suite (examples/*.yaml): free vs locked redundancy, TOPP-RA.

    .venv/bin/python benchmarks/bench_planner.py [--tasks a.yaml ...]

For every task: our OCP with the cranks free and locked at 90 deg (duration, solve time,
IPOPT iterations of the last solve, max |tau| / limit and the smallest margin from the
10x Pinocchio re-check); TOPP-RA on our free solution's platform path with the cranks
locked at 90 deg (the redundancy-less baseline on the same geometric path); and the
time-optimality certificate, for both: TOPP-RA along our own path (ParametrizeConstAccel, 1600
gridpoints per rest-to-rest piece, toppra_baseline.toppra_along), which knows no jerk or
torque-rate limit, and the like-for-like certificate: the fastest re-timing of our own
path under all of the plan's limits, jerk and torque rate included
(planner.certificate.certify); the target is ours / that <= 1.02.  Then the largest
static tilt at home, free and locked.
"""

from __future__ import annotations

import argparse
import statistics
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from sixplus3.dynamics.codegen import ensure_optimised
from sixplus3.errors import InfeasibleTaskError
from sixplus3.kinematics.robot import robot_ik
from sixplus3.planner.analysis import largest_tilt
from sixplus3.planner.certificate import certify
from sixplus3.planner.options import PlannerOptions
from sixplus3.planner.problem import Problem
from sixplus3.planner.strategy import solve
from sixplus3.planner.task import load_task, task_from_dict
from sixplus3.planner.toppra_baseline import toppra_along
from sixplus3.robot_description.robot import Robot

#: Height of the default robot's home [m].
HOME_Z = Robot.default().home_position[2]


def run(task, locked: bool):
    try:
        opts = PlannerOptions(lock_redundancy=locked)
        return solve(Problem(task, Robot.default(), options=opts))
    except InfeasibleTaskError as exc:
        print(f"  {task.name} locked={locked}: infeasible: {exc}", flush=True)
        return None


def locked_path_note(sol, task) -> str:
    """Flag the baseline path if locking the cranks leaves it below the margin."""
    t = np.linspace(0, sol.final_time, 201)
    x, _, _ = sol.sample(t)
    cfg = robot_ik(x[:, 0:3], Rotation.from_rotvec(x[:, 3:6]).as_matrix(),
                   np.full((len(t), 3), np.pi / 2), robot=Robot.default())
    worst = cfg.margins.minimum.min() if cfg.ok.all() else -1.0
    return "" if worst >= sol.limits.margin else f" (margin {worst:.3f} on it)"


def planned_tilt(axis: str, locked: bool, static_deg: float) -> str:
    """Plan home -> tilt -> home at the static limit, backing off 5 deg at a time."""
    rpy = {"x": 0, "y": 1}[axis]
    tried = []
    deg = float(np.floor(static_deg))
    for _ in range(6):
        angles = [0.0, 0.0, 0.0]
        angles[rpy] = deg
        task = task_from_dict({"name": f"tilt_{axis}_{deg:g}", "nodes_per_segment": 10,
                               "waypoints": [{"position": [0, 0, HOME_Z]},
                                             {"position": [0, 0, HOME_Z], "rpy": angles},
                                             {"position": [0, 0, HOME_Z]}]})
        try:
            opts = PlannerOptions(lock_redundancy=locked)
            sol = solve(Problem(task, Robot.default(), options=opts))
            if sol.is_feasible():
                return (f"{deg:g} deg in {sol.final_time:.4f} s (solve {sol.solve_time:.2f} s, "
                        f"max|tau|/lim {sol.check.max_torque_ratio:.3f}, margin "
                        f"{sol.check.min_margin:.3f}, clearance "
                        f"{sol.check.min_clearance * 1e3:.1f} mm)"
                        + (f"; failed at {', '.join(tried)}" if tried else ""))
            tried.append(f"{deg:g} ({'; '.join(sol.check.violations)})")
        except InfeasibleTaskError as exc:
            tried.append(f"{deg:g} ({exc.limit})")
        deg -= 5.0
    return "none; failed at " + ", ".join(tried)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", nargs="*", type=Path,
                    default=sorted(Path(__file__).parents[1].glob("examples/*.yaml")))
    ap.add_argument("--gridpoints", type=int, default=1600,
                    help="TOPP-RA gridpoints per rest-to-rest piece (default 1600)")
    args = ap.parse_args()
    # time the planner as it runs after its first use: with the optimised build
    ensure_optimised(Robot.default())
    print("| task | cranks | T [s] | solve [s] | iters | max\\|tau\\|/lim | min margin | "
          "TOPP-RA, this path, cranks at 90 deg [s] | TOPP-RA along this path [s] | "
          "ours / TOPP-RA | re-timed along this path, all limits [s] | ours / re-timed |")
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    solves, certs = [], []
    for path in args.tasks:
        task = load_task(path)
        for locked in (False, True):
            s = run(task, locked)
            row = [task.name, "locked" if locked else "free"]
            if s is None or not s.is_feasible():
                print("| " + " | ".join(row + ["infeasible"] + [""] * 9) + " |", flush=True)
                continue
            solves.append(s.solve_time)
            row += [f"{s.final_time:.4f}", f"{s.solve_time:.2f}", str(s.iterations),
                    f"{s.check.max_torque_ratio:.3f}", f"{s.check.min_margin:.3f}"]
            if locked:
                row.append("(same)")
            else:  # the redundancy-less baseline: this platform path, cranks at 90 deg
                try:
                    tl = toppra_along(s, s.limits, args.gridpoints, cranks=np.pi / 2)
                    row.append(f"{tl:.4f}{locked_path_note(s, task)}")
                except RuntimeError:
                    row.append("no parametrisation")
            try:  # the certificate: TOPP-RA along our own path, cranks as planned
                tc = toppra_along(s, s.limits, args.gridpoints)
                row += [f"{tc:.4f}", f"{s.final_time / tc:.3f}"]
            except RuntimeError:
                row += ["no parametrisation", ""]
            cert = certify(s)  # like for like: jerk and torque rate included
            certs.append(cert.ratio)
            row += [f"{cert.duration:.4f}" + ("" if cert.success else f" ({cert.status})"),
                    f"{cert.ratio:.3f}"]
            print("| " + " | ".join(row) + " |", flush=True)
    if solves:
        print(f"\nmedian solve time over {len(solves)} solves: {statistics.median(solves):.2f} s "
              f"(min {min(solves):.2f}, max {max(solves):.2f}; NLP build and the one-time "
              "compilation excluded)")
    if certs:
        print("ours / re-timed along our path (all limits): median "
              f"{statistics.median(certs):.3f}, range {min(certs):.3f}-{max(certs):.3f}; "
              f"<= 1.02 on {sum(c <= 1.02 for c in certs)} of {len(certs)}")
    print(f"\nlargest static tilt at home (0, 0, {HOME_Z} m), margins >= 0.05, 10 N m, and the "
          "largest tilt-and-back motion the planner then delivers (dense check incl. leg "
          "clearance):")
    for axis in ("x", "y"):
        for locked in (False, True):
            r = largest_tilt(Robot.default(), axis, locked, max_deg=179.0)
            print(f"  about {axis}, redundancy {'locked' if locked else 'free  '}: "
                  f"{r.tilt_deg:.1f} deg (psi {r.psi_deg} deg, margin {r.min_margin:.3f}, "
                  f"|tau_g| {r.max_gravity_torque:.2f} N m; beyond: "
                  f"{r.binding or 'scan limit 175 deg'})", flush=True)
            print("      planned: " + planned_tilt(axis, locked, r.tilt_deg), flush=True)


if __name__ == "__main__":
    main()
