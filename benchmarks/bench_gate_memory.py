"""The gate's memory and time on long files: the real ``sixplus3 validate`` as a subprocess.

    .venv/bin/python benchmarks/bench_gate_memory.py [--samples 20000 100000]

For each length it builds a slow, valid rest-to-rest motion (a quintic blend of a 3 cm,
10 deg move in minimal coordinates, sampled at 1 kHz), writes it with
``validate_and_write`` (the gate, then one atomic file), and runs ``sixplus3 validate
FILE`` in a fresh process.  It prints the file's size, the command's wall time and its
peak resident memory (``getrusage`` of the child: ru_maxrss).  The attack audit measured
5.5 GB for 10^5 rows before the gate checked long motions in windows.
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def long_motion(robot, n: int, rate: float):
    from sixplus3.dynamics.symbolic import symbolic_robot

    sr = symbolic_robot(robot)
    t = np.arange(n) / rate
    s = t / t[-1]
    T = t[-1]
    b = 10 * s**3 - 15 * s**4 + 6 * s**5
    db = (30 * s**2 - 60 * s**3 + 30 * s**4) / T
    ddb = (60 * s - 180 * s**2 + 120 * s**3) / T**2
    x0 = np.r_[robot.home_position, 0, 0, 0, robot.home_psi]
    step = np.r_[0.03, 0.0, 0.0, np.radians(10.0), 0.0, 0.0, 0.0, 0.0, 0.0]
    x, xd, xdd = x0 + b[:, None] * step, db[:, None] * step, ddb[:, None] * step
    th = np.array(sr.theta.map(n)(x.T)).T
    thd = np.array(sr.theta_dot.map(n)(x.T, xd.T)).T
    thdd = np.array(sr.theta_ddot.map(n)(x.T, xd.T, xdd.T)).T
    thd[[0, -1]] = 0.0
    thdd[[0, -1]] = 0.0
    return t, th, thd, thdd, x


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--samples", type=int, nargs="+", default=[20000, 100000])
    ap.add_argument("--rate", type=float, default=1000.0)
    args = ap.parse_args()
    if any(n < 2 or n > 1_100_000 for n in args.samples):
        ap.error("--samples must be in [2, 1100000]")
    from sixplus3.control.gate.validation import validate_and_write
    from sixplus3.motion import Motion
    from sixplus3.robot_description.robot import Robot

    robot = Robot.default()
    print(f"{'samples':>9} {'file MB':>8} {'write s':>8} {'validate wall s':>16} "
          f"{'peak RSS MB':>12} verdict")
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.samples:
            t, th, thd, thdd, x = long_motion(robot, n, args.rate)
            t0 = time.perf_counter()
            motion = Motion(t, th, thd, thdd, args.rate)
            path, _ = validate_and_write(Path(tmp) / f"long{n}.csv", motion, robot, x)
            wrote = time.perf_counter() - t0
            before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
            t0 = time.perf_counter()
            out = subprocess.run([sys.executable, "-m", "sixplus3.cli", "validate",
                                  str(path)], capture_output=True, text=True)
            wall = time.perf_counter() - t0
            peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
            verdict = "OK" if out.returncode == 0 else f"exit {out.returncode}"
            # ru_maxrss of children is the largest child so far: report it only if it grew
            rss = f"{peak / 1024:.0f}" if peak > before else f"<= {before / 1024:.0f}"
            print(f"{n:>9} {path.stat().st_size / 1e6:>8.1f} {wrote:>8.1f} {wall:>16.2f} "
                  f"{rss:>12} {verdict}")
            path.unlink()


if __name__ == "__main__":
    main()
