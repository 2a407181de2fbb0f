"""Offline feed: stream a validated trajectory file to the controller at its rate.

    .venv/bin/python scripts/stream_to_controller.py TRAJ.csv [--udp 127.0.0.1:9870]
                                         [--speed 0.5] [--dry-run] [--robot ROBOT.yaml]

The same as ``sixplus3 feed``: the file is read once and its bytes are validated by the
library (:func:`sixplus3.control.drive.feed.prepare_feed`); the samples sent are exactly the
validated ones (or, with --speed < 1, a real retiming of them, validated again).  A bad
file exits 2, a violated limit 1, and nothing is sent.  Each sample is one UDP datagram
(JSON: t, positions, velocities, accelerations, feed-forward torques, in the URDF joint
order) at the file's rate, on loopback by default; --dry-run prints them.  Adapt
``udp_sender`` to the controller's real interface.
"""

from __future__ import annotations

import sys

from sixplus3.cli import main as cli

if __name__ == "__main__":
    sys.exit(cli(["feed", *sys.argv[1:]]))
