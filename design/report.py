"""Text report of a robot's leg design: sample configurations and the usable area."""

from __future__ import annotations

import math

import numpy as np

from sixplus3.design.cow import home_in_cow
from sixplus3.design.workspace import THETA_MAX, usable_area
from sixplus3.errors import InputError
from sixplus3.kinematics.leg import leg_ik
from sixplus3.robot_description.geometry import LegLoad
from sixplus3.robot_description.robot import Robot, require_robot


def leg_report(robot: Robot, ws_step: float = 0.005) -> str:
    """Sample configurations and the usable half-plane area of the robot's leg design."""
    robot = require_robot(robot)
    if not (math.isfinite(ws_step) and 0.0005 <= ws_step <= 0.05):
        raise InputError(f"ws_step must be in [0.0005, 0.05] m, got {ws_step!r}",
                         value=ws_step, valid="[0.0005, 0.05] m")
    geometry, mode = robot.leg, robot.mode
    load = LegLoad(torque_limit=robot.limits.torque)
    lines = [
        f"sixplus3 leg report: {robot.summary()}",
        f"  design l2 = l3 = {geometry.l2:.3f}, l4 = l5 = {geometry.l4:.3f}, ex = fx = "
        f"{geometry.ex:.3f}, ey = -fy = {geometry.ey:.3f} m (paper: 0.139, 0.350, 0.097, "
        f"ey 'as small as possible'); assembly mode {mode.name}",
        "  " + home_in_cow(robot, step=0.02).line() + " (grid 2 cm)",
        "  geometry [m]: " + ", ".join(f"{k}={v:g}" for k, v in geometry.as_dict().items()),
        f"  assembly mode {mode.name}; load {load.mass} kg at P, "
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
    st = leg_ik(samples, geometry, mode, load)
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
    rep = usable_area(geometry, ws_step, mode, load)
    lines += [
        "",
        f"  design half-plane z = 0, y >= 0 (grid {ws_step * 1000:g} mm):",
        f"    reachable disk          {rep.disk_area:.5f} m^2",
        f"    solved in mode {mode.name}    {rep.reachable_area:.5f} m^2",
        f"    0 <= theta <= {math.degrees(THETA_MAX):.0f} deg    {rep.theta_ok_area:.5f} m^2",
        f"    and tau_ext <= {load.torque_limit:g} N m  {rep.usable_area:.5f} m^2"
        "  (the paper's design objective)",
    ]
    return "\n".join(lines)
