"""Text report of the default leg design (the main job until the planner exists)."""

from __future__ import annotations

import math

import numpy as np

from sixplus3.design.workspace import THETA_MAX, usable_area
from sixplus3.kinematics.leg import DEFAULT_MODE, leg_ik
from sixplus3.robot_description.geometry import LegGeometry, LegLoad


def leg_report(geometry: LegGeometry | None = None, ws_step: float = 0.005) -> str:
    """Sample configurations and the usable half-plane area of a leg design."""
    geometry = geometry or LegGeometry()
    load = LegLoad()
    lines = [
        "sixplus3 leg report (paper defaults, SPEC.md conventions)",
        "  geometry [m]: " + ", ".join(f"{k}={v:g}" for k, v in geometry.as_dict().items()),
        f"  assembly mode {DEFAULT_MODE.name}; load {load.mass} kg at P, "
        f"{load.accel_g:g} g in any direction, limit {load.torque_limit:g} N m",
        "",
        "  p (leg frame) [m]          theta [deg]                margins I/II   tau_ext [N m]",
    ]
    l1 = geometry.l1
    samples = np.array([
        [0.0, l1 * math.sqrt(2), 0.0],
        [0.0, l1, 0.0],
        [0.15, 0.45, 0.0],
        [-0.15, 0.30, 0.10],
        [0.0, 0.30, 0.30],
        [0.0, 0.20, -0.05],
    ])
    st = leg_ik(samples, geometry, DEFAULT_MODE, load)
    sing = st.singularity()
    for i, p in enumerate(samples):
        if not st.ok[i]:
            lines.append(f"  ({p[0]:+.3f}, {p[1]:+.3f}, {p[2]:+.3f})  unreachable")
            continue
        th = " ".join(f"{v:7.2f}" for v in np.degrees(st.theta[i]))
        lines.append(
            f"  ({p[0]:+.3f}, {p[1]:+.3f}, {p[2]:+.3f})  {th}   "
            f"{st.margin_I[i]:.3f}/{st.margin_II[i]:.3f}   {st.tau_ext[i]:8.3f}  {sing[i]}"
        )
    rep = usable_area(geometry, ws_step, DEFAULT_MODE, load)
    lines += [
        "",
        f"  design half-plane z = 0, y >= 0 (grid {ws_step * 1000:g} mm):",
        f"    reachable disk          {rep.disk_area:.5f} m^2",
        f"    solved in mode {DEFAULT_MODE.name}    {rep.reachable_area:.5f} m^2",
        f"    0 <= theta <= {math.degrees(THETA_MAX):.0f} deg    {rep.theta_ok_area:.5f} m^2",
        f"    and tau_ext <= {load.torque_limit:g} N m  {rep.usable_area:.5f} m^2"
        "  (the paper's design objective)",
    ]
    return "\n".join(lines)
