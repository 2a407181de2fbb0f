"""Static choices at the waypoints, before any motion is planned.

Per waypoint, the crank angles psi that keep every singularity margin largest among
those that pass the official checks in order (reach, actuated range, spherical joints,
clearance, margin; at rest also the holding torque); a failure names the first check no
candidate passes.  Also: the crank-side rule (a crank never passes the singular 0 deg)
and whether the clearance rows must be bounded from the first solve.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.errors import InfeasibleTaskError
from sixplus3.kinematics.checks import PSI_MAX, PSI_MIN, pose_masks
from sixplus3.kinematics.collision import clearance, closest
from sixplus3.kinematics.leg import failing_chain, status_reason
from sixplus3.kinematics.robot import robot_ik
from sixplus3.planner.task import Task
from sixplus3.planner.waypoint import Waypoint
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot


def static_checks(robot: Robot, limits: Limits, position: Any, rotation: Any,
                  psis: np.ndarray) -> tuple[Any, ...]:
    """One pose with candidate crank angles (k, 3), checked in order (batched):
    (cfg, theta_ok, spherical_ok, clearance_ok, margin), each mask implying the previous
    and margin = the smallest singularity margin where clearance_ok, else -1."""
    cfg = robot_ik(position, rotation, psis, robot)
    theta_ok, sph_ok = pose_masks(cfg, limits)
    clear_ok = sph_ok & (clearance(cfg) >= 0.0)
    margin = np.where(clear_ok, cfg.margins.minimum, -1.0)
    return cfg, theta_ok, sph_ok, clear_ok, margin


def static_candidates(robot: Robot, limits: Limits, wp: Waypoint,
                       locked: bool) -> tuple[Any, ...]:
    """Crank-angle candidates at a waypoint with their official checks (batched)."""
    if wp.psi is not None:
        psis = wp.psi[None, :]
    elif locked:
        psis = np.asarray(robot.home_psi)[None, :]
    else:
        axis = np.radians(np.arange(35.0, 146.0, 10.0))
        psis = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3)
    return (psis, *static_checks(robot, limits, wp.position, wp.rotation, psis))


def choose_static_psi(task: Task, robot: Robot, lim: Limits, locked: bool,
                      at_rest: set[int]) -> np.ndarray:
    """Per waypoint, crank angles maximising the smallest margin; raises naming the limit."""

    dyn = ClosedLoopDynamics(robot)
    out = []
    for k, wp in enumerate(task.waypoints):
        psis, cfg, theta_ok, sph_ok, clear_ok, margin = static_candidates(robot, lim, wp,
                                                                           locked)
        where = f"waypoint {k} (position {np.round(wp.position, 4).tolist()} m)"
        if not cfg.ok.any():
            st = next(int(s) for s in cfg.leg_status[0] if s)
            leg = int(np.flatnonzero(cfg.leg_status[0])[0])

            raise InfeasibleTaskError(
                f"{where} is outside the workspace: leg {leg} {failing_chain(st)} chain: "
                f"{status_reason(st)}", k, "reach",
                value=wp.position.tolist(), valid="inside the workspace")
        if not theta_ok.any():
            raise InfeasibleTaskError(
                f"{where}: an actuated angle leaves [{math.degrees(lim.theta_min):g}, "
                f"{math.degrees(lim.theta_max):g}] deg (base collision) for every crank "
                "choice", k, "theta range",
                value=wp.position.tolist(),
                valid=f"[{math.degrees(lim.theta_min):g}, {math.degrees(lim.theta_max):g}] deg")
        if not sph_ok.any():
            raise InfeasibleTaskError(
                f"{where}: a spherical joint exceeds {math.degrees(lim.spherical):g} deg for "
                "every crank choice", k, "spherical joints",
                value=wp.position.tolist(), valid=f"<= {math.degrees(lim.spherical):g} deg")
        if not clear_ok.any():
            c = clearance(cfg, sph_ok)
            a, b, d = closest(cfg, int(np.argmax(c)))
            raise InfeasibleTaskError(
                f"{where}: bodies interfere for every crank choice (at the best one, "
                f"{a} and {b} overlap by {-d * 1e3:.1f} mm)",
                k, "interference", value=wp.position.tolist(), valid="clearance >= 0 m")
        # crank angles inside the NLP's range [PSI_MIN, PSI_MAX] first (its platform
        # margin rows hold there only): a waypoint at 145 deg made the NLP's start
        # clip to 135 deg and fail (BENCHMARKS.md); outside it only when nothing inside
        # passes (then the baseline can still plan it)
        inside = np.all((psis >= PSI_MIN - 1e-12) & (psis <= PSI_MAX + 1e-12), axis=1)
        order = np.argsort(-np.where(inside & (margin >= lim.margin), margin + 10.0, margin),
                           kind="stable")
        if margin[order[0]] < lim.margin:
            raise InfeasibleTaskError(
                f"{where}: no crank choice keeps every singularity margin >= {lim.margin:g} "
                f"(best {margin[order[0]]:.4f} at psi = "
                f"{np.round(np.degrees(psis[order[0]]), 1).tolist()} deg)", k, "margin",
                value=float(margin[order[0]]), valid=f">= {lim.margin:g}")
        chosen = None
        best_tau = math.inf
        for idx in order[:40]:
            if margin[idx] < lim.margin:
                break
            if k not in at_rest:
                chosen = idx
                break
            tau = dyn.gravity_torques(cfg.q[idx])
            if np.abs(tau).max() <= lim.torque * 0.95:
                chosen = idx
                break
            best_tau = min(best_tau, float(np.abs(tau).max()))
        if chosen is None:
            given = task.limits.get("torque", robot.limits.torque)
            raise InfeasibleTaskError(
                f"{where}: holding the platform at rest needs {best_tau:.2f} N m > "
                f"{lim.torque:g} N m (the torque limit planned to: {given:g} N m x "
                f"torque_fraction {task.torque_fraction:g}) for every crank choice with "
                f"margins >= {lim.margin:g}", k, "torque", value=best_tau,
                valid=f"<= {lim.torque:g} N m")
        out.append(psis[chosen])
    return np.array(out)


def check_crank_sides(task: Task) -> None:
    """Raise InfeasibleTaskError when one crank has to pass 0 deg between waypoints.

    A crank angle of 0 (or 180) deg is radial: the platform is singular there
    (docs/planner.md), so no motion joins a waypoint whose crank is negative to one
    where it is positive (given, or free: the static choice takes 35-145 deg).
    Without this check the solver failed from every start and the error named a
    binding torque limit instead.  (Not called with the cranks locked.)
    """
    wps = task.waypoints
    for i in range(3):
        side = [None if wp.psi is None else float(wp.psi[i]) for wp in wps]
        neg = [w for w, v in enumerate(side) if v is not None and v < 0.0]
        pos = [w for w, v in enumerate(side) if v is None or v > 0.0]
        if neg and pos:
            a, b = sorted((neg[0], pos[0]))
            say = [f"waypoint {w} free (35-145 deg)" if (v := side[w]) is None else
                   f"waypoint {w} at {math.degrees(v):.1f} deg" for w in (a, b)]
            raise InfeasibleTaskError(
                f"crank {i} would have to pass the singular 0 deg between {say[0]} "
                f"and {say[1]}: give that crank angles of one sign at every waypoint",
                b, "crank angle sign", value=[None if v is None else
                                              round(math.degrees(v), 3) for v in side],
                valid="one sign per crank: all in (0, 180) deg or all in (-180, 0) deg")


def clearance_needed(robot: Robot, task: Task, psi_wp: np.ndarray,
                     near: float = 0.02) -> bool:
    """Whether the legs' links come within ``near`` [m] at some waypoint.

    Only then are the clearance rows bounded from the first solve; otherwise they
    stay unbounded (IPOPT ignores them) unless the dense check finds interference.
    Bounding them everywhere made IPOPT slower and lost a random task (BENCHMARKS.md).
    """
    wps = task.waypoints
    cfg = robot_ik(np.array([wp.position for wp in wps]),
                   np.array([wp.rotation for wp in wps]), psi_wp, robot)
    return bool(clearance(cfg).min() < near)


__all__ = ["check_crank_sides", "choose_static_psi", "clearance_needed", "static_candidates",
           "static_checks"]
