"""How long a 60 s, 1 kHz log takes to identify (BENCHMARKS.md, "Identification").

The excitation (``sixplus3 identify excite``) is run on a perturbed plant in MuJoCo and
its log repeated, times continued, to the length asked for (the same motion again and
again: the speed does not depend on what the motion is). Then the whole estimate is
timed: reading the CSV, the filter, the regressor, least squares and the SDP.

    .venv/bin/python benchmarks/bench_identify_speed.py \
        --excitation out/bench_identification/excitation.csv [--seconds 60] [--repeat 3]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from sixplus3.control.drive.plant import run_on_plant
from sixplus3.control.file.drive_log import DriveLog, read_log, write_log
from sixplus3.identification.identify import identify
from sixplus3.identification.plants import perturbed_plant
from sixplus3.robot_description.robot import Robot


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--excitation", required=True)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    robot = Robot.default()
    run = run_on_plant(args.excitation, robot, perturbed_plant(robot, 1), seed=1)
    one = run.log
    n = int(np.ceil(args.seconds * one.rate / len(one.t)))
    th = np.vstack([one.theta] * n)[: int(args.seconds * one.rate) + 1]
    tau = np.vstack([one.tau] * n)[: len(th)]
    t = np.arange(len(th)) / one.rate
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "long.csv"
        write_log(path, DriveLog(t, th, tau), robot)
        times, reads = [], []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            log = read_log(path, robot)
            t1 = time.perf_counter()
            idf = identify([log], robot)
            times.append(time.perf_counter() - t0)
            reads.append(t1 - t0)
    print(f"{args.seconds:g} s log at {one.rate:g} Hz ({len(t)} samples, {idf.rows} rows "
          f"fitted): identify median {statistics.median(times):.2f} s (read "
          f"{statistics.median(reads):.2f} s) over {args.repeat} runs; "
          f"condition {idf.condition:.4g}")


if __name__ == "__main__":
    main()
