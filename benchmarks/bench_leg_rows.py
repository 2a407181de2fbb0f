"""The cost of the leg rows (issue 70): every example and any held-out task planned for
a body region at the platform only (``pfl_links: []``) and with every reachable leg
link (the default), judged by the gate (BENCHMARKS.md, "The legs in power and force
limiting").

    .venv/bin/python benchmarks/bench_leg_rows.py [--region hand] [--robot R.yaml]
        [--tasks translate ... | HO/heldout_0.yaml ...]

Printed per task and variant: the motion's duration, the planning wall time, the gate's
largest ratio at the platform and over the legs' vertices (<= 1 holds), and where.  The
platform-only plan's leg ratio is what a person meets at a leg without the rows.
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path

import numpy as np

from sixplus3 import examples
from sixplus3.control.file.trajectory_read import read_trajectory
from sixplus3.control.gate.pfl import judged, pfl_profile
from sixplus3.control.gate.validation import validate_file
from sixplus3.control.pipeline import run_plan
from sixplus3.errors import Sixplus3Error
from sixplus3.planner.task import load_task
from sixplus3.robot_description.robot import Robot, load_robot


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", nargs="+", default=examples.names())
    ap.add_argument("--region", default="hand")
    ap.add_argument("--robot", default=None)
    args = ap.parse_args()
    robot = load_robot(args.robot) if args.robot else Robot.default()
    print("| task | links | duration [s] | wall [s] | ratio at the platform | "
          "ratio at the legs (where) |")
    print("|---|---|---|---|---|---|")
    for name in args.tasks:
        task = load_task(name) if Path(name).is_file() else examples.load(name)
        for label, links in (("platform only", ()), ("legs (default)", None)):
            t = dataclasses.replace(task, pfl=(args.region,), pfl_links=links)
            with tempfile.TemporaryDirectory() as d:
                t0 = time.perf_counter()
                try:
                    res = run_plan(t, d, robot, html=False, plots=False)
                except Sixplus3Error as exc:
                    print(f"| {task.name} | {label} | - | {time.perf_counter() - t0:.1f} "
                          f"| not planned: {str(exc)[:90]} | |", flush=True)
                    continue
                wall = time.perf_counter() - t0
                setup = t.robot_for(robot)
                rep = validate_file(res.csv, setup)
                motion = read_trajectory(res.csv, setup).motion
                prof = pfl_profile(rep, setup, motion, judged([args.region], None))
            worst = prof.ratio.max(axis=(0, 2))
            legs = [i for i, p in enumerate(prof.points) if p.startswith("leg")]
            plat = [i for i, p in enumerate(prof.points) if not p.startswith("leg")]
            k = legs[int(np.argmax(worst[legs]))]
            print(f"| {task.name} | {label} | {rep.duration:.4f} | {wall:.1f} | "
                  f"{worst[plat].max():.3f} | {worst[k]:.3f} ({prof.points[k]}) |",
                  flush=True)


if __name__ == "__main__":
    main()
