"""Offline feed: stream a validated trajectory file to the controller at its rate.

    .venv/bin/python scripts/stream_to_controller.py TRAJ.csv [--udp 127.0.0.1:9870]
                                                     [--dry-run] [--speed 1.0]

The file is re-validated first (format, robot hash, Pinocchio torques and margins); an
invalid file is refused with exit code 2 and nothing is sent.  Each sample is sent as one
UDP datagram (JSON: t, positions, velocities, accelerations, feed-forward torques, in the
URDF joint order) at the file's rate, on loopback by default; ``--dry-run`` prints them.
Adapt ``send`` to the controller's real interface.
"""

from __future__ import annotations

import argparse
import json
import socket
import sys
import time

from click.testing import CliRunner

from sixplus3.control.trajectory_file import JOINTS, TrajectoryFileError, columns, read_trajectory
from sixplus3.cli import main as cli


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv")
    ap.add_argument("--udp", default="127.0.0.1:9870", help="host:port of the controller")
    ap.add_argument("--dry-run", action="store_true", help="print instead of sending")
    ap.add_argument("--speed", type=float, default=1.0, help="time scale (1 = real time)")
    args = ap.parse_args()
    check = CliRunner().invoke(cli, ["validate", args.csv])
    if check.exit_code != 0:
        print(f"refused: {check.output.strip()}", file=sys.stderr)
        return 2
    try:
        header, data = read_trajectory(args.csv)
    except TrajectoryFileError as exc:
        print(f"refused: {exc}", file=sys.stderr)
        return 2
    pos, vel, acc, tau = (columns(data, k) for k in ("pos", "vel", "acc", "tau"))
    host, port = args.udp.rsplit(":", 1)
    sock = None if args.dry_run else socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    t0 = time.perf_counter()
    for k in range(len(data)):
        msg = json.dumps({"t": data[k, 0], "joints": JOINTS, "pos": pos[k].tolist(),
                          "vel": vel[k].tolist(), "acc": acc[k].tolist(),
                          "tau_ff": tau[k].tolist()})
        delay = data[k, 0] / args.speed - (time.perf_counter() - t0)
        if delay > 0:
            time.sleep(delay)
        if sock is None:
            print(msg)
        else:
            sock.sendto(msg.encode(), (host, int(port)))
    print(f"sent {len(data)} samples of {header['duration_s']:.4f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
