"""Reports of a robot: its whole-robot check (:func:`robot_check`, ``sixplus3 robot check``)
and its leg design (:func:`leg_report`, ``sixplus3 report``)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from sixplus3.design.cow import home_in_cow
from sixplus3.design.readings import READINGS
from sixplus3.design.search import Reading
from sixplus3.design.workspace import usable_area
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.errors import check_number
from sixplus3.kinematics import collision
from sixplus3.kinematics.leg import leg_ik
from sixplus3.kinematics.robot import home
from sixplus3.kinematics.spherical import spherical_tilts
from sixplus3.robot_description.generated import check as urdf_stale
from sixplus3.robot_description.geometry import LegLoad
from sixplus3.robot_description.hardware import effective_limits, envelope_record
from sixplus3.robot_description.robot import Robot, require_robot


def leg_report(robot: Robot, ws_step: float = 0.005) -> str:
    """Sample configurations and the usable half-plane area of the robot's leg design."""
    robot = require_robot(robot)
    check_number("ws_step [m]", ws_step, 0.0005, 0.05)
    geometry, mode = robot.leg, robot.mode
    load = LegLoad(torque_limit=robot.limits.torque)
    lines = [
        f"sixplus3 leg report: {robot.summary()}",
        f"  design l2 = l3 = {geometry.l2:.3f}, l4 = l5 = {geometry.l4:.3f}, ex = fx = "
        f"{geometry.ex:.3f}, ey = -fy = {geometry.ey:.3f} m (paper: 0.139, 0.350, 0.097, "
        f"ey 'as small as possible'); assembly mode {mode.name}",
        "  " + home_in_cow(robot, step=0.02).line(),
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
    reading = reading_of(mode.name)
    rep = usable_area(geometry, ws_step, mode, load, reading.theta_max, reading.theta_zero,
                      reading.theta_direction)
    lines += [
        "",
        f"  design half-plane z = 0, y >= 0 (grid {ws_step * 1000:g} mm), this robot's own "
        f"leg (ey = {geometry.ey:.3f} m), the angles read as '{reading.name}' (the reading "
        f"in assembly mode {mode.name}; docs/design.md, 'Readings'):",
        f"    reachable disk          {rep.disk_area:.5f} m^2",
        f"    solved in mode {mode.name}    {rep.reachable_area:.5f} m^2",
        f"    0 <= theta <= {math.degrees(reading.theta_max):.0f} deg    "
        f"{rep.theta_ok_area:.5f} m^2",
        f"    and tau_ext <= {load.torque_limit:g} N m  {rep.usable_area:.5f} m^2"
        "  (the paper's design objective, in that reading)",
    ]
    if geometry.ey != 0.0:
        flat = usable_area(replace(geometry, ey=0.0, fy=0.0), ws_step, mode, load,
                           reading.theta_max, reading.theta_zero, reading.theta_direction)
        lines.append(f"    the same leg with E = F (ey = 0, the paper's assumption): "
                     f"{flat.usable_area:.5f} m^2")
    return "\n".join(lines)


@dataclass(frozen=True)
class RobotCheck:
    """The whole-robot check: ``doc`` (the JSON document of ``sixplus3 robot check
    --json``), ``lines`` (its text report), ``inside`` (home is inside the robot's
    constant-orientation workspace) and ``cow_line`` (that verdict in one line)."""

    doc: dict[str, Any]
    lines: tuple[str, ...]
    inside: bool
    cow_line: str


def reading_of(mode: str) -> Reading:
    """The reading of the paper's conventions in assembly mode ``mode``
    (:data:`design.readings.READINGS`: paper-match for ++--, paper-mirror for -+++, ours
    for ++++); ours for any other mode."""

    return next((r for r in READINGS.values() if r.mode == mode
                 and r.theta_max < 2 * math.pi), READINGS["spec"])


def robot_check(robot: Robot) -> RobotCheck:
    """Build the robot's URDF + closures model and check its home pose: the closures'
    rank and mobility, the residual, margins, tilts, gravity torques, mass, layout and
    clearance at home, and whether home lies in the robot's COW (2 cm grid)."""

    robot = require_robot(robot)
    dyn = ClosedLoopDynamics(robot)
    clm = dyn.clm
    h = home(robot)
    where = home_in_cow(robot, step=0.02)
    g = robot.geometry
    near = collision.closest(h)
    layout = {"axis_turn_deg": math.degrees(g.axis_turn),
              "platform_phase_deg": math.degrees(g.platform_phase),
              "base_radius_m": g.base_radius, "platform_radius_m": g.platform_radius,
              "platform_crank_m": g.platform_crank,
              "home_clearance_m": near[2], "home_closest_pair": list(near[:2]),
              "collision_model_m": robot.collision.as_dict()}
    q = h.q[0]
    residual = float(np.abs(clm.residual(q)).max())
    rank = int(np.linalg.matrix_rank(clm.constraint_jacobian(q), tol=1e-9))
    tau = dyn.gravity_torques(q)
    out = {
        "robot": robot.summary(), "robot_hash": robot.hash, "assembly_mode": robot.mode.name,
        "committed_urdf_fresh": not urdf_stale(),
        "nq": clm.model.nq, "nv": clm.model.nv, "actuated": len(clm.actuated_names),
        "closures": len(clm.pairs), "constraint_rows": clm.n_constraints,
        "constraint_rank_home": rank, "mobility": clm.model.nv - rank,
        "home_position_m": list(robot.home_position),
        "home_psi_deg": np.degrees(robot.home_psi), "home_residual_m": residual,
        "margins": h.margins.as_dict(),
        "max_spherical_tilt_deg": float(np.degrees(spherical_tilts(h).max())),
        "tau_gravity_home": tau, "total_mass_kg": clm.total_mass(),
        "design_m": {"l2": robot.leg.l2, "l4": robot.leg.l4, "ex": robot.leg.ex,
                     "ey": robot.leg.ey},
        "layout": layout,
        "home_in_cow": {"inside": where.inside, "failing": where.failing,
                        "depth_m": where.depth, "deepest_m": list(where.deepest),
                        "z_range_m": list(where.z_range), "volume_l": where.volume_l,
                        "grid_m": where.step},
        # the site's envelope ($SIXPLUS3_HARDWARE or --hardware) and what it leaves
        "envelope": envelope_record(),
        "limits_in_force": effective_limits(robot).as_dict(),
    }
    inforce = out["limits_in_force"]
    m = out["margins"]
    lines = (
        f"robot     {out['robot']}",
        f"gravity   {list(robot.gravity)} m/s^2; committed URDF of the default robot fresh: "
        f"{out['committed_urdf_fresh']}",
        f"tree DoF  nq = {out['nq']}, nv = {out['nv']}; {out['actuated']} actuated joints",
        f"closures  {out['closures']} spherical, {out['constraint_rows']} rows, rank {rank} "
        f"at home -> mobility {out['mobility']}",
        f"design    l2 = l3 = {robot.leg.l2:.3f}, l4 = l5 = {robot.leg.l4:.3f}, ex = fx = "
        f"{robot.leg.ex:.3f}, ey = -fy = {robot.leg.ey:.3f} m; assembly mode "
        f"{robot.mode.name}",
        f"layout    actuated axes turned {layout['axis_turn_deg']:.1f} deg from the tangent "
        f"(|a_j - a_i| = {g.base_radius * math.sqrt(3):.3f} m), platform phase "
        f"{layout['platform_phase_deg']:.1f} deg; at home the closest bodies are "
        f"{near[0]} and {near[1]}, {near[2] * 1e3:.1f} mm apart",
        f"home      platform at {list(robot.home_position)} m, psi = "
        f"{np.round(np.degrees(robot.home_psi), 2).tolist()} deg; closure residual "
        f"{residual:.2e} m",
        f"COW       {where.line()}",
        "margins   leg type I " + " ".join(f"{v:.3f}" for v in m["leg_type1"])
        + " | leg type II " + " ".join(f"{v:.3f}" for v in m["leg_type2"])
        + f" | platform {m['platform']:.3f}",
        "tau_g     " + " ".join(f"{v:+.3f}" for v in tau) + "  N m (home)",
        f"mass      {out['total_mass_kg']:.3f} kg",
        f"envelope  {out['envelope']['drive_train']} ({out['envelope']['origin']}); in "
        f"force: torque {inforce['torque']:g} N m, rate {inforce['velocity']:g} rad/s",
    )
    return RobotCheck(out, lines, where.inside, where.line())
