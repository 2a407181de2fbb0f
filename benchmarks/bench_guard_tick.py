"""The cost of one ContactGuard.step in Python (BENCHMARKS.md, "Safe in contact").

    .venv/bin/python benchmarks/bench_guard_tick.py FILE [--ticks 2000] [--no-gains]

Steps the guard along FILE with the file's own angles and torques (no plant), times each
call with perf_counter_ns, prints the median and the 99th percentile.  The guard is given
a stiff drive's gains (3000 / 30: every command bounded to the envelope), unless
``--no-gains``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from sixplus3.control.file.trajectory_read import read_trajectory
from sixplus3.interaction.contact.guard import ContactGuard
from sixplus3.robot_description.robot import Robot


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file")
    ap.add_argument("--ticks", type=int, default=2000)
    ap.add_argument("--no-gains", action="store_true")
    args = ap.parse_args()
    robot = Robot.default()
    tr = read_trajectory(args.file, robot)
    th, tau = tr.joints("pos"), tr.joints("tau")
    times = []
    g = ContactGuard(robot, args.file, drive_gains=None if args.no_gains else (3000.0, 30.0))
    while len(times) < args.ticks:
        g.reset()
        for k in range(len(th)):
            t0 = time.perf_counter_ns()
            g.step(th[k], tau[max(k - 1, 0)])
            times.append(time.perf_counter_ns() - t0)
    us = np.array(times[:args.ticks]) / 1e3
    print(f"ContactGuard.step over {len(us)} ticks: median {np.median(us):.1f} us, p99 "
          f"{np.percentile(us, 99):.1f} us, max {us.max():.1f} us")


if __name__ == "__main__":
    main()
