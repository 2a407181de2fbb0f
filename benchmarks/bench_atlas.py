"""The orientation-workspace atlas: throughput, Dask speed-up, and a cost model.

    .venv/bin/python benchmarks/bench_atlas.py [--layers 0.30 0.46]

1. Throughput: the atlas of two 2 cm layers (default 15 deg directions, torsion 0) in
   this process on one core (``scheduler="synchronous"``, numba on one thread): pose
   evaluations per second and (position, direction) pairs per second per core.
2. Speed-up: the same layers on a Dask LocalCluster of 1 and of 2 worker processes
   (wall time including the cluster start).
3. Cost model: measured core-seconds per (position, direction) pair of the zero-tilt
   workspace, times the pair count of a finer atlas, divided by N workers; memory of
   its result (34 bytes per position and direction: tilt float32, binding int8 and three
   crank angles float32, free and locked).
The default atlas itself is timed with the command a user runs: ``/usr/bin/time -v
sixplus3 atlas -o out/atlas``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from sixplus3.design import atlas as at
from sixplus3.design import atlas_data as ad
from sixplus3.robot_description.robot import Robot


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--layers", nargs="+", type=float, default=[0.30, 0.46])
    args = ap.parse_args()
    robot = Robot.default()
    st = ad.AtlasSettings()
    xs, ys, zs = ad.position_grid(robot, st.step)
    pick = np.array([zs[np.argmin(np.abs(zs - z))] for z in args.layers])
    grid = (xs, ys, pick)
    print(f"grid {len(xs)} x {len(ys)} x {len(pick)} at z = {pick.tolist()} m, "
          f"{len(st.azimuths_deg)} directions")
    t0, c0 = time.perf_counter(), time.process_time()
    ds = at.compute_atlas(robot, st, scheduler="synchronous", grid=grid)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    ws = np.isfinite(ds["max_tilt"].sel(cranks="free").isel(torsion=0, azimuth=0)).sum()
    pairs = int(ws) * len(st.azimuths_deg)
    ev = ds.attrs["pose_evaluations"]
    print(f"one core: {wall:.1f} s wall, {cpu:.1f} s CPU; {ev} pose evaluations "
          f"({ev / cpu:.0f} per core-second); {int(ws)} positions in the zero-tilt "
          f"workspace, {pairs} pairs ({pairs / cpu:.0f} pairs per core-second, "
          f"{cpu / pairs * 1e3:.2f} ms each)")
    walls = {}
    for w in (1, 2):
        t0 = time.perf_counter()
        at.compute_atlas(robot, st, workers=w, grid=grid)
        walls[w] = time.perf_counter() - t0
        print(f"Dask LocalCluster, {w} worker(s): {walls[w]:.1f} s wall")
    print(f"speed-up 1 -> 2 workers: {walls[1] / walls[2]:.2f}x")
    # cost model: pairs scale with the workspace volume and the direction count
    frac = float(ws) / (len(xs) * len(ys) * len(pick))
    for step, daz in ((0.02, 15.0), (0.005, 5.0)):
        sx, sy, sz = ad.position_grid(robot, step)
        n_pos = len(sx) * len(sy) * len(sz)
        n_pairs = n_pos * frac * (360.0 / daz)
        core_s = n_pairs * cpu / pairs
        mem = n_pos * (360.0 / daz) * 34
        print(f"{step * 1000:g} mm x {daz:g} deg: {n_pos} grid positions, ~{n_pairs:.3g} "
              f"pairs (zero-tilt fraction {frac:.2f} of these layers), ~{core_s / 3600:.2f} "
              f"core-hours: {core_s / 2 / 60:.1f} min on 2 workers, "
              f"{core_s / 64 / 60:.1f} min on 64; result {mem / 1e9:.2f} GB")


if __name__ == "__main__":
    main()
