"""Commissioning on simulated prototypes: zero offsets and reversed motors.

    .venv/bin/python benchmarks/bench_commission.py [--plants 23:4 37:8] [--mass 0.3]

For each PLANT_SEED:REVERSED_MOTOR, a perturbed plant (identification.plants, masses and
inertias within 1 +- ``--mass``) with random zero offsets within +-3 rad and that motor
reversed is jogged in MuJoCo (``control.drive.plant.run_jog``: 5 deg, 0.8 s each, the
log in the drive's counts, as ``sixplus3 commission jog`` writes it).  The nominal robot
file is then zeroed from the first 0.29 s (at rest in the home jig) and checked for
reversed motors (``identification.commission``, as ``sixplus3 commission zero`` and
``directions`` run them).  Prints the largest offset error in counts (reversed motor
excluded), the motors named, each motor's error ratio (as logged / reversed: >= 2
names it), and the check's wall time.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from sixplus3.control.drive.plant import run_jog
from sixplus3.control.file.drive_log import counts_per_rad, read_log, write_log
from sixplus3.identification.commission import check_directions, known_pose, zero_offsets
from sixplus3.identification.plants import perturbed_plant
from sixplus3.robot_description.robot import Robot


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plants", nargs="+", default=["23:4", "37:8"])
    ap.add_argument("--mass", type=float, default=0.3)
    args = ap.parse_args()
    nominal = Robot.default()
    k = counts_per_rad(nominal)
    for spec in args.plants:
        seed, rev = (int(v) for v in spec.split(":"))
        rng = np.random.default_rng(seed)
        dirs = [1] * 9
        dirs[rev] = -1
        p = perturbed_plant(nominal, seed, mass=args.mass)
        plant = p.replace(motors=replace(p.motors, zero_offsets=tuple(rng.uniform(-3, 3, 9)),
                                         directions=tuple(dirs)))
        log = run_jog(plant, amplitude=np.radians(5.0), each=0.8, seed=seed)
        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / "jog.csv"
            write_log(path, log, plant, units="drive")
            lab = read_log(path, nominal)
            assert lab.counts is not None
            z = zero_offsets(nominal, lab.counts[:290], known_pose(nominal))
            err = np.abs(z.offsets - np.array(plant.motors.zero_offsets)) * k
            t0 = time.perf_counter()
            res = check_directions(z.robot, read_log(path, z.robot))
            wall = time.perf_counter() - t0
        ratio = res.error_as_logged / res.error_reversed
        print(f"plant {seed}, motor {rev} reversed, mass +-{args.mass:g}: offsets within "
              f"{np.delete(err, rev).max():.2f} counts; named {list(res.reversed)}; ratios "
              + " ".join(f"{r:.2f}" for r in ratio) + f"; {wall:.1f} s", flush=True)


if __name__ == "__main__":
    main()
