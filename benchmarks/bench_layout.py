"""The layout study and the numbers of docs/design.md ("Which robot is the paper's",
"ey", "Layout") and BENCHMARKS.md ("The layout study").

    python benchmarks/bench_layout.py --robots      # named robots: COW, clearance, home
    python benchmarks/bench_layout.py --ey          # ey on the default layout
    python benchmarks/bench_layout.py --study       # the study (LocalCluster, 2 workers)

The study is `sixplus3 design layout` with its defaults; this script prints the same
table and the wall time.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

from sixplus3.design.cow import compute_cow, deepest_point, home_in_cow
from sixplus3.design.layout import LayoutSettings, layout_study
from sixplus3.kinematics import collision
from sixplus3.kinematics.collision import _segment_distance
from sixplus3.kinematics.robot import home, robot_ik
from sixplus3.robot_description.geometry import LegGeometry
from sixplus3.robot_description.robot import NAMED_ROBOTS, Robot


def robots() -> None:
    print("| robot | 2 g COW [L] | + no interference [L] | z range on the axis [m] | home | "
          "deepest point | COW/footprint |")
    print("| --- | ---: | ---: | --- | --- | --- | ---: |")
    for name in NAMED_ROBOTS:
        r = Robot.named(name)
        c = compute_cow(r, step=0.01, z_step=0.01, extent=0.4, z_max=0.8,
                        margin=r.limits.margin, z_min=0.0)
        where = home_in_cow(r, step=0.01)
        try:
            deep = deepest_point(r, step=0.01)
            deep_s = f"{np.round(deep[0], 3).tolist()} ({deep[1] * 100:.1f} cm)"
        except Exception as exc:  # noqa: BLE001 - an empty COW is a result here
            deep_s = f"none ({type(exc).__name__})"
        h = home(r)
        a, b, d = collision.closest(h)
        print(f"| {name} | {c.volume('torque') * 1e3:.1f} | {c.volume('clear') * 1e3:.1f} | "
              f"{where.z_range[0]:.2f}-{where.z_range[1]:.2f} | "
              f"{list(r.home_position)} {'inside' if where.inside else 'outside'}, "
              f"{where.depth * 100:.1f} cm; closest {a}/{b} {d * 1e3:.1f} mm | {deep_s} | "
              f"{c.ratio('clear'):.2f} (2 g: {c.ratio('torque'):.2f}), footprint "
              f"{c.footprint_area * 1e4:.0f} cm^2 |")


def ey_table() -> None:
    base = Robot.default()
    print("| ey [m] | type II-free COW [L] | 2 g COW [L] | + no interference [L] | "
          "GE-HF axes of one leg, at least [mm] |")
    print("| ---: | ---: | ---: | ---: | ---: |")
    for ey in (0.0, 0.005, 0.010, 0.015, 0.020):
        r = base.replace(geometry=replace(base.geometry, leg=LegGeometry(ey=ey, fy=-ey)))
        c = compute_cow(r, step=0.02, z_step=0.02, extent=0.4, z_max=0.8,
                        margin=r.limits.margin, z_min=0.02)
        Z, X, Y = np.nonzero(c.masks["clear"] | c.masks["torque"])
        pos = np.c_[c.xs[X], c.ys[Y], c.zs[Z]]
        cfg = robot_ik(pos, np.eye(3), r.home_psi, r)
        g = min(float(_segment_distance(s.g, s.e, s.h, s.f).min()) for s in cfg.legs)
        print(f"| {ey:.3f} | {c.volume('singfree') * 1e3:.1f} | {c.volume('torque') * 1e3:.1f} "
              f"| {c.volume('clear') * 1e3:.1f} | {g * 1e3:.1f} |")


def study(workers: int) -> None:
    t = time.perf_counter()
    s = layout_study(Robot.default(), LayoutSettings(), workers=workers)
    print(s.report())
    print(f"wall {time.perf_counter() - t:.0f} s ({len(s.points)} layouts, "
          f"{workers} workers)")


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--robots", action="store_true")
    ap.add_argument("--ey", action="store_true")
    ap.add_argument("--study", action="store_true")
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    if a.robots:
        robots()
    if a.ey:
        ey_table()
    if a.study:
        study(a.workers)
