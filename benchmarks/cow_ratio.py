"""The COW / footprint ratio (paper: 5.03) and the encoder resolution (paper: 8.4 um), in
one consistent reading, with the variants that move them (docs/design.md).

    .venv/bin/python benchmarks/cow_ratio.py

Consistent reading: the paper-mirror robot (the paper's design, E = F: ey = 0, mode -+++,
theta counted from -z about +x, the paper's [0, 270] deg collision rule), COW cumulative
up to ``torque`` (singularity-free and 2 g within 10 N m), platform horizontal with P_i on
the 0.173 m triangle.  Each row changes one thing.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from sixplus3.design.cow import (
    JOINT_RESOLUTION,
    SINGFREE_MARGIN,
    compute_cow,
    encoder_resolution,
)
from sixplus3.design.figures import cow_robot
from sixplus3.design.readings import READINGS
from sixplus3.design.search import PAPER_DESIGN
from sixplus3.design.workspace import counted_reading, halfplane_grid
from sixplus3.kinematics.leg import leg_ik
from sixplus3.robot_description.geometry import LegGeometry, LegLoad


def hull_area(mask2d: np.ndarray, step: float) -> float:
    from scipy.spatial import ConvexHull

    idx = np.argwhere(mask2d)
    if len(idx) < 3:
        return 0.0
    pts = np.vstack([idx + d for d in ((0, 0), (0, 1), (1, 0), (1, 1))]) * step
    return float(ConvexHull(pts).volume)


def ratio_rows() -> None:
    base = READINGS["paper-mirror"]
    print("| variant | projected / footprint |")
    print("| --- | ---: |")

    def row(label: str, robot, reading, step=0.01, z_step=0.05, margin=SINGFREE_MARGIN,
            key="torque", how="union"):
        c = compute_cow(robot, step=step, z_step=z_step, reading=reading, margin=margin)
        m = c.masks[key]
        if how == "union":
            a = c.projected_area(key)
        elif how == "largest layer":
            a = float(m.sum(axis=(1, 2)).max()) * step**2
        else:  # convex hull of the projection
            a = hull_area(m.any(axis=0), step)
        print(f"| {label} | {a / c.footprint_area:.2f} |", flush=True)

    r0 = cow_robot(base)
    row("**consistent: paper-mirror, ey = 0, 1 cm grid, layers 5 cm, union of layers**",
        r0, base)
    row("layers every 2.5 cm", r0, base, z_step=0.025)
    row("layers every 1 cm", r0, base, z_step=0.01)
    row("grid 0.5 cm", r0, base, step=0.005)
    row("projected area = largest single layer", r0, base, how="largest layer")
    row("projected area = convex hull of the projection", r0, base, how="hull")
    row("singularity-free at margin 0.05 (the robot's limit)", r0, base, margin=0.05)
    for deg in (60.0, 180.0):
        r = r0.replace(geometry=replace(r0.geometry, platform_phase=r0.geometry.platform_phase
                                        + math.radians(deg)))
        where = "between two legs" if deg == 60.0 else "pointing away from its leg"
        row(f"platform triangle turned {deg:g} deg (P_i {where})", r, base)
    for ey in (0.005, 0.01, 0.02):
        rd = replace(base, ey=ey, name=f"paper-mirror ey={ey:g}")
        row(f"ey = {ey:g} m (built robot's E, F offset)", cow_robot(rd), rd)
    row("with leg clearance (no interference between legs)", r0, base, key="clear")
    spec = READINGS["spec"]
    row("the built robot's assembly (spec: mode ++++, ey = 0.02, its theta rule)",
        cow_robot(spec), spec)


def resolution_rows() -> None:
    print()
    print("| encoder reading | region | worst resolution of P [um] |")
    print("| --- | --- | ---: |")
    rd = READINGS["paper-mirror"]
    geometry = LegGeometry.symmetric(*PAPER_DESIGN, ey=rd.ey, fy=-rd.ey)
    s = leg_ik(halfplane_grid(geometry, 0.0025), geometry, rd.mode, LegLoad())
    cnt = counted_reading(s, LegLoad(), rd) & (s.det_K != 0)
    solved = s.ok & (s.det_K != 0)
    safe = solved & (s.margin_I >= 0.05) & (s.margin_II >= 0.05)
    dth = s.dtheta_dp()
    counts = 2**20
    readings = {
        "20 bit on the motor, through 72/34 (joint step 2.83 urad)": JOINT_RESOLUTION,
        "20 bit at the joint, belt not counted (5.99 urad)": 2 * math.pi / counts,
        "20 bit on the motor, belt inverted (72/34 instead of 34/72)": 2 * math.pi / counts
        * 72 / 34,
        "half a count (rounding), through 72/34": JOINT_RESOLUTION / 2,
    }
    regions = {"counted region (theta <= 135, tau_ext <= 10)": cnt,
               "solved disk, every margin >= 0.05": safe}
    for rname, res in readings.items():
        for gname, mask in regions.items():
            worst = encoder_resolution(res, dth[mask]).max()
            print(f"| {rname} | {gname} | {worst * 1e6:.2f} |", flush=True)
    # one joint at a time (the worst column) instead of the worst box vertex
    cols = np.linalg.norm(np.linalg.inv(dth[cnt]), axis=1).max(axis=1) * JOINT_RESOLUTION
    print(f"| one joint moving (worst column), through 72/34 | counted region | "
          f"{cols.max() * 1e6:.2f} |")


if __name__ == "__main__":
    ratio_rows()
    resolution_rows()
