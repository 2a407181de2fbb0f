"""The gate's speed: the real ``sixplus3 validate`` on a 5 s, 1 kHz trajectory file.

    .venv/bin/python benchmarks/bench_validate.py [--repeat 3]

Plans the combined example task (translation, tilt and torsion through four poses) with
its velocity and acceleration limits tightened until the motion lasts about 5 s, writes
the trajectory file at 1 kHz, then times the command a user runs, ``sixplus3 validate
FILE``, as a subprocess (wall time, including the interpreter start-up and imports), and
the library call ``validate_file`` inside one process.  Every check runs, midpoints
included.  The command is timed twice: as shipped (a forked worker shares the dynamics,
control/gate/offload.py ``Offload``) and in one process (``SIXPLUS3_NO_FORK=1``); the
in-process library call runs in one process too (numba's threads are started there).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    from sixplus3.control.gate.validation import validate_file
    from sixplus3.control.pipeline import run_plan
    from sixplus3.planner.task import load_task, task_from_dict
    from sixplus3.robot_description.robot import Robot

    robot = Robot.default()
    src = load_task(ROOT / "examples" / "combined.yaml").source
    assert src is not None
    doc = {**src, "name": "slow_combined",
           "limits": {**src.get("limits", {}), "velocity": 0.35, "acceleration": 1.5}}
    with tempfile.TemporaryDirectory() as tmp:
        res = run_plan(task_from_dict(doc), tmp, robot, html=False, plots=False)
        path = res.csv
        n = res.report.samples
        print(f"file: {n} samples, {res.smoothed.duration:.3f} s at 1 kHz, "
              f"{path.stat().st_size / 1e6:.1f} MB")
        walls: dict[str, list[float]] = {"worker": [], "one process": []}
        for _ in range(args.repeat):
            for label, env in (("worker", {}), ("one process", {"SIXPLUS3_NO_FORK": "1"})):
                t0 = time.perf_counter()
                r = subprocess.run([sys.executable, "-m", "sixplus3.cli", "validate",
                                    str(path)], capture_output=True, text=True,
                                   env={**os.environ, **env})
                walls[label].append(time.perf_counter() - t0)
                assert r.returncode == 0, r.stdout + r.stderr
        libs = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            rep = validate_file(path, robot)
            libs.append(time.perf_counter() - t0)
            assert rep.ok
        for label, w in walls.items():
            print(f"sixplus3 validate (subprocess wall time, {label}): median "
                  f"{statistics.median(w):.2f} s (min {min(w):.2f}, max {max(w):.2f}) over "
                  f"{args.repeat} runs")
        print(f"validate_file in-process: median {statistics.median(libs):.2f} s for "
              f"{rep.checked_points} points with the full dynamics "
              f"({1e6 * statistics.median(libs) / rep.checked_points:.0f} us per point)")


if __name__ == "__main__":
    main()
