"""Every example planned at 1 kHz and replayed in MuJoCo with each tick's feed-forward
held as its own sample and as the interval's mean (docs/validation.md, "Torque for
sampled drives").

    python benchmarks/bench_torque_hold.py
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from sixplus3 import examples
from sixplus3.control.drive.simulation import simulate_file
from sixplus3.control.pipeline import run_plan
from sixplus3.robot_description.robot import Robot

if __name__ == "__main__":
    robot = Robot.default()
    print("| example | duration [s] | peak |tau|, `sample` | peak |tau|, `mean` |")
    print("|---|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as d:
        for name in examples.names():
            task = examples.load(name)
            res = run_plan(task, Path(d), robot, rate=1000.0, html=False, plots=False)
            r = task.robot_for(robot)
            _, sample = simulate_file(res.csv, r, torque_hold="sample")
            _, mean = simulate_file(res.csv, r, torque_hold="mean")
            print(f"| {name} | {res.solution.final_time:.4f} | {sample.peak_total_torque:.3f} "
                  f"| {mean.peak_total_torque:.3f} |", flush=True)
