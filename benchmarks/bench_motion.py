"""Motions a drive can follow: the example suite planned end to end, with what a drive
sees at the start and the end of each file.

    .venv/bin/python benchmarks/bench_motion.py [--tasks a.yaml ...]

Per task (``run_plan``: plan, smooth at 1 kHz, validate, write; the default robot with
its motor model): duration, max |tau| / the hardware limit, the largest jerk and torque
rate between samples, the torque at the first and last samples minus the holding torque
there (Pinocchio's gravity torques at the file's own configuration, computed here), the
largest torque change over the first and last period, the crank angles at both ends,
and the plan's wall time.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from sixplus3.control.file.file_format import columns
from sixplus3.control.file.trajectory_read import read_trajectory
from sixplus3.control.pipeline import run_plan
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.dynamics.codegen import ensure_optimised
from sixplus3.kinematics.robot import robot_ik
from sixplus3.kinematics.rotations import matrix_from_quat
from sixplus3.planner.task import load_task
from sixplus3.robot_description.robot import Robot

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--tasks", nargs="*", default=None)
    args = ap.parse_args()
    # time the planner as it runs after its first use: with the optimised build
    ensure_optimised(Robot.default())
    tasks = [Path(t) for t in args.tasks] if args.tasks else sorted(
        (ROOT / "examples").glob("*.yaml"))
    out = Path(tempfile.mkdtemp(prefix="sixplus3-motion-"))
    print("| task | T [s] | max abs(tau)/limit | max jerk [rad/s^3] | max torque rate "
          "[N m/s] | tau - holding, first / last [N m] | first / last step [N m] | "
          "psi start / end [deg] | wall [s] |")
    print("|---|---|---|---|---|---|---|---|---|")
    for path in tasks:
        task = load_task(path)
        robot = task.robot_for(Robot.default())
        t0 = time.perf_counter()
        res = run_plan(task, out, Robot.default(), html=False, plots=False)
        wall = time.perf_counter() - t0
        _, data = read_trajectory(res.csv, robot)
        rep = res.report
        tau, acc = columns(data, "tau"), columns(data, "acc")
        dt = data[1, 0] - data[0, 0]
        dyn = ClosedLoopDynamics(robot)
        hold = []
        for k in (0, -1):
            R = matrix_from_quat(rep.quaternion[k])[0]
            q = robot_ik(rep.position[k], R, rep.psi[k], robot).q[0]
            hold.append(float(np.abs(tau[k] - dyn.gravity_torques(q)).max()))
        steps = (np.abs(tau[1] - tau[0]).max(), np.abs(tau[-1] - tau[-2]).max())
        psi = np.degrees(rep.psi[[0, -1]])
        print(f"| {task.name} | {res.smoothed.duration:.4f} | "
              f"{np.abs(tau).max() / robot.limits.torque:.3f} | "
              f"{np.abs(np.diff(acc, axis=0)).max() / dt:.3g} | "
              f"{np.abs(np.diff(tau, axis=0)).max() / dt:.0f} | "
              f"{hold[0]:.1e} / {hold[1]:.1e} | {steps[0]:.3f} / {steps[1]:.3f} | "
              f"{np.round(psi[0]).astype(int).tolist()} / "
              f"{np.round(psi[1]).astype(int).tolist()} | {wall:.1f} |", flush=True)


if __name__ == "__main__":
    main()
