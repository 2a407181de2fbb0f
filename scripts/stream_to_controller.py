"""Offline feed: stream a validated trajectory file to the controller at its rate.

    .venv/bin/python scripts/stream_to_controller.py TRAJ.csv [--udp 127.0.0.1:9870]
                                                     [--dry-run] [--robot ROBOT.yaml]

The file is read once and validated by the library (:func:`sixplus3.validate_file`:
format, robot hash, Pinocchio torques and margins against the robot's hardware limits);
the samples sent are exactly those validated.  An invalid file is refused (exit 2 for a
bad file, 1 for a violated limit) and nothing is sent.  Each sample is one UDP datagram
(JSON: t, positions, velocities, accelerations, feed-forward torques, in the URDF joint
order) at the file's rate, on loopback by default; ``--dry-run`` prints them.  Adapt
``send`` to the controller's real interface.
"""

from __future__ import annotations

import argparse
import json
import socket
import sys
import time
from pathlib import Path

from sixplus3.control.trajectory_file import JOINTS, columns
from sixplus3.control.validation import validate_file
from sixplus3.errors import Sixplus3Error
from sixplus3.robot_description.robot import Robot, load_robot


def _address(text: str) -> tuple[str, int]:
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise argparse.ArgumentTypeError(f"--udp must be HOST:PORT with PORT in 1..65535, "
                                         f"got {text!r}")
    return host, int(port)


def main() -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("csv", type=Path)
    ap.add_argument("--udp", type=_address, default=("127.0.0.1", 9870),
                    help="HOST:PORT of the controller")
    ap.add_argument("--dry-run", action="store_true", help="print instead of sending")
    ap.add_argument("--robot", type=Path, default=None, help="robot file (default: paper's)")
    args = ap.parse_args()
    try:
        robot = load_robot(args.robot) if args.robot else Robot.default()
        rep = validate_file(args.csv, robot)
    except Sixplus3Error as exc:
        print(f"refused: {exc}", file=sys.stderr)
        return 2
    if not rep.ok or rep.data is None:
        print("refused: " + "; ".join(rep.violations), file=sys.stderr)
        return 1
    data = rep.data  # exactly the samples validated
    pos, vel, acc, tau = (columns(data, k) for k in ("pos", "vel", "acc", "tau"))
    sock = None if args.dry_run else socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    t0 = time.perf_counter()
    for k in range(len(data)):
        msg = json.dumps({"t": data[k, 0], "joints": JOINTS, "pos": pos[k].tolist(),
                          "vel": vel[k].tolist(), "acc": acc[k].tolist(),
                          "tau_ff": tau[k].tolist()})
        delay = data[k, 0] - (time.perf_counter() - t0)
        if delay > 0:
            time.sleep(delay)
        if sock is None:
            print(msg)
        else:
            sock.sendto(msg.encode(), args.udp)
    print(f"sent {len(data)} samples of {rep.duration:.4f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
