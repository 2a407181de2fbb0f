"""The physical robot: the task suite with the links only, with the motor model, and with
the motor model plus a 0.5 kg payload; MuJoCo replay of every file; largest tilt at home.

    .venv/bin/python benchmarks/bench_physical.py [--tasks a.yaml ...] [--out DIR]

Each variant is planned end to end (``run_plan``: plan, smooth, validate, write) with the
default 90 % torque fraction; max |tau| is the validator's, over the hardware limit.  Each
file then goes through ``validate --simulate``'s MuJoCo stage (``engine_check``): MuJoCo's
constrained inverse dynamics against the file's torques on every sample, and the replay
(Kp 300, Kd 6, 1 kHz zero-order hold): tracking error, PD share, peak total torque.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from sixplus3.control.drive.simulation import engine_check
from sixplus3.control.gate.validation import validate_file
from sixplus3.control.pipeline import run_plan
from sixplus3.dynamics.codegen import ensure_optimised
from sixplus3.errors import Sixplus3Error
from sixplus3.planner.analysis import largest_tilt
from sixplus3.planner.task import load_task
from sixplus3.robot_description.physical import NO_MOTORS, Payload
from sixplus3.robot_description.robot import Robot

ROOT = Path(__file__).resolve().parents[1]
BASE = Robot.default()
VARIANTS = {
    "links only": BASE.replace(motors=NO_MOTORS),
    "motors": BASE,
    "motors + 0.5 kg": BASE.replace(payload=Payload(mass=0.5, com=(0.0, 0.0, 0.03),
                                                    inertia=(3e-4, 3e-4, 2e-4, 0, 0, 0))),
}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--tasks", nargs="*", default=None)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    # time the planner as it runs after its first use: with the optimised build
    ensure_optimised(Robot.default())
    tasks = [Path(t) for t in args.tasks] if args.tasks else sorted(
        p for p in (ROOT / "examples").glob("*.yaml"))
    out = Path(args.out or tempfile.mkdtemp(prefix="sixplus3-physical-"))
    print("| task | model | duration [s] | max abs(tau)/limit | plan wall [s] | "
          "MuJoCo ID vs file [N m] | MuJoCo max err [deg] | PD share | peak tau+PD [N m] |")
    print("|---|---|---|---|---|---|---|---|---|")
    for path in tasks:
        task = load_task(path)
        for name, robot in VARIANTS.items():
            if task.payload is not None and name != "motors":
                continue  # the task brings its own setup
            t = replace(task, name=f"{task.name}_{name.replace(' ', '').replace('+', '_')}"
                        .replace(".", ""))
            t0 = time.perf_counter()
            try:
                res = run_plan(t, out, robot, html=False, plots=False)
            except Sixplus3Error as exc:
                print(f"| {task.name} | {name} | infeasible: {str(exc)[:80]} |||||")
                continue
            wall = time.perf_counter() - t0
            rep = res.report
            planned_robot = task.robot_for(robot)
            eng = engine_check(planned_robot, validate_file(res.csv, planned_robot))
            sim = eng.simulation
            print(f"| {task.name} | {name} | {res.smoothed.duration:.4f} | "
                  f"{rep.max_torque_ratio * res.solution.limits.torque / robot.limits.torque:.3f}"
                  f" | {wall:.1f} | {eng.feedforward_error:.1e} | "
                  f"{math.degrees(sim.max_tracking_error_rad):.3f} | "
                  f"{100 * sim.pd_share:.1f}% | {sim.peak_total_torque:.2f} |", flush=True)
    print()
    print("Largest static tilt at home [deg] (cranks free / locked at 90 deg):")
    for name, robot in VARIANTS.items():
        row = []
        for axis in ("x", "y"):
            free = largest_tilt(robot, axis, locked=False, max_deg=175.0)
            locked = largest_tilt(robot, axis, locked=True, max_deg=175.0)
            row.append(f"{axis}: {free.tilt_deg:.1f} / {locked.tilt_deg:.1f} (binding: "
                       f"{free.binding} / {locked.binding})")
        print(f"  {name}: " + "; ".join(row), flush=True)


if __name__ == "__main__":
    main()
