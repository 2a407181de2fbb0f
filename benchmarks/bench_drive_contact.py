"""The drive's position loop in a contact (issue 70, dynamics/drive_contact.py) against
MuJoCo: each plan's leg contacts (where a leg vertex moves fastest, and where the
gate's ratio is largest), a free region met along the motion with no guard, on the
torques held (PD 0/0), the soft drive (300/6) and the stiff one (3000/30); the model's
peak at MuJoCo's contact speed beside MuJoCo's (BENCHMARKS.md, "The drive in the
contact").  ``--clamp``: the region clamped, the contact guard in MuJoCo's loop, the
model's reference standing one tick after the guard's own measured detection (the soft
and the stiff drive).

    .venv/bin/python benchmarks/bench_drive_contact.py PLANS/lower_arm/combined.csv \
        PLANS/hand/translate.csv [--region lower_arm] [--clamp]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_contact_battery import file_robot, leg_instants  # noqa: E402

from sixplus3.control.drive.person import contact_from_dict  # noqa: E402
from sixplus3.control.file.file_format import columns, motion_of  # noqa: E402
from sixplus3.control.gate.validation import validate_file  # noqa: E402
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics  # noqa: E402
from sixplus3.dynamics.drive_contact import DriveCase, contact_peaks, drive_cap  # noqa: E402
from sixplus3.dynamics.leg_points import vertex_jacobians  # noqa: E402
from sixplus3.interaction.people.person import run_contact  # noqa: E402
from sixplus3.kinematics import rotations as rot  # noqa: E402
from sixplus3.kinematics.robot import robot_ik  # noqa: E402
from sixplus3.robot_description.body_regions import REGIONS  # noqa: E402
from sixplus3.robot_description.hardware import PositionLoop  # noqa: E402

DRIVES = {"held": (0.0, 0.0), "soft": (300.0, 6.0), "stiff": (3000.0, 30.0)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="+")
    ap.add_argument("--region", default=None, help="default: the file's first region")
    ap.add_argument("--clamp", action="store_true", help="a clamp, with the guard")
    args = ap.parse_args()
    cap = drive_cap()
    for f in args.files:
        path = Path(f)
        robot = file_robot(path)
        rep = validate_file(path, robot)
        assert rep.header is not None and rep.data is not None
        region = REGIONS[(args.region or rep.header["pfl"][0]).replace("-clamped", "")]
        kind = "clamp" if args.clamp else "free"
        rate = float(rep.header["rate_hz"])
        dyn = ClosedLoopDynamics(robot)
        motion = motion_of(rep.data, rate)
        for label, at, point, vel in leg_instants(path, robot):
            u = vel / np.linalg.norm(vel)
            k = int(round(at * rate))
            cfg = robot_ik(rep.position[k:k + 1], rot.matrix_from_quat(rep.quaternion[k:k + 1]),
                           rep.psi[k:k + 1], robot, platform_margins=False)
            Jth, M = vertex_jacobians(dyn, cfg.q, ((int(point[3]), point[5:]),))[1:]
            contact = contact_from_dict({"region": region.name, "kind": kind, "at": at,
                                         "normal": [float(x) for x in u], "point": point})
            cells = []
            for name, (kp, kd) in DRIVES.items():
                if args.clamp and name == "held":
                    continue  # the guard commands the drives: no torques held
                run = run_contact(path, robot, robot, contact, guard=args.clamp, kp=kp,
                                  kd=kd, after=0.1)
                thd = motion.theta_dot[k] * run.speed / float(u @ Jth[0, 0]
                                                               @ motion.theta_dot[k])
                case = DriveCase(np.linalg.inv(M), (Jth[0, 0].T @ u)[None],
                                 np.array([run.speed]), columns(rep.data, "tau")[k][None],
                                 cap, np.array([np.inf if args.clamp else region.mass]),
                                 np.array([region.stiffness]), thd[None])
                det = run.detection_delay
                stop = np.inf if not args.clamp or det is None else det + 1.0 / rate
                model = contact_peaks(case, PositionLoop(kp, kd), rate, stop=stop)[0]
                cells.append(f"{name} v={run.speed:.2f} det={det} MuJoCo "
                             f"{run.peak_transient:6.1f} model {model:6.1f} "
                             f"({run.peak_transient / model:.3f})")
            print(f"{path.stem:12s} {region.name:9s} {label:5s} {point:7s} | "
                  + " | ".join(cells), flush=True)


if __name__ == "__main__":
    main()
