"""Throughput of the batched leg kernel: IK + J + K + tau_ext, points per second.

    .venv/bin/python benchmarks/bench_leg.py [--points N] [--repeat R]

Points are uniform in the bounding box of the design half-plane disk (about 78% of them
inside it, the rest failing early in the RU chain, as in the design search).  Each
configuration is timed R times after a warm-up; the best and median are reported.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time

import numba
import numpy as np

from sixplus3.kinematics.leg import leg_eval_packed, leg_ik
from sixplus3.robot_description.assembly import DEFAULT_MODE
from sixplus3.robot_description.geometry import LegGeometry


def timed(fn, repeat: int) -> list[float]:
    fn()
    out = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=2_000_000)
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args()
    n = args.points
    rng = np.random.default_rng(0)
    geo = LegGeometry()
    pts = np.c_[rng.uniform(-0.35, 0.35, n), rng.uniform(0.0, 0.7, n), np.zeros(n)]
    packed = geo.packed()
    buf = np.empty((n, 9))
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cpus, "
          f"numba {numba.__version__}, numpy {np.__version__}; {n:,} points")
    print(f"{'kernel':52s} {'threads':>7s} {'best Mpts/s':>12s} {'median':>8s}")
    cases = [
        ("IK+J+K+tau_ext, reused buffer (design search)",
         lambda: leg_eval_packed(pts, packed, DEFAULT_MODE, margin_ii=False, out=buf)),
        ("... + type II margin sigma_min, reused buffer",
         lambda: leg_eval_packed(pts, packed, DEFAULT_MODE, margin_ii=True, out=buf)),
        ("IK+J+K+tau_ext, fresh output each call",
         lambda: leg_eval_packed(pts, packed, DEFAULT_MODE, margin_ii=False)),
        ("full LegState (all fields, 76 floats/point)",
         lambda: leg_ik(pts[: n // 4], geo)),
    ]
    for threads in sorted({1, numba.config.NUMBA_NUM_THREADS}):
        numba.set_num_threads(threads)
        for name, fn in cases:
            count = n // 4 if name.startswith("full") else n
            ts = timed(fn, args.repeat)
            print(f"{name:52s} {threads:7d} {count / min(ts) / 1e6:12.2f} "
                  f"{count / statistics.median(ts) / 1e6:8.2f}")


if __name__ == "__main__":
    main()
