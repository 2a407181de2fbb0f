"""Power and force limiting: how long the examples take under ``pfl`` against the free
plan and the blanket collaborative speed (BENCHMARKS.md, "Power and force limiting").

    .venv/bin/python benchmarks/bench_pfl.py [--tasks translate tilt30_x ...]
        [--regions hand chest face]

For each task: the free plan, ``people: collaborative`` (0.25 m/s, 2 m/s^2) and each
region's PFL plan (``pfl: [REGION]``), planned by the product's pipeline and judged by
the gate; printed: the motion's duration, the tool centre point's top speed, the gate's
largest PFL ratio (<= 1 holds) and the planning wall time.
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time

from sixplus3 import examples
from sixplus3.control.gate.validation import validate_file
from sixplus3.control.pipeline import run_plan
from sixplus3.robot_description.hardware import people_limits
from sixplus3.robot_description.robot import Robot


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", nargs="+", default=["translate", "tilt30_x", "torsion_z"])
    ap.add_argument("--regions", nargs="+", default=["hand", "chest", "face"])
    args = ap.parse_args()
    robot = Robot.default()
    print("| task | limits | duration [s] | top TCP speed [m/s] | PFL ratio | wall [s] |")
    print("|---|---|---|---|---|---|")
    for name in args.tasks:
        task = examples.load(name)
        variants = [("free", task),
                    ("collaborative", dataclasses.replace(
                        task, limits={**task.limits, **people_limits("collaborative")}))]
        variants += [(f"pfl: [{r}]", dataclasses.replace(task, pfl=(r,)))
                     for r in args.regions]
        for label, t in variants:
            with tempfile.TemporaryDirectory() as d:
                t0 = time.perf_counter()
                res = run_plan(t, d, robot, html=False, plots=False)
                wall = time.perf_counter() - t0
                rep = validate_file(res.csv, robot)
            ratio = "-" if rep.max_pfl_ratio is None else f"{rep.max_pfl_ratio:.3f}"
            print(f"| {name} | {label} | {rep.duration:.4f} | {rep.max_tcp_speed:.3f} | "
                  f"{ratio} | {wall:.1f} |", flush=True)


if __name__ == "__main__":
    main()
