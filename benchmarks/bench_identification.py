"""The identification loop on virtual prototypes (BENCHMARKS.md, "Identification").

For each plant seed: a plant perturbed as a real build would be (masses and inertias
+-30 %, centres of mass +-1 cm, rotor inertia +-40 %, friction x[1, 3]):

(a) a task planned on the nominal model, run on the plant: its peak torque;
(b) identification from the excitation's log on the plant;
(c) the same task re-planned on the identified robot, run on the plant: its peak torque,
    and the torque prediction error on a log the identification did not see (a second,
    smooth plan), identified against nominal.

    .venv/bin/python benchmarks/bench_identification.py [--seeds 1 2 3] [--task tilt60_x]
        [--duration 6] [--candidates 8] [--out out/bench_identification]
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from sixplus3 import examples
from sixplus3.control.drive.loop import TORQUE_NOISE
from sixplus3.control.drive.plant import run_on_plant
from sixplus3.control.pipeline import run_plan
from sixplus3.identification.excite import ExcitationSettings, excite
from sixplus3.identification.identify import check, identify
from sixplus3.identification.plants import perturbed_plant
from sixplus3.planner.task import task_from_dict
from sixplus3.robot_description.robot import Robot

#: The unseen validation plan: a smooth, jerk-limited tilt (not an excitation tour).
VALIDATION = {"name": "validation", "waypoints": [
    {"position": [0.0, 0.0, 0.58]},
    {"position": [0.02, -0.01, 0.60], "rpy": [20, -10, 5]},
    {"position": [-0.015, 0.02, 0.57], "rpy": [-10, 15, -10]},
    {"position": [0.0, 0.0, 0.58]}],
    "limits": {"jerk": 3000, "torque_rate": 60}, "torque_fraction": 0.6}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--task", default="tilt60_x")
    ap.add_argument("--duration", type=float, default=6.0)
    ap.add_argument("--candidates", type=int, default=8)
    ap.add_argument("--noise", type=float, default=TORQUE_NOISE)
    ap.add_argument("--out", default="out/bench_identification")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    robot = Robot.default()
    t0 = time.perf_counter()
    ex = excite(robot, out, ExcitationSettings(duration=args.duration,
                                               candidates=args.candidates))
    t_ex = time.perf_counter() - t0
    print(f"excitation: {ex.duration:.2f} s, condition {ex.condition:.4g}, planned in "
          f"{t_ex:.0f} s")
    task = examples.load(args.task)
    nominal_plan = run_plan(task, out / "nominal", robot, html=False, plots=False).csv
    val_plan = run_plan(task_from_dict(VALIDATION), out / "nominal", robot, html=False,
                        plots=False).csv
    unit = robot.motors.gear_ratio * robot.motors.rated_torque / 1000.0
    sigma_inj = math.sqrt(args.noise ** 2 + unit ** 2 / 12.0)
    rows = []
    for seed in args.seeds:
        plant = perturbed_plant(robot, seed)
        a = run_on_plant(nominal_plan, robot, plant, seed=seed)
        exc = run_on_plant(ex.path, robot, plant, seed=100 + seed, torque_noise=args.noise)
        t1 = time.perf_counter()
        idf = identify([exc.log], robot)
        t_id = time.perf_counter() - t1
        ident = idf.robot
        t2 = time.perf_counter()
        replanned = run_plan(task, out / f"identified_{seed}", ident, html=False,
                             plots=False)
        t_plan = time.perf_counter() - t2
        c = run_on_plant(replanned.csv, ident, plant, seed=seed)
        val = run_on_plant(val_plan, robot, plant, seed=200 + seed, torque_noise=args.noise,
                           hold=1.0)
        e_nom = check(val.log, robot)
        e_id = check(val.log, ident)
        rows.append({
            "seed": seed,
            "nominal_plan_peak_on_plant": a.peak_torque,
            "identified_plan_peak_on_plant": c.peak_torque,
            "excitation_peak_on_plant": exc.peak_torque,
            "condition": idf.condition, "identify_s": t_id, "replan_s": t_plan,
            "replan_compiled": replanned.solution.source,
            "unseen_rms_nominal": e_nom.rms_all, "unseen_rms_identified": e_id.rms_all,
            "unseen_rms_identified_over_noise": e_id.rms_all / sigma_inj,
            "unseen_max_joint_rms_identified": float(np.nanmax(e_id.rms)),
        })
        print(json.dumps(rows[-1]))
    summary = {"excitation": {"duration_s": ex.duration, "condition": ex.condition,
                              "plan_s": t_ex},
               "task": args.task, "noise_n_m": args.noise, "injected_sigma_n_m": sigma_inj,
               "rows": rows}
    (out / "summary.json").write_text(json.dumps(summary, indent=1))
    print("| seed | (a) nominal plan on plant: peak N m | (c) re-planned on identified: "
          "peak N m | unseen RMS nominal | unseen RMS identified (x injected noise) | "
          "identify s |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['seed']} | {r['nominal_plan_peak_on_plant']:.3f} | "
              f"{r['identified_plan_peak_on_plant']:.3f} | {r['unseen_rms_nominal']:.4f} | "
              f"{r['unseen_rms_identified']:.4f} ({r['unseen_rms_identified_over_noise']:.2f}x)"
              f" | {r['identify_s']:.1f} |")


if __name__ == "__main__":
    main()
