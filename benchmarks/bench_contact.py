"""A battery of simulated contacts with the guard (BENCHMARKS.md, "Safe in contact").

    .venv/bin/python benchmarks/bench_contact.py FILE [--regions hand lower_arm upper_arm]
        [--at 0.08 0.22] [--plant-seeds 12] [--json]

FILE: a trajectory planned with ``pfl`` for the regions tried (e.g. ``sixplus3 plan
translate --pfl hand`` for free contacts, ``--pfl hand-clamped`` for clamps).
Each contact: a region, free or clamped, at an instant of the
plan (its normal along the motion there), the drives' PD soft (300 / 6) or stiff
(3000 / 30), on the nominal plant and on perturbed plants (``identify plant``-like:
masses, rotors +-5 %, friction x[1, 1.2], the residual of an identification), with the
guard; and the clamps on the stiff drive without it.  Then each plant runs the file with
nobody in the way (false alarms).  Prints one row per run and a summary.
"""

from __future__ import annotations

import argparse
import json
import statistics

from sixplus3.control.drive.person import contact_from_dict
from sixplus3.identification.plants import perturbed_plant
from sixplus3.interaction.people.person import run_contact
from sixplus3.robot_description.robot import Robot, load_robot


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file")
    ap.add_argument("--regions", nargs="+", default=["hand", "lower_arm", "upper_arm"])
    ap.add_argument("--at", nargs="+", type=float, default=[0.08, 0.22])
    ap.add_argument("--kinds", nargs="+", default=["free", "clamp"],
                    choices=["free", "clamp"])
    ap.add_argument("--plant-seeds", nargs="*", type=int, default=[12, 21])
    ap.add_argument("--quiet-files", nargs="*", default=[],
                    help="more trajectory files run with nobody in the way (false alarms)")
    ap.add_argument("--robot", default=None,
                    help="the model the file was planned for and the guard uses (a robot "
                         "file, e.g. an identified one); default: the default robot")
    ap.add_argument("--plant", default=None,
                    help="a plant robot file, run instead of the nominal and --plant-seeds "
                         "ones")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    robot = Robot.default() if args.robot is None else load_robot(args.robot)
    plants = [("nominal", robot)] + [(f"near-{s}", perturbed_plant(robot, s, mass=0.05,
                                                                   rotor=0.05, friction=1.2))
                                     for s in args.plant_seeds]
    if args.plant is not None:
        plants = [(args.plant, load_robot(args.plant))]
    rows = []
    for pname, plant in plants:
        for gains in ((300.0, 6.0), (3000.0, 30.0)):
            res = run_contact(args.file, robot, plant, None, guard=True, kp=gains[0],
                              kd=gains[1], after=0.2)
            rows.append({"plant": pname, "kp": gains[0], "contact": "none", "guard": True,
                         "false_alarm": res.false_alarm, "peak_command": res.peak_command})
            for region in args.regions:
                for kind in args.kinds:
                    for at in args.at:
                        c = contact_from_dict({"region": region, "kind": kind, "at": at})
                        for guard in ((True, False) if kind == "clamp" and gains[0] > 1000
                                      and pname == plants[0][0] else (True,)):
                            r = run_contact(args.file, robot, plant, c, guard=guard,
                                            kp=gains[0], kd=gains[1], after=0.3)
                            rows.append({"plant": pname, "kp": gains[0], "contact":
                                         f"{region} {kind} @{at:g}", "guard": guard,
                                         **{k: v for k, v in r.summary().items()
                                            if k not in ("events", "modes")},
                                         "final_mode": r.modes[-1] if r.modes else "-"})
                            if not args.json:
                                print(json.dumps(rows[-1]), flush=True)
    for f in args.quiet_files:
        for pname, plant in plants:
            for gains in ((300.0, 6.0), (3000.0, 30.0)):
                res = run_contact(f, robot, plant, None, guard=True, kp=gains[0],
                                  kd=gains[1], after=0.2)
                rows.append({"plant": pname, "kp": gains[0], "contact": "none", "file": f,
                             "guard": True, "false_alarm": res.false_alarm,
                             "peak_command": res.peak_command})
                if not args.json:
                    print(json.dumps(rows[-1]), flush=True)
    guarded = [r for r in rows if r["guard"] and r["contact"] != "none"]
    det = [r["detection_delay"] for r in guarded if r.get("detection_delay") is not None]
    summary = {
        "contacts_with_guard": len(guarded),
        "within_limits": sum(bool(r["within_limits"]) for r in guarded),
        "detected": len(det),
        "detection_median_ms": 1e3 * statistics.median(det) if det else None,
        "detection_worst_ms": 1e3 * max(det) if det else None,
        "stop_worst_ms": 1e3 * max((r["stop_time"] for r in guarded
                                    if r.get("stop_time") is not None), default=float("nan")),
        "false_alarms": sum(bool(r.get("false_alarm")) for r in rows),
        "no_contact_runs": sum(r["contact"] == "none" for r in rows),
        "clamps_without_guard_final_force_n": [round(r["quasi_static"], 1) for r in rows
                                               if not r["guard"]],
    }
    print(json.dumps(rows if args.json else summary, indent=1))


if __name__ == "__main__":
    main()
