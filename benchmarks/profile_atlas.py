"""Where the atlas kernel's time goes: cProfile of ``largest_tilts`` on one layer.

    .venv/bin/python benchmarks/profile_atlas.py [--z 0.30] [--every 4]

Every ``--every``-th position of the z layer whose level pose is admissible (cranks
free), the default 24 directions, torsion 0, free and locked, numba on one thread (as a
Dask task runs it).  Prints ms per (position, direction) pair, evaluations per pair and
the functions by their own time.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import time

import numba
import numpy as np

from sixplus3.design import atlas as at
from sixplus3.design import atlas_checks as ac
from sixplus3.design import atlas_data as ad
from sixplus3.robot_description.robot import Robot


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--z", type=float, default=0.30)
    ap.add_argument("--every", type=int, default=4)
    args = ap.parse_args()
    numba.set_num_threads(1)
    robot = Robot.default()
    st = ad.AtlasSettings()
    xs, ys, zs = ad.position_grid(robot, st.step)
    z = zs[np.argmin(np.abs(zs - args.z))]
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    pts = np.c_[X.ravel(), Y.ravel(), np.full(X.size, z)]
    chk = ac.PoseChecker(robot, st.psi_step_deg)
    ok, _, _ = chk.admissible(pts, np.broadcast_to(np.eye(3), (len(pts), 3, 3)), True)
    pts = pts[ok][::args.every]
    at.largest_tilts(robot, pts[:4], st.azimuths_deg, (0.0,), st)  # compile numba first
    pr = cProfile.Profile()
    t0 = time.perf_counter()
    pr.enable()
    res = at.largest_tilts(robot, pts, st.azimuths_deg, (0.0,), st)
    pr.disable()
    wall = time.perf_counter() - t0
    pairs = len(pts) * len(st.azimuths_deg)
    ev = int(res["evaluations"][0])
    print(f"z = {z:.2f} m: {len(pts)} positions x {len(st.azimuths_deg)} directions; "
          f"{wall:.2f} s, {wall / pairs * 1e3:.2f} ms per pair, {ev / pairs:.1f} "
          "evaluations per pair (free and locked)")
    pstats.Stats(pr).sort_stats("tottime").print_stats(18)


if __name__ == "__main__":
    main()
