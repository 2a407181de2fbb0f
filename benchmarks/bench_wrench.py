"""Sensorless touch on the virtual prototype (BENCHMARKS.md, "Sensorless touch"): the
error table of the wrench estimate (RMS and peak, force and moment, hold and motion; the
nominal plant, and a perturbed plant with its identified robot), the streaming form's
cost per sample, and the force resolution at home and over the workspace.

    .venv/bin/python benchmarks/bench_wrench.py \
        [--excitation out/bench_identification/excitation.csv] [--out out/bench_wrench]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numpy as np

from sixplus3.control.drive.plant import WrenchProfile, run_on_plant
from sixplus3.control.pipeline import run_plan
from sixplus3.interaction.observer.resolution import plot_resolution_map, resolution
from sixplus3.interaction.observer.stream import WrenchStream
from sixplus3.interaction.observer.wrench import estimate
from sixplus3.planner.task import task_from_dict
from sixplus3.robot_description.robot import Robot

HOLD = {"name": "small", "nodes_per_segment": 6, "waypoints": [
    {"position": [0, 0, 0.58]}, {"position": [0.01, 0, 0.58]}]}
SLOW = {"name": "slow", "waypoints": [
    {"position": [0.0, 0.0, 0.58]}, {"position": [0.02, -0.01, 0.60], "rpy": [20, -10, 5]},
    {"position": [0.0, 0.0, 0.58]}], "limits": {"jerk": 3000, "torque_rate": 60},
    "torque_fraction": 0.6}


def errors(est, w, lo, hi) -> dict:
    on = (est.t > lo) & (est.t < hi)
    e = est.wrench[on] - w
    f, m = np.linalg.norm(e[:, :3], axis=1), np.linalg.norm(e[:, 3:], axis=1)
    return {"force_rms_n": float(np.sqrt(np.mean(f ** 2))), "force_peak_n": float(f.max()),
            "moment_rms_n_m": float(np.sqrt(np.mean(m ** 2))),
            "moment_peak_n_m": float(m.max())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--excitation", default="out/bench_identification/excitation.csv")
    ap.add_argument("--out", default="out/bench_wrench")
    ap.add_argument("--stream-only", action="store_true",
                    help="Only the streaming form's cost per sample.")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    robot = Robot.default()
    hold = run_plan(task_from_dict(HOLD), out, robot, html=False, plots=False).csv
    slow = run_plan(task_from_dict(SLOW), out, robot, html=False, plots=False).csv
    push = np.array([10.0, 0, 0, 0, 0, 0.5])
    moving = np.array([0.0, 8.0, -5.0, 0, 0, 0.3])
    cases = [] if args.stream_only else [("nominal plant", robot, robot)]
    if Path(args.excitation).exists() and not args.stream_only:
        from sixplus3.identification.identify import identify
        from sixplus3.identification.plants import perturbed_plant

        plant = perturbed_plant(robot, 1)
        idf = identify([run_on_plant(args.excitation, robot, plant, seed=2).log], robot)
        cases.append(("plant seed 1, identified robot", plant, idf.robot))
        cases.append(("plant seed 1, nominal robot", plant, robot))
    rows = []
    for label, plant, model in cases:
        for what, path, w, t_on, t_off, lo, hi, hold_s in (
                ("hold", hold, push, 0.6, 1.4, 0.7, 1.35, 1.6),
                ("slow plan", slow, moving, 0.15, 0.6, 0.2, 0.55, 0.5)):
            prof = WrenchProfile(np.array([0.0, t_on, t_off]), np.array([np.zeros(6), w,
                                                                           np.zeros(6)]))
            run = run_on_plant(path, robot, plant, seed=3, hold=hold_s, wrench=prof)
            est = estimate(run.log, model)
            r = {"case": label, "motion": what, **errors(est, w, lo, hi)}
            on = (est.t > lo) & (est.t < hi)
            r["band_fx_n"] = float(est.band[on, 0].max())
            if what == "hold":
                r["detection_ms"] = float(1e3 * (est.t[(est.t >= t_on) & est.contact][0]
                                                 - t_on))
            rows.append(r)
            print(json.dumps(r))
    # streaming cost
    run = run_on_plant(slow, robot, robot, seed=3, hold=0.5)
    # the Pinocchio state and the compiled CasADi one (interaction/observer/compiled_state.py):
    # that they agree (stepped in turn), then each one's cost (a fresh stream alone over
    # the log: two stepped in turn evict each other's caches)
    streams = {"pinocchio": WrenchStream(robot, run.log.rate),
               "compiled": WrenchStream(robot, run.log.rate, compiled=True)}
    worst = 0.0
    for k in range(len(run.log.t)):
        a, b = (st.update(run.log.theta[k], run.log.tau[k]) for st in streams.values())
        worst = max(worst, float(np.abs(a[0] - b[0]).max()))
    per: dict[str, list[float]] = {}
    for name in streams:
        st = WrenchStream(robot, run.log.rate, compiled=name == "compiled")
        per[name] = []
        for k in range(len(run.log.t)):
            t0 = time.perf_counter()
            st.update(run.log.theta[k], run.log.tau[k])
            per[name].append(time.perf_counter() - t0)
    stream = {name: {"median_us": 1e6 * statistics.median(v[10:]),
                     "p99_us": 1e6 * float(np.percentile(v[10:], 99))}
              for name, v in per.items()}
    stream["samples"] = len(run.log.t)
    stream["max_wrench_difference"] = worst
    print("stream", json.dumps(stream))
    if args.stream_only:
        return
    home = resolution(robot, robot.home_position)
    stats = plot_resolution_map(robot, str(out / "resolution.png"))
    summary = {"errors": rows, "stream": stream,
               "home": {"at_rest": home.at_rest.tolist(), "moving": home.moving.tolist()},
               "map": stats}
    (out / "summary.json").write_text(json.dumps(summary, indent=1))
    print("| plant / model | motion | force RMS / peak [N] | moment RMS / peak [N m] | "
          "friction band fx [N] | detection [ms] |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['case']} | {r['motion']} | {r['force_rms_n']:.3f} / "
              f"{r['force_peak_n']:.3f} | {r['moment_rms_n_m']:.4f} / "
              f"{r['moment_peak_n_m']:.4f} | {r['band_fx_n']:.2f} | "
              f"{r.get('detection_ms', float('nan')):.0f} |")
    print(f"home: at rest {np.round(home.at_rest, 3).tolist()}, moving "
          f"{np.round(home.moving, 3).tolist()}; map {stats}")


if __name__ == "__main__":
    main()
