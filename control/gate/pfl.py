"""The gate's power and force limiting check (docs/safety.md): from the file's own
samples, recomputed independently of the planner, the largest contact energy over every
direction and every body region named, at the tool centre point and (under a tool) the
platform centre, against what the region's spring holds at its ISO/TS 15066 limit.

The regions judged are the union of the file's header (``pfl``: the set it was planned
for) and the site's hardware file (``pfl``: the set the site requires, which no file can
drop).  The configurations come from the gate's own forward kinematics (the report's
platform pose and crank angles), the velocity from the actuated rates through the IK
Jacobian, the effective mass from Pinocchio's reduced inertia (rotors included).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from sixplus3.control.gate.findings import finding
from sixplus3.control.report import Finding, ValidationReport
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.dynamics.effective_mass import pfl_ratio, point_inverse_mass, point_map
from sixplus3.errors import InputError
from sixplus3.kinematics import rotations as rot
from sixplus3.kinematics.robot import RobotConfig, robot_ik
from sixplus3.kinematics.robot_fk import ik_jacobian
from sixplus3.motion import Motion
from sixplus3.robot_description import hardware
from sixplus3.robot_description.body_regions import BodyRegion, names_of, regions
from sixplus3.robot_description.robot import Robot

#: Points evaluated at a time (the reduced inertia of each: one Pinocchio pass).
CHUNK = 4096


def judged_regions(*named: object) -> tuple[BodyRegion, ...]:
    """The regions named by each of ``named`` (a header's list, a task's, ...) and those
    the site's hardware file requires, without repeats, in the standard's order."""
    names: list[str] = list(hardware.active().pfl)
    for n in named:
        if n is None:
            continue
        if not isinstance(n, (list, tuple)):
            raise InputError(f"pfl must be a list of body region names, got {n!r}",
                             value=n, valid="a list of region names")
        names += [str(x) for x in n]
    return regions(names)


def platform_twist(cfg: RobotConfig, theta_dot: np.ndarray) -> np.ndarray:
    """(n, 9) (v, omega, psi_dot) of the platform from the actuated rates through the
    inverse of the IK Jacobian (inf where it is singular)."""
    J = ik_jacobian(cfg)
    out = np.full((len(theta_dot), 9), np.inf)
    ok = np.all(np.isfinite(J), axis=(1, 2))
    if ok.any():
        out[ok] = np.linalg.solve(J[ok], np.asarray(theta_dot, dtype=float)[ok][:, :, None])[
            :, :, 0]
    return out


def pfl_check(rep: ValidationReport, robot: Robot, motion: Motion,
              judged: tuple[BodyRegion, ...]) -> ValidationReport:
    """``rep`` with the PFL check on the samples of ``motion`` (a report whose forward
    kinematics went through: ``rep.position``, ``rep.quaternion``, ``rep.psi``): its
    findings added, ``pfl`` and ``max_pfl_ratio`` set.  No region: ``rep`` itself."""
    if not judged or rep.position is None or rep.quaternion is None or rep.psi is None:
        return rep
    t, theta_dot = motion.t, motion.theta_dot
    dyn = ClosedLoopDynamics(robot)
    tool = tuple(float(c) for c in robot.tool.xyz)
    points = [tool] + ([] if tool == (0.0, 0.0, 0.0) else [(0.0, 0.0, 0.0)])
    n = len(rep.position)
    ratio = np.empty(n)
    worst = np.zeros(n, dtype=int)
    for i in range(0, n, CHUNK):
        sl = slice(i, min(n, i + CHUNK))
        R = rot.matrix_from_quat(rep.quaternion[sl])
        cfg = robot_ik(rep.position[sl], R, rep.psi[sl], robot, platform_margins=False)
        twist = platform_twist(cfg, theta_dot[sl])
        best = np.full(len(twist), -np.inf)
        for point in points:  # the tool centre point, and the centre under a tool
            A = point_inverse_mass(dyn, cfg, point=point)
            r = np.einsum("nij,j->ni", cfg.rotation, np.asarray(point, dtype=float))
            v = np.einsum("nij,nj->ni", point_map(r), twist)
            rk, wk = pfl_ratio(A, v, judged)
            rk = np.nan_to_num(rk, nan=np.inf)
            better = rk > best
            best = np.where(better, rk, best)
            worst[sl] = np.where(better, wk, worst[sl])
        ratio[sl] = best
    ratio = np.nan_to_num(ratio, nan=np.inf)
    out: list[Finding] = []
    for k, region in enumerate(judged):
        mine = np.where(worst == k, ratio, 0.0)
        f = finding(f"pfl {region.name} (contact energy / ISO/TS 15066 limit)", "limit", "",
                    1.0, mine - 1.0, mine, t, ["tcp"])
        if f:
            out.append(f)
    return replace(rep, pfl=tuple(names_of(judged)), max_pfl_ratio=float(ratio.max()),
                   findings=list(rep.findings) + out, ok=rep.ok and not out)


__all__ = ["judged_regions", "pfl_check"]
