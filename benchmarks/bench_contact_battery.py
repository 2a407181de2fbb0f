"""The contact battery of issue 55 (BENCHMARKS.md, "Safe in contact"): every body region,
free and clamped, normals along and across the motion, speeds from 0.1 m/s to the
fastest the region's plan reaches, on several plants and drives, with the guard (and a
subset without it).

    .venv/bin/python benchmarks/bench_contact_battery.py PLANS [--regions ...]
        [--speeds 0.1 0.3 0.6 1.0 max] [--normals along across] [--drives soft stiff]
        [--plant FILE ...] [--robot FILE] [--no-nominal] [--unguarded] [--out r.jsonl]
        [--task translate ...] [--point tcp|centre|legs|leg0_D ...]
    .venv/bin/python benchmarks/bench_contact_battery.py - --quiet FILE ... [--plant ...]

PLANS: a folder with one plan per region, ``PLANS/<region>/<task>.csv`` planned with
``--pfl <region>`` (free contacts) and ``PLANS/<region>-clamped/<task>.csv`` with
``--pfl <region>-clamped`` (clamps): e.g. ``sixplus3 plan translate --pfl hand -o
PLANS/hand``.  The model the guard uses is the robot of each file's header (its tool
too: the contact is at the tool centre point; ``--point centre`` for the centre).

Each contact's instant is the first sample where the tool centre point's planned speed
reaches the target (``max``: the fastest sample).  ``--point legs`` meets the legs
instead (issue 70): at the fastest moment of any leg vertex (``max``: the joint centre
and the sample where a leg link moves fastest) and at the leg vertex and sample of the
gate's largest ratio (``worst``), the speed targets aside; its normal is the planned velocity's
direction (``along``) or that direction turned 60 degrees toward the horizontal
perpendicular of the motion (``across``: the point meets the body at half its speed,
and slides along it).  Drives: soft = PD 300 / 6, stiff = 3000 / 30 (N m/rad, N m s/rad).
One JSON row per run (``--out``), and a summary.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from sixplus3.control.drive.loop import DriveSettings
from sixplus3.control.drive.person import POINTS, contact_from_dict
from sixplus3.control.file.file_format import columns
from sixplus3.control.file.trajectory_parse import parse
from sixplus3.control.file.trajectory_read import read_bytes
from sixplus3.control.gate.validation import validate_file
from sixplus3.identification.plants import perturbed_plant
from sixplus3.interaction.contact.guard import ContactGuard
from sixplus3.interaction.people.person import run_contact
from sixplus3.kinematics import rotations as rot
from sixplus3.kinematics.robot import robot_ik
from sixplus3.kinematics.tcp import tcp_velocity
from sixplus3.robot_description.body_regions import REGIONS
from sixplus3.robot_description.robot import Robot, load_robot

DRIVES = {"soft": (300.0, 6.0), "stiff": (3000.0, 30.0)}


def file_robot(path: Path) -> Robot:
    header, _ = parse(read_bytes(path), path.name)
    return Robot.from_dict(header["robot"]["parameters"])


def planned_velocity(path: Path, robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    """(t (n,), the tool centre point's planned velocity (n, 3))."""
    rep = validate_file(path, robot)
    assert rep.data is not None and rep.position is not None
    assert rep.quaternion is not None and rep.psi is not None
    cfg = robot_ik(rep.position, rot.matrix_from_quat(rep.quaternion), rep.psi, robot,
                   platform_margins=False)
    return rep.data[:, 0], tcp_velocity(cfg, columns(rep.data, "vel"))


def instants(t: np.ndarray, v: np.ndarray, speeds: list[str]) -> list[tuple[str, float]]:
    sp = np.linalg.norm(v, axis=1)
    out = []
    for s in speeds:
        if s == "max":
            out.append(("max", float(t[int(np.argmax(sp))])))
            continue
        target = float(s)
        if target > 0.98 * sp.max():
            continue
        out.append((s, float(t[int(np.argmax(sp >= target))])))
    return out


def across(u: np.ndarray) -> list[float]:
    """u turned 60 degrees toward its horizontal perpendicular (vertical u: toward x)."""
    w = np.cross(u, [0.0, 0.0, 1.0])
    if np.linalg.norm(w) < 1e-6:
        w = np.array([1.0, 0.0, 0.0])
    w /= np.linalg.norm(w)
    n = 0.5 * u + np.sqrt(3.0) / 2.0 * w
    return [float(x) for x in n / np.linalg.norm(n)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("plans")
    ap.add_argument("--task", nargs="+", default=["translate"])
    ap.add_argument("--regions", nargs="+", default=list(REGIONS))
    ap.add_argument("--kinds", nargs="+", default=["free", "clamp"], choices=["free", "clamp"])
    ap.add_argument("--speeds", nargs="+", default=["0.1", "0.3", "0.6", "1.0", "max"])
    ap.add_argument("--normals", nargs="+", default=["along", "across"],
                    choices=["along", "across"])
    ap.add_argument("--drives", nargs="+", default=["soft", "stiff"], choices=list(DRIVES))
    ap.add_argument("--point", default="tcp", choices=[*POINTS, "legs"])
    ap.add_argument("--plant", nargs="*", default=[], help="plant robot files (perturbed)")
    ap.add_argument("--plant-seeds", nargs="*", type=int, default=[],
                    help="plants perturbed from each file's own robot (its setup too): "
                         "masses and rotors +-5 %%, friction x[1, 1.2], centres of mass "
                         "by up to 1 cm (identify plant's generator)")
    ap.add_argument("--full-spread", action="store_true",
                    help="--plant-seeds perturb the file's robot as `identify plant` does "
                         "(masses +-30 %%, rotors +-40 %%, friction up to x3), not by +-5 %%")
    ap.add_argument("--no-nominal", action="store_true",
                    help="skip the nominal plant (the file's own robot)")
    ap.add_argument("--robot", default=None,
                    help="the guard's model, instead of each file's header robot")
    ap.add_argument("--unguarded", action="store_true",
                    help="also run each max-speed contact without the guard")
    ap.add_argument("--reaction", default="hold", choices=["hold", "yield"])
    ap.add_argument("--parameters", default=None,
                    help="an identification's parameters.npz (with --robot): the guard "
                         "knows its robot identified (its thresholds; else the prior)")
    ap.add_argument("--model-error", type=float, default=None,
                    help="the guard's model share (default: its prior for the robot)")
    ap.add_argument("--rate-feedback", nargs="+", default=["encoder"],
                    choices=["encoder", "plant", "filtered"],
                    help="the drives' rate feedback: the encoder's difference, the plant's "
                         "true rate, a filtered rate (control/drive/loop.py)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--quiet", nargs="*", default=[],
                    help="trajectory files run with nobody in the way (false alarms) on "
                         "every plant and drive, instead of the contacts (PLANS unused)")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    root = Path(args.plans)
    out = open(args.out, "a") if args.out else None  # noqa: SIM115
    rows = []
    t_start = time.perf_counter()
    if args.quiet:
        quiet(args, out, t_start)
        return
    for region, kind, task in [(r, k, t) for r in args.regions for k in args.kinds
                               for t in args.task]:
        folder = root / (region if kind == "free" else f"{region}-clamped")
        path = folder / f"{task}.csv"
        if not path.exists():
            print(f"no plan {path}: skipped", file=sys.stderr)
            continue
        model = load_robot(args.robot) if args.robot else file_robot(path)
        plants = plants_for(args, model)
        t, v = planned_velocity(path, model)
        built = ContactGuard(model, path, 1.0 / (t[1] - t[0]), reaction=args.reaction,
                             **guard_settings(args))
        points = (leg_instants(path, model) if args.point == "legs" else
                  [(label, at, args.point, v[int(round(at / (t[1] - t[0])))])
                   for label, at in instants(t, v, args.speeds)])
        for label, at, point, vel in points:
            u = vel / np.linalg.norm(vel)
            for nname in args.normals:
                normal = [float(x) for x in u] if nname == "along" else across(u)
                c = contact_from_dict({"region": region, "kind": kind, "at": at,
                                       "normal": normal, "point": point})
                for pname, plant in plants:
                    for dname, fb in [(d, f) for d in args.drives
                                      for f in args.rate_feedback]:
                        kp, kd = DRIVES[dname]
                        guards = [True] + ([False] if args.unguarded and label in (
                            "max", "worst") and nname == "along" else [])
                        for guard in guards:
                            r = run_contact(path, model, plant, c,
                                            guard=built if guard else False, kp=kp,
                                            kd=kd, after=0.3, reaction=args.reaction,
                                            drive=DriveSettings(rate_feedback=fb,
                                                                seed=args.seed))
                            row = {"region": region, "kind": kind, "task": task,
                                   "target": label, "at": round(at, 4), "normal": nname,
                                   "point": point, "plant": pname,
                                   "drive": dname, "rate_feedback": fb, "guard": guard,
                                   **{q: w for q, w in r.summary().items()
                                      if q not in ("region", "kind", "guard")},
                                   "final_mode": r.modes[-1] if r.modes else "-"}
                            rows.append(row)
                            line = json.dumps(row)
                            if out:
                                out.write(line + "\n")
                                out.flush()
                            print(f"{task[:12]:12s} {point:7s} "
                                  f"{region:10s} {kind:5s} {label:>4s} {nname:6s} "
                                  f"{pname:10s} {dname:5s} {fb:8s} guard={guard!s:5s} "
                                  f"v={r.speed:5.2f} F={r.peak_transient:6.1f}/"
                                  f"{r.limit_transient:.0f} Fqs={r.quasi_static:6.1f}/"
                                  f"{r.limit_quasi_static:.0f} det={r.detection_delay} "
                                  f"stop={r.stop_time} cmd={r.peak_command:.2f} "
                                  f"{row['final_mode']}", flush=True)
    print(json.dumps(summarise(rows), indent=1))
    print(f"{len(rows)} runs in {time.perf_counter() - t_start:.0f} s")


def leg_instants(path: Path, robot: Robot) -> list[tuple[str, float, str, np.ndarray]]:
    """The leg contacts of a plan (module doc): ("max", t, vertex, its velocity) where a
    leg vertex moves fastest, ("worst", ...) where the gate's ratio over the leg vertices
    is largest (the file's regions; a file without any: the hand's)."""
    from sixplus3.control.file.file_format import motion_of
    from sixplus3.control.gate.pfl import judged, pfl_profile
    from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
    from sixplus3.dynamics.leg_points import vertex_rates

    rep = validate_file(path, robot)
    assert rep.data is not None and rep.header is not None
    motion = motion_of(rep.data, float(rep.header["rate_hz"]))
    prof = pfl_profile(rep, robot, motion, judged(rep.header.get("pfl") or ["hand"], None))
    legs = [j for j, p in enumerate(prof.points) if p.startswith("leg")]
    cfg = robot_ik(rep.position, rot.matrix_from_quat(rep.quaternion), rep.psi, robot,
                   platform_margins=False)
    out = []
    for label, table in (("max", prof.speed[:, legs]),
                         ("worst", prof.ratio[:, legs].max(axis=2))):
        k, j = np.unravel_index(int(np.argmax(table)), table.shape)
        name = prof.points[legs[j]]
        vertex = (int(name[3]), name[5:])
        vel = vertex_rates(ClosedLoopDynamics(robot), cfg.q[k:k + 1],
                           motion.theta_dot[k:k + 1], (vertex,))[1][0, 0]
        out.append((label, float(motion.t[k]), name, vel))
    return out


def guard_settings(args: argparse.Namespace) -> dict:
    """The guard's model_error and parameter_cov from the options."""
    out: dict = {"model_error": args.model_error}
    if args.parameters:
        with np.load(args.parameters, allow_pickle=False) as z:
            out["parameter_cov"] = (np.array(z["index"]), np.array(z["cov"]))
    return out


def plants_for(args: argparse.Namespace, model: Robot) -> list[tuple[str, Robot]]:
    """The nominal plant (the model itself), the --plant files, and the --plant-seeds
    plants perturbed from the model (a file's robot, with its task's setup)."""
    return (([] if args.no_nominal else [("nominal", model)])
            + [(Path(p).stem, load_robot(p)) for p in args.plant]
            + [(f"near-{s}", perturbed_plant(model, s, mass=0.05, rotor=0.05, friction=1.2))
               for s in args.plant_seeds if not args.full_spread]
            + [(f"seed-{s}", perturbed_plant(model, s)) for s in args.plant_seeds
               if args.full_spread])


def quiet(args: argparse.Namespace, out: object, t_start: float) -> None:
    """Every file, plant and drive with nobody in the way: false alarms, stops of a
    drive that could not follow, the largest command."""
    rows = []
    for f in args.quiet:
        path = Path(f)
        model = load_robot(args.robot) if args.robot else file_robot(path)
        plants = plants_for(args, model)
        built = ContactGuard(model, path, **guard_settings(args))
        for pname, plant in plants:
            for dname, fb in [(d, f) for d in args.drives for f in args.rate_feedback]:
                kp, kd = DRIVES[dname]
                r = run_contact(path, model, plant, None, guard=built, kp=kp, kd=kd,
                                after=0.2, drive=DriveSettings(rate_feedback=fb,
                                                               seed=args.seed))
                row = {"file": path.name, "plant": pname, "drive": dname, "rate_feedback": fb,
                       "false_alarm": r.false_alarm, "peak_command": r.peak_command,
                       "saturation_stop": any("saturated" in e for e in r.events),
                       "final_mode": r.modes[-1] if r.modes else "-", "events": r.events}
                rows.append(row)
                if out:
                    out.write(json.dumps(row) + "\n")  # type: ignore[attr-defined]
                    out.flush()  # type: ignore[attr-defined]
                print(f"{path.name:24s} {pname:12s} {dname:5s} {fb:8s} false_alarm="
                      f"{r.false_alarm!s:5s} cmd={r.peak_command:.2f} {row['final_mode']} "
                      f"{r.events[:1]}", flush=True)
    print(json.dumps({"runs": len(rows),
                      "false_alarms": sum(r["false_alarm"] for r in rows),
                      "saturation_stops": sum(r["saturation_stop"] for r in rows),
                      "ended_done": sum(r["final_mode"] == "done" for r in rows),
                      "peak_command_worst_nm": max(r["peak_command"] for r in rows)},
                     indent=1))
    print(f"{len(rows)} runs in {time.perf_counter() - t_start:.0f} s")


def said(rows: list[dict], kind: str) -> list[int]:
    """[runs of ``kind`` the guard called a collision, runs it called a clamp]."""
    ev = [" ".join(r["events"]) for r in rows if r["kind"] == kind]
    clamp = sum("clamp" in e for e in ev)
    return [len(ev) - clamp, clamp]


def summarise(rows: list[dict]) -> dict:
    g = [r for r in rows if r["guard"] and r["onset"] is not None]
    det = [r["detection_delay"] for r in g if r["detection_delay"] is not None]
    stops = [r["stop_time"] for r in g if r["detection_delay"] is not None
             and r["stop_time"] is not None]
    missed = [r for r in g if r["detection_delay"] is None]
    return {
        "runs": len(rows),
        "contacts_with_guard": len(g),
        "within_limits": sum(r["within_limits"] for r in g),
        "worst_transient_share": max((r["peak_transient"] / r["limit_transient"] for r in g),
                                     default=None),
        "worst_quasi_static_share": max((r["quasi_static"] / r["limit_quasi_static"]
                                         for r in g), default=None),
        "detected": len(det),
        "detection_median_ms": 1e3 * statistics.median(det) if det else None,
        "detection_worst_ms": 1e3 * max(det) if det else None,
        "not_flagged": len(missed),
        "not_flagged_worst_force_share": max((max(r["peak_transient"] / r["limit_transient"],
                                                  r["quasi_static"] / r["limit_quasi_static"])
                                              for r in missed), default=None),
        "stopped_within_25_ms": int(sum(x <= 0.025 + 1e-9 for x in stops)),
        # what the guard said at rest: [a collision (held), a clamp or pressing (retract)]
        "free_said_collision_clamp": said(g, "free"),
        "clamp_said_collision_clamp": said(g, "clamp"),
        "stop_median_ms": 1e3 * statistics.median(stops) if stops else None,
        "stop_worst_ms": 1e3 * max(stops) if stops else None,
        "false_alarms": sum(bool(r["false_alarm"]) for r in rows),
        "peak_command_worst_nm": max((r["peak_command"] for r in rows if r["guard"]),
                                     default=None),
        "unguarded_within_limits": [sum(r["within_limits"] for r in rows if not r["guard"]),
                                    sum(not r["guard"] for r in rows)],
    }


if __name__ == "__main__":
    main()
